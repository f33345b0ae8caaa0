//! What a drive's own supervision of its plant raises and shows, as its manual gives it
//! (device file `[device.plant]`): the diagnostic messages for the motor's and the power
//! stage's temperatures and the encoder, the objects holding the temperature limits and those
//! showing the temperatures.

/// The messages (numbers of the device's diagnostic table, as the file prints them) and
/// objects (`(index, sub-index)` of integer entries, °C) of the plant supervision; `None`
/// where the manual has no such message or object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlantSupervision {
    /// The motor within the warning margin of its limit.
    pub motor_warning: Option<&'static str>,
    /// The motor above its limit.
    pub motor_over: Option<&'static str>,
    /// The power stage within the warning margin of its limit (an FHPP device's).
    pub stage_warning: Option<&'static str>,
    /// The power stage above its limit.
    pub stage_over: Option<&'static str>,
    /// The power stage below its lower limit (an FHPP device's).
    pub stage_under: Option<&'static str>,
    /// The encoder signal lost.
    pub encoder_lost: Option<&'static str>,
    /// Implausible encoder counts.
    pub encoder_implausible: Option<&'static str>,
    /// The object holding the motor's limit; `None`: the drive model's own.
    pub motor_limit: Option<(u16, u8)>,
    /// The object holding the power stage's limit; `None`: the drive model's own.
    pub stage_limit: Option<(u16, u8)>,
    /// The object holding the power stage's lower limit (an FHPP device's); `None`: the
    /// drive model's own.
    pub stage_low_limit: Option<(u16, u8)>,
    /// Where the drive shows the motor's temperature.
    pub motor_temperature: Option<(u16, u8)>,
    /// Where the drive shows the power stage's temperature.
    pub stage_temperature: Option<(u16, u8)>,
}

impl PlantSupervision {
    /// No message and no object: CiA 402 names none, so a file without `[device.plant]` (an
    /// EDS too) raises nothing of its plant and shows no temperature.
    pub const NONE: PlantSupervision = PlantSupervision {
        motor_warning: None,
        motor_over: None,
        stage_warning: None,
        stage_over: None,
        stage_under: None,
        encoder_lost: None,
        encoder_implausible: None,
        motor_limit: None,
        stage_limit: None,
        stage_low_limit: None,
        motor_temperature: None,
        stage_temperature: None,
    };
}

impl Default for PlantSupervision {
    fn default() -> Self {
        PlantSupervision::NONE
    }
}
