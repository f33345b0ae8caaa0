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
