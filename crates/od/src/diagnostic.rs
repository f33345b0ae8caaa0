//! A device's diagnostic messages as its manual tables them (CMMP-AS App. B, CMMO-ST App. D,
//! Nanotec §7, Kinco §7): the `[[diagnostic]]` rows of `devices/*.toml`, generated into the
//! description beside the objects. The drive models read them to raise a message by its
//! number exactly as their own supervision does.

/// The default reaction the manual prints for a message (CMMP-AS Tab. B.1 legend; the other
/// manuals' reactions map onto the same words).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reaction {
    /// "PS off": output stage off at once, not configurable.
    PsOff,
    /// "QStop": quick stop with the parameterised ramp, then fault; not configurable.
    QuickStop,
    /// "configurable": the device's error management decides (CMMP-AS 2100h, Nanotec
    /// 2020h/605Eh, the FHPP PNU 242).
    Configurable,
    /// "Warn": a warning, no stop.
    Warning,
    /// "Ignore": no message, an entry of the diagnostic memory only.
    Ignore,
    /// The manual prints no reaction ("n/s"); the device's error management decides.
    Unstated,
}

/// One row of a diagnostic table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Diagnostic {
    /// The number as the manual prints it and as the API names it: "08-2" (CMMP-AS main-sub),
    /// "2Fh" (CMMO-ST), "0800h" (Nanotec error bit code), "ES.5" (Kinco Error_State bit 5).
    pub number: &'static str,
    /// The CiA 301 EMCY error code (603Fh, 1003h), `None` where the manual assigns none.
    pub code: Option<u16>,
    /// The error register 1001h bits the message sets (bit 0 generic is added by the stack).
    pub register: u8,
    pub reaction: Reaction,
    /// The manual's text (English extract wording).
    pub text: &'static str,
    /// What the device's display shows where the manual prints it (Kinco LED `002.0`);
    /// empty where the display is derived from the number.
    pub display: &'static str,
    /// FHPP classes the message may have, "F/W/I" with "-" for an impossible one; empty
    /// for CiA 402 devices.
    pub classes: &'static str,
    /// FHPP reactions A…G PNU 242 may select ("ABCEF"); empty for CiA 402 devices.
    pub reactions: &'static str,
    /// FHPP: "always" or "optional" (App. D "Diag. memory"); empty for CiA 402 devices.
    pub memory: &'static str,
    /// FHPP: "immediately", "after_cause" or "reset" (App. D "Ack"); empty for CiA 402 devices.
    pub ack: &'static str,
    /// Where the manual says so.
    pub source: &'static str,
}
