//! The cell file's `[[bus]]` entries and the interfaces a `[[drive]]` lists.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drivetwin::cell::config::{CellFile, ConfigError};

fn parse(text: &str) -> CellFile {
    toml::from_str(text).expect("a cell file")
}

#[test]
fn the_single_bus_table_keeps_working() {
    let file = parse(
        r#"
        [bus]
        socketcand = "127.0.0.1:0"
        channel = "vcan0"
        [[drive]]
        device = "cmmp-as"
        node = 1
        "#,
    );
    assert_eq!(file.bus.all().len(), 1);
    let specs = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("drives");
    assert_eq!(specs[0].bus, 0);
}

#[test]
fn drives_name_their_bus_and_node_ids_are_per_bus() {
    let file = parse(
        r#"
        [[bus]]
        name = "line-a"
        socketcand = "127.0.0.1:0"
        channel = "vcan0"
        [[bus]]
        name = "line-b"
        socketcan = "vcan1"
        socketcand = ""
        [[drive]]
        device = "cmmp-as"
        node = 1
        bus = "line-a"
        [[drive]]
        device = "cmmp-as"
        node = 1
        bus = "line-b"
        "#,
    );
    let specs = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("drives");
    assert_eq!(specs.iter().map(|s| s.bus).collect::<Vec<_>>(), [0, 1]);
    let wrong = parse(
        r#"
        [[bus]]
        name = "line-a"
        [[drive]]
        device = "cmmp-as"
        bus = "line-c"
        "#,
    );
    let e = wrong
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap_err();
    assert!(matches!(e, ConfigError::UnknownBus { .. }));
    assert!(e.to_string().contains("line-a"), "{e}");
}

#[test]
fn a_combination_the_device_lacks_is_refused_with_the_manuals_rule() {
    let text = r#"
        [[drive]]
        device = "cmmp-as"
        node = 1
        interfaces = ["canopen", "ethercat"]
        "#;
    let e = parse(text)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap_err();
    assert!(e.to_string().contains("§2.3"), "{e}");
    assert!(e.to_string().contains("allow_unreal_interfaces"), "{e}");
    let allowed = format!("{text}allow_unreal_interfaces = true\n");
    assert!(parse(&allowed)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .is_ok());
    let modbus = parse(
        r#"
        [[drive]]
        device = "cmmp-as"
        interfaces = ["canopen", "modbus-tcp"]
        allow_unreal_interfaces = true
        "#,
    );
    assert!(modbus
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap_err()
        .to_string()
        .contains("no modbus-tcp"));
}

#[test]
fn the_ethercat_key_puts_a_drive_on_a_chain_by_interface() {
    let specs = parse(
        r#"
        [[drive]]
        device = "cmmp-as"
        node = 1

        [[drive]]
        device = "cmmp-as"
        node = 2
        ethercat = "veth0"

        [[drive]]
        device = "cmmp-as"
        node = 3
        interfaces = ["canopen", "ethercat"]
        allow_unreal_interfaces = true
        "#,
    )
    .drives(drivetwin::vendors::VENDORS.runtime)
    .expect("drives");
    let places: Vec<_> = specs
        .iter()
        .map(|s| (s.canopen, s.ethercat.clone()))
        .collect();
    assert_eq!(
        places,
        [
            (true, None),
            (false, Some(Some("veth0".to_string()))),
            // No chain named: `--ethercat`'s.
            (true, Some(None)),
        ]
    );
    let lacking = parse(
        r#"
        [[drive]]
        device = "cmmp-as"
        interfaces = ["canopen"]
        ethercat = "veth0"
        "#,
    );
    let e = lacking
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap_err();
    assert!(e.to_string().contains("no \"ethercat\""), "{e}");
    let cmmo = parse(
        r#"
        [[drive]]
        device = "cmmo-st"
        ethercat = "veth0"
        "#,
    );
    assert!(cmmo
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap_err()
        .to_string()
        .contains("no ethercat"));
}
