//! SDO server behaviour on the test bench personality: every transfer kind and every abort
//! cause of CiA 301 §7.2.4 (vectors in the CiA 301 / 305 notes kept beside the project, §1).

mod common;
use common::*;

fn bench() -> Bench {
    Bench::new(&devices::TESTBENCH, 1)
}

#[test]
fn expedited_upload_and_download() {
    let mut b = bench();
    assert_eq!(
        b.sdo1(&[0x40, 0x18, 0x10, 0x02]),
        p8(&[0x43, 0x18, 0x10, 0x02, 1, 0, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0x2B, 0x03, 0x20, 0x00, 0x9C, 0xFF]),
        p8(&[0x60, 0x03, 0x20, 0x00])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x20, 0x00]),
        p8(&[0x4B, 0x03, 0x20, 0x00, 0x9C, 0xFF])
    );
    // One byte: n = 3.
    assert_eq!(
        b.sdo1(&[0x40, 0x05, 0x20, 0x00]),
        p8(&[0x4F, 0x05, 0x20, 0x00, 42])
    );
}

#[test]
fn expedited_download_without_size_uses_the_object_size() {
    let mut b = bench();
    // e = 1, s = 0: size not indicated.
    assert_eq!(
        b.sdo1(&[0x22, 0x03, 0x20, 0x00, 0x05, 0x00, 0xAA, 0xBB]),
        p8(&[0x60, 0x03, 0x20])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x20, 0x00]),
        p8(&[0x4B, 0x03, 0x20, 0x00, 5, 0])
    );
}

#[test]
fn abort_causes() {
    let mut b = bench();
    // Unknown object / sub-index.
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x21, 0x00]),
        abort(0x2100, 0, 0x0602_0000)
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x18, 0x10, 0x09]),
        abort(0x1018, 9, 0x0609_0011)
    );
    // Read-only, write-only.
    assert_eq!(
        b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 1]),
        abort(0x2005, 0, 0x0601_0002)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x10, 0x00, 1, 2, 3, 4]),
        abort(0x1000, 0, 0x0601_0002)
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x02, 0x20, 0x00]),
        abort(0x2002, 0, 0x0601_0001)
    );
    // Length too high / too low.
    assert_eq!(
        b.sdo1(&[0x23, 0x03, 0x20, 0x00, 1, 0, 0, 0]),
        abort(0x2003, 0, 0x0607_0012)
    );
    assert_eq!(
        b.sdo1(&[0x2F, 0x03, 0x20, 0x00, 1]),
        abort(0x2003, 0, 0x0607_0013)
    );
    // Value range.
    assert_eq!(
        b.sdo1(&[0x2B, 0x03, 0x20, 0x00, 101, 0]),
        abort(0x2003, 0, 0x0609_0031)
    );
    assert_eq!(
        b.sdo1(&[0x2B, 0x03, 0x20, 0x00, 0x9B, 0xFF]),
        abort(0x2003, 0, 0x0609_0032)
    );
    // Unknown command specifier (CCT SDO 07 sends E0).
    assert_eq!(
        b.sdo1(&[0xE0, 0x00, 0x10, 0x00]),
        abort(0x1000, 0, 0x0504_0001)
    );
    // An empty frame.
    assert_eq!(b.sdo1(&[]), abort(0, 0, 0x0504_0001));
    // Nothing changed on error.
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x20, 0x00]),
        p8(&[0x4B, 0x03, 0x20, 0x00, 0, 0])
    );
}

#[test]
fn short_requests_are_zero_padded() {
    let mut b = bench();
    // Nanotec-style 4-byte upload request (the Nanotec manual prints short request frames).
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x10]),
        p8(&[0x43, 0x00, 0x10, 0x00, 0, 0, 0, 0])
    );
}

