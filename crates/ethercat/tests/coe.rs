//! CoE: SDO over the mailbox, complete access, SDO information, emergencies, mailbox-level
//! checks, and a round trip through an ESC (the ESC reference kept beside the project, §5, §6).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod common;

use common::*;
use ethercat::coe::{self, CoeConfig, CoeServer, Emergency};
use ethercat::sii::{build_sii, SiiConfig, DEFAULT_IMAGE_SIZE};
use ethercat::Esc;
use od::{AbortCode, ObjectAccess, ObjectDictionary};

type Od = ObjectDictionary<Vec<u8>>;

fn dict(desc: &'static od::DeviceDescription) -> Od {
    ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap()
}

fn testbench() -> (CoeServer, Od) {
    (
        CoeServer::new(&devices::TESTBENCH, CoeConfig::FULL),
        dict(&devices::TESTBENCH),
    )
}

fn cmmp_as() -> (CoeServer, Od) {
    (
        CoeServer::new(
            &devices::CMMP_AS,
            CoeConfig::from_description(&devices::CMMP_AS),
        ),
        dict(&devices::CMMP_AS),
    )
}

/// A CoE request as a master writes it: header (counter `cnt`) + payload, padded to 128.
fn msg(cnt: u8, payload: &[u8]) -> Vec<u8> {
    let mut m = vec![0u8; 0x80];
    m[0..2].copy_from_slice(&(payload.len() as u16).to_le_bytes());
    m[5] = 0x03 | (cnt << 4);
    m[6..6 + payload.len()].copy_from_slice(payload);
    m
}

/// SDO request payload: CoE header 0x2000, command, index, sub, 4 data bytes.
fn sdo(cmd: u8, index: u16, sub: u8, data: [u8; 4]) -> Vec<u8> {
    let [il, ih] = index.to_le_bytes();
    let mut p = vec![0x00, 0x20, cmd, il, ih, sub];
    p.extend_from_slice(&data);
    p
}

struct Link {
    srv: CoeServer,
    od: Od,
    cnt: u8,
    /// Send mailbox size.
    size: usize,
}

impl Link {
    fn new((srv, od): (CoeServer, Od), size: usize) -> Self {
        Link {
            srv,
            od,
            cnt: 0,
            size,
        }
    }
    /// Send a payload with the next counter; the reply (header included), if any.
    fn send(&mut self, payload: &[u8]) -> Option<Vec<u8>> {
        self.cnt = ethercat::mailbox::next_counter(self.cnt);
        self.raw(&msg(self.cnt, payload))
    }
    fn raw(&mut self, m: &[u8]) -> Option<Vec<u8>> {
        let mut out = vec![0u8; self.size];
        let n = self.srv.process(m, &mut self.od, &mut out)?;
        out.truncate(n);
        Some(out)
    }
    fn poll(&mut self) -> Option<Vec<u8>> {
        let mut out = vec![0u8; self.size];
        let n = self.srv.poll(&mut out)?;
        out.truncate(n);
        Some(out)
    }
    /// The reply without its header, checking header length and type.
    fn coe(&mut self, payload: &[u8]) -> Vec<u8> {
        let r = self.send(payload).expect("a reply");
        assert_eq!(r[0] as usize | (r[1] as usize) << 8, r.len() - 6);
        assert_eq!(r[5] & 0x0F, 0x03, "CoE reply: {r:02x?}");
        r[6..].to_vec()
    }
    fn abort_code(&mut self, payload: &[u8]) -> u32 {
        let r = self.coe(payload);
        assert_eq!(r.len(), 10, "{r:02x?}");
        assert_eq!(
            &r[0..3],
            &[0x00, 0x20, 0x80],
            "abort with service 2: {r:02x?}"
        );
        assert_eq!(&r[3..6], &payload[3..6], "index/sub echoed");
        u32::from_le_bytes(r[6..10].try_into().unwrap())
    }
}

fn abort_bytes(index: u16, sub: u8, code: u32) -> Vec<u8> {
    let [il, ih] = index.to_le_bytes();
    let mut v = vec![0x00, 0x20, 0x80, il, ih, sub];
    v.extend_from_slice(&code.to_le_bytes());
    v
}

// ------------------------------------------------------------------ expedited

#[test]
fn expedited_upload_and_download_exact_bytes() {
    let mut l = Link::new(cmmp_as(), 0x80);
    // Read 1018h:01 (vendor ID 0x1D).
    let r = l
        .send(&[0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])
        .unwrap();
    assert_eq!(
        r,
        [
            0x0A, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x1D, 0x00,
            0x00, 0x00
        ]
    );
    // Write 6060h := 1 (INTEGER8, expedited 1 byte: 0x2F).
    let r = l
        .send(&[0x00, 0x20, 0x2F, 0x60, 0x60, 0x00, 0x01, 0, 0, 0])
        .unwrap();
    assert_eq!(
        r,
        [
            0x0A, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x30, 0x60, 0x60, 0x60, 0x00, 0x00, 0x00,
            0x00, 0x00
        ]
    );
    assert_eq!(l.od.read_u8(0x6060, 0), Some(1));
    // Read it back: 1 byte, size bits 3 unused (0x4F).
    let r = l.coe(&sdo(0x40, 0x6060, 0, [0; 4]));
    assert_eq!(r, [0x00, 0x30, 0x4F, 0x60, 0x60, 0x00, 0x01, 0, 0, 0]);
    // 2-byte object: 0x4B; 1C12h:01 = 1600h as UINT16.
    let r = l.coe(&sdo(0x40, 0x1C12, 1, [0; 4]));
    assert_eq!(r, [0x00, 0x30, 0x4B, 0x12, 0x1C, 0x01, 0x00, 0x16, 0, 0]);
    // Expedited download without the size bit (0x22): size from the entry.
    let r = l.coe(&sdo(0x22, 0x6060, 0, [3, 0, 0, 0]));
    assert_eq!(r[2], 0x60);
    assert_eq!(l.od.read_u8(0x6060, 0), Some(3));
    // Normal download (0x21, size 1) of a 1-byte value.
    let r = l.coe(&[0x00, 0x20, 0x21, 0x60, 0x60, 0x00, 1, 0, 0, 0, 0x06]);
    assert_eq!(r, [0x00, 0x30, 0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0]);
    assert_eq!(l.od.read_u8(0x6060, 0), Some(6));
}

