//! A tiny master for the tests: builds frames with `FrameWriter`, passes them through a
//! chain of ESCs, and decodes the returned datagrams.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use ethercat::datagram::Command;
use ethercat::frame::{Address, EthernetFrame, Frame, FrameWriter, ETHERNET_HEADER_LEN};
use ethercat::{process_chain, Esc, EscConfig, FrameOutcome, MailboxLayout};
use od::Instant;

pub const MASTER_MAC: [u8; 6] = [0x10; 6];

/// A returned datagram.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    pub cmd: Command,
    pub idx: u8,
    pub adp: u16,
    pub ado: u16,
    pub data: Vec<u8>,
    pub wkc: u16,
    pub irq: u16,
}

impl Reply {
    pub fn u16(&self) -> u16 {
        u16::from_le_bytes([self.data[0], self.data[1]])
    }
    pub fn u32(&self) -> u32 {
        u32::from_le_bytes(self.data[0..4].try_into().unwrap())
    }
    pub fn u64(&self) -> u64 {
        u64::from_le_bytes(self.data[0..8].try_into().unwrap())
    }
}

/// One datagram to send.
#[derive(Debug, Clone)]
pub struct Req {
    pub cmd: Command,
    pub addr: Address,
    pub data: Vec<u8>,
}

pub fn req(cmd: Command, addr: Address, data: &[u8]) -> Req {
    Req {
        cmd,
        addr,
        data: data.to_vec(),
    }
}

pub fn phys(adp: u16, ado: u16) -> Address {
    Address::Physical { adp, ado }
}

/// Build an Ethernet frame holding `reqs`.
pub fn build(reqs: &[Req]) -> Vec<u8> {
    let mut buf = vec![0u8; 1514];
    let mut w = FrameWriter::ethernet(&mut buf, MASTER_MAC).unwrap();
    for (i, r) in reqs.iter().enumerate() {
        w.push(r.cmd, i as u8, r.addr, &r.data).unwrap();
    }
    let n = w.finish();
    buf.truncate(n);
    buf
}

/// Decode the datagrams of a returned Ethernet frame.
pub fn parse(frame: &[u8]) -> Vec<Reply> {
    let eth = EthernetFrame::new_checked(frame).unwrap();
    let f = Frame::new_checked(eth.payload()).unwrap();
    f.datagrams()
        .map(|d| {
            let d = d.unwrap();
            Reply {
                cmd: d.command(),
                idx: d.index(),
                adp: d.adp(),
                ado: d.ado(),
                data: d.data().to_vec(),
                wkc: d.wkc(),
                irq: d.irq(),
            }
        })
        .collect()
}

pub struct Bus {
    pub slaves: Vec<Esc<'static>>,
    pub now: Instant,
}

impl Bus {
    pub fn new(slaves: Vec<Esc<'static>>) -> Self {
        Bus {
            slaves,
            now: Instant::from_millis(1),
        }
    }

    /// `n` slaves with the test SII image.
    pub fn with_sii(n: usize) -> Self {
        let image: &'static [u8] = Box::leak(test_sii().into_boxed_slice());
        Bus::new((0..n).map(|_| Esc::with_sii(image)).collect())
    }

    /// `n` slaves without SII (no mailbox configured).
    pub fn plain(n: usize) -> Self {
        Bus::new(
            (0..n)
                .map(|_| Esc::new(EscConfig::default(), ethercat::Eeprom::None))
                .collect(),
        )
    }

    pub fn send_frame(&mut self, frame: &mut [u8]) -> FrameOutcome {
        process_chain(&mut self.slaves, self.now, frame)
    }

    pub fn send(&mut self, reqs: &[Req]) -> Vec<Reply> {
        let mut f = build(reqs);
        let before = f.len();
        let o = self.send_frame(&mut f);
        assert!(matches!(o, FrameOutcome::Processed { .. }), "{o:?}");
        assert_eq!(f.len(), before);
        assert_eq!(
            f[ETHERNET_HEADER_LEN - 8],
            MASTER_MAC[0] | 0x02,
            "source MAC bit"
        );
        parse(&f)
    }

    pub fn one(&mut self, cmd: Command, addr: Address, data: &[u8]) -> Reply {
        self.send(&[req(cmd, addr, data)]).remove(0)
    }

    pub fn fprd(&mut self, station: u16, ado: u16, len: usize) -> Reply {
        self.one(Command::Fprd, phys(station, ado), &vec![0; len])
    }
    pub fn fpwr(&mut self, station: u16, ado: u16, data: &[u8]) -> Reply {
        self.one(Command::Fpwr, phys(station, ado), data)
    }
    pub fn aprd(&mut self, pos: u16, ado: u16, len: usize) -> Reply {
        self.one(Command::Aprd, phys(pos, ado), &vec![0; len])
    }
    pub fn apwr(&mut self, pos: u16, ado: u16, data: &[u8]) -> Reply {
        self.one(Command::Apwr, phys(pos, ado), data)
    }
    pub fn brd(&mut self, ado: u16, len: usize) -> Reply {
        self.one(Command::Brd, phys(0, ado), &vec![0; len])
    }
    pub fn bwr(&mut self, ado: u16, data: &[u8]) -> Reply {
        self.one(Command::Bwr, phys(0, ado), data)
    }
    pub fn lrw(&mut self, addr: u32, data: &[u8]) -> Reply {
        self.one(Command::Lrw, Address::Logical(addr), data)
    }