#[test]
fn segmented_upload_of_a_string() {
    let mut b = bench();
    // "drivetwin test bench" = 20 bytes.
    let r = b.sdo1(&[0x40, 0x08, 0x10, 0x00]);
    assert_eq!(r, p8(&[0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0]));
    let s1 = b.sdo1(&[0x60]);
    assert_eq!(s1, [0x00, b'd', b'r', b'i', b'v', b'e', b't', b'w']);
    let s2 = b.sdo1(&[0x70]);
    assert_eq!(s2, [0x10, b'i', b'n', b' ', b't', b'e', b's', b't']);
    let s3 = b.sdo1(&[0x60]);
    // 6 bytes left: t 0, n 1, c 1.
    assert_eq!(s3, [0x03, b' ', b'b', b'e', b'n', b'c', b'h', 0]);
}

#[test]
fn segmented_upload_toggle_error() {
    let mut b = bench();
    b.sdo1(&[0x40, 0x08, 0x10, 0x00]);
    // CCT SDO 17: 70 first → 0503 0000h.
    assert_eq!(b.sdo1(&[0x70]), abort(0x1008, 0, 0x0503_0000));
}

#[test]
fn segmented_download_and_upload_of_a_domain() {
    let mut b = bench();
    let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
    let size = (data.len() as u32).to_le_bytes();
    assert_eq!(
        b.sdo1(&[0x21, 0x00, 0x20, 0x00, size[0], size[1], size[2], size[3]]),
        p8(&[0x60, 0x00, 0x20, 0x00])
    );
    let mut toggle = 0u8;
    for (i, chunk) in data.chunks(7).enumerate() {
        let last = (i + 1) * 7 >= data.len();
        let n = 7 - chunk.len() as u8;
        let mut req = vec![(toggle << 4) | (n << 1) | last as u8];
        req.extend_from_slice(chunk);
        req.resize(8, 0);
        assert_eq!(b.sdo1(&req), p8(&[0x20 | (toggle << 4)]));
        toggle ^= 1;
    }
    // Read back segmented.
    let r = b.sdo1(&[0x40, 0x00, 0x20, 0x00]);
    assert_eq!(
        r,
        p8(&[0x41, 0x00, 0x20, 0x00, size[0], size[1], size[2], size[3]])
    );
    let mut got = Vec::new();
    let mut t = 0u8;
    loop {
        let s = b.sdo1(&[0x60 | (t << 4)]);
        assert_eq!(s[0] & 0x10, t << 4);
        let n = ((s[0] >> 1) & 7) as usize;
        got.extend_from_slice(&s[1..8 - n]);
        t ^= 1;
        if s[0] & 1 == 1 {
            break;
        }
    }
    assert_eq!(got, data);
}

