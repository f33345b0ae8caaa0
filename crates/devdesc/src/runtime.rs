//! A checked description turned into an `od::DeviceDescription` while the program runs, for
//! devices that are not compiled in (a drive from its EDS). The build-time path
//! ([`crate::codegen`]) writes the same tables as Rust source; both lay out the storage
//! buffer the same way.
//!
//! `od::DeviceDescription` holds `&'static` tables so that the `no_std` dictionary and drive
//! need no allocator. A description built here is therefore leaked: once per file, at
//! start-up, in the std runtime, and it lives as long as the process, as a compiled-in one
//! does.

use crate::model::Device;

/// The description of `d`, leaked to live for the rest of the process (see the module doc:
/// call it once per device, at start-up).
pub fn leak(d: &Device) -> &'static od::DeviceDescription {
    let mut offset: u32 = 0;
    let objects: Vec<od::Object> = d
        .objects
        .iter()
        .map(|o| {
            let entries: Vec<od::Entry> = o
                .entries
                .iter()
                .map(|e| {
                    let entry = od::Entry {
                        index: e.index,
                        sub: e.sub,
                        name: text(&e.name),
                        data_type: e.data_type,
                        access: e.access,
                        pdo_mappable: e.pdo,
                        default: Box::leak(e.default.clone().into_boxed_slice()),
                        default_plus_node_id: e.default_plus_node_id,
                        min: e.min,
                        max: e.max,
                        unit: text(&e.unit),
                        behaviour: e.behaviour,
                        storable: e.storable,
                        kept_on_restore: e.kept_on_restore,
                        allowed_bits: e.allowed_bits,
                        offset,
                        capacity: e.capacity,
                    };
                    offset += entry.storage_len() as u32;
                    entry
                })
                .collect();
            od::Object {
                index: o.index,
                name: text(&o.name),
                kind: o.kind,
                min_max: o.min_max,
                entries: Box::leak(entries.into_boxed_slice()),
            }
        })
        .collect();
    let diagnostics: Vec<od::Diagnostic> = d
        .diagnostics
        .iter()
        .map(|g| od::Diagnostic {
            number: text(&g.number),
            code: g.code,
            register: g.register,
            reaction: g.reaction,
            text: text(&g.text),
            display: text(&g.display),
            classes: text(&g.classes),
            reactions: text(&g.reactions),
            memory: text(&g.memory),
            ack: text(&g.ack),
            source: text(&g.source),
        })
        .collect();
    let texts = |v: &[String]| -> &'static [&'static str] {
        Box::leak(
            v.iter()
                .map(|s| text(s))
                .collect::<Vec<_>>()
                .into_boxed_slice(),
        )
    };
    Box::leak(Box::new(od::DeviceDescription {
        name: text(&d.name),
        product_name: text(&d.product_name),
        vendor_name: text(&d.vendor_name),
        vendor_id: d.vendor_id,
        product_code: d.product_code,
        revision: d.revision,
        order_code: text(&d.order_code),
        description: text(&d.description),
        profile: d.profile,
        default_node_id: d.default_node_id,
        baud_rates: Box::leak(d.baud_rates.clone().into_boxed_slice()),
        rotary_switches: d.rotary_switches,
        can_bit_rate: d.can_bit_rate.as_ref().map(|c| od::CanBitRateCodes {
            index: c.index,
            name: text(&c.name),
            codes: Box::leak(c.codes.clone().into_boxed_slice()),
        }),
        serial_bit_rate: d.serial_bit_rate.as_ref().map(|c| od::SerialBitRateCodes {
            objects: Box::leak(c.objects.clone().into_boxed_slice()),
            codes: Box::leak(c.codes.clone().into_boxed_slice()),
        }),
        serial_ports: Box::leak(
            d.serial_ports
                .iter()
                .map(|(interface, p)| od::SerialPort {
                    interface: text(interface),
                    bit_rate: p.bit_rate,
                    bit_rate_now: p.bit_rate_now,
                    loop_enable: p.loop_enable,
                    protocol: p.protocol.as_ref().map(|pr| od::ProtocolSelect {
                        object: pr.object,
                        modbus_rtu: pr.modbus_rtu,
                        telegrams: pr.telegrams,
                    }),
                })
                .collect::<Vec<_>>()
                .into_boxed_slice(),
        ),
        fieldbus_switches: d.fieldbus_switches,
        fhpp: d.fhpp.as_ref().map(|f| od::FhppParameters {
            records: f.records,
            stage_off_pnus: Box::leak(f.stage_off_pnus.clone().into_boxed_slice()),
        }),
        ethercat: d.ethercat.as_ref().map(|e| od::EthercatSlave {
            group_type: text(&e.group_type),
            group_name: text(&e.group_name),
            pdi_control: e.pdi_control,
            mailbox_out: (e.mailbox_out[0], e.mailbox_out[1]),
            mailbox_in: (e.mailbox_in[0], e.mailbox_in[1]),
            outputs_start: e.outputs_start,
            inputs_start: e.inputs_start,
            rx_assigned: Box::leak(e.rx_assigned.clone().into_boxed_slice()),
            tx_assigned: Box::leak(e.tx_assigned.clone().into_boxed_slice()),
            ds402_channels: e.ds402_channels,
            physical_ports: e.physical_ports,
            complete_access: e.complete_access,
            sdo_info: e.sdo_info,
            coe_hidden: Box::leak(e.coe_hidden.clone().into_boxed_slice()),
            version: e.version,
            watchdog_diagnostic: e.watchdog_diagnostic.as_deref().map(text),
        }),
        interfaces: od::InterfaceOffer {
            has: texts(&d.interfaces),
            one_of: texts(&d.interfaces_one_of),
            rule: text(&d.interfaces_rule),
        },
        bus_faults: od::BusFaultReactions {
            on_passive: Box::leak(d.bus_faults.on_passive.clone().into_boxed_slice()),
            on_active: Box::leak(d.bus_faults.on_active.clone().into_boxed_slice()),
            on_bus_off: Box::leak(d.bus_faults.on_bus_off.clone().into_boxed_slice()),
            on_recovered: Box::leak(d.bus_faults.on_recovered.clone().into_boxed_slice()),
        },
        brake: od::BrakeTiming {
            release: Box::leak(d.brake.release.clone().into_boxed_slice()),
            motion: Box::leak(d.brake.motion.clone().into_boxed_slice()),
            engage: Box::leak(d.brake.engage.clone().into_boxed_slice()),
            only_with_brake: d.brake.only_with_brake,
        },
        plant: od::PlantSupervision {
            motor_warning: d.plant.motor_warning.as_deref().map(text),
            motor_over: d.plant.motor_over.as_deref().map(text),
            stage_warning: d.plant.stage_warning.as_deref().map(text),
            stage_over: d.plant.stage_over.as_deref().map(text),
            stage_under: d.plant.stage_under.as_deref().map(text),
            encoder_lost: d.plant.encoder_lost.as_deref().map(text),
            encoder_implausible: d.plant.encoder_implausible.as_deref().map(text),
            motor_limit: d.plant.motor_limit,
            stage_limit: d.plant.stage_limit,
            stage_low_limit: d.plant.stage_low_limit,
            motor_temperature: d.plant.motor_temperature,
            stage_temperature: d.plant.stage_temperature,
        },
        cia301: d.cia301,
        objects: Box::leak(objects.into_boxed_slice()),
        diagnostics: Box::leak(diagnostics.into_boxed_slice()),
        storage_size: offset as usize,
    }))
}

fn text(s: &str) -> &'static str {
    Box::leak(s.to_owned().into_boxed_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A compiled-in device and the same file built at run time lay out the same dictionary.
    #[test]
    fn the_same_tables_as_the_code_generator() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/cmmp-as.toml");
        let d = crate::load_file(&path).unwrap();
        let desc = leak(&d);
        let source = crate::codegen::generate(&d);
        assert!(source.contains(&format!("storage_size: {},", desc.storage_size)));
        let last = desc.entries().last().unwrap();
        assert!(source.contains(&format!(
            "offset: {}, capacity: {}",
            last.offset, last.capacity
        )));
        assert_eq!(
            desc.entry(0x6040, 0).unwrap().data_type,
            od::DataType::Unsigned16
        );
    }
}
