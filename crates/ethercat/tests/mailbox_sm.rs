//! Mailbox sync managers: full/empty handshake, refusals, repeat request, mailbox header
//! (the ESC reference kept beside the project, §5).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod common;

use common::*;
use ethercat::mailbox::{self, Mailbox, MailboxErrorDetail, MailboxType};
use ethercat::PdiError;

const ST: u16 = 0x1001;

fn preop() -> Bus {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 0x0012);
    assert_eq!(bus.al(ST), (0x0002, 0));
    bus
}

fn request(counter: u8) -> Vec<u8> {
    // Expedited SDO upload 0x6041:00 as a master sends it, padded to the SM0 window.
    let mut m = vec![0u8; 0x80];
    m[..16].copy_from_slice(&[
        10,
        0,
        0,
        0,
        0,
        0x03 | (counter << 4),
        0x00,
        0x20,
        0x40,
        0x41,
        0x60,
        0,
        0,
        0,
        0,
        0,
    ]);
    m
}

#[test]
fn master_write_device_read_handshake() {
    let mut bus = preop();
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0, "SM0 empty");
    assert_eq!(bus.fpwr(ST, 0x1000, &request(1)).wkc, 1);
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0x08, "SM0 full");
    // A second write while full is refused (WKC 0, memory unchanged).
    assert_eq!(bus.fpwr(ST, 0x1000, &request(2)).wkc, 0);
    // The master cannot read its own mailbox.
    assert_eq!(bus.fprd(ST, 0x1000, 0x80).wkc, 0);
    let msg = bus.slaves[0].mailbox_read().expect("a message").to_vec();
    assert_eq!(msg, request(1));
    let m = Mailbox::new_checked(&msg[..]).unwrap();
    assert_eq!(
        (m.length(), m.mailbox_type(), m.counter()),
        (10, MailboxType::Coe, 1)
    );
    assert_eq!(m.payload().len(), 10);
    assert!(bus.slaves[0].mailbox_read().is_none(), "taken");
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0, "empty again");
    assert_eq!(bus.fpwr(ST, 0x1000, &request(2)).wkc, 1);
}

#[test]
fn partial_write_does_not_fill_the_mailbox() {
    let mut bus = preop();
    assert_eq!(bus.fpwr(ST, 0x1000, &request(1)[..16]).wkc, 1);
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0);
    assert!(bus.slaves[0].mailbox_read().is_none());
    // Writing the last byte completes it.
    assert_eq!(bus.fpwr(ST, 0x107F, &[0]).wkc, 1);
    assert!(bus.slaves[0].mailbox_read().is_some());
}

#[test]
fn device_write_master_read_handshake() {
    let mut bus = preop();
    // Read while empty: refused.
    let r = bus.fprd(ST, 0x1080, 0x80);
    assert_eq!((r.wkc, r.data.iter().all(|&b| b == 0)), (0, true));
    let reply = [
        10, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0, 0,
    ];
    assert!(bus.slaves[0].mailbox_write_ready());
    bus.slaves[0].mailbox_write(&reply).unwrap();
    assert_eq!(bus.slaves[0].mailbox_write(&reply), Err(PdiError::Busy));
    // SOEM polls 2 bytes at 0x080D (status + activate).
    let st = bus.fprd(ST, 0x080D, 2);
    assert_eq!(st.data[0] & 0x08, 0x08);
    assert_eq!(st.data[1], 0x01);
    // The master cannot write the send mailbox.
    assert_eq!(bus.fpwr(ST, 0x1080, &[0; 0x80]).wkc, 0);
    let r = bus.fprd(ST, 0x1080, 0x80);
    assert_eq!(r.wkc, 1);
    assert_eq!(&r.data[..16], &reply);
    assert!(
        r.data[16..].iter().all(|&b| b == 0),
        "rest of the window zeroed"
    );
    assert_eq!(
        bus.fprd(ST, 0x080D, 1).data[0] & 0x08,
        0,
        "read clears full"
    );
    assert_eq!(bus.fprd(ST, 0x1080, 0x80).wkc, 0);
    assert_eq!(
        bus.slaves[0].mailbox_write(&[0; 0x81]),
        Err(PdiError::TooLong)
    );
}

