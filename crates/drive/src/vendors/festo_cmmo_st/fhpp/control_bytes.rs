//! The output telegram (PLC → drive): CCON, CPOS, CDIR and the set-point bytes
//! (CMMO-ST manual §5.3.2 Tab. 5.11, §5.4.1 Tab. 5.12, 5.14–5.20).

use super::bit_byte;

bit_byte! {
    /// CCON, control byte 1, in every FHPP operating mode (Tab. 5.14).
    Ccon {
        /// 1 = enable drive (controller); 0 = drive disabled, the current task stops (Quick Stop).
        ENABLE = 0x01, "ENABLE";
        /// 1 = operation enabled; 0 = STOP: task aborted, stop with the Quick-Stop deceleration.
        STOP = 0x02, "STOP";
        /// 1 = release (open) the brake; only while the controller is disabled.
        BRAKE = 0x04, "BRAKE";
        /// Rising edge acknowledges pending faults.
        RESET = 0x08, "RESET";
        /// 1 = FCT (and the web server) cannot take device control.
        LOCK = 0x20, "LOCK";
        /// FHPP operating mode, low bit (B6).
        OPM1 = 0x40, "OPM1";
        /// FHPP operating mode, high bit (B7).
        OPM2 = 0x80, "OPM2";
    }
}

bit_byte! {
    /// CPOS, control byte 2, in every FHPP operating mode (Tab. 5.15).
    Cpos {
        /// Active low: 1 = no halt requested; 0 = halt (intermediate stop in position mode).
        HALT = 0x01, "HALT";
        /// Rising edge takes over the set-point data and starts the task.
        START = 0x02, "START";
        /// Rising edge starts homing.
        HOM = 0x04, "HOM";
        /// Jog towards increasing actual value while set.
        JOGP = 0x08, "JOGP";
        /// Jog towards decreasing actual value while set.
        JOGN = 0x10, "JOGN";
        /// Falling edge teaches the actual value (target per PNU 520).
        TEACH = 0x20, "TEACH";
        /// Rising edge in "halt" deletes the remaining path (→ SA1 "ready").
        CLEAR = 0x40, "CLEAR";
    }
}

bit_byte! {
    /// CDIR, control byte 3 in direct mode (Tab. 5.16).
    Cdir {
        /// 1 = set-point relative; 0 = absolute (position mode only).
        ABS = 0x01, "ABS";
        /// Control mode, low bit.
        COM1 = 0x02, "COM1";
        /// Control mode, high bit.
        COM2 = 0x04, "COM2";
        /// 1 = stroke monitoring inactive (force and velocity modes only).
        XLIM = 0x20, "XLIM";
    }
}

impl Ccon {
    /// The bits the manual defines; B4 is reserved and "must be 0" (Tab. 5.14).
    pub const DEFINED: Ccon = Ccon(0xEF);

    /// The operating mode requested by OPM2/OPM1.
    pub const fn operating_mode(self) -> OperatingMode {
        OperatingMode::from_bits(self.0 >> 6)
    }

    /// `self` with OPM2/OPM1 set to `mode`.
    #[must_use]
    pub const fn with_operating_mode(self, mode: OperatingMode) -> Ccon {
        Ccon((self.0 & 0x3F) | (mode.bits() << 6))
    }
}

impl Cpos {
    /// The bits the manual defines; B7 is reserved and "must be 0" (Tab. 5.15).
    pub const DEFINED: Cpos = Cpos(0x7F);
}

impl Cdir {
    /// The bits the manual defines; B3, B4, B6, B7 are reserved (Tab. 5.16).
    pub const DEFINED: Cdir = Cdir(0x27);

    /// COM2/COM1; `None` for the reserved value 11.
    pub const fn control_mode(self) -> Option<ControlMode> {
        ControlMode::from_bits((self.0 >> 1) & 0x03)
    }

    /// `self` with COM2/COM1 set to `mode`.
    #[must_use]
    pub const fn with_control_mode(self, mode: ControlMode) -> Cdir {
        Cdir((self.0 & !0x06) | (mode.bits() << 1))
    }

    /// ABS = 1: the set-point is relative (position mode only).
    pub const fn relative(self) -> bool {
        self.contains(Cdir::ABS)
    }
}

/// The FHPP operating mode, CCON / SCON bits OPM2 OPM1 (Tab. 5.14, 5.21).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum OperatingMode {
    /// 00: record selection.
    #[default]
    RecordSelection,
    /// 01: direct mode.
    Direct,
    /// 10 or 11: reserved (the raw value of OPM2 OPM1).
    Reserved(u8),
}

impl OperatingMode {
    /// From the two bits OPM2 OPM1 (only the low two bits of `bits` are used).
    pub const fn from_bits(bits: u8) -> Self {
        match bits & 0x03 {
            0 => OperatingMode::RecordSelection,
            1 => OperatingMode::Direct,
            other => OperatingMode::Reserved(other),
        }
    }

    pub const fn bits(self) -> u8 {
        match self {
            OperatingMode::RecordSelection => 0,
            OperatingMode::Direct => 1,
            OperatingMode::Reserved(b) => b & 0x03,
        }
    }
}