#[test]
fn cmmp_as_hides_string_objects_and_has_no_complete_access() {
    // Tab. 4.9: 1008h–100Ah are not supported under CoE.
    let mut l = Link::new(cmmp_as(), 0x80);
    assert_eq!(l.abort_code(&sdo(0x40, 0x1008, 0, [0; 4])), 0x0602_0000);
    assert_eq!(l.abort_code(&sdo(0x40, 0x608B, 0, [0; 4])), 0x0602_0000);
    assert_eq!(l.abort_code(&sdo(0x50, 0x1018, 0, [0; 4])), 0x0601_0004);
    assert_eq!(l.abort_code(&sdo(0x31, 0x1C12, 0, [0; 4])), 0x0601_0004);
}

// ------------------------------------------------------------------ normal and segmented

#[test]
fn normal_upload_of_a_string() {
    let mut l = Link::new(testbench(), 0x80);
    let r = l.send(&sdo(0x40, 0x1008, 0, [0; 4])).unwrap();
    let mut want = vec![
        30, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0,
    ];
    want.extend_from_slice(b"drivetwin test bench");
    assert_eq!(r, want);
    // An empty string cannot go expedited: normal with size 0.
    l.od.write(0x2001, 0, b"").unwrap();
    let r = l.coe(&sdo(0x40, 0x2001, 0, [0; 4]));
    assert_eq!(r, [0x00, 0x30, 0x41, 0x01, 0x20, 0x00, 0, 0, 0, 0]);
    // A 3-byte string goes expedited.
    l.od.write(0x2001, 0, b"abc").unwrap();
    let r = l.coe(&sdo(0x40, 0x2001, 0, [0; 4]));
    assert_eq!(r, [0x00, 0x30, 0x47, 0x01, 0x20, 0x00, b'a', b'b', b'c', 0]);
}

fn pattern(n: usize) -> Vec<u8> {
    (0..n).map(|i| (i * 7 + i / 256) as u8).collect()
}

/// Run a segmented upload; returns the data and the segment commands.
fn segmented_upload(l: &mut Link, index: u16) -> (Vec<u8>, Vec<u8>) {
    let r = l.coe(&sdo(0x40, index, 0, [0; 4]));
    assert_eq!(r.len(), 10, "initiate response carries only the size");
    assert_eq!(r[2], 0x41);
    let size = u32::from_le_bytes(r[6..10].try_into().unwrap()) as usize;
    let mut data = Vec::new();
    let mut cmds = Vec::new();
    let mut toggle = 0u8;
    loop {
        let r = l.coe(&sdo(0x60 | toggle, 0, 0, [0; 4]));
        assert!(r.len() <= l.size - 6);
        assert_eq!(r[1], 0x30);
        let cmd = r[2];
        assert_eq!(cmd & 0xE0, 0x00, "upload segment response");
        assert_eq!(cmd & 0x10, toggle, "toggle echoed");
        let mut k = r.len() - 3;
        if k == 7 {
            k -= ((cmd >> 1) & 7) as usize;
        }
        data.extend_from_slice(&r[3..3 + k]);
        cmds.push(cmd);
        toggle ^= 0x10;
        if cmd & 1 != 0 {
            break;
        }
    }
    assert_eq!(data.len(), size);
    (data, cmds)
}

#[test]
fn segmented_upload_of_a_large_domain() {
    let mut l = Link::new(testbench(), 64);
    let value = pattern(8192);
    l.od.write(0x2000, 0, &value).unwrap();
    let (data, cmds) = segmented_upload(&mut l, 0x2000);
    assert_eq!(data, value);
    // 64-byte mailbox: 55 data bytes per segment; 148 full ones and one of 52.
    assert_eq!(cmds.len(), 149);
    assert_eq!(cmds[0], 0x00);
    assert_eq!(cmds[1], 0x10);
    assert_eq!(*cmds.last().unwrap(), 0x01);
    assert!(!l.srv.busy());

    // A short last segment: padded to length 10 with the unused count.
    let s: Vec<u8> = (0..58u8).map(|i| b'A' + i % 26).collect();
    l.od.write(0x2001, 0, &s).unwrap();
    let (data, cmds) = segmented_upload(&mut l, 0x2001);
    assert_eq!(data, s);
    assert_eq!(cmds, vec![0x00, 0x19]);
}

#[test]
fn segmented_upload_exact_segment_bytes() {
    let mut l = Link::new(testbench(), 32);
    l.od.write(0x2001, 0, b"0123456789abcdefghijklmnopqrstuvwxyz")
        .unwrap();
    let r = l.coe(&sdo(0x40, 0x2001, 0, [0; 4]));
    assert_eq!(r, [0x00, 0x30, 0x41, 0x01, 0x20, 0x00, 36, 0, 0, 0]);
    // 32-byte mailbox: 23 bytes, then 13 (last).
    let r = l.coe(&sdo(0x60, 0, 0, [0; 4]));
    let mut want = vec![0x00, 0x30, 0x00];
    want.extend_from_slice(b"0123456789abcdefghijklm");
    assert_eq!(r, want);
    let r = l.coe(&sdo(0x70, 0, 0, [0; 4]));
    let mut want = vec![0x00, 0x30, 0x11];
    want.extend_from_slice(b"nopqrstuvwxyz");
    assert_eq!(r, want);
    // No transfer any more: a segment request is an unknown command.
    let r = l.coe(&sdo(0x60, 0, 0, [0; 4]));
    assert_eq!(r, abort_bytes(0, 0, 0x0504_0001));
}

#[test]
fn segmented_upload_toggle_error_aborts() {
    let mut l = Link::new(testbench(), 32);
    l.od.write(0x2000, 0, &pattern(100)).unwrap();
    l.coe(&sdo(0x40, 0x2000, 0, [0; 4]));
    l.coe(&sdo(0x60, 0, 0, [0; 4]));
    let r = l.coe(&sdo(0x60, 0, 0, [0; 4]));
    assert_eq!(r, abort_bytes(0x2000, 0, 0x0503_0000));
    assert!(!l.srv.busy());
}

