//! The vendors: each folder one drive's manual where it departs from CiA 402 (its
//! [`Personality`] tables and its [`Vendor`](crate::personality::Vendor) hooks with the
//! vendor's own state) and what no standard describes (serial protocols, switches, codes),
//! and [`AnyDrive`], the drive a device file names.
//!
//! Decision: the device file names its vendor by its `name` ([`AnyDrive::new`]); a CiA 402
//! device file no vendor serves runs as the standard CiA 402 drive ([`Cia402`]).

pub mod cia402;
pub mod festo_cmmo_st;
pub mod festo_cmmp_as;
pub mod kinco;
pub mod nanotec;

use core::time::Duration;

use od::{AbortCode, Diagnostic, Entry, Instant, ObjectAccess, ObjectDictionary};

use crate::axis::{Axis, Demand};
use crate::device_control::State;
use crate::drive::diagnostics::DiagnosticError;
use crate::drive::named_switches::{NamedSwitch, SwitchInput};
use crate::drive::plant_supervision::PlantWatch;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::{Drive, DriveEvent, DriveSettings};
use crate::encoder_fault::EncoderFault;
use crate::factor_group::FactorGroup;
use crate::personality::Personality;
use crate::stepper::Stepper;
use crate::thermal::ThermalData;
pub use cia402::Cia402;
/// How the runtime builds an FHPP drive (the CMMO-ST's stepper, axis and settings), as it
/// holds the CiA 402 drives as [`AnyDrive`].
pub use festo_cmmo_st::device::FhppSettings;
use festo_cmmp_as::display::Display;
use festo_cmmp_as::error_management::MemoryEntry;
use festo_cmmp_as::{CmmpAs, CMMP_AS};
use kinco::{Kinco, KINCO};
use nanotec::{Nanotec, NANOTEC};

/// A drive of any vendor, chosen by the device file's name: what a runtime holds when the
/// vendor is known only when the device file is read.
// The variants differ by the Kinco's own state (position table, panel); a runtime that holds
// many drives boxes the whole (`no_std`: no box here), so the size difference costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum AnyDrive<S> {
    CmmpAs(Drive<S, CmmpAs>),
    Nanotec(Drive<S, Nanotec>),
    Kinco(Drive<S, Kinco>),
    Cia402(Drive<S, Cia402>),
}

/// Calls `$body` with the drive of whatever vendor `$any` holds, as `$d`.
macro_rules! each {
    ($any:expr, $d:ident => $body:expr) => {
        match $any {
            AnyDrive::CmmpAs($d) => $body,
            AnyDrive::Nanotec($d) => $body,
            AnyDrive::Kinco($d) => $body,
            AnyDrive::Cia402($d) => $body,
        }
    };
}

