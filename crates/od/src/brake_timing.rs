//! The holding brake's delays as a device's manual gives them (device file
//! `[device.brake]`): the objects whose values, in ms, make the waits after the output stage
//! goes on and before it goes off. The drive model reads the objects each time it switches;
//! the file says which they are.

/// The brake's delays, each the sum of its objects' values in ms (an empty list: none).
/// Each object is `(index, sub-index)` of an integer entry of the device's dictionary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BrakeTiming {
    /// Output stage on → brake open.
    pub release: &'static [(u16, u8)],
    /// Output stage on → the set-point released.
    pub motion: &'static [(u16, u8)],
    /// Brake closed → output stage off.
    pub engage: &'static [(u16, u8)],
    /// Without a holding brake fitted nothing waits.
    pub only_with_brake: bool,
}

impl BrakeTiming {
    /// No delays: CiA 402 names no brake delay object, so a file without `[device.brake]`
    /// (an EDS too) switches at once.
    pub const NONE: BrakeTiming = BrakeTiming {
        release: &[],
        motion: &[],
        engage: &[],
        only_with_brake: false,
    };
}

impl Default for BrakeTiming {
    fn default() -> Self {
        BrakeTiming::NONE
    }
}
