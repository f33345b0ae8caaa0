//! The example load FMU's C library (a cdylib, linked by no crate): the FMI 3.0 co-simulation
//! functions `fmi_export::export_fmu!` writes for the [`conveyor`] model, and the FMI 2.0 ones
//! written by hand ([`fmi2`]). `conveyor-fmu-pack` (src/bin/pack.rs) packs it with the model
//! description written from the model's declarations (docs/cosimulation.md).

#[allow(unsafe_code)]
pub mod fmi2;

fmi_export::export_fmu!(conveyor::Conveyor);
