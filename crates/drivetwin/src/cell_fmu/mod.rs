//! A cell as an FMI 3.0 co-simulation FMU (FMI 3.0 §4 "Co-Simulation"): the importer's
//! `fmi3DoStep` advances the cell's virtual clock, its inputs are each drive's load torque and
//! digital inputs, its outputs each drive's shaft, current and words (docs/cosimulation.md).
//!
//! - [`variables`]: the FMU's variables and value references, from the cell's drives;
//! - [`model_description`]: `modelDescription.xml` from those variables;
//! - [`instance`]: one instance: the cell on the virtual clock, stepped by the importer;
//! - [`front_ends`]: the cell's socketcand servers, open while the importer steps it;
//! - [`modbus_front`]: the Modbus TCP servers of its CMMO-STs, open while the importer steps it;
//! - [`parameters`]: the cell file's keys that are FMI parameters, set before it is built;
//! - [`ethercat_front`]: its EtherCAT chains on the FMU's clock, their raw sockets open while
//!   the importer steps it;
//! - [`serving_thread`]: the thread each of those front ends serves its sockets on;
//! - [`archive`]: the `.fmu` (a zip of the description, the binary and the cell file);
//! - [`ls_bus`]: FMI-LS-BUS CAN bus operations, parsed and emitted;
//! - [`can_terminal`]: one FMI-LS-BUS CAN terminal per bus of the cell (`canB.Rx_Data`, …).
//!
//! The FMI C functions are in `crates/cell-fmu` (a `cdylib` on `fmi-export`), which holds an
//! [`instance::CellInstance`]; `drivetwin fmu` writes the archive.

pub mod archive;
pub mod can_terminal;
pub mod ethercat_front;
pub mod front_ends;
pub mod instance;
pub mod ls_bus;
pub mod modbus_front;
pub mod model_description;
pub mod parameters;
pub mod serving_thread;
pub mod variables;

/// The FMU's `modelIdentifier`: its binary is `binaries/x86_64-linux/drivetwin_cell.so`.
pub const MODEL_IDENTIFIER: &str = "drivetwin_cell";

/// The instantiation token of the description and of the binary of one drivetwin version
/// (FMI 3.0 §2.4.1: the importer passes the description's token to `fmi3Instantiate…`).
pub const INSTANTIATION_TOKEN: &str = concat!("{drivetwin-cell-", env!("CARGO_PKG_VERSION"), "}");

/// The cell file in the FMU's `resources/` folder.
pub const CELL_FILE: &str = "cell.toml";

/// The timeline in the FMU's `resources/` folder (a scenario file whose actions run at their
/// times), when the FMU has one.
pub const TIMELINE_FILE: &str = "timeline.toml";

/// The network interface of the chain of the EtherCAT slaves that name none (`interfaces =
/// ["ethercat"]`), in the FMU's `resources/` folder, when `drivetwin fmu --ethercat IFNAME`
/// names it: the cell file's form `drivetwin run --ethercat IFNAME` takes.
pub const ETHERCAT_FILE: &str = "ethercat_interface.txt";

/// Why a cell FMU could not be made or stepped.
#[derive(Debug, thiserror::Error)]
pub enum CellFmuError {
    #[error("{path}: {source}")]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error("cell: {0}")]
    Cell(String),
    #[error("timeline: {0}")]
    Timeline(String),
    #[error("the cell has no drive to show as variables (the virtual clock runs the CANopen drives of its buses, its CMMO-STs and its EtherCAT slaves)")]
    NoDrive,
    #[error("two drives' variables would be named `{0}`: a CANopen drive's are named by its node-ID, and that node-ID is on more than one bus")]
    DuplicateName(String),
    #[error("no variable with value reference {0} of that type")]
    UnknownVariable(u32),
    #[error("{needed} value references and room for {given} values")]
    TooFewValues { given: usize, needed: usize },
    #[error("{0} is not a time the FMU can step to (0 … 584 years, in ns)")]
    BadTime(f64),
    #[error("doStep at t = {given} s: the FMU is at t = {at} s")]
    NotAtTime { given: f64, at: f64 },
    #[error("the cell stopped at t = {at} s: {why}")]
    Stopped { at: f64, why: String },
    #[error("front end: {what}: {source}")]
    FrontEnd {
        what: String,
        source: std::io::Error,
    },
    #[error("fmu archive: {0}")]
    Archive(String),
}
