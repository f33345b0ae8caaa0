//! The input telegram (drive → PLC): SCON, SPOS, SDIR, RSB and the actual values
//! (CMMO-ST manual §5.3.2 Tab. 5.11, §5.4.2 Tab. 5.13, 5.21–5.28).

use super::bit_byte;
use super::control_bytes::{ControlMode, OperatingMode};

bit_byte! {
    /// SCON, status byte 1, in every FHPP operating mode (Tab. 5.21).
    Scon {
        /// 1 = drive (controller) enabled.
        ENABLED = 0x01, "ENABLED";
        /// 1 = operation enabled, positioning possible; 0 = stop active.
        OPEN = 0x02, "OPEN";
        /// 1 = warning present.
        WARN = 0x04, "WARN";
        /// 1 = fault present (also while the fault reaction runs, see `state_machine`).
        FAULT = 0x08, "FAULT";
        /// 1 = load voltage present.
        VLOAD = 0x10, "VLOAD";
        /// 1 = device control is not possible via the fieldbus (FCT or the web server has it).
        FCT_MMI = 0x20, "FCT/MMI";
        /// Operating-mode feedback, low bit.
        OPM1 = 0x40, "OPM1";
        /// Operating-mode feedback, high bit.
        OPM2 = 0x80, "OPM2";
    }
}

bit_byte! {
    /// SPOS, status byte 2, in every FHPP operating mode (Tab. 5.22).
    Spos {
        /// Active low like CPOS.HALT: 1 = halt not active, the axis can move; 0 = halt active.
        HALT = 0x01, "HALT";
        /// 1 = start executed (homing, jog, positioning); 0 = ready for start.
        ACK = 0x02, "ACK";
        /// Motion complete: 1 = task complete (or ended by an error); 0 = task started.
        MC = 0x04, "MC";
        /// 1 = teach executed, actual value accepted; 0 = ready for teach.
        TEACH = 0x08, "TEACH";
        /// 1 = axis speed ≥ limit value.
        MOV = 0x10, "MOV";
        /// 1 = following error active (FOLERR, as the manual names it).
        FOLERR = 0x20, "FOLERR";
        /// 1 = after MC the axis has left the standstill window.
        STILL = 0x40, "STILL";
        /// 1 = axis referenced, homing not needed.
        REF = 0x80, "REF";
    }
}

bit_byte! {
    /// SDIR, status byte 3 in direct mode (Tab. 5.23). The CMMO-ST has no FAST bit (RCB1 bit 6
    /// "FAST" is "not supported / reserved").
    Sdir {
        /// 1 = set-point relative.
        ABS = 0x01, "ABS";
        /// Control-mode feedback, low bit.
        COM1 = 0x02, "COM1";
        /// Control-mode feedback, high bit.
        COM2 = 0x04, "COM2";
        /// 1 = velocity limit reached.
        VLIM = 0x10, "VLIM";
        /// 1 = stroke limit reached.
        XLIM = 0x20, "XLIM";
    }
}

bit_byte! {
    /// RSB, status byte 4 in record selection (Tab. 5.27).
    Rsb {
        /// 1 = first switching condition of a record chain reached.
        RC1 = 0x01, "RC1";
        /// Valid while MC: 1 = record chain processed completely; 0 = chain aborted.
        RCC = 0x02, "RCC";
        /// 1 = velocity limit reached.
        VLIM = 0x10, "VLIM";
        /// 1 = stroke limit reached.
        XLIM = 0x20, "XLIM";
    }
}

impl Scon {
    /// The operating-mode feedback OPM2/OPM1.
    pub const fn operating_mode(self) -> OperatingMode {
        OperatingMode::from_bits(self.0 >> 6)
    }
}

impl Sdir {
    /// The control-mode feedback; `None` for the reserved 11.
    pub const fn control_mode(self) -> Option<ControlMode> {
        ControlMode::from_bits((self.0 >> 1) & 0x03)
    }
}

/// The 8 input bytes (Tab. 5.11). Byte 1 is SCON and byte 2 SPOS in every mode; bytes 3…8
/// follow the operating mode *feedback* (SCON.OPM):
///
/// | mode | byte 3 | byte 4 | bytes 5…8 |
/// |---|---|---|---|
/// | record selection | record number feedback | RSB | actual position \[SINC\] |
/// | direct | SDIR | actual value 1 (`u8`) | actual value 2 (`i32`) |
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct InputData {
    pub scon: Scon,
    pub spos: Spos,
    /// Record number feedback (record selection) or SDIR (direct mode).
    pub byte3: u8,
    /// RSB (record selection) or actual value 1 (direct mode).
    pub byte4: u8,
    /// Actual position (record selection) or actual value 2 (direct mode), bytes 5…8.
    pub actual2: i32,
}

impl InputData {
    /// Byte 3 read as the record number feedback.
    pub const fn record_number(&self) -> u8 {
        self.byte3
    }

    /// Byte 3 read as SDIR.
    pub const fn sdir(&self) -> Sdir {
        Sdir(self.byte3)
    }

    /// Byte 4 read as RSB.
    pub const fn rsb(&self) -> Rsb {
        Rsb(self.byte4)
    }

    /// Byte 4 read as actual value 1.
    pub const fn actual1(&self) -> u8 {
        self.byte4
    }

    pub const fn from_bytes(b: [u8; 8]) -> Self {
        InputData {
            scon: Scon(b[0]),
            spos: Spos(b[1]),
            byte3: b[2],
            byte4: b[3],
            actual2: i32::from_be_bytes([b[4], b[5], b[6], b[7]]),
        }
    }

    pub const fn to_bytes(&self) -> [u8; 8] {
        let a = self.actual2.to_be_bytes();
        [
            self.scon.0,
            self.spos.0,
            self.byte3,
            self.byte4,
            a[0],
            a[1],
            a[2],
            a[3],
        ]
    }
}
