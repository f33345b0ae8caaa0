//! Device description files: the TOML schema of `devices/*.toml`, its validation, and the
//! Rust code generator that turns a description into `od::DeviceDescription` tables at build
//! time. Runs on the host only (build scripts and tools), so it may allocate freely.

pub mod codegen;
pub mod model;
pub mod schema;

pub use model::{load_file, parse, DescError, Device};
