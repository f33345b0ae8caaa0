//! Co-simulation: machine models as FMI co-simulation FMUs coupled to the drives' shafts on
//! the cell's clock (docs/cosimulation.md).

pub mod fmu_load;
pub mod fmu_log;
pub mod load_instance;
pub mod loaded_drive;
pub mod mapping;

pub use fmu_load::{FmuLoad, FmuLoadError, LoadReport, LoadValue};
pub use loaded_drive::LoadedDrive;
pub use mapping::LoadMapping;