/// Segmented download as SOEM does it: initiate with the first SM0 size − 16 bytes, then
/// segments of up to `seg` bytes.
fn segmented_download(l: &mut Link, index: u16, value: &[u8], rx: usize, seg: usize) -> Vec<u8> {
    let first = (rx - 16).min(value.len());
    let [il, ih] = index.to_le_bytes();
    let mut p = vec![0x00, 0x20, 0x21, il, ih, 0x00];
    p.extend_from_slice(&(value.len() as u32).to_le_bytes());
    p.extend_from_slice(&value[..first]);
    let r = l.coe(&p);
    if r[2] == 0x80 {
        return r;
    }
    assert_eq!(r, [0x00, 0x30, 0x60, il, ih, 0x00, 0, 0, 0, 0]);
    let mut pos = first;
    let mut toggle = 0u8;
    while pos < value.len() {
        let k = (value.len() - pos).min(seg);
        let last = pos + k == value.len();
        let mut cmd = toggle | u8::from(last);
        let mut p = vec![0x00, 0x20];
        if k < 7 {
            cmd |= ((7 - k) as u8) << 1;
            p.push(cmd);
            p.extend_from_slice(&value[pos..pos + k]);
            p.resize(10, 0);
        } else {
            p.push(cmd);
            p.extend_from_slice(&value[pos..pos + k]);
        }
        let r = l.coe(&p);
        if r[2] == 0x80 {
            return r;
        }
        assert_eq!(r, [0x00, 0x30, 0x20 | toggle, 0, 0, 0, 0, 0, 0, 0]);
        pos += k;
        toggle ^= 0x10;
    }
    vec![]
}

#[test]
fn segmented_download_of_a_large_domain() {
    let mut l = Link::new(testbench(), 64);
    let value = pattern(8192);
    assert_eq!(segmented_download(&mut l, 0x2000, &value, 64, 55), vec![]);
    let mut b = vec![0u8; 8192];
    assert_eq!(l.od.read(0x2000, 0, &mut b), Ok(8192));
    assert_eq!(b, value);
    // A short last segment (3 bytes in a length-10 message).
    let value = pattern(48 + 55 + 3);
    assert_eq!(segmented_download(&mut l, 0x2000, &value, 64, 55), vec![]);
    let n = l.od.read(0x2000, 0, &mut b).unwrap();
    assert_eq!(&b[..n], &value[..]);
    assert!(!l.srv.busy());
}

#[test]
fn segmented_download_errors() {
    let mut l = Link::new(testbench(), 64);
    // Toggle not alternated.
    let [il, ih] = 0x2000u16.to_le_bytes();
    let mut p = vec![0x00, 0x20, 0x21, il, ih, 0x00, 100, 0, 0, 0];
    p.extend_from_slice(&[1; 48]);
    assert_eq!(l.coe(&p)[2], 0x60);
    let mut seg = vec![0x00, 0x20, 0x10];
    seg.extend_from_slice(&[2; 20]);
    assert_eq!(l.coe(&seg), abort_bytes(0x2000, 0, 0x0503_0000));
    // Too much data in the segments.
    assert_eq!(l.coe(&p)[2], 0x60);
    let mut seg = vec![0x00, 0x20, 0x00];
    seg.extend_from_slice(&[2; 53]);
    assert_eq!(l.coe(&seg), abort_bytes(0x2000, 0, 0x0607_0012));
    // Last segment too early.
    assert_eq!(l.coe(&p)[2], 0x60);
    let mut seg = vec![0x00, 0x20, 0x01];
    seg.extend_from_slice(&[2; 10]);
    assert_eq!(l.coe(&seg), abort_bytes(0x2000, 0, 0x0607_0013));
    // Announced size beyond the entry, read-only entry: refused at the initiate request.
    let mut p = vec![0x00, 0x20, 0x21, il, ih, 0x00, 0x01, 0x20, 0, 0];
    p.extend_from_slice(&[1; 48]);
    assert_eq!(l.coe(&p), abort_bytes(0x2000, 0, 0x0607_0012));
    let mut p = vec![0x00, 0x20, 0x21, 0x08, 0x10, 0x00, 100, 0, 0, 0];
    p.extend_from_slice(&[1; 48]);
    assert_eq!(l.coe(&p), abort_bytes(0x1008, 0, 0x0601_0002));
    // A segment without a transfer.
    assert_eq!(l.coe(&seg), abort_bytes(0, 0, 0x0504_0001));
    // The master's abort ends a transfer without reply.
    let mut p = vec![0x00, 0x20, 0x21, il, ih, 0x00, 100, 0, 0, 0];
    p.extend_from_slice(&[1; 48]);
    assert_eq!(l.coe(&p)[2], 0x60);
    assert!(l.srv.busy());
    assert_eq!(l.send(&abort_bytes(0x2000, 0, 0x0504_0000)), None);
    assert!(!l.srv.busy());
    assert_eq!(l.srv.counters().aborts_received, 1);
}

// ------------------------------------------------------------------ aborts

