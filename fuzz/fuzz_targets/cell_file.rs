//! Any text as a cell file: parsed, its drives built into a CAN cell and an EtherCAT chain.
//! A bad file is an error, never a panic.
#![no_main]

use drivetwin::cell::config::CellFile;
use drivetwin::ecat::chain::SlaveChain;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(file) = toml::from_str::<CellFile>(text) else {
        return;
    };
    let _ = file.drives(drivetwin::vendors::VENDORS.runtime);
    let _ = SlaveChain::from_cell_file(&file, drivetwin::vendors::VENDORS.runtime);
});