#[test]
fn repeat_request_reposts_last_reply() {
    let mut bus = preop();
    let reply = [4, 0, 0, 0, 0, 0x10, 0x01, 0x00, 0x02, 0x00];
    bus.slaves[0].mailbox_write(&reply).unwrap();
    assert_eq!(bus.fprd(ST, 0x1080, 0x80).wkc, 1);
    // The reply is lost on the way back; the master toggles the repeat bit (SOEM writes 2
    // bytes at 0x080D, the status byte part being read-only).
    assert_eq!(bus.fpwr(ST, 0x080D, &[0x00, 0x03]).wkc, 1);
    let st = bus.fprd(ST, 0x080D, 3);
    assert_eq!(st.data[0] & 0x08, 0x08, "full again");
    assert_eq!(st.data[1], 0x03);
    assert_eq!(st.data[2] & 0x02, 0x02, "repeat ack follows the request");
    let r = bus.fprd(ST, 0x1080, 0x80);
    assert_eq!((r.wkc, &r.data[..10]), (1, &reply[..]));
}

#[test]
fn sm_rewrite_with_same_layout_keeps_mailbox_full() {
    // Pitfall 12: a master rewriting SM0/SM1 (status byte sent as 0) must not clear "full".
    let mut bus = preop();
    bus.fpwr(ST, 0x1000, &request(1));
    bus.write_mailbox_sms(ST);
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0x08);
    // Disabling SM0 resets it (and, in Pre-Op, drops the slave to Init with 0x0016).
    bus.bwr(0x0800, &[0; 32]);
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0);
    assert_eq!(bus.al(ST), (0x0011, 0x0016));
}

#[test]
fn mailbox_not_served_in_init() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.write_mailbox_sms(ST);
    // In Init the ESC still applies the SM rules, but the device side does not serve it.
    assert_eq!(bus.fpwr(ST, 0x1000, &request(1)).wkc, 1);
    assert!(bus.slaves[0].mailbox_read().is_none());
    assert_eq!(
        bus.slaves[0].mailbox_write(&[0; 6]),
        Err(PdiError::NotRunning)
    );
    // Init → Pre-Op starts the handler with empty mailboxes.
    bus.request_state(ST, 0x0002);
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0);
    assert!(bus.slaves[0].mailbox_read().is_none());
}

#[test]
fn mailbox_header_and_error_reply() {
    let mut buf = [0u8; 16];
    let n =
        mailbox::write_error_reply(&mut buf, MailboxErrorDetail::UnsupportedProtocol, 2).unwrap();
    assert_eq!(&buf[..n], &[4, 0, 0, 0, 0, 0x20, 0x01, 0x00, 0x02, 0x00]);
    let m = Mailbox::new_checked(&buf[..n]).unwrap();
    assert_eq!(
        (m.mailbox_type(), m.counter(), m.length()),
        (MailboxType::Error, 2, 4)
    );
    // The capture example of spec §5.1.
    let hdr = [0x0A, 0x00, 0x00, 0x00, 0x00, 0x33];
    let m = Mailbox::new_unchecked(&hdr[..]);
    assert_eq!(
        (m.length(), m.address(), m.mailbox_type(), m.counter()),
        (10, 0, MailboxType::Coe, 3)
    );
    assert!(
        Mailbox::new_checked(&hdr[..]).is_err(),
        "length 10 but no data"
    );
    assert_eq!(mailbox::next_counter(7), 1);
    assert_eq!(mailbox::next_counter(0), 1);
    assert_eq!(mailbox::next_counter(3), 4);
}