#[test]
fn every_abort_cause() {
    let mut l = Link::new(testbench(), 0x80);
    let up = |i, s| sdo(0x40, i, s, [0; 4]);
    // Unknown object, unknown sub-index.
    assert_eq!(l.abort_code(&up(0x3000, 0)), 0x0602_0000);
    assert_eq!(l.abort_code(&up(0x1018, 9)), 0x0609_0011);
    assert_eq!(
        l.coe(&up(0x3000, 0)),
        [0x00, 0x20, 0x80, 0x00, 0x30, 0x00, 0x00, 0x00, 0x02, 0x06]
    );
    // Write to a read-only object, read of a write-only one.
    assert_eq!(
        l.abort_code(&sdo(0x2F, 0x2005, 0, [1, 0, 0, 0])),
        0x0601_0002
    );
    assert_eq!(l.abort_code(&up(0x2002, 0)), 0x0601_0001);
    // Length too high / too low (1017h is UNSIGNED16).
    assert_eq!(
        l.abort_code(&sdo(0x23, 0x1017, 0, [1, 0, 0, 0])),
        0x0607_0012
    );
    assert_eq!(
        l.abort_code(&sdo(0x2F, 0x1017, 0, [1, 0, 0, 0])),
        0x0607_0013
    );
    // Value range (2003h: −100…100).
    assert_eq!(
        l.abort_code(&sdo(0x2B, 0x2003, 0, [101, 0, 0, 0])),
        0x0609_0031
    );
    assert_eq!(
        l.abort_code(&sdo(
            0x2B,
            0x2003,
            0,
            (-101i16)
                .to_le_bytes()
                .into_iter()
                .chain([0, 0])
                .collect::<Vec<_>>()
                .try_into()
                .unwrap()
        )),
        0x0609_0032
    );
    // Wrong signature for store (1010h:01).
    assert_eq!(l.abort_code(&sdo(0x23, 0x1010, 1, *b"xxxx")), 0x0800_0020);
    // Unknown command specifier (5: block upload does not exist in CoE).
    assert_eq!(l.abort_code(&sdo(0xA0, 0x1000, 0, [0; 4])), 0x0504_0001);
    // Complete access with sub-index > 1, and on an object with a string entry.
    assert_eq!(l.abort_code(&sdo(0x50, 0x1018, 2, [0; 4])), 0x0601_0000);
    assert_eq!(l.abort_code(&sdo(0x50, 0x2004, 0, [0; 4])), 0x0601_0004);
    assert_eq!(l.srv.counters().aborts_sent, 13);
    // Valid values still work.
    assert_eq!(l.coe(&sdo(0x2B, 0x2003, 0, [100, 0, 0, 0]))[2], 0x60);
    assert_eq!(l.od.read_u16(0x2003, 0), Some(100));
    assert_eq!(AbortCode(0x0601_0004), coe::CA_NOT_SUPPORTED);
}

// ------------------------------------------------------------------ complete access

#[test]
fn complete_access_read_of_identity() {
    let mut l = Link::new(testbench(), 0x80);
    let r = l.send(&sdo(0x50, 0x1018, 0, [0; 4])).unwrap();
    let want = [
        28, 0, 0, 0, 0, 0x13, // header
        0x00, 0x30, 0x51, 0x18, 0x10, 0x00, 18, 0, 0, 0, // normal response with CA
        4, 0, // sub 0 padded to 16 bits
        0, 0, 0, 0, // vendor
        1, 0, 0, 0, // product
        0, 0, 1, 0, // revision
        1, 0, 0, 0, // serial
    ];
    assert_eq!(r, want);
    // From sub-index 1: no count.
    let r = l.coe(&sdo(0x50, 0x1018, 1, [0; 4]));
    assert_eq!(r[2], 0x51);
    assert_eq!(&r[6..10], &[16, 0, 0, 0]);
    assert_eq!(&r[10..], &want[18..]);
}

