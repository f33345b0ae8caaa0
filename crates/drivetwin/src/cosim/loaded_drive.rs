//! A drive with its load: the engine's drive and, where the cell file gives one, the FMU
//! stepped with its plant cycles. Every path that steps the drive ([`LoadedDrive::step`])
//! steps the load with it, so no plant cycle runs without it.
//!
//! An error of the FMU stops the drive's steps: the drive stands where the error found it,
//! the error is kept ([`LoadedDrive::load_failure`]) and logged, and the cell that runs it
//! stops with the FMU's message.

use std::ops::{Deref, DerefMut};

use drive::vendors::AnyDrive;
use od::Instant;

use super::fmu_load::{FmuLoad, FmuLoadError};

/// A drive and its load FMU, if any.
pub struct LoadedDrive {
    drive: AnyDrive<Vec<u8>>,
    load: Option<FmuLoad>,
    failure: Option<FmuLoadError>,
}

impl LoadedDrive {
    pub fn new(drive: AnyDrive<Vec<u8>>) -> Self {
        LoadedDrive {
            drive,
            load: None,
            failure: None,
        }
    }

    /// Couples `load` to the shaft from the next step on (in place of any other, and of an
    /// error a former one stopped the drive with).
    pub fn set_load(&mut self, load: FmuLoad) {
        self.uncouple();
        self.load = Some(load);
    }

    /// Uncouples the load: the switches it drove go back to the travel, the shaft's load
    /// torque to 0 N·m (the console's "load" sets another), and a failure it had is
    /// forgotten: the drive steps again.
    pub fn uncouple(&mut self) {
        if let Some(load) = self.load.take() {
            for s in load.switches() {
                self.drive.set_switch(s, None);
            }
            self.drive.axis_mut().motor_mut().set_load_torque(0.0);
        }
        self.failure = None;
    }

    pub fn load(&self) -> Option<&FmuLoad> {
        self.load.as_ref()
    }

    /// Why the load stopped the drive, once it has.
    pub fn load_failure(&self) -> Option<&FmuLoadError> {
        self.failure.as_ref()
    }

    /// Runs the drive (and its load) up to `now`; the next time it wants to run. After an
    /// error of the load: nothing more (`None`).
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        if self.failure.is_some() {
            return None;
        }
        let Some(load) = &mut self.load else {
            return self.drive.step(now);
        };
        match self.drive.step_with_load(now, load) {
            Ok(next) => next,
            Err(e) => {
                tracing::error!(error = %e, "load FMU failed: the drive stops");
                self.failure = Some(e);
                None
            }
        }
    }
}

impl Deref for LoadedDrive {
    type Target = AnyDrive<Vec<u8>>;
    fn deref(&self) -> &Self::Target {
        &self.drive
    }
}

impl DerefMut for LoadedDrive {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.drive
    }
}