/// [`Drive`]'s methods on [`AnyDrive`], each passed to the drive it holds.
macro_rules! forward {
    () => {};
    ($(#[$m:meta])* fn $name:ident(&self $(, $arg:ident: $ty:ty)*) $(-> $ret:ty)?; $($rest:tt)*) => {
        $(#[$m])*
        pub fn $name(&self $(, $arg: $ty)*) $(-> $ret)? {
            each!(self, d => d.$name($($arg),*))
        }
        forward!($($rest)*);
    };
    ($(#[$m:meta])* fn $name:ident(&mut self $(, $arg:ident: $ty:ty)*) $(-> $ret:ty)?; $($rest:tt)*) => {
        $(#[$m])*
        pub fn $name(&mut self $(, $arg: $ty)*) $(-> $ret)? {
            each!(self, d => d.$name($($arg),*))
        }
        forward!($($rest)*);
    };
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> AnyDrive<S> {
    /// The drive of the vendor that serves the device file of `od` (by its name), else the
    /// standard CiA 402 drive.
    pub fn new(od: ObjectDictionary<S>, settings: DriveSettings) -> Self {
        let name = od.description().name;
        let serves = |p: &Personality| p.devices.contains(&name);
        if serves(&CMMP_AS) {
            AnyDrive::CmmpAs(Drive::new(od, settings))
        } else if serves(&NANOTEC) {
            AnyDrive::Nanotec(Drive::new(od, settings))
        } else if serves(&KINCO) {
            AnyDrive::Kinco(Drive::new(od, settings))
        } else {
            AnyDrive::Cia402(Drive::new(od, settings))
        }
    }

    /// [`Drive::step_with_load`] on the drive it holds.
    pub fn step_with_load<L: crate::drive::external_load::ExternalLoad>(
        &mut self,
        now: od::Instant,
        load: &mut L,
    ) -> Result<Option<od::Instant>, L::Error> {
        each!(self, d => d.step_with_load(now, load))
    }

    /// [`Drive::shaft`] of the drive it holds.
    pub fn shaft(&self) -> crate::drive::external_load::Shaft {
        each!(self, d => d.shaft())
    }

    /// The personality the drive runs with.
    pub fn personality(&self) -> &'static Personality {
        each!(self, d => d.personality)
    }

    /// The Kinco's own API (its inputs, panel, position table), `None` for another vendor.
    pub fn as_kinco(&self) -> Option<&Drive<S, Kinco>> {
        match self {
            AnyDrive::Kinco(d) => Some(d),
            _ => None,
        }
    }

    /// [`AnyDrive::as_kinco`], to change.
    pub fn as_kinco_mut(&mut self) -> Option<&mut Drive<S, Kinco>> {
        match self {
            AnyDrive::Kinco(d) => Some(d),
            _ => None,
        }
    }

    /// The messages raised by their number and not yet cleared, in the order raised.
    pub fn raised_diagnostics(&self) -> impl Iterator<Item = &'static Diagnostic> + '_ {
        each!(self, d => d.injected.iter().copied())
    }

    /// The diagnostic memory, oldest first (the CMMP-AS's; the other drives keep none).
    pub fn diagnostic_memory(&self) -> impl Iterator<Item = &MemoryEntry> {
        let memory = match self {
            AnyDrive::CmmpAs(d) => Some(d.diagnostic_memory()),
            _ => None,
        };
        memory.into_iter().flatten()
    }

    /// What the drive's display shows: the CMMP-AS's 7-segment display (App. B). `None`
    /// for a drive whose manual names no such display: the Nanotec (its manual has none),
    /// the standard CiA 402 drive (the profile has none), the Kinco (its LED panel is its
    /// own, [`Drive::kinco_panel`]).
    pub fn display(&self) -> Option<Display> {
        match self {
            AnyDrive::CmmpAs(d) => Some(d.display()),
            AnyDrive::Nanotec(_) | AnyDrive::Kinco(_) | AnyDrive::Cia402(_) => None,
        }
    }

    forward! {
        fn od(&self) -> &ObjectDictionary<S>;
        fn od_mut(&mut self) -> &mut ObjectDictionary<S>;
        fn step(&mut self, now: Instant) -> Option<Instant>;
        fn sync(&mut self, now: Instant);
        fn interpolation_period(&self) -> Duration;
        fn ip_synchronised(&self) -> bool;
        fn errors(&self) -> &[u16];
        fn state(&self) -> State;
        fn axis(&self) -> &Axis;
        fn axis_mut(&mut self) -> &mut Axis;
        fn factor_group(&self) -> &FactorGroup;
        fn demand(&self) -> Demand;
        fn take_event(&mut self) -> Option<DriveEvent>;
        fn reload(&mut self);
        fn set_safe_standstill(&mut self, on: bool);
        fn diagnostic_table(&self) -> &'static [Diagnostic];
        fn raise_diagnostic(&mut self, number: &str) -> Result<&'static Diagnostic, DiagnosticError>;
        fn clear_diagnostic(&mut self, number: &str) -> Result<&'static Diagnostic, DiagnosticError>;
        fn diagnostic_active(&self, row: &'static Diagnostic) -> bool;
        fn force_inputs(&mut self, mask: u16, levels: u16);
        fn digital_outputs(&self) -> u32;
        fn inject_fault(&mut self, code: u16, register: u8);
        fn clear_fault(&mut self, code: u16);
        fn switch_input(&self, switch: NamedSwitch) -> Option<SwitchInput>;
        fn forced_inputs(&self) -> (u16, u16);
        fn set_switch(&mut self, switch: NamedSwitch, actuated: Option<bool>) -> Option<SwitchInput>;
        fn plant_position(&self) -> i64;
        fn plant_velocity_rpm(&self) -> f32;
        fn stepper(&self) -> Option<&Stepper>;
        fn stepper_mut(&mut self) -> Option<&mut Stepper>;
        fn bldc(&self) -> Option<&crate::bldc::BldcData>;
        fn plant_watch(&self) -> &PlantWatch;
        fn set_ambient_temperature(&mut self, celsius: f64);
        fn set_thermal_data(&mut self, data: ThermalData);
        fn set_encoder_fault(&mut self, fault: EncoderFault);
        fn set_dc_link_voltage(&mut self, mv: Option<u32>);
        fn refusal(&self, request: Request) -> Option<Refusal>;
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectAccess for AnyDrive<S> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        each!(self, d => ObjectAccess::entry(d, index, sub))
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        each!(self, d => ObjectAccess::read(d, index, sub, buf))
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        each!(self, d => ObjectAccess::write(d, index, sub, data))
    }

    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        each!(self, d => ObjectAccess::write_internal(d, index, sub, data))
    }
}