#[test]
fn complete_access_write_of_pdo_mapping_and_assignment() {
    let cfg = CoeConfig {
        complete_access: true,
        ..CoeConfig::from_description(&devices::CMMP_AS)
    };
    let mut l = Link::new(
        (
            CoeServer::new(&devices::CMMP_AS, cfg),
            dict(&devices::CMMP_AS),
        ),
        0x80,
    );
    // 1600h := controlword (6040h:00, 16 bit) + modes of operation (6060h:00, 8 bit).
    let mut p = vec![0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 10, 0, 0, 0];
    p.extend_from_slice(&[2, 0]);
    p.extend_from_slice(&0x6040_0010u32.to_le_bytes());
    p.extend_from_slice(&0x6060_0008u32.to_le_bytes());
    let r = l.coe(&p);
    assert_eq!(r, [0x00, 0x30, 0x70, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
    assert_eq!(l.od.read_u8(0x1600, 0), Some(2));
    assert_eq!(l.od.read_u32(0x1600, 1), Some(0x6040_0010));
    assert_eq!(l.od.read_u32(0x1600, 2), Some(0x6060_0008));
    // Read back by CA: count, pad, then all four entries.
    let r = l.coe(&sdo(0x50, 0x1600, 0, [0; 4]));
    assert_eq!(&r[6..10], &[18, 0, 0, 0]);
    assert_eq!(&r[10..12], &[2, 0]);
    assert_eq!(&r[12..16], &0x6040_0010u32.to_le_bytes());
    // A non-mappable object: the mapping procedure's abort, count left at 0.
    let mut p = vec![0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 6, 0, 0, 0, 1, 0];
    p.extend_from_slice(&0x1018_0120u32.to_le_bytes());
    assert_eq!(l.coe(&p)[2], 0x80);
    assert_eq!(l.od.read_u8(0x1600, 0), Some(0));
    // pysoem's assignment write: struct 'BxH' to 1C12h, expedited CA (4 bytes).
    let r = l.coe(&sdo(0x33, 0x1C12, 0, [1, 0, 0x01, 0x16]));
    assert_eq!(r[2], 0x70, "{r:02x?}");
    assert_eq!(l.od.read_u8(0x1C12, 0), Some(1));
    assert_eq!(l.od.read_u16(0x1C12, 1), Some(0x1601));
    // Data ending inside an entry, and more data than the object holds.
    assert_eq!(
        l.abort_code(&[0x00, 0x20, 0x31, 0x12, 0x1C, 0x00, 3, 0, 0, 0, 1, 0, 0x01]),
        0x0607_0010
    );
    let mut p = vec![0x00, 0x20, 0x31, 0x12, 0x1C, 0x00, 12, 0, 0, 0, 4, 0];
    p.extend_from_slice(&[0x00, 0x16, 0x01, 0x16, 0x02, 0x16, 0x03, 0x16, 0x04, 0x16]);
    p[6] = 12;
    assert_eq!(l.abort_code(&p), 0x0607_0012);
    // A record's read-only count given its own value is accepted (1018h is all ro: the
    // entries then abort with 0601 0002h unless they equal the current values).
    let mut p = vec![0x00, 0x20, 0x31, 0x18, 0x10, 0x00, 6, 0, 0, 0, 4, 0];
    p.extend_from_slice(&0x1Du32.to_le_bytes());
    assert_eq!(l.coe(&p)[2], 0x70);
    p[10] = 3;
    assert_eq!(l.abort_code(&p), 0x0601_0002);
}

// ------------------------------------------------------------------ SDO information

fn info(op: u8, body: &[u8]) -> Vec<u8> {
    let mut p = vec![0x00, 0x80, op, 0x00, 0x00, 0x00];
    p.extend_from_slice(body);
    p
}

#[test]
fn sdo_info_od_list_with_fragments() {
    let desc = &devices::TESTBENCH;
    let all: Vec<u16> = desc.objects.iter().map(|o| o.index).collect();
    assert_eq!(all.len(), 14);
    let mut l = Link::new(testbench(), 32);
    // 32-byte mailbox: 9 indices in the first fragment, 10 in the others.
    let r = l.send(&info(0x01, &[0x01, 0x00])).unwrap();
    let mut want = vec![
        26, 0, 0, 0, 0, 0x13, 0x00, 0x80, 0x82, 0x00, 0x01, 0x00, 0x01, 0x00,
    ];
    for i in &all[..9] {
        want.extend_from_slice(&i.to_le_bytes());
    }
    assert_eq!(r, want);
    assert!(l.srv.busy());
    let r = l.poll().unwrap();
    let mut want = vec![16, 0, 0, 0, 0, 0x23, 0x00, 0x80, 0x02, 0x00, 0x00, 0x00];
    for i in &all[9..] {
        want.extend_from_slice(&i.to_le_bytes());
    }
    assert_eq!(r, want);
    assert!(!l.srv.busy());
    assert_eq!(l.poll(), None);

    // Counts of the five lists.
    let r = l.coe(&info(0x01, &[0x00, 0x00]));
    let tx = desc
        .objects
        .iter()
        .filter(|o| o.entries.iter().any(|e| e.pdo_mappable))
        .count() as u8;
    assert_eq!(r[..8], [0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00]);
    assert_eq!(r[8..10], [14, 0]);
    assert_eq!(r[12..14], [tx, 0]);
    // TxPDO-mappable list: 1001h only on the test bench.
    let r = l.coe(&info(0x01, &[0x03, 0x00]));
    assert_eq!(
        r,
        [0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x03, 0x00, 0x01, 0x10]
    );
    // Unknown list type.
    let r = l.coe(&info(0x01, &[0x09, 0x00]));
    assert_eq!(
        r,
        [0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x06]
    );
}

#[test]
fn sdo_info_fragments_through_a_large_dictionary() {
    // The CMMP-AS list in 128-byte mailboxes; hidden objects are left out.
    let mut l = Link::new(cmmp_as(), 0x80);
    let want: Vec<u16> = devices::CMMP_AS
        .objects
        .iter()
        .map(|o| o.index)
        .filter(|i| {
            !CoeConfig::from_description(&devices::CMMP_AS)
                .hidden
                .contains(i)
        })
        .collect();
    let mut r = l.coe(&info(0x01, &[0x01, 0x00]));
    let mut got = Vec::new();
    let mut left = u16::from_le_bytes([r[4], r[5]]);
    let total = left;
    assert!(total > 0, "fragmented");
    assert_eq!(&r[6..8], &[1, 0]);
    r.drain(..8);
    loop {
        got.extend(r.chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])));
        if left == 0 {
            break;
        }
        let m = l.poll().unwrap();
        assert_eq!(m[5] & 0x0F, 3);
        let incomplete = m[8] & 0x80 != 0;
        let l2 = u16::from_le_bytes([m[10], m[11]]);
        assert_eq!(l2, left - 1);
        assert_eq!(incomplete, l2 > 0);
        left = l2;
        r = m[12..].to_vec();
    }
    assert_eq!(got, want);
    assert!(!got.contains(&0x1008));
}

#[test]
fn sdo_info_object_and_entry_description() {
    let mut l = Link::new(testbench(), 0x80);
    let r = l.send(&info(0x03, &[0x18, 0x10])).unwrap();
    let mut want = vec![27, 0, 0, 0, 0, 0x13, 0x00, 0x80, 0x04, 0x00, 0x00, 0x00];
    want.extend_from_slice(&[0x18, 0x10, 0x23, 0x00, 0x04, 0x09]);
    want.extend_from_slice(b"identity_object");
    assert_eq!(r, want);
    // A VAR: its type; an ARRAY: the element type.
    let r = l.coe(&info(0x03, &[0x17, 0x10]));
    assert_eq!(&r[6..12], &[0x17, 0x10, 0x06, 0x00, 0x00, 0x07]);
    assert_eq!(&r[12..], b"producer_heartbeat_time");
    let r = l.coe(&info(0x03, &[0x16, 0x10]));
    assert_eq!(&r[6..12], &[0x16, 0x10, 0x07, 0x00, 0x04, 0x08]);

    // Entry 2003h:00 with everything: default 0, min −100, max 100.
    let r = l.coe(&info(0x05, &[0x03, 0x20, 0x00, 0x7F]));
    let mut want = vec![0x00, 0x80, 0x06, 0x00, 0x00, 0x00];
    want.extend_from_slice(&[0x03, 0x20, 0x00, 0x77]); // unit type (0x08) not included
    want.extend_from_slice(&[0x03, 0x00, 0x10, 0x00, 0x3F, 0x03]);
    want.extend_from_slice(&[0x00, 0x00, 0x9C, 0xFF, 0x64, 0x00]);
    want.extend_from_slice(b"limited_i16");
    assert_eq!(r, want);
    // As SOEM asks (value info 7): name at mailbox length − 16.
    let r = l.send(&info(0x05, &[0x18, 0x10, 0x01, 0x07])).unwrap();
    let len = u16::from_le_bytes([r[0], r[1]]) as usize;
    assert_eq!(&r[6 + 16..6 + len], b"vendor_id");
    assert_eq!(
        &r[12..22],
        &[0x18, 0x10, 0x01, 0x07, 0x07, 0x00, 0x20, 0x00, 0x07, 0x00]
    );
    // 1001h: ro, TxPDO mappable.
    let r = l.coe(&info(0x05, &[0x01, 0x10, 0x00, 0x07]));
    assert_eq!(&r[14..16], &[0x87, 0x00]);
    // DOMAIN: bit length from the capacity (8 KiB is more than 16 bits can say: FFFFh).
    let r = l.coe(&info(0x05, &[0x00, 0x20, 0x00, 0x07]));
    assert_eq!(&r[10..16], &[0x0F, 0x00, 0xFF, 0xFF, 0x3F, 0x03]);
    let r = l.coe(&info(0x05, &[0x08, 0x10, 0x00, 0x07]));
    assert_eq!(&r[10..16], &[0x09, 0x00, 0x00, 0x01, 0x07, 0x00]);

    // Errors: unknown object, unknown sub-index, unknown opcode.
    let r = l.send(&info(0x03, &[0x00, 0x30])).unwrap();
    assert_eq!(
        r,
        [10, 0, 0, 0, 0, r[5], 0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06]
    );
    let r = l.coe(&info(0x05, &[0x18, 0x10, 0x09, 0x07]));
    assert_eq!(&r[6..], &[0x11, 0x00, 0x09, 0x06]);
    let r = l.coe(&info(0x02, &[0, 0]));
    assert_eq!(&r[6..], &[0x01, 0x00, 0x04, 0x05]);
    assert_eq!(l.srv.counters().info_errors, 3);
    // Too short a request: mailbox error "invalid size".
    let r = l.send(&info(0x05, &[0x18, 0x10])).unwrap();
    assert_eq!(&r[5..], &[r[5], 0x01, 0x00, 0x08, 0x00][..]);
    assert_eq!(r[5] & 0x0F, 0);
}

