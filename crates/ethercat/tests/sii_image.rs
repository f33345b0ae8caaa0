//! What a master takes from the SII image of a device file's slave
//! (`ethercat::master::sii_image`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use ethercat::master::sii_image::*;
use ethercat::sii::{self, build_sii, SiiConfig, DEFAULT_IMAGE_SIZE};

fn image() -> [u8; DEFAULT_IMAGE_SIZE] {
    let mut buf = [0u8; DEFAULT_IMAGE_SIZE];
    build_sii(
        &devices::CMMP_AS,
        &SiiConfig::from_description(&devices::CMMP_AS),
        &mut buf,
    )
    .expect("image");
    buf
}

#[test]
fn identity_mailbox_and_name_of_the_cmmp_as_image() {
    let img = image();
    let id = identity(&img);
    assert_eq!(id.vendor_id, 0x1D, "Festo");
    assert_eq!(id.product_code, devices::CMMP_AS.product_code);
    assert_eq!(id.revision, devices::CMMP_AS.revision);
    let m = mailbox(&img).expect("mailbox");
    assert_eq!(
        (m.rx_offset, m.rx_size, m.tx_offset, m.tx_size),
        (0x1000, 0x80, 0x1080, 0x80)
    );
    assert_eq!(mailbox_protocols(&img) & sii::mailbox_protocol::COE, 0x0004);
    let n = name(&img).expect("string 1");
    assert!(n.starts_with(b"CMMP-AS"), "{n:?}");
    let [sm0, sm1] = mailbox_sync_managers(&img).expect("mailbox");
    assert_eq!(sm0.to_bytes(), [0x00, 0x10, 0x80, 0, 0x26, 0, 1, 0]);
    assert_eq!(sm1.to_bytes(), [0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0]);
    let sm2 = sync_manager(&img, 2).expect("SM2");
    assert_eq!((sm2.start, sm2.control), (0x1100, 0x64));
    let sm3 = sync_manager(&img, 3).expect("SM3");
    assert_eq!((sm3.start, sm3.control), (0x1180, 0x20));
    assert!(sync_manager(&img, 4).is_none());
}

#[test]
fn completeness_follows_the_category_list() {
    let img = image();
    let end = sii::categories(&img)
        .last()
        .map(|c| c.word_addr as usize * 2 + 4 + c.data.len());
    let end = end.expect("categories");
    // The END marker word follows the last category.
    assert!(is_complete(&img[..end + 2]));
    assert!(!is_complete(&img[..end]));
    assert!(!is_complete(&img[..0x80]));
    assert!(!is_complete(&[]));
    // An erased EEPROM (all 0xFFFF) ends at once; a list of huge categories stops at 4 KiB.
    assert!(is_complete(&[0xFF; 0x84]));
    let mut big = [0u8; 0x84];
    big[0x80..0x84].copy_from_slice(&[0x01, 0x00, 0xFF, 0x7F]);
    assert!(is_complete(&big));
}