#[test]
fn segmented_download_errors() {
    let mut b = bench();
    // Announced size larger than a fixed-size object.
    assert_eq!(
        b.sdo1(&[0x21, 0x03, 0x20, 0x00, 3, 0, 0, 0]),
        abort(0x2003, 0, 0x0607_0012)
    );
    // Announced size larger than the domain's capacity.
    assert_eq!(
        b.sdo1(&[0x21, 0x00, 0x20, 0x00, 0x01, 0x20, 0, 0]),
        abort(0x2000, 0, 0x0607_0012)
    );
    // Wrong toggle in the first segment.
    b.sdo1(&[0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    assert_eq!(
        b.sdo1(&[0x10, 1, 2, 3, 4, 5, 6, 7]),
        abort(0x2000, 0, 0x0503_0000)
    );
    // Fewer bytes than announced.
    b.sdo1(&[0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    b.sdo1(&[0x00, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(
        b.sdo1(&[0x15, 1, 2, 3, 4, 5, 6, 7]),
        abort(0x2000, 0, 0x0607_0013)
    );
    // A frame of the wrong kind mid-transfer.
    b.sdo1(&[0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x20, 0x00]),
        abort(0x2000, 0, 0x0504_0001)
    );
    // Zero-length final segment (python-canopen, unknown size) on a string.
    assert_eq!(b.sdo1(&[0x20, 0x01, 0x20, 0x00]), p8(&[0x60, 0x01, 0x20]));
    assert_eq!(b.sdo1(&[0x0F]), p8(&[0x20]));
    assert_eq!(
        b.sdo1(&[0x40, 0x01, 0x20, 0x00]),
        p8(&[0x41, 0x01, 0x20, 0x00, 0, 0, 0, 0])
    );
}

#[test]
fn client_abort_ends_a_transfer_silently() {
    let mut b = bench();
    b.sdo1(&[0x40, 0x08, 0x10, 0x00]);
    assert!(b.sdo(&abort(0, 0, 0x0504_0000)).is_empty());
    // Server idle again: a segment request is now an unknown command.
    assert_eq!(b.sdo1(&[0x60]), abort(0, 0, 0x0504_0001));
}

#[test]
fn timeout_aborts_a_silent_transfer() {
    let mut b = bench();
    b.sdo1(&[0x40, 0x08, 0x10, 0x00]);
    let out = b.advance_ms(999);
    assert!(out.is_empty(), "{out:?}");
    let out = b.advance_ms(2);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].data, abort(0x1008, 0, 0x0504_0000));
}

fn crc(data: &[u8]) -> u16 {
    canopen::sdo_crc::crc16(data)
}

/// Block download of `data` to 2000h with a given sub-block size seen from the server.
fn block_download(b: &mut Bench, data: &[u8], with_crc: bool) -> [u8; 8] {
    let size = (data.len() as u32).to_le_bytes();
    let cs = 0xC2 | if with_crc { 0x04 } else { 0 };
    let r = b.sdo1(&[cs, 0x00, 0x20, 0x00, size[0], size[1], size[2], size[3]]);
    assert_eq!(r, p8(&[0xA4, 0x00, 0x20, 0x00, 127]));
    let segments: Vec<&[u8]> = data.chunks(7).collect();
    let mut seq = 0u8;
    for (i, s) in segments.iter().enumerate() {
        seq += 1;
        let last = i + 1 == segments.len();
        let mut req = vec![seq | if last { 0x80 } else { 0 }];
        req.extend_from_slice(s);
        req.resize(8, 0);
        let out = b.sdo(&req);
        if last || seq == 127 {
            assert_eq!(out, vec![p8(&[0xA2, seq, 127])]);
            seq = 0;
        } else {
            assert!(out.is_empty());
        }
    }
    let pad = (7 - (data.len() - 1) % 7 - 1) as u8;
    let c = if with_crc { crc(data) } else { 0 }.to_le_bytes();
    b.sdo1(&[0xC1 | (pad << 2), c[0], c[1]])
}

#[test]
fn block_download_with_crc_then_block_upload() {
    let mut b = bench();
    let data: Vec<u8> = (0..5000u32).map(|i| (i % 251) as u8).collect();
    assert_eq!(block_download(&mut b, &data, true), p8(&[0xA1]));

    // Block upload, blksize 127, pst 0, client CRC.
    let r = b.sdo1(&[0xA4, 0x00, 0x20, 0x00, 127, 0]);
    let size = (data.len() as u32).to_le_bytes();
    assert_eq!(
        r,
        p8(&[0xC6, 0x00, 0x20, 0x00, size[0], size[1], size[2], size[3]])
    );
    let mut got = Vec::new();
    let mut req = vec![0xA3];
    loop {
        let segs = b.sdo(&req);
        assert!(!segs.is_empty());
        if segs[0][0] & 0xE3 == 0xC1 {
            let pad = ((segs[0][0] >> 2) & 7) as usize;
            got.truncate(got.len() - pad);
            assert_eq!(u16::from_le_bytes([segs[0][1], segs[0][2]]), crc(&data));
            break;
        }
        for (i, s) in segs.iter().enumerate() {
            assert_eq!(s[0] & 0x7F, i as u8 + 1);
            got.extend_from_slice(&s[1..]);
        }
        req = vec![0xA2, segs.len() as u8, 127];
    }
    assert!(b.sdo(&[0xA1]).is_empty());
    assert_eq!(got, data);
}

#[test]
fn block_download_crc_error_and_old_value_kept() {
    let mut b = bench();
    let data = b"A really really long string...";
    assert_eq!(crc(data), 0x6945);
    let size = (data.len() as u32).to_le_bytes();
    b.sdo1(&[0xC6, 0x01, 0x20, 0x00, size[0], size[1], size[2], size[3]]);
    for (i, s) in data.chunks(7).enumerate() {
        let last = (i + 1) * 7 >= data.len();
        let mut req = vec![(i as u8 + 1) | if last { 0x80 } else { 0 }];
        req.extend_from_slice(s);
        req.resize(8, 0);
        b.sdo(&req);
    }
    // n = 5, wrong CRC.
    assert_eq!(b.sdo1(&[0xD5, 0x00, 0x00]), abort(0x2001, 0, 0x0504_0004));
    let r = b.sdo1(&[0x40, 0x01, 0x20, 0x00]);
    assert_eq!(
        r,
        p8(&[0x41, 0x01, 0x20, 0x00, 9, 0, 0, 0]),
        "old value kept"
    );
}

#[test]
fn block_download_lost_segment_is_repeated() {
    let mut b = bench();
    let data: Vec<u8> = (0..30u8).collect();
    b.sdo1(&[0xC6, 0x00, 0x20, 0x00, 30, 0, 0, 0]);
    b.sdo(&p8(&[0x01, 0, 1, 2, 3, 4, 5, 6]));
    // Segment 2 lost: 3 arrives → early ack with ackseq 1.
    let out = b.sdo(&p8(&[0x03, 14, 15, 16, 17, 18, 19, 20]));
    assert_eq!(out, vec![p8(&[0xA2, 1, 127])]);
    // The rest of the broken sub-block is ignored.
    assert!(b.sdo(&p8(&[0x84, 21, 22, 23, 24, 25, 26, 27])).is_empty());
    // Client restarts after ackseq, renumbered from 1.
    let rest: Vec<&[u8]> = data[7..].chunks(7).collect();
    for (i, s) in rest.iter().enumerate() {
        let last = i + 1 == rest.len();
        let mut req = vec![(i as u8 + 1) | if last { 0x80 } else { 0 }];
        req.extend_from_slice(s);
        req.resize(8, 0);
        let out = b.sdo(&req);
        if last {
            assert_eq!(out, vec![p8(&[0xA2, i as u8 + 1, 127])]);
        }
    }
    let pad = 7 - (30 - 28) as u8;
    let c = crc(&data).to_le_bytes();
    assert_eq!(b.sdo1(&[0xC1 | (pad << 2), c[0], c[1]]), p8(&[0xA1]));
    let r = b.sdo1(&[0x40, 0x00, 0x20, 0x00]);
    assert_eq!(r[4], 30);
}

#[test]
fn block_upload_errors_and_protocol_switch() {
    let mut b = bench();
    // blksize 0x80 (CCT SDO 26).
    assert_eq!(
        b.sdo1(&[0xA0, 0x00, 0x10, 0x00, 0x80]),
        abort(0x1000, 0, 0x0504_0002)
    );
    // pst ≥ size: answered as a normal (expedited) upload.
    assert_eq!(
        b.sdo1(&[0xA0, 0x00, 0x10, 0x00, 20, 8]),
        p8(&[0x43, 0x00, 0x10, 0x00])
    );
    // CCT SDO 19: block upload of 1000h without CRC.
    assert_eq!(
        b.sdo1(&[0xA0, 0x00, 0x10, 0x00, 0x14, 0]),
        p8(&[0xC6, 0x00, 0x10, 0x00, 4])
    );
    assert_eq!(b.sdo(&[0xA3]), vec![p8(&[0x81, 0, 0, 0, 0])]);
    // ackseq beyond what was sent (CCT SDO 27 credits 0504 0003h).
    assert_eq!(b.sdo1(&[0xA2, 0x80, 0x14]), abort(0x1000, 0, 0x0504_0003));
}

#[test]
fn block_upload_end_frame_carries_the_crc() {
    let mut b = bench();
    // Long string default "drivetwin" (9 bytes), CRC always real.
    assert_eq!(
        b.sdo1(&[0xA0, 0x01, 0x20, 0x00, 127, 0]),
        p8(&[0xC6, 0x01, 0x20, 0x00, 9])
    );
    let segs = b.sdo(&[0xA3]);
    assert_eq!(segs.len(), 2);
    assert_eq!(segs[1][0], 0x82);
    let end = b.sdo1(&[0xA2, 2, 127]);
    let c = crc(b"drivetwin").to_le_bytes();
    assert_eq!(end, p8(&[0xC1 | (5 << 2), c[0], c[1]]));
}