#[test]
fn sdo_info_off_is_an_unsupported_service() {
    let cfg = CoeConfig {
        sdo_info: false,
        ..CoeConfig::FULL
    };
    let mut l = Link::new(
        (
            CoeServer::new(&devices::TESTBENCH, cfg),
            dict(&devices::TESTBENCH),
        ),
        0x80,
    );
    let r = l.send(&info(0x01, &[0x01, 0x00])).unwrap();
    assert_eq!(r, [4, 0, 0, 0, 0, 0x10, 0x01, 0x00, 0x04, 0x00]);
}

// ------------------------------------------------------------------ emergencies

#[test]
fn emergency_queueing() {
    let mut l = Link::new(testbench(), 0x80);
    assert_eq!(l.poll(), None);
    l.srv
        .queue_emergency(Emergency::new(0x2310, 0x03, [0; 5]))
        .unwrap();
    l.srv
        .queue_emergency(Emergency::new(0x0000, 0x00, [1, 2, 3, 4, 5]))
        .unwrap();
    assert_eq!(l.srv.pending_emergencies(), 2);
    // Not while a segmented transfer is in progress (spec §5.6).
    l.od.write(0x2000, 0, &pattern(300)).unwrap();
    l.coe(&sdo(0x40, 0x2000, 0, [0; 4]));
    assert!(l.srv.busy());
    assert_eq!(l.poll(), None);
    l.send(&abort_bytes(0x2000, 0, 0x0504_0000));
    let r = l.poll().unwrap();
    assert_eq!(
        r,
        [10, 0, 0, 0, 0, 0x23, 0x00, 0x10, 0x10, 0x23, 0x03, 0, 0, 0, 0, 0]
    );
    let r = l.poll().unwrap();
    assert_eq!(&r[6..], &[0x00, 0x10, 0x00, 0x00, 0x00, 1, 2, 3, 4, 5]);
    assert_eq!(r[5], 0x33);
    assert_eq!(l.poll(), None);
    // A full queue refuses and counts.
    for i in 0..coe::EMERGENCY_QUEUE {
        l.srv
            .queue_emergency(Emergency::new(0x1000 + i as u16, 1, [0; 5]))
            .unwrap();
    }
    assert!(l
        .srv
        .queue_emergency(Emergency::new(0xFFFF, 1, [0; 5]))
        .is_err());
    let c = l.srv.counters();
    assert_eq!((c.emergencies_sent, c.emergencies_dropped), (2, 1));
    // Oldest first.
    assert_eq!(&l.poll().unwrap()[8..10], &[0x00, 0x10]);
}

// ------------------------------------------------------------------ mailbox level

#[test]
fn counter_and_duplicate_handling() {
    let mut l = Link::new(cmmp_as(), 0x80);
    let req = sdo(0x40, 0x1018, 1, [0; 4]);
    let r = l.raw(&msg(1, &req)).unwrap();
    assert_eq!(r[5], 0x13);
    // The same counter again: a repetition, dropped.
    assert_eq!(l.raw(&msg(1, &req)), None);
    assert_eq!(l.srv.counters().duplicates, 1);
    // Counter 0 disables the check.
    assert_eq!(l.raw(&msg(0, &req)).unwrap()[5], 0x23);
    assert_eq!(l.raw(&msg(0, &req)).unwrap()[5], 0x33);
    // Replies count 1…7 and wrap to 1.
    let mut seen = Vec::new();
    for i in 0..8u8 {
        let r = l.raw(&msg(i % 7 + 1, &req)).unwrap();
        seen.push(r[5] >> 4);
    }
    assert_eq!(seen, [4, 5, 6, 7, 1, 2, 3, 4]);
    // A restart of the mailbox forgets the last counter.
    let _ = l.raw(&msg(5, &req)).unwrap();
    l.srv.reset();
    assert!(l.raw(&msg(5, &req)).is_some());
}

