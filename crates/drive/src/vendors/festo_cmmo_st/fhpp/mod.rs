//! FHPP, the Festo Handling and Positioning Profile, as the CMMO-ST manual
//! (GDCP-CMMO-ST-LK-C-HP, ch. 5 and 6) defines it: the 8 bytes of cyclic control and
//! status data (16 with the parameter channel, [`parameter_channel`]), the FHPP state
//! machine S1…S6 with its transitions T1…T11, the sub-states SA1…SA6 of "operation enabled"
//! with TA1…TA12, control authority (fieldbus against FCT / web server), and the start /
//! acknowledge handshakes of record selection, direct mode, homing, jog and teach.
//!
//! Sans-IO: [`Fhpp::cycle`] takes one output telegram (PLC → drive), the record table and the
//! [`MotionStatus`] of the motion layer, reports what the motion layer has to do as
//! [`Event`]s ([`MotionCommand`]s among them), and returns the input telegram (drive → PLC).
//! It never reads a clock: every timing rule of the manual (MC window time, start delay, warning
//! hold time) belongs to the motion or diagnostics layer that feeds [`MotionStatus`].
//!
//! Files, one concept each, named as the manual names them:
//! - [`control_bytes`]: CCON, CPOS, CDIR and the output telegram (Tab. 5.12, 5.14–5.20);
//! - [`status_bytes`]: SCON, SPOS, SDIR, RSB and the input telegram (Tab. 5.13, 5.21–5.28);
//! - [`state_machine`]: Fig. 5.1 / Tab. 5.2–5.4 and the handshakes of §5.2.3 and ch. 6;
//! - [`record_table`]: the records of PNU 401…442 (Tab. 6.7) with RCB1…RCB3 (data only);
//! - [`parameter_channel`]: the EFPC bytes 9…16 (App. C), wire codec for drive and master, and
//!   the drive's server;
//! - [`parameter_file`]: the parameter file and the permanent memory (C.4.3, PNU 127);
//! - [`parameter_file_transfer`]: its upload and download in 6-byte packets (C.4.5–C.4.7).
//!
//! The profile imports nothing of the CMMO-ST device ([`super`]): its diagnostics, homing
//! methods and device model use the profile, never the reverse.

pub mod control_bytes;
pub mod parameter_channel;
pub mod parameter_file;
pub mod parameter_file_transfer;
pub mod record_table;
pub mod state_machine;
pub mod status_bytes;

pub use control_bytes::{Ccon, Cdir, ControlMode, Cpos, OperatingMode, OutputData};
pub use record_table::{
    ChainCondition, Comparator, Comparators, Rcb1, Record, RecordSelect, RecordTable,
    StartBehaviour, TimeComparator,
};
pub use state_machine::{
    Ack, Authority, AuthorityError, Config, Event, Fault, Fhpp, MotionCommand, MotionStatus,
    OpState, Reaction, Refusal, RelativeTo, State, Transition,
};
pub use status_bytes::{InputData, Rsb, Scon, Sdir, Spos};

/// Length of the cyclic data with the profile "FHPP Standard" (§2.2, Tab. 5.11).
pub const FHPP_STD_LEN: usize = 8;
/// Length of the cyclic data with "FHPP Standard + FPC": bytes 9…16 are the EFPC channel.
pub const FHPP_FPC_LEN: usize = 16;

/// A byte written B7…B0 with a dot between the nibbles, as the manual prints bit patterns
/// (`0001.0011`). For test messages and the master's status printout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BitPattern(pub u8);

impl core::fmt::Display for BitPattern {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for i in (0..8).rev() {
            if i == 3 {
                f.write_str(".")?;
            }
            f.write_str(if self.0 & (1 << i) != 0 { "1" } else { "0" })?;
        }
        Ok(())
    }
}

/// Defines a control or status byte: a newtype over `u8` with one constant per named bit, the
/// bit names as data (for printing), and the set operations.
macro_rules! bit_byte {
    (
        $(#[$meta:meta])*
        $name:ident { $( $(#[$bmeta:meta])* $bit:ident = $value:expr, $text:expr; )* }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub u8);

        impl $name {
            $( $(#[$bmeta])* pub const $bit: $name = $name($value); )*
            /// Every named bit, with the name the manual prints, B0 first.
            pub const NAMES: &'static [($name, &'static str)] = &[$( ($name($value), $text), )*];
        }

        $crate::bit_word::bit_set_ops!($name, u8);

        /// The names of the set bits joined by `|` (B7 first), then the byte as `0001.0011`.
        impl core::fmt::Display for $name {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                let mut first = true;
                for (bit, name) in Self::NAMES.iter().rev() {
                    if self.contains(*bit) && bit.0 != 0 {
                        if !first {
                            f.write_str("|")?;
                        }
                        f.write_str(name)?;
                        first = false;
                    }
                }
                if first {
                    f.write_str("-")?;
                }
                write!(f, " ({})", $crate::vendors::festo_cmmo_st::fhpp::BitPattern(self.0))
            }
        }
    };
}

pub(crate) use bit_byte;