/// The control mode of a direct task or a record: CDIR / SDIR COM2 COM1, RCB1 bits 2, 1
/// (Tab. 5.16, 5.23; PNU 401).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ControlMode {
    /// 00: position mode.
    #[default]
    Position,
    /// 01: force / torque mode (current control).
    Force,
    /// 10: velocity mode (speed control).
    Velocity,
}

impl ControlMode {
    /// From COM2 COM1; `None` for the reserved value 11 (an "invalid record" in RCB1).
    pub const fn from_bits(bits: u8) -> Option<Self> {
        match bits & 0x03 {
            0 => Some(ControlMode::Position),
            1 => Some(ControlMode::Force),
            2 => Some(ControlMode::Velocity),
            _ => None,
        }
    }

    pub const fn bits(self) -> u8 {
        match self {
            ControlMode::Position => 0,
            ControlMode::Force => 1,
            ControlMode::Velocity => 2,
        }
    }
}

/// The 8 output bytes (Tab. 5.11). Byte 1 is CCON and byte 2 CPOS in every mode; bytes 3…8
/// depend on the operating mode:
///
/// | mode | byte 3 | byte 4 | bytes 5…8 |
/// |---|---|---|---|
/// | record selection | record number (0 = homing, 1…64) | reserved (0) | reserved (0) |
/// | direct | CDIR | set-point value 1 (`u8`, percent) | set-point value 2 (`i32`) |
///
/// Multi-byte values are big-endian on Modbus (§5.3.1: "high byte first").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct OutputData {
    pub ccon: Ccon,
    pub cpos: Cpos,
    /// Record number (record selection) or CDIR (direct mode).
    pub byte3: u8,
    /// Reserved (record selection) or set-point value 1 (direct mode).
    pub byte4: u8,
    /// Reserved (record selection) or set-point value 2 (direct mode), bytes 5…8.
    pub setpoint2: i32,
}

impl OutputData {
    /// A record-selection telegram: record number in byte 3, bytes 4…8 reserved (Tab. 5.19/5.20).
    pub const fn record(ccon: Ccon, cpos: Cpos, record: u8) -> Self {
        OutputData {
            ccon,
            cpos,
            byte3: record,
            byte4: 0,
            setpoint2: 0,
        }
    }

    /// A direct-mode telegram: CDIR, set-point value 1 and 2 (Tab. 5.16–5.18).
    pub const fn direct(ccon: Ccon, cpos: Cpos, cdir: Cdir, setpoint1: u8, setpoint2: i32) -> Self {
        OutputData {
            ccon,
            cpos,
            byte3: cdir.0,
            byte4: setpoint1,
            setpoint2,
        }
    }

    /// Byte 3 read as the record number (record selection).
    pub const fn record_number(&self) -> u8 {
        self.byte3
    }

    /// Byte 3 read as CDIR (direct mode).
    pub const fn cdir(&self) -> Cdir {
        Cdir(self.byte3)
    }

    /// Byte 4 read as set-point value 1 (direct mode).
    pub const fn setpoint1(&self) -> u8 {
        self.byte4
    }

    pub const fn from_bytes(b: [u8; 8]) -> Self {
        OutputData {
            ccon: Ccon(b[0]),
            cpos: Cpos(b[1]),
            byte3: b[2],
            byte4: b[3],
            setpoint2: i32::from_be_bytes([b[4], b[5], b[6], b[7]]),
        }
    }

    pub const fn to_bytes(&self) -> [u8; 8] {
        let s = self.setpoint2.to_be_bytes();
        [
            self.ccon.0,
            self.cpos.0,
            self.byte3,
            self.byte4,
            s[0],
            s[1],
            s[2],
            s[3],
        ]
    }

    /// Splits a received output image of 8 bytes (FHPP Standard) or 16 bytes (FHPP + FPC) into
    /// the FHPP part and the 8 EFPC bytes (FPCC first). `None` for any other length.
    pub fn parse(image: &[u8]) -> Option<(OutputData, Option<[u8; 8]>)> {
        let (fhpp, rest) = image.split_first_chunk::<8>()?;
        let fpc = match rest.len() {
            0 => None,
            8 => Some(<[u8; 8]>::try_from(rest).ok()?),
            _ => return None,
        };
        Some((OutputData::from_bytes(*fhpp), fpc))
    }
}

/// Rising and falling edges of one control byte between two cycles ("P" and "N" of the
/// manual's patterns, Tab. 5.2 footnote 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Edges {
    pub rising: u8,
    pub falling: u8,
}

impl Edges {
    pub const fn between(previous: u8, current: u8) -> Self {
        Edges {
            rising: current & !previous,
            falling: previous & !current,
        }
    }

    pub const fn rose(&self, bit: u8) -> bool {
        self.rising & bit != 0
    }

    pub const fn fell(&self, bit: u8) -> bool {
        self.falling & bit != 0
    }
}

/// Direct-mode percent scaling (Tab. 5.17, §5.3.2 Example 6 step 6.1): `percent` of `base`,
/// where 0 = no velocity and anything above 100 (up to 255) is "internally limited to 100 %".
pub const fn percent_of(percent: u8, base: u32) -> u32 {
    let p = if percent > 100 { 100 } else { percent };
    ((p as u64 * base as u64) / 100) as u32
}