#[test]
fn bad_mailbox_headers_get_mailbox_errors() {
    let mut l = Link::new(cmmp_as(), 0x80);
    let detail = |r: Vec<u8>| {
        assert_eq!(&r[..5], &[4, 0, 0, 0, 0]);
        assert_eq!(r[5] & 0x0F, 0, "type 0");
        assert_eq!(&r[6..8], &[0x01, 0x00]);
        u16::from_le_bytes([r[8], r[9]])
    };
    // Shorter than a header.
    assert_eq!(detail(l.raw(&[10, 0, 0]).unwrap()), 0x0001);
    // Length 0.
    let mut m = msg(1, &[]);
    assert_eq!(detail(l.raw(&m).unwrap()), 0x0005);
    // Length beyond the message.
    m[0] = 200;
    assert_eq!(detail(l.raw(&m).unwrap()), 0x0005);
    // Type 0 (error) from the master.
    let mut m = msg(2, &sdo(0x40, 0x1000, 0, [0; 4]));
    m[5] &= 0xF0;
    assert_eq!(detail(l.raw(&m).unwrap()), 0x0005);
    // EoE, FoE, VoE: protocol not supported.
    for ty in [2u8, 4, 15] {
        let mut m = msg(3, &sdo(0x40, 0x1000, 0, [0; 4]));
        m[5] = (m[5] & 0xF0) | ty;
        m[5] = (m[5] & 0x0F) | ((ty % 7 + 1) << 4);
        assert_eq!(detail(l.raw(&m).unwrap()), 0x0002);
    }
    // CoE without its header, SDO shorter than its fixed part.
    assert_eq!(detail(l.send(&[0x00]).unwrap()), 0x0006);
    assert_eq!(
        detail(l.send(&[0x00, 0x20, 0x40, 0x00, 0x10]).unwrap()),
        0x0008
    );
    // PDO services, SDO response and emergency from the master: service not supported.
    for svc in [1u8, 3, 4, 5, 6, 7, 9, 15] {
        let mut p = sdo(0x40, 0x1000, 0, [0; 4]);
        p[1] = svc << 4;
        assert_eq!(detail(l.send(&p).unwrap()), 0x0004, "service {svc}");
    }
    assert!(l.srv.counters().mailbox_errors >= 15);
    // A too small send mailbox: nothing to answer with.
    let mut out = [0u8; 8];
    assert_eq!(l.srv.process(&[10, 0, 0], &mut l.od, &mut out), None);
}

// ------------------------------------------------------------------ through an ESC

const ST: u16 = 0x1001;

fn esc_bus() -> Bus {
    let mut image = vec![0u8; DEFAULT_IMAGE_SIZE];
    build_sii(
        &devices::CMMP_AS,
        &SiiConfig::from_description(&devices::CMMP_AS),
        &mut image,
    )
    .expect("image");
    let image: &'static [u8] = Box::leak(image.into_boxed_slice());
    let mut bus = Bus::new(vec![Esc::with_sii(image)]);
    bus.assign_addresses();
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 0x0002);
    assert_eq!(bus.al(ST), (0x0002, 0));
    bus
}

/// The master's side of one mailbox exchange: write SM0, let the device pump, poll SM1.
fn exchange(bus: &mut Bus, srv: &mut CoeServer, od: &mut Od, request: &[u8]) -> Vec<u8> {
    assert_eq!(bus.fprd(ST, 0x0805, 1).data[0] & 0x08, 0, "SM0 empty");
    assert_eq!(bus.fpwr(ST, 0x1000, request).wkc, 1);
    assert!(coe::pump(&mut bus.slaves[0], srv, od));
    read_sm1(bus)
}

fn read_sm1(bus: &mut Bus) -> Vec<u8> {
    let st = bus.fprd(ST, 0x080D, 2);
    assert_eq!(st.data[0] & 0x08, 0x08, "SM1 full");
    let r = bus.fprd(ST, 0x1080, 0x80);
    assert_eq!(r.wkc, 1);
    let len = u16::from_le_bytes([r.data[0], r.data[1]]) as usize;
    r.data[..6 + len].to_vec()
}

#[test]
fn end_to_end_through_an_esc() {
    let mut bus = esc_bus();
    let (mut srv, mut od) = cmmp_as();
    // Nothing to do: no request, no emergency.
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    // Read 1018h:01 as SOEM does.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(1, &sdo(0x40, 0x1018, 1, [0; 4])),
    );
    assert_eq!(
        r,
        [0x0A, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x1D, 0, 0, 0]
    );
    // Write 1C12h:00 := 0, read it back.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(2, &sdo(0x2F, 0x1C12, 0, [0; 4])),
    );
    assert_eq!(&r[6..], &[0x00, 0x30, 0x60, 0x12, 0x1C, 0x00, 0, 0, 0, 0]);
    assert_eq!(od.read_u8(0x1C12, 0), Some(0));
    // A mailbox error for a non-CoE message.
    let mut m = msg(3, &sdo(0x40, 0x1018, 1, [0; 4]));
    m[5] = (m[5] & 0xF0) | 0x04;
    let r = exchange(&mut bus, &mut srv, &mut od, &m);
    assert_eq!(&r[6..], &[0x01, 0x00, 0x02, 0x00]);

    // An emergency waits while SM1 is full, goes out when it is free.
    srv.queue_emergency(Emergency::new(0x3210, 0x05, [0; 5]))
        .unwrap();
    assert_eq!(
        bus.fpwr(ST, 0x1000, &msg(4, &sdo(0x40, 0x6060, 0, [0; 4])))
            .wkc,
        1
    );
    // The request is answered first, the emergency waits for SM1.
    assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    let r = read_sm1(&mut bus);
    assert_eq!(&r[6..9], &[0x00, 0x30, 0x4F]);
    assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    let r = read_sm1(&mut bus);
    assert_eq!(&r[6..], &[0x00, 0x10, 0x10, 0x32, 0x05, 0, 0, 0, 0, 0]);

    // SDO info list: the fragments follow one another as the master reads SM1.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(5, &info(0x01, &[0x01, 0x00])),
    );
    let mut got: Vec<u16> = r[14..]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let mut incomplete = r[8] & 0x80 != 0;
    while incomplete {
        assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
        let r = read_sm1(&mut bus);
        got.extend(r[12..].chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])));
        incomplete = r[8] & 0x80 != 0;
    }
    assert_eq!(
        got.len(),
        devices::CMMP_AS.objects.len()
            - CoeConfig::from_description(&devices::CMMP_AS).hidden.len()
    );

    // Back to Init: the mailbox stops and the server forgets its state.
    bus.request_state(ST, 0x0001);
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    bus.request_state(ST, 0x0002);
    // Counter 5 again after the restart is a new request, not a repetition.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(5, &sdo(0x40, 0x1018, 2, [0; 4])),
    );
    assert_eq!(&r[6..9], &[0x00, 0x30, 0x43]);
}

