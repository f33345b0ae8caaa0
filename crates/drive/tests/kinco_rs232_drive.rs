//! The RS232 telegrams of the manual (§10.4, L2286-2292 of its text kept beside the project; the
//! KINCO-232 vectors, each named where it is sent) against the drive itself, the way public Kinco
//! RS232 drivers talk to the real one: one 10-byte telegram, one 10-byte answer. On the factory
//! set-up the controlword telegram is answered 80h with 0800 0021h (the Enable input owns it,
//! L1287); once Din1_Function and Din3_Function are 0, the printed sequence enables the drive and
//! an absolute move runs to 607Ah = 50 000.

mod kinco_rig;

use drive::vendors::kinco::rs232::{checksum, KincoRs232};
use kinco_rig::Rig;

/// The telegram of station 1 with `body` (bytes 1…8) and its negated-sum checksum.
fn telegram(body: [u8; 8]) -> [u8; 10] {
    let mut t = [0u8; 10];
    t[0] = 1;
    t[1..9].copy_from_slice(&body);
    t[9] = checksum(&t[..9]);
    t
}

fn exchange(r: &mut Rig, port: &mut KincoRs232, t: &[u8; 10]) -> Vec<u8> {
    let mut out = Vec::new();
    let now = r.now;
    port.on_bytes(now, t, &mut r.d, &mut |b| out.extend_from_slice(b));
    r.run_ms(2);
    out
}

fn write(r: &mut Rig, port: &mut KincoRs232, cmd: u8, index: u16, sub: u8, v: u32) -> Vec<u8> {
    let [i0, i1] = index.to_le_bytes();
    let [b0, b1, b2, b3] = v.to_le_bytes();
    exchange(r, port, &telegram([cmd, i0, i1, sub, b0, b1, b2, b3]))
}

#[test]
fn printed_sequence_moves_the_drive() {
    let mut r = Rig::factory();
    let mut port = KincoRs232::new(1, false);
    // KINCO-232-01 as printed, on the factory set-up: refused (local control).
    let a = exchange(
        &mut r,
        &mut port,
        &[0x01, 0x2B, 0x40, 0x60, 0x00, 0x2F, 0x00, 0x00, 0x00, 0x05],
    );
    assert_eq!(
        &a[..9],
        &[0x01, 0x80, 0x40, 0x60, 0x00, 0x21, 0x00, 0x00, 0x08]
    );
    // The inputs to the bus, as EA02 = 8 ("protocol") sets them up.
    assert_eq!(write(&mut r, &mut port, 0x2B, 0x2010, 0x03, 0)[1], 0x60);
    assert_eq!(write(&mut r, &mut port, 0x2B, 0x2010, 0x05, 0)[1], 0x60);
    for (cmd, index, v) in [
        (0x23u8, 0x6081u16, 1_638_400u32),
        (0x23, 0x6083, 16_384),
        (0x23, 0x6084, 16_384),
    ] {
        assert_eq!(write(&mut r, &mut port, cmd, index, 0, v)[1], 0x60);
    }
    // Mode 1, 06h, then KINCO-232-01 (2Fh) and KINCO-232-03 (607Ah := 50 000) as printed.
    assert_eq!(write(&mut r, &mut port, 0x2F, 0x6060, 0, 1)[1], 0x60);
    assert_eq!(write(&mut r, &mut port, 0x2B, 0x6040, 0, 0x06)[1], 0x60);
    let a = exchange(
        &mut r,
        &mut port,
        &[0x01, 0x2B, 0x40, 0x60, 0x00, 0x2F, 0x00, 0x00, 0x00, 0x05],
    );
    assert_eq!(
        &a,
        &[0x01, 0x60, 0x40, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF],
        "KINCO-232-05"
    );
    let a = exchange(
        &mut r,
        &mut port,
        &[0x01, 0x23, 0x7A, 0x60, 0x00, 0x50, 0xC3, 0x00, 0x00, 0xEF],
    );
    assert_eq!(a[1], 0x60);
    assert_eq!(write(&mut r, &mut port, 0x2B, 0x6040, 0, 0x3F)[1], 0x60);
    // KINCO-232-04 polled until target reached: answer 4Bh with the statusword in bytes 5-6.
    let mut sw = 0u16;
    for _ in 0..200 {
        r.run_ms(10);
        let a = exchange(
            &mut r,
            &mut port,
            &[0x01, 0x40, 0x41, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1E],
        );
        assert_eq!(&a[..5], &[0x01, 0x4B, 0x41, 0x60, 0x00], "KINCO-232-06");
        sw = u16::from_le_bytes([a[5], a[6]]);
        if sw & 0x0400 != 0 {
            break;
        }
    }
    assert_eq!(sw & 0x046F, 0x0427, "enabled, target reached: {sw:04X}");
    let a = write(&mut r, &mut port, 0x40, 0x6063, 0, 0);
    assert_eq!(a[1], 0x43);
    let p = i32::from_le_bytes([a[5], a[6], a[7], a[8]]);
    assert!((p - 50_000).abs() <= 20, "6063h = {p}");
}
