//! Stored parameter files as they come back from disk, damaged in any way: the CANopen store
//! (one `index sub value` line each, CiA 306 style) applied to a CMMP-AS dictionary, and the
//! CMMO-ST permanent memory (its parameter file with CRC) at power-on. A bad file is refused
//! or skipped, never a panic, and a refused CMMO-ST file changes nothing.
//!
//! Speed: both dictionaries are built with their defaults once and copied for every input;
//! the parse buffer is allocated once.
#![no_main]

use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
use drivetwin::cell::param_store::{apply, StoredValue};
use libfuzzer_sys::fuzz_target;
use od::{DeviceDescription, ObjectDictionary};
use std::cell::RefCell;
use std::sync::OnceLock;

type Od = ObjectDictionary<Vec<u8>>;

fn build(desc: &'static DeviceDescription) -> Option<Od> {
    ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).ok()
}

/// The CMMP-AS and CMMO-ST dictionaries with their defaults, built once.
fn dictionary(cmmo_st: bool) -> Option<Od> {
    static OD: OnceLock<(Option<Od>, Option<Od>)> = OnceLock::new();
    let (cmmp, cmmo) = OD.get_or_init(|| (build(&devices::CMMP_AS), build(&devices::CMMO_ST)));
    if cmmo_st {
        cmmo.clone()
    } else {
        cmmp.clone()
    }
}

thread_local! {
    static BUF: RefCell<Vec<u8>> = RefCell::new(vec![0u8; 65536]);
}

fn canopen_store(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Some(mut od) = dictionary(false) else {
        return;
    };
    BUF.with(|buf| parse_and_apply(text, &mut buf.borrow_mut(), &mut od));
}

fn parse_and_apply(text: &str, buf: &mut [u8], od: &mut Od) {
    let mut values = Vec::new();
    for line in text.lines() {
        match od::parameter_file::parse_line(line, buf) {
            Ok(Some((index, sub, n))) => values.push(StoredValue {
                index,
                sub,
                bytes: buf.get(..n).unwrap_or(&[]).to_vec(),
            }),
            Ok(None) => {}
            Err(_) => return,
        }
    }
    apply(od, &values, |_| true);
}

fn cmmo_st_memory(data: &[u8]) {
    let Some(od) = dictionary(true) else {
        return;
    };
    let mut dev = FhppDevice::new(od, FhppSettings::default());
    // The stored values one after the other, each after its length.
    let snapshot = |dev: &FhppDevice<Vec<u8>>| -> Vec<u8> {
        let mut all = Vec::new();
        for (_, v) in dev.od().storable_values(1) {
            all.extend_from_slice(&(v.len() as u32).to_le_bytes());
            all.extend_from_slice(v);
        }
        all
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
