//! Turns a checked description into Rust source: one `static` `od::DeviceDescription`.

use std::fmt::Write;

use od::{Access, Behaviour, Limit, ObjectKind};

use crate::model::{Device, Ent};

/// The Rust identifier of a personality's static (`cmmp-as` → `CMMP_AS`).
pub fn static_name(device: &str) -> String {
    device.to_ascii_uppercase().replace('-', "_")
}

/// Rust source defining `pub static NAME: od::DeviceDescription`.
pub fn generate(d: &Device) -> String {
    let mut s = String::new();
    let mut offset: u32 = 0;
    let _ = writeln!(s, "/// Generated from `devices/{}.toml`.", d.name);
    let _ = writeln!(
        s,
        "pub static {}: od::DeviceDescription = od::DeviceDescription {{",
        static_name(&d.name)
    );
    let _ = writeln!(s, "    name: {:?},", d.name);
    let _ = writeln!(s, "    product_name: {:?},", d.product_name);
    let _ = writeln!(s, "    vendor_name: {:?},", d.vendor_name);
    let _ = writeln!(s, "    vendor_id: 0x{:X},", d.vendor_id);
    let _ = writeln!(s, "    product_code: 0x{:X},", d.product_code);
    let _ = writeln!(s, "    revision: 0x{:X},", d.revision);
    let _ = writeln!(s, "    order_code: {:?},", d.order_code);
    let _ = writeln!(s, "    description: {:?},", d.description);
    let _ = writeln!(s, "    profile: od::Profile::{:?},", d.profile);
    let _ = writeln!(s, "    default_node_id: {},", d.default_node_id);
    let _ = writeln!(s, "    baud_rates: &{:?},", d.baud_rates);
    let _ = writeln!(s, "    rotary_switches: {},", d.rotary_switches);
    match &d.can_bit_rate {
        None => {
            let _ = writeln!(s, "    can_bit_rate: None,");
        }
        Some(c) => {
            let _ = writeln!(
                s,
                "    can_bit_rate: Some(od::CanBitRateCodes {{ index: 0x{:04X}, name: {:?}, codes: &{:?} }}),",
                c.index, c.name, c.codes
            );
        }
    }
    match &d.serial_bit_rate {
        None => {
            let _ = writeln!(s, "    serial_bit_rate: None,");
        }
        Some(c) => {
            let objects: Vec<String> = c.objects.iter().map(|i| format!("0x{i:04X}")).collect();
            let _ = writeln!(
                s,
                "    serial_bit_rate: Some(od::SerialBitRateCodes {{ objects: &[{}], codes: &{:?} }}),",
                objects.join(", "),
                c.codes
            );
        }
    }
    let _ = writeln!(s, "    serial_ports: &[");
    for (interface, p) in &d.serial_ports {
        let protocol = p.protocol.as_ref().map_or("None".to_owned(), |pr| {
            format!(
                "Some(od::ProtocolSelect {{ object: (0x{:04X}, 0x{:02X}), modbus_rtu: {}, telegrams: {} }})",
                pr.object.0, pr.object.1, pr.modbus_rtu, pr.telegrams
            )
        });
        let _ = writeln!(
            s,
            "        od::SerialPort {{ interface: {interface:?}, bit_rate: 0x{:04X}, bit_rate_now: {}, loop_enable: {}, protocol: {protocol} }},",
            p.bit_rate,
            p.bit_rate_now.map_or("None".to_owned(), |i| format!("Some(0x{i:04X})")),
            object_key(p.loop_enable),
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(
        s,
        "    interfaces: od::InterfaceOffer {{ has: &{:?}, one_of: &{:?}, rule: {:?} }},",
        d.interfaces, d.interfaces_one_of, d.interfaces_rule
    );
    let _ = writeln!(s, "    fieldbus_switches: {},", d.fieldbus_switches);
    match &d.fhpp {
        None => {
            let _ = writeln!(s, "    fhpp: None,");
        }
        Some(f) => {
            let _ = writeln!(
                s,
                "    fhpp: Some(od::FhppParameters {{ records: {}, stage_off_pnus: &{:?} }}),",
                f.records, f.stage_off_pnus
            );
        }
    }
    match &d.ethercat {
        None => {
            let _ = writeln!(s, "    ethercat: None,");
        }
        Some(e) => {
            let _ = writeln!(
                s,
                "    ethercat: Some(od::EthercatSlave {{ group_type: {:?}, group_name: {:?}, pdi_control: 0x{:04X}, mailbox_out: (0x{:04X}, 0x{:04X}), mailbox_in: (0x{:04X}, 0x{:04X}), outputs_start: 0x{:04X}, inputs_start: 0x{:04X}, rx_assigned: &{:?}, tx_assigned: &{:?}, ds402_channels: {}, physical_ports: 0x{:04X}, complete_access: {}, sdo_info: {}, coe_hidden: &{:?}, version: {}, watchdog_diagnostic: {:?} }}),",
                e.group_type,
                e.group_name,
                e.pdi_control,
                e.mailbox_out[0],
                e.mailbox_out[1],
                e.mailbox_in[0],
                e.mailbox_in[1],
                e.outputs_start,
                e.inputs_start,
                e.rx_assigned,
                e.tx_assigned,
                e.ds402_channels,
                e.physical_ports,
                e.complete_access,
                e.sdo_info,
                e.coe_hidden,
                e.version,
                e.watchdog_diagnostic
            );
        }
    }
    let b = &d.bus_faults;
    let _ = writeln!(
        s,
        "    bus_faults: od::BusFaultReactions {{ on_passive: &[{}], on_active: &[{}], on_bus_off: &[{}], on_recovered: &[{}] }},",
        reactions(&b.on_passive),
        reactions(&b.on_active),
        reactions(&b.on_bus_off),
        reactions(&b.on_recovered)
    );
    let k = &d.brake;
    let _ = writeln!(
        s,
        "    brake: od::BrakeTiming {{ release: &[{}], motion: &[{}], engage: &[{}], only_with_brake: {} }},",
        object_keys(&k.release),
        object_keys(&k.motion),
        object_keys(&k.engage),
        k.only_with_brake
    );
    let p = &d.plant;
    let _ = writeln!(
        s,
        "    plant: od::PlantSupervision {{ motor_warning: {:?}, motor_over: {:?}, stage_warning: {:?}, stage_over: {:?}, stage_under: {:?}, encoder_lost: {:?}, encoder_implausible: {:?}, motor_limit: {}, stage_limit: {}, stage_low_limit: {}, motor_temperature: {}, stage_temperature: {} }},",
        p.motor_warning,
        p.motor_over,
        p.stage_warning,
        p.stage_over,
        p.stage_under,
        p.encoder_lost,
        p.encoder_implausible,
        object_key(p.motor_limit),
        object_key(p.stage_limit),
        object_key(p.stage_low_limit),
        object_key(p.motor_temperature),
        object_key(p.stage_temperature)
    );
    let c = &d.cia301;
    let _ = writeln!(
        s,
        "    cia301: od::Cia301Options {{ pdo_params_locked_while_valid: {}, pdo_config_outside_operational: {}, tpdo_transmit_mask_index: {:?}, tpdo_254_cyclic_inhibit: {}, pdo_refuses_type_254: {}, pdo_map_length_filled: {}, nmt_command_answered_with_state: {}, life_guard_emcy_code: {:?}, restore_writes_stored_set: {}, life_time_max_ms: {:?}, pdo_valid_without_mapping: {}, lss_unsupported: {}, dummy_usage: {:?} }},",
        c.pdo_params_locked_while_valid,
        c.pdo_config_outside_operational,
        c.tpdo_transmit_mask_index,
        c.tpdo_254_cyclic_inhibit,
        c.pdo_refuses_type_254,
        c.pdo_map_length_filled,
        c.nmt_command_answered_with_state,
        c.life_guard_emcy_code,
        c.restore_writes_stored_set,
        c.life_time_max_ms,
        c.pdo_valid_without_mapping,
        c.lss_unsupported,
        c.dummy_usage
    );
    let _ = writeln!(s, "    objects: &[");
    for o in &d.objects {
        let _ = writeln!(s, "        od::Object {{");
        let _ = writeln!(s, "            index: 0x{:04X},", o.index);
        let _ = writeln!(s, "            name: {:?},", o.name);
        let _ = writeln!(s, "            kind: od::ObjectKind::{},", kind(o.kind));
        let _ = writeln!(s, "            min_max: {:?},", o.min_max);
        let _ = writeln!(s, "            entries: &[");
        for e in &o.entries {
            entry(&mut s, e, offset);
            offset += storage_len(e);
        }
        let _ = writeln!(s, "            ],");
        let _ = writeln!(s, "        }},");
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    diagnostics: &[");
    for g in &d.diagnostics {
        let _ = writeln!(
            s,
            "        od::Diagnostic {{ number: {:?}, code: {:?}, register: 0x{:02X}, reaction: od::Reaction::{:?}, text: {:?}, display: {:?}, classes: {:?}, reactions: {:?}, memory: {:?}, ack: {:?}, source: {:?} }},",
            g.number, g.code, g.register, g.reaction, g.text, g.display, g.classes, g.reactions, g.memory, g.ack, g.source
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    storage_size: {offset},");
    let _ = writeln!(s, "}};");
    s
}

/// `od::BusFaultReaction::Raise(0x8120), …`
fn reactions(list: &[od::BusFaultReaction]) -> String {
    let one = |r: &od::BusFaultReaction| match r {
        od::BusFaultReaction::Raise(c) => format!("od::BusFaultReaction::Raise(0x{c:04X})"),
        od::BusFaultReaction::Clear(c) => format!("od::BusFaultReaction::Clear(0x{c:04X})"),
        od::BusFaultReaction::Fault(c) => format!("od::BusFaultReaction::Fault(0x{c:04X})"),
        od::BusFaultReaction::Repeat(c) => format!("od::BusFaultReaction::Repeat(0x{c:04X})"),
    };
    list.iter().map(one).collect::<Vec<_>>().join(", ")
}

/// `(0x2007, 0x01), …`
fn object_keys(list: &[(u16, u8)]) -> String {
    list.iter()
        .map(|(i, s)| format!("(0x{i:04X}, 0x{s:02X})"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `Some((0x6510, 0x2F))` or `None`.
fn object_key(key: Option<(u16, u8)>) -> String {
    match key {
        Some((i, s)) => format!("Some((0x{i:04X}, 0x{s:02X}))"),
        None => "None".into(),
    }
}

fn storage_len(e: &Ent) -> u32 {
    if e.data_type.fixed_size().is_some() {
        e.capacity
    } else {
        e.capacity + 2
    }
}

fn entry(s: &mut String, e: &Ent, offset: u32) {
    let _ = writeln!(s, "                od::Entry {{");
    let _ = writeln!(
        s,
        "                    index: 0x{:04X}, sub: {}, name: {:?},",
        e.index, e.sub, e.name
    );
    let _ = writeln!(
        s,
        "                    data_type: od::DataType::{:?}, access: od::Access::{},",
        e.data_type,
        access(e.access)
    );
    let _ = writeln!(
        s,
        "                    pdo_mappable: {}, default: &{:?}, default_plus_node_id: {},",
        e.pdo, e.default, e.default_plus_node_id
    );
    let _ = writeln!(
        s,
        "                    min: {}, max: {}, unit: {:?},",
        limit(e.min),
        limit(e.max),
        e.unit
    );
    let _ = writeln!(
        s,
        "                    behaviour: od::Behaviour::{}, storable: {}, kept_on_restore: {}, allowed_bits: {:?}, offset: {offset}, capacity: {},",
        behaviour(e.behaviour),
        e.storable,
        e.kept_on_restore,
        e.allowed_bits,
        e.capacity
    );
    let _ = writeln!(s, "                }},");
}

fn kind(k: ObjectKind) -> &'static str {
    match k {
        ObjectKind::Var => "Var",
        ObjectKind::Array => "Array",
        ObjectKind::Record => "Record",
    }
}

fn access(a: Access) -> &'static str {
    match a {
        Access::ReadOnly => "ReadOnly",
        Access::WriteOnly => "WriteOnly",
        Access::ReadWrite => "ReadWrite",
        Access::Const => "Const",
    }
}

fn behaviour(b: Behaviour) -> &'static str {
    match b {
        Behaviour::Plain => "Plain",
        Behaviour::StoreSignature => "StoreSignature",
        Behaviour::RestoreSignature => "RestoreSignature",
        Behaviour::ErrorHistoryCount => "ErrorHistoryCount",
        Behaviour::ReadsZero => "ReadsZero",
        Behaviour::PdoCobId => "PdoCobId",
        Behaviour::PdoTransmissionType => "PdoTransmissionType",
        Behaviour::PdoInhibitTime => "PdoInhibitTime",
        Behaviour::PdoEventTimer => "PdoEventTimer",
        Behaviour::PdoSyncStart => "PdoSyncStart",
        Behaviour::PdoMapCount => "PdoMapCount",
        Behaviour::PdoMapEntry => "PdoMapEntry",
    }
}

fn limit(l: Option<Limit>) -> String {
    match l {
        None => "None".into(),
        Some(Limit::Signed(v)) => format!("Some(od::Limit::Signed({v}))"),
        Some(Limit::Unsigned(v)) => format!("Some(od::Limit::Unsigned({v}))"),
        Some(Limit::Real(v)) => format!("Some(od::Limit::Real({v:?}))"),
    }
}

/// Rust source defining `pub static NAME_ADDRESSES: crate::Addresses`: the panel addresses and
/// Modbus registers of the description's entries (the other keys of an object beside index
/// and sub-index; empty for most devices).
pub fn generate_addresses(d: &Device) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/// Panel addresses and Modbus registers of `devices/{}.toml`.",
        d.name
    );
    let _ = writeln!(
        s,
        "pub static {}_ADDRESSES: crate::Addresses = crate::Addresses {{",
        static_name(&d.name)
    );
    let _ = writeln!(s, "    device: {:?},", d.name);
    let _ = writeln!(s, "    panel: &[");
    let mut panel: Vec<(&str, &Ent)> = d
        .objects
        .iter()
        .flat_map(|o| &o.entries)
        .flat_map(|e| e.panel.iter().map(move |k| (k.as_str(), e)))
        .collect();
    panel.sort_by_key(|(k, _)| *k);
    for (k, e) in panel {
        let _ = writeln!(
            s,
            "        crate::PanelAddress {{ key: {k:?}, index: 0x{:04X}, sub: {} }},",
            e.index, e.sub
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "    modbus: &[");
    let mut modbus: Vec<(u16, &Ent)> = d
        .objects
        .iter()
        .flat_map(|o| &o.entries)
        .filter_map(|e| e.modbus.map(|r| (r, e)))
        .collect();
    modbus.sort_by_key(|(r, _)| *r);
    for (r, e) in modbus {
        let _ = writeln!(
            s,
            "        crate::ModbusRegister {{ register: 0x{r:04X}, index: 0x{:04X}, sub: {}, words: {} }},",
            e.index,
            e.sub,
            e.capacity.div_ceil(2).max(1)
        );
    }
    let _ = writeln!(s, "    ],");
    let _ = writeln!(s, "}};");
    s
}
