//! The CMMO-ST's `[device.plant]`: its App. D messages and PNU objects taken, and a key its
//! FHPP supervision does not read (a motor temperature; the CMMO-ST has no sensor) or a
//! broken entry refused with the file, the table and the key.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::Path;

const FILE: &str = "devices/cmmo-st.toml";

fn cmmo_st() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(FILE);
    std::fs::read_to_string(path).unwrap()
}

fn refused(from: &str, to: &str) -> String {
    let text = cmmo_st();
    assert!(text.contains(from), "{from}");
    match devdesc::parse(&text.replacen(from, to, 1), FILE) {
        Ok(_) => panic!("accepted: {to}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_cmmo_sts_plant_table_is_taken() {
    let d = devdesc::parse(&cmmo_st(), FILE).unwrap();
    let p = devdesc::runtime::leak(&d).plant;
    assert_eq!(
        (p.stage_warning, p.stage_over, p.stage_under),
        (Some("33h"), Some("15h"), Some("16h"))
    );
    assert_eq!(
        (p.encoder_lost, p.encoder_implausible),
        (Some("06h"), Some("06h"))
    );
    assert_eq!(p.stage_limit, Some((0x242C, 2)));
    assert_eq!(p.stage_low_limit, Some((0x242C, 1)));
    assert_eq!(p.stage_temperature, Some((0x242A, 1)));
    assert_eq!((p.motor_over, p.motor_temperature), (None, None));
}

#[test]
fn a_key_the_fhpp_supervision_does_not_read_is_refused() {
    let head = "devices/cmmo-st.toml: device: [device.plant] ";
    assert_eq!(
        refused(
            "stage_over = \"15h\"\n",
            "stage_over = \"15h\"\nmotor_over = \"15h\"\n"
        ),
        format!("{head}motor_over: the Fhpp profile's supervision has no such condition")
    );
    assert_eq!(
        refused("stage_under = \"16h\"", "stage_under = \"16x\""),
        format!("{head}stage_under: message \"16x\" is no [[diagnostic]] row of this file")
    );
    assert_eq!(
        refused(
            "stage_low_limit = [0x242C, 1]",
            "stage_low_limit = [0x242C, 3]"
        ),
        format!("{head}stage_low_limit: object 242Ch sub 03h is not in this file")
    );
}
