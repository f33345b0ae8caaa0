//! The SMCI47-S brake timing 2007h and the digital-output mask 60FEh:02 (Nanotec §11.8, §9.2–9.3).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod nanotec_rig;

use nanotec_rig::Rig;

fn ms16(r: &mut Rig, sub: u8, v: u16) {
    od::ObjectAccess::write(&mut r.d, 0x2007, sub, &v.to_le_bytes()).unwrap();
}

/// Switched On: power on, the brake opens after 2007h:01; Operation Enabled moves only after
/// 2007h:02 more; mode changes wait for the delays; off: brake on, power off after 2007h:03.
#[test]
fn brake_wait_times_2007h() {
    let mut r = Rig::new();
    ms16(&mut r, 1, 50);
    ms16(&mut r, 2, 30);
    ms16(&mut r, 3, 40);
    r.cw(0x0006);
    r.cw(0x0007);
    assert!(
        r.d.axis().motor().brake(),
        "brake still closed right after power on"
    );
    r.run_ms(30);
    assert!(r.d.axis().motor().brake(), "closed before 2007h:01");
    r.run_ms(25);
    assert!(!r.d.axis().motor().brake(), "open after 2007h:01");
    // Operation enabled: a mode change during the wait is refused, later taken.
    let mut r = Rig::new();
    ms16(&mut r, 1, 50);
    ms16(&mut r, 2, 30);
    r.cw(0x0006);
    r.cw(0x000F);
    assert_eq!(
        r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x01]),
        [0x80, 0x60, 0x60, 0x00, 0x22, 0x00, 0x00, 0x08],
        "0800 0022h during the wait"
    );
    r.run_ms(80);
    assert_eq!(
        r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x01]),
        [0x60, 0x60, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00]
    );
    // Power down: the brake closes at once, the output stage follows after 2007h:03.
    ms16(&mut r, 3, 40);
    r.run_ms(5);
    r.cw(0x0006);
    assert!(r.d.axis().motor().brake(), "brake on at once");
    assert!(r.d.stepper().unwrap().energised(), "power still on");
    r.run_ms(45);
    assert!(
        !r.d.stepper().unwrap().energised(),
        "power off after 2007h:03"
    );
}

/// §9.3: 60FEh:02 takes bits 16 … 18 only; any other bit discards the whole write (the
/// device file's `allowed_bits`, through the drive's object access).
#[test]
fn output_mask_outside_16_to_18_is_discarded() {
    let mut r = Rig::new();
    assert_eq!(r.i(0x60FE, 2), 0x0007_0000);
    assert_eq!(
        r.sdo(&[0x23, 0xFE, 0x60, 0x02, 0x01, 0x00, 0x01, 0x00]),
        [0x80, 0xFE, 0x60, 0x02, 0x30, 0x00, 0x09, 0x06]
    );
    assert_eq!(r.i(0x60FE, 2), 0x0007_0000, "unchanged");
    assert_eq!(
        r.sdo(&[0x23, 0xFE, 0x60, 0x02, 0x00, 0x00, 0x02, 0x00]),
        [0x60, 0xFE, 0x60, 0x02, 0x00, 0x00, 0x00, 0x00]
    );
    assert_eq!(r.i(0x60FE, 2), 0x0002_0000);
    assert_eq!(
        r.i(0x60FE, 1) & 1,
        0,
        "bit 0 is no brake bit on the Nanotec"
    );
}

/// The PD4-N has no brake output (no 2007h): no holding brake, not even at power-on; the
/// SMCI47-S holds with its brake until Switched On.
#[test]
fn pd4n_has_no_brake() {
    let desc = &devices::NANOTEC_PD4N;
    let od = od::ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let d: drive::drive::Drive<_, drive::vendors::nanotec::Nanotec> =
        drive::drive::Drive::new(od, drive::drive::DriveSettings::default());
    assert!(!d.axis().motor().brake());
    let r = Rig::new();
    assert!(r.d.axis().motor().brake());
}