/// `coe::due` says when `serve` has work: a request waiting in SM0 (left there until the
/// server takes it), a further fragment or an emergency once SM1 is free, the mailbox stopped;
/// an idle mailbox, or a full SM1, has none, and `pump` then posts nothing.
#[test]
fn due_tells_when_the_mailbox_has_work() {
    let mut bus = esc_bus();
    let (mut srv, mut od) = cmmp_as();
    let due = |bus: &Bus, srv: &CoeServer| coe::due(&bus.slaves[0], srv);
    assert!(!due(&bus, &srv), "idle mailbox");
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));

    // A request: it waits in SM0 until the server takes it.
    assert_eq!(
        bus.fpwr(ST, 0x1000, &msg(1, &sdo(0x40, 0x1018, 1, [0; 4])))
            .wkc,
        1
    );
    assert!(bus.slaves[0].mailbox_waiting());
    assert!(due(&bus, &srv));
    assert!(bus.slaves[0].mailbox_waiting(), "still there");
    assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    assert!(!bus.slaves[0].mailbox_waiting());

    // SM1 full: an emergency waits, nothing is due.
    srv.queue_emergency(Emergency::new(0x3210, 0x05, [0; 5]))
        .unwrap();
    assert!(!due(&bus, &srv), "SM1 full");
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    read_sm1(&mut bus);
    assert!(due(&bus, &srv), "the emergency can go");
    assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    read_sm1(&mut bus);
    assert!(!due(&bus, &srv));

    // A fragmented SDO info reply: each further fragment is due once SM1 is read.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(2, &info(0x01, &[0x01, 0x00])),
    );
    assert_eq!(r[8], 0x82, "first of several fragments");
    assert!(due(&bus, &srv));
    assert!(coe::pump(&mut bus.slaves[0], &mut srv, &mut od));

    // The mailbox stopped: due, so that the server forgets its state.
    bus.request_state(ST, 0x0001);
    assert!(due(&bus, &srv));
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
    assert!(!srv.busy(), "reset");
}

#[test]
fn a_request_ends_a_fragmented_reply() {
    let mut bus = esc_bus();
    let (mut srv, mut od) = cmmp_as();
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(1, &info(0x01, &[0x01, 0x00])),
    );
    assert_eq!(r[8], 0x82, "first of several fragments");
    assert!(srv.busy());
    // The master gives up the list and reads an object instead.
    let r = exchange(
        &mut bus,
        &mut srv,
        &mut od,
        &msg(2, &sdo(0x40, 0x1018, 1, [0; 4])),
    );
    assert_eq!(&r[6..9], &[0x00, 0x30, 0x43]);
    assert!(!srv.busy());
    assert!(!coe::pump(&mut bus.slaves[0], &mut srv, &mut od));
}

#[test]
fn arbitrary_bytes_never_panic() {
    // A small LCG: deterministic garbage, mostly with a CoE header so the SDO and SDO info
    // paths see it, in several send mailbox sizes.
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = move || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (x >> 33) as u32
    };
    for cfg in [
        CoeConfig::FULL,
        CoeConfig::from_description(&devices::CMMP_AS),
    ] {
        for desc in [&devices::TESTBENCH, &devices::CMMP_AS] {
            let mut srv: CoeServer = CoeServer::new(desc, cfg);
            let mut od = dict(desc);
            for i in 0..20_000u32 {
                let len = (next() % 80) as usize;
                let mut m: Vec<u8> = (0..len).map(|_| next() as u8).collect();
                if len >= 8 && i % 4 != 0 {
                    let l = (next() % (len as u32 - 5)) as u16;
                    m[0..2].copy_from_slice(&l.to_le_bytes());
                    m[5] = 0x03 | ((next() % 8) as u8) << 4;
                    m[7] = [0x20, 0x80, 0x20, 0x10][(next() % 4) as usize];
                    if m[7] == 0x20 && len > 11 {
                        // Mostly known objects.
                        let o = &desc.objects[(next() as usize) % desc.objects.len()];
                        m[9..11].copy_from_slice(&o.index.to_le_bytes());
                    }
                }
                let size = [0usize, 9, 16, 32, 64, 128][(next() % 6) as usize];
                let mut out = vec![0u8; size];
                if let Some(n) = srv.process(&m, &mut od, &mut out) {
                    assert!(n <= size);
                    let len = u16::from_le_bytes([out[0], out[1]]) as usize;
                    assert_eq!(len + 6, n);
                }
                let _ = srv.poll(&mut out);
            }
        }
    }
}

#[test]
fn pdo_configuration_is_locked_outside_pre_op() {
    use ethercat::coe::MappingLock;
    let (_, mut od) = cmmp_as();
    let mut lock = MappingLock::new(&mut od, true);
    // Assignment and mapping: the present device state forbids it (0800 0022h).
    assert_eq!(lock.write(0x1C12, 0, &[0]), Err(AbortCode::DEVICE_STATE));
    assert_eq!(lock.write(0x1600, 0, &[0]), Err(AbortCode::DEVICE_STATE));
    assert_eq!(
        lock.write(0x1A00, 1, &0x6041_0010u32.to_le_bytes()),
        Err(AbortCode::DEVICE_STATE)
    );
    // A missing or read-only entry keeps its own abort.
    assert_eq!(lock.write(0x1A7F, 0, &[0]), Err(AbortCode::NO_OBJECT));
    assert_eq!(lock.write(0x1C00, 1, &[1]), Err(AbortCode::READ_ONLY));
    // Reads and other objects pass.
    let mut b = [0u8; 1];
    assert_eq!(lock.read(0x1C12, 0, &mut b), Ok(1));
    assert_eq!(lock.write(0x607A, 0, &1000i32.to_le_bytes()), Ok(()));
    // Unlocked (Pre-Op): the same write is taken.
    let mut open = MappingLock::new(&mut od, false);
    assert_eq!(open.write(0x1600, 0, &[0]), Ok(()));
}
