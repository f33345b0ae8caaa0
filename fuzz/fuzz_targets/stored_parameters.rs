//! Stored parameter files as they come back from disk, damaged in any way: the CANopen store
//! (one `index sub value` line each, CiA 306 style) applied to a CMMP-AS dictionary, and the
//! CMMO-ST permanent memory (its parameter file with CRC) at power-on. A bad file is refused
//! or skipped, never a panic, and a refused CMMO-ST file changes nothing.
#![no_main]

use drive::fhpp::device::{FhppDevice, FhppSettings};
use drivetwin::cell::param_store::{apply, StoredValue};
use libfuzzer_sys::fuzz_target;
use od::ObjectDictionary;

fn canopen_store(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let desc = &devices::CMMP_AS;
    let Ok(mut od) = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]) else {
        return;
    };
    let mut buf = vec![0u8; 65536];
    let mut values = Vec::new();
    for line in text.lines() {
        match od::parameter_file::parse_line(line, &mut buf) {
            Ok(Some((index, sub, n))) => values.push(StoredValue {
                index,
                sub,
                bytes: buf.get(..n).unwrap_or(&[]).to_vec(),
            }),
            Ok(None) => {}
            Err(_) => return,
        }
    }
    apply(&mut od, &values, |_| true);
}

fn cmmo_st_memory(data: &[u8]) {
    let desc = &devices::CMMO_ST;
    let Ok(od) = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]) else {
        return;
    };
    let mut dev = FhppDevice::new(od, FhppSettings::default());
    let snapshot = |dev: &FhppDevice<Vec<u8>>| -> Vec<Vec<u8>> {
        dev.od()
            .storable_values(1)
            .map(|(_, v)| v.to_vec())
            .collect()
    };
    let before = snapshot(&dev);
    if dev.power_on_from_memory(data).is_err() {
        assert_eq!(snapshot(&dev), before, "a refused file changes nothing");
    }
}

fuzz_target!(|data: &[u8]| {
    match data.split_first() {
        Some((0, rest)) => cmmo_st_memory(rest),
        Some((_, rest)) => canopen_store(rest),
        None => {}
    }
});