    /// Give slave i the station address 0x1001 + i (APWR, as SOEM does).
    pub fn assign_addresses(&mut self) {
        for i in 0..self.slaves.len() {
            let pos = (i as u16).wrapping_neg();
            let r = self.apwr(pos, 0x0010, &(0x1001 + i as u16).to_le_bytes());
            assert_eq!(r.wkc, 1);
        }
    }

    /// Write the mailbox SMs of the test SII to `station` (one 16-byte FPWR as SOEM).
    pub fn write_mailbox_sms(&mut self, station: u16) {
        let mut d = Vec::new();
        d.extend_from_slice(&[0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00]);
        d.extend_from_slice(&[0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00]);
        assert_eq!(self.fpwr(station, 0x0800, &d).wkc, 1);
    }

    pub fn request_state(&mut self, station: u16, control: u16) -> Reply {
        self.fpwr(station, 0x0120, &control.to_le_bytes())
    }

    /// (AL status, AL status code) read as SOEM does (6 bytes at 0x0130).
    pub fn al(&mut self, station: u16) -> (u16, u16) {
        let r = self.fprd(station, 0x0130, 6);
        assert_eq!(r.wkc, 1);
        (r.u16(), u16::from_le_bytes([r.data[4], r.data[5]]))
    }

    /// Read SII word `addr` (4 or 8 bytes) as SOEM does.
    pub fn sii_read(&mut self, station: u16, addr: u32, len: usize) -> Vec<u8> {
        let st = self.fprd(station, 0x0502, 2);
        assert_eq!(st.u16() & 0x8000, 0, "not busy");
        let mut cmd = vec![0x00, 0x01];
        cmd.extend_from_slice(&addr.to_le_bytes());
        assert_eq!(self.fpwr(station, 0x0502, &cmd).wkc, 1);
        let st = self.fprd(station, 0x0502, 2);
        assert_eq!(
            st.u16() & 0xF800,
            0,
            "no busy/error bits: {:#06x}",
            st.u16()
        );
        self.fprd(station, 0x0508, len).data
    }
}

pub const SM2_START: u16 = 0x1100;
pub const SM3_START: u16 = 0x1180;

/// A small SII image: PDI 0x0005, vendor 0x1D, product 0x1234_5678, revision 2,
/// mailbox 0x1000/0x80 + 0x1080/0x80, CoE; categories General + SyncM + End.
pub fn test_sii() -> Vec<u8> {
    let mut w = vec![0u16; 0x40];
    w[0x00] = 0x0005;
    w[0x04] = 0x0000;
    w[0x08] = 0x001D;
    w[0x0A] = 0x5678;
    w[0x0B] = 0x1234;
    w[0x0C] = 0x0002;
    w[0x0E] = 0x0042;
    w[0x18] = 0x1000;
    w[0x19] = 0x0080;
    w[0x1A] = 0x1080;
    w[0x1B] = 0x0080;
    w[0x1C] = 0x0004;
    w[0x3E] = 0x000F;
    w[0x3F] = 0x0001;
    // General, 16 words.
    w.extend_from_slice(&[30, 16]);
    w.extend_from_slice(&[0u16; 16]);
    // SyncM, 4 × 4 words.
    w.extend_from_slice(&[41, 16]);
    for (start, len, ctl, ty) in [
        (0x1000u16, 0x80u16, 0x26u8, 1u8),
        (0x1080, 0x80, 0x22, 2),
        (SM2_START, 2, 0x64, 3),
        (SM3_START, 2, 0x20, 4),
    ] {
        w.push(start);
        w.push(len);
        w.push(u16::from(ctl));
        w.push(0x0001 | (u16::from(ty) << 8));
    }
    w.push(0xFFFF);
    let mut b: Vec<u8> = w.iter().flat_map(|v| v.to_le_bytes()).collect();
    let crc = crc8(&b[0..14]);
    b[14] = crc;
    b[15] = 0;
    b
}

pub fn fmmu_bytes(logical: u32, len: u16, phys: u16, read: bool, write: bool) -> [u8; 16] {
    ethercat::Fmmu::bytes(logical, len, phys, read, write).to_bytes()
}

pub fn mailbox_layout() -> MailboxLayout {
    MailboxLayout {
        rx_offset: 0x1000,
        rx_size: 0x80,
        tx_offset: 0x1080,
        tx_size: 0x80,
    }
}

/// CRC-8 of the SII configuration area (poly 0x07, init 0xFF; spec §3.2).
pub fn crc8(data: &[u8]) -> u8 {
    let mut crc = 0xFFu8;
    for &b in data {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}
