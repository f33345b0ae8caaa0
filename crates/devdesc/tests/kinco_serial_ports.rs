//! The Kinco FD3's device file with its `[device.serial_ports]` broken: each bad entry stops
//! the build with the file, the table and the key, as the build script reads the file.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::Path;

fn fd3() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/kinco-fd3.toml");
    std::fs::read_to_string(path).unwrap()
}

/// `devices/kinco-fd3.toml` with `from` replaced by `to` (once), refused: the message.
fn refused(from: &str, to: &str) -> String {
    let text = fd3();
    assert!(text.contains(from), "{from}");
    match devdesc::parse(&text.replacen(from, to, 1), "devices/kinco-fd3.toml") {
        Ok(_) => panic!("accepted: {to}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_fd3s_file_as_it_is_is_taken() {
    let d = devdesc::parse(&fd3(), "devices/kinco-fd3.toml").unwrap();
    let names: Vec<&str> = d.serial_ports.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["rs232", "rs485"]);
}

#[test]
fn a_bad_serial_port_entry_stops_the_build_with_file_table_and_key() {
    let head = "devices/kinco-fd3.toml: device: [device.serial_ports] ";
    assert_eq!(
        refused("bit_rate = 0x2FE2", "bit_rate = 0x2FE3"),
        format!("{head}rs485.bit_rate: object 2FE3h is no object of serial_bit_rate")
    );
    assert_eq!(
        refused(
            "loop_enable = [0x6510, 0x0B]",
            "loop_enable = [0x6510, 0x7F]"
        ),
        format!("{head}rs232.loop_enable: object 6510h sub 7Fh is not in this file")
    );
    assert_eq!(
        refused(
            "modbus_rtu = 0, telegrams = 1",
            "modbus_rtu = 5, telegrams = 1"
        ),
        format!(
            "{head}rs485.protocol: the default of object 6510h sub 0Ch is neither modbus_rtu \
             nor telegrams"
        )
    );
    let e = refused(
        "[device.serial_ports.rs485]\n",
        "[device.serial_ports.rs422]\n",
    );
    assert!(e.starts_with("devices/kinco-fd3.toml: "), "{e}");
    assert!(e.contains("unknown field `rs422`"), "{e}");
    assert_eq!(
        refused(
            "interfaces = [\"canopen\", \"rs232\", \"rs485\"]",
            "interfaces = [\"canopen\", \"rs232\"]"
        ),
        format!("{head}rs485: the device has no \"rs485\" interface")
    );
}
