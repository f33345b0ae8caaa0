//! The ESC serving the CMMP-AS SII image from `sii::build_sii`: power-on values, identity
//! through 0x0502, and the mailbox layout it checks on Init → Pre-Op.

mod common;

use common::*;
use ethercat::sii::{build_sii, SiiConfig, DEFAULT_IMAGE_SIZE};
use ethercat::{Esc, EscConfig, MailboxLayout};

#[test]
fn esc_with_cmmp_as_sii() {
    let mut image = vec![0u8; DEFAULT_IMAGE_SIZE];
    build_sii(
        &devices::CMMP_AS,
        &SiiConfig::from_description(&devices::CMMP_AS),
        &mut image,
    )
    .expect("image");
    let image: &'static [u8] = Box::leak(image.into_boxed_slice());
    let cfg = EscConfig::from_sii(image);
    assert_eq!(cfg.mailbox, Some(mailbox_layout()));
    assert_eq!(
        MailboxLayout::from_sii(image),
        Some(MailboxLayout {
            rx_offset: 0x1000,
            rx_size: 0x80,
            tx_offset: 0x1080,
            tx_size: 0x80
        })
    );
    let mut bus = Bus::new(vec![Esc::with_sii(image)]);
    bus.assign_addresses();
    assert_eq!(bus.sii_read(0x1001, 0x08, 4), vec![0x1D, 0, 0, 0]);
    assert_eq!(bus.fprd(0x1001, 0x0140, 1).data, vec![0x05]);
    bus.write_mailbox_sms(0x1001);
    bus.request_state(0x1001, 0x0012);
    assert_eq!(bus.al(0x1001), (0x0002, 0));
}

/// The device file's `[device.ethercat]` gives the layout of the ESC reference kept beside the
/// project, §3.5 with the CMMP-AS's group and CoE services (its manual's extract, part 1 §2.13,
/// §2.11, Tab. 4.9): the SII image and the CoE answers the interop tests were written against.
#[test]
fn cmmp_as_layout_and_coe_services_from_its_device_file() {
    use ethercat::coe::CoeConfig;
    use ethercat::sii::{coe_details, mailbox_protocol};
    let sii = SiiConfig::from_description(&devices::CMMP_AS);
    assert_eq!(
        sii,
        SiiConfig {
            pdi_control: 0x0005,
            pdi_config: 0,
            sync_impulse_len: 0,
            station_alias: 0,
            serial_number: 0,
            mailbox_out: (0x1000, 0x0080),
            mailbox_in: (0x1080, 0x0080),
            outputs_start: 0x1100,
            inputs_start: 0x1180,
            mailbox_protocols: mailbox_protocol::COE,
            coe_details: coe_details::SDO
                | coe_details::SDO_INFO
                | coe_details::PDO_ASSIGN
                | coe_details::PDO_CONFIG,
            ds402_channels: 1,
            flags: 0,
            ebus_current_ma: 0,
            physical_ports: 0x0011,
            group_type: "Festo Electric-Drives",
            device_name: "",
            rx_assigned: &[0x1600],
            tx_assigned: &[0x1A00],
            version: 1,
        }
    );
    assert_eq!(
        CoeConfig::from_description(&devices::CMMP_AS),
        CoeConfig {
            complete_access: false,
            sdo_info: true,
            hidden: &[0x1008, 0x1009, 0x100A, 0x6089, 0x608A, 0x608B, 0x608C, 0x608D, 0x608E],
        }
    );
    // A device file without the section: the baseline, nothing hidden.
    assert_eq!(
        SiiConfig::from_description(&devices::TESTBENCH),
        SiiConfig::BASELINE
    );
    assert_eq!(
        CoeConfig::from_description(&devices::TESTBENCH),
        CoeConfig::BASELINE
    );
}
