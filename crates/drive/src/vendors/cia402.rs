//! The standard CiA 402 drive: every [`Vendor`] hook at its default, the modes a device
//! description's 6502h supported_drive_modes allows, the factor group of the objects the
//! description has (the feed constant 6092h where it has one, else 6093h / 6094h / 6097h).
//! A device file without a vendor of its own runs as this drive.

use od::{AbortCode, DeviceDescription, ObjectAccess, Value};

use crate::drive::refusal::{Refusal, Request};
use crate::drive::{Drive, Hook};
use crate::homing::{engine_method, Method};
use crate::personality::{Capabilities, ErrorSpec, Fault, ModeSpec, Personality, Vendor};

/// The generic CiA 402 drive; it keeps no state beside the engine's.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cia402;

const fn mode(mode: i8, bit: u8) -> ModeSpec {
    ModeSpec {
        mode,
        bit: Some(bit),
        ethercat_only: false,
    }
}

/// The CiA 402 modes the engine runs (§6.4.4 6502h bits): profile position, velocity (VL),
/// profile velocity, profile torque, homing, interpolated position, cyclic synchronous
/// position. [`Cia402::refusal`] narrows them to the device's 6502h.
const MODES: [ModeSpec; 7] = [
    mode(1, 0),
    mode(2, 1),
    mode(3, 2),
    mode(4, 3),
    mode(6, 5),
    mode(7, 6),
    mode(8, 7),
];

/// CiA 402 §6.3.1 error codes (the EMCY codes of CiA 301 §7.2.7.1 Tab. 21 for drives) with
/// the generic bit of the error register and the bit of their class (CiA 301 §7.5.2.2).
const ERRORS: [ErrorSpec; 4] = [
    ErrorSpec {
        fault: Fault::FollowingError,
        code: 0x8611,
        register: 0x01,
        critical: false,
    },
    ErrorSpec {
        fault: Fault::DcLinkUndervoltage,
        code: 0x3220,
        register: 0x05,
        critical: false,
    },
    ErrorSpec {
        fault: Fault::I2tMotor,
        code: 0x2310,
        register: 0x03,
        critical: false,
    },
    // 8700h "sync controller": the SYNC grid (a CANopen SYNC in interpolated position, the
    // SYNC0 events on EtherCAT) lost while the drive runs on it, with the communication bit
    // (bit 4) of the error register: a slave that falls back to Safe-Op with 0x001A takes no
    // more set-points, and the drive says so in its statusword rather than stand enabled on
    // the last one.
    ErrorSpec {
        fault: Fault::FieldbusSyncError,
        code: 0x8700,
        register: 0x11,
        critical: false,
    },
];

/// The CiA 402 homing methods (§6.7.4) the engine has steps for.
const HOMING_METHODS: [Method; 11] = [
    engine_method(1),
    engine_method(2),
    engine_method(7),
    engine_method(11),
    engine_method(17),
    engine_method(18),
    engine_method(23),
    engine_method(27),
    engine_method(33),
    engine_method(34),
    engine_method(35),
];

const fn personality(feed_constant: bool) -> Personality {
    Personality {
        devices: &[],
        modes: &MODES,
        option_codes: &[],
        // CiA 402 §6.1.1 Tab. 3: "Switch on + enable operation" (0Fh) in READY TO SWITCH ON
        // runs transition 3 and then 4.
        enable_from_ready: true,
        errors: &ERRORS,
        stepper_plant: false,
        pp_overwrite_queued: false,
        capabilities: Capabilities {
            feed_constant,
            pp_target_limits: false,
            ip_follows_sync: false,
            ip_changing_until_synchronised: false,
            ip_abrupt_quick_stop: false,
            homing_immediate: false,
            brake_in_60fe: false,
            zero_ramp_is_abrupt: false,
            vl_actual_closed_loop_only: false,
            internal_position_in_user_units: false,
        },
        homing_methods: &HOMING_METHODS,
        external_home_switch: None,
        hardware_enable: None,
    }
}

/// The standard drive with the factor group 6093h / 6094h / 6097h.
pub const CIA402: Personality = personality(false);
/// The standard drive with the feed constant 6092h and the gear ratio 6091h (CiA 402 v2).
pub const CIA402_FEED_CONSTANT: Personality = personality(true);

impl Vendor for Cia402 {
    fn for_device(desc: &'static DeviceDescription) -> (&'static Personality, Self) {
        let personality = if desc.object(0x6092).is_some() {
            &CIA402_FEED_CONSTANT
        } else {
            &CIA402
        };
        (personality, Cia402)
    }

    fn write_hook<S: AsRef<[u8]> + AsMut<[u8]>>(index: u16, sub: u8) -> Option<Hook<S, Self>> {
        match (index, sub) {
            (0x6060, 0x00) => Some(Drive::<S, Self>::cia402_write_mode),
            (0x6098, 0x00) => Some(Drive::<S, Self>::cia402_write_homing_method),
            _ => None,
        }
    }

    /// A mode 6502h does not list is not supported (§6.4.4).
    fn refusal<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        request: Request,
    ) -> Option<Refusal> {
        match request {
            Request::Mode(m) if !d.cia402_supports(m) => Some(Refusal::ModeUnsupported { mode: m }),
            _ => None,
        }
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Cia402> {
    /// Whether 6502h supported_drive_modes has the bit of `mode` (a device without 6502h:
    /// every mode of the engine).
    fn cia402_supports(&self, mode: i8) -> bool {
        let Some(Value::Unsigned(modes)) = self.od().value(0x6502, 0) else {
            return true;
        };
        MODES
            .iter()
            .find(|m| m.mode == mode)
            .and_then(|m| m.bit)
            .is_some_and(|bit| modes & (1 << bit) != 0)
    }

    /// 6060h: a mode outside 6502h is refused with 0609 0030h (value range).
    fn cia402_write_mode(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_mode_unless(index, sub, data, |d, m| {
            (!d.cia402_supports(m)).then_some(AbortCode::INVALID_VALUE)
        })
    }

    /// 6098h: a method the drive has no steps for (not in its personality, e.g. not in the
    /// 60E3h of its EDS) is refused with 0609 0030h (value range), as CiA 402 §6.7.4 leaves
    /// the supported methods to the device and 60E3h lists them.
    fn cia402_write_homing_method(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if let [b] = data {
            if !self.personality.homing_method(*b as i8) {
                self.od.entry(index, sub)?;
                return Err(AbortCode::INVALID_VALUE);
            }
        }
        self.od.write(index, sub, data)
    }
}
