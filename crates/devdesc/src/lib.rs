//! Device descriptions: the TOML schema of `devices/*.toml`, its validation, and the
//! Rust code generator that turns a description into `od::DeviceDescription` tables at build
//! time; and CiA 306 EDS / DCF files read into the same description and built into tables
//! at run time. Runs on the host only (build scripts and tools), so it may allocate freely.

pub mod codegen;
pub mod eds;
pub mod model;
pub mod runtime;
pub mod schema;

pub use model::{load_file, parse, DescError, Device};
