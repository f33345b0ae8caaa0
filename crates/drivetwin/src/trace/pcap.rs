//! Trace writers: pcap with link type 227 (LINKTYPE_CAN_SOCKETCAN) and candump `.log` for CAN,
//! pcap with link type 1 (LINKTYPE_ETHERNET) for EtherCAT frames.
//!
//! Wireshark / tshark read them: CANopen with `tshark -r FILE -d can.subdissector,canopen` (the
//! notes on open-source systems kept beside the project, §7), EtherCAT (EtherType 88A4h) and its
//! CoE mailbox without options.
//!
//! pcap record body, the SocketCAN `struct can_frame` with the identifier in network byte
//! order (as Wireshark expects for link type 227):
//!
//! ```text
//! u32 BE  can_id | EFF 0x80000000 | RTR 0x40000000
//! u8      payload length (DLC for a remote frame)
//! u8      FD flags (0)   u8 reserved (0)   u8 len8_dlc (0)
//! u8[8]   data, zero padded
//! ```

use std::io::{self, Write};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;

use crate::can::bus::Tap;

/// LINKTYPE_CAN_SOCKETCAN.
pub const LINKTYPE_CAN_SOCKETCAN: u32 = 227;
/// LINKTYPE_ETHERNET.
pub const LINKTYPE_ETHERNET: u32 = 1;
/// Extended frame format flag in `can_id`.
pub const CAN_EFF_FLAG: u32 = 0x8000_0000;
/// Remote transmission request flag in `can_id`.
pub const CAN_RTR_FLAG: u32 = 0x4000_0000;
/// Error frame flag in `can_id` (never set by us; listed for readers).
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;

const PCAP_MAGIC_MICROS: u32 = 0xA1B2_C3D4;
const SNAPLEN: u32 = 65535;
const CAN_FRAME_LEN: u32 = 16;

/// The 16-byte SocketCAN `can_frame` of `frame`, identifier big-endian.
pub fn socketcan_record(frame: &CanFrame) -> [u8; 16] {
    let mut id = if frame.extended {
        (frame.id & CanFrame::MAX_EXTENDED_ID) | CAN_EFF_FLAG
    } else {
        frame.id & CanFrame::MAX_STANDARD_ID
    };
    if frame.rtr {
        id |= CAN_RTR_FLAG;
    }
    let mut out = [0u8; 16];
    let [i0, i1, i2, i3] = id.to_be_bytes();
    // can_id, can_dlc, 3 bytes of padding, then the data (payload() holds at most 8 bytes).
    let head = [i0, i1, i2, i3, frame.len.min(8), 0, 0, 0];
    for (dst, src) in out.iter_mut().zip(head.iter().chain(frame.payload())) {
        *dst = *src;
    }
    out
}

/// Writes a pcap file (microsecond timestamps, little-endian headers) of CAN frames, or of
/// Ethernet frames ([`PcapWriter::ethernet`]).
#[derive(Debug)]
pub struct PcapWriter<W: Write> {
    out: W,
}

impl<W: Write> PcapWriter<W> {
    /// Writes the global header of a CAN trace.
    pub fn new(out: W) -> io::Result<Self> {
        Self::with_link_type(out, LINKTYPE_CAN_SOCKETCAN)
    }

    /// Writes the global header of an Ethernet trace.
    pub fn ethernet(out: W) -> io::Result<Self> {
        Self::with_link_type(out, LINKTYPE_ETHERNET)
    }

    fn with_link_type(mut out: W, link_type: u32) -> io::Result<Self> {
        let mut header = [0u8; 24];
        let fields: [&[u8]; 7] = [
            &PCAP_MAGIC_MICROS.to_le_bytes(),
            &2u16.to_le_bytes(), // version major
            &4u16.to_le_bytes(), // version minor
            &0i32.to_le_bytes(), // thiszone
            &0u32.to_le_bytes(), // sigfigs
            &SNAPLEN.to_le_bytes(),
            &link_type.to_le_bytes(),
        ];
        for (dst, src) in header.iter_mut().zip(fields.into_iter().flatten()) {
            *dst = *src;
        }
        out.write_all(&header)?;
        Ok(PcapWriter { out })
    }

    /// Appends one frame seen at wall time `ts`.
    pub fn write_frame(&mut self, ts: SystemTime, frame: &CanFrame) -> io::Result<()> {
        self.write_frame_at(
            ts.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO),
            frame,
        )
    }

    /// Appends one frame seen `since_epoch` after the Unix epoch (or after any origin the
    /// reader should see as 1970-01-01, e.g. a virtual clock).
    pub fn write_frame_at(&mut self, since_epoch: Duration, frame: &CanFrame) -> io::Result<()> {
        let secs = u32::try_from(since_epoch.as_secs()).unwrap_or(u32::MAX);
        let mut record = [0u8; 32];
        // ts_sec, ts_usec, incl_len, orig_len, then the frame.
        let fields = [
            secs.to_le_bytes(),
            since_epoch.subsec_micros().to_le_bytes(),
            CAN_FRAME_LEN.to_le_bytes(),
            CAN_FRAME_LEN.to_le_bytes(),
        ];
        let body = socketcan_record(frame);
        for (dst, src) in record
            .iter_mut()
            .zip(fields.iter().flatten().chain(body.iter()))
        {
            *dst = *src;
        }
        self.out.write_all(&record)
    }

    /// Appends one packet (an Ethernet frame in an Ethernet trace) seen `since_epoch` after
    /// the Unix epoch; longer than the snap length, it is cut there.
    pub fn write_packet_at(&mut self, since_epoch: Duration, packet: &[u8]) -> io::Result<()> {
        let secs = u32::try_from(since_epoch.as_secs()).unwrap_or(u32::MAX);
        let len = u32::try_from(packet.len()).unwrap_or(u32::MAX);
        let caplen = len.min(SNAPLEN);
        let mut header = [0u8; 16];
        header[0..4].copy_from_slice(&secs.to_le_bytes());
        header[4..8].copy_from_slice(&since_epoch.subsec_micros().to_le_bytes());
        header[8..12].copy_from_slice(&caplen.to_le_bytes());
        header[12..16].copy_from_slice(&len.to_le_bytes());
        self.out.write_all(&header)?;
        self.out
            .write_all(packet.get(..caplen as usize).unwrap_or(packet))
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn get_ref(&self) -> &W {
        &self.out
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

/// One candump `-l` log line (without newline), e.g. `(1700000000.000100) vcan0 605#4018100100000000`.
/// Remote frames are written `ID#R` with the DLC digit appended when it is not zero.
pub fn candump_line(since_epoch: Duration, interface: &str, frame: &CanFrame) -> String {
    format!(
        "({:010}.{:06}) {} {}",
        since_epoch.as_secs(),
        since_epoch.subsec_micros(),
        interface,
        candump_frame(frame)
    )
}

/// A frame as candump writes it: `ID#DATA` or `ID#R` (with the length when it is not 0).
pub fn candump_frame(frame: &CanFrame) -> String {
    use std::fmt::Write as _;
    let mut text = String::with_capacity(26);
    if frame.extended {
        let _ = write!(text, "{:08X}#", frame.id & CanFrame::MAX_EXTENDED_ID);
    } else {
        let _ = write!(text, "{:03X}#", frame.id & CanFrame::MAX_STANDARD_ID);
    }
    if frame.rtr {
        text.push('R');
        if frame.len > 0 {
            let _ = write!(text, "{}", frame.len.min(8));
        }
    } else {
        for b in frame.payload() {
            let _ = write!(text, "{b:02X}");
        }
    }
    text
}

/// Writes candump `.log` files (one [`candump_line`] per frame), as `candump -l` and python-can's
/// `can.logger` do.
#[derive(Debug)]
pub struct CandumpWriter<W: Write> {
    out: W,
    interface: String,
}

impl<W: Write> CandumpWriter<W> {
    /// `interface` is the name written on each line, e.g. `vcan0`.
    pub fn new(out: W, interface: impl Into<String>) -> Self {
        CandumpWriter {
            out,
            interface: interface.into(),
        }
    }

    pub fn write_frame(&mut self, ts: SystemTime, frame: &CanFrame) -> io::Result<()> {
        self.write_frame_at(
            ts.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO),
            frame,
        )
    }

    pub fn write_frame_at(&mut self, since_epoch: Duration, frame: &CanFrame) -> io::Result<()> {
        let line = candump_line(since_epoch, &self.interface, frame);
        self.out.write_all(line.as_bytes())?;
        self.out.write_all(b"\n")
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

/// Record every frame of `tap` into `writer` until the bus is gone, flushing whenever the tap
/// runs dry. Use a `BufWriter<File>`; for heavy traffic run it on its own task.
pub async fn record_pcap<W: Write>(mut tap: Tap, mut writer: PcapWriter<W>) -> io::Result<W> {
    while let Some(first) = tap.recv().await {
        writer.write_frame(first.timestamp, &first.frame)?;
        while let Some(more) = tap.try_recv() {
            writer.write_frame(more.timestamp, &more.frame)?;
        }
        writer.flush()?;
    }
    writer.flush()?;
    Ok(writer.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::Command;

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("frame")
    }

    #[test]
    fn global_header_bytes() {
        let w = PcapWriter::new(Vec::new()).expect("header");
        assert_eq!(
            w.into_inner(),
            [
                0xD4, 0xC3, 0xB2, 0xA1, 2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xFF, 0xFF, 0, 0, 227,
                0, 0, 0
            ]
        );
    }

    #[test]
    fn record_bytes() {
        let mut w = PcapWriter::new(Vec::new()).expect("header");
        let ts = Duration::new(1_700_000_000, 123_456_789);
        w.write_frame_at(ts, &f(0x605, &[0x40, 0x18, 0x10, 0x01]))
            .expect("write");
        let bytes = w.into_inner();
        let record = bytes.get(24..).expect("record");
        let secs = 1_700_000_000u32.to_le_bytes();
        let usecs = 123_456u32.to_le_bytes();
        let mut expected = Vec::new();
        expected.extend_from_slice(&secs);
        expected.extend_from_slice(&usecs);
        expected.extend_from_slice(&[16, 0, 0, 0, 16, 0, 0, 0]);
        expected.extend_from_slice(&[0x00, 0x00, 0x06, 0x05, 4, 0, 0, 0]);
        expected.extend_from_slice(&[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        assert_eq!(record, expected.as_slice());
    }

    #[test]
    fn socketcan_record_flags() {
        let ext = CanFrame::with_id(0x1234_5678, true, &[0xAA]).expect("frame");
        assert_eq!(
            socketcan_record(&ext),
            [0x92, 0x34, 0x56, 0x78, 1, 0, 0, 0, 0xAA, 0, 0, 0, 0, 0, 0, 0]
        );
        let rtr = CanFrame::remote(0x705, 1);
        assert_eq!(
            socketcan_record(&rtr),
            [0x40, 0x00, 0x07, 0x05, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
        );
        // Bytes beyond `len` are never leaked into the trace.
        let mut short = f(0x1, &[1]);
        short.data[5] = 0xEE;
        assert_eq!(
            socketcan_record(&short),
            [0, 0, 0, 1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]
        );
    }

    #[test]
    fn candump_lines() {
        let ts = Duration::new(1_700_000_000, 100_000);
        assert_eq!(
            candump_line(ts, "vcan0", &f(0x605, &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0])),
            "(1700000000.000100) vcan0 605#4018100100000000"
        );
        assert_eq!(
            candump_line(ts, "vcan0", &f(0x5, &[])),
            "(1700000000.000100) vcan0 005#"
        );
        let ext = CanFrame::with_id(0x1ABCDEF, true, &[1]).expect("frame");
        assert_eq!(
            candump_line(ts, "can1", &ext),
            "(1700000000.000100) can1 01ABCDEF#01"
        );
        assert_eq!(
            candump_line(ts, "vcan0", &CanFrame::remote(0x701, 0)),
            "(1700000000.000100) vcan0 701#R"
        );
        assert_eq!(
            candump_line(ts, "vcan0", &CanFrame::remote(0x701, 1)),
            "(1700000000.000100) vcan0 701#R1"
        );
    }

    /// The CANopen frames of the notes on open-source systems kept beside the project (§7), in
    /// order, at 1 ms steps.
    fn canopen_sample() -> Vec<CanFrame> {
        vec![
            f(0x000, &[0x01, 0x05]),                         // NMT start node 5
            f(0x705, &[0x00]),                               // boot-up
            f(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]), // SDO upload 1000:00
            f(0x585, &[0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06]), // abort 06020000
            f(0x085, &[0x10, 0x81, 0x11, 0, 0, 0, 0, 0]),    // EMCY 8110
            CanFrame::with_id(0x1234_5678, true, &[0xAA]).expect("ext"),
        ]
    }

    fn tshark() -> Option<&'static str> {
        match Command::new("tshark").arg("--version").output() {
            Ok(out) if out.status.success() => Some("tshark"),
            _ => None,
        }
    }

    fn run_tshark(path: &std::path::Path, fields: &[&str]) -> String {
        let mut cmd = Command::new("tshark");
        cmd.arg("-r").arg(path).args([
            "-d",
            "can.subdissector,canopen",
            "-T",
            "fields",
            "-E",
            "separator=,",
        ]);
        for field in fields {
            cmd.args(["-e", field]);
        }
        let out = cmd.output().expect("run tshark");
        assert!(
            out.status.success(),
            "tshark failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn temp_path(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("drivetwin-{}-{name}", std::process::id()))
    }

    #[test]
    fn tshark_decodes_pcap_as_canopen() {
        if tshark().is_none() {
            println!("SKIPPED: tshark not installed (apt-get install tshark)");
            return;
        }
        let mut w = PcapWriter::new(Vec::new()).expect("header");
        for (i, frame) in canopen_sample().iter().enumerate() {
            w.write_frame_at(Duration::new(1_700_000_000, i as u32 * 1_000_000), frame)
                .expect("write");
        }
        let path = temp_path("trace.pcap");
        std::fs::write(&path, w.into_inner()).expect("write pcap");
        let out = run_tshark(
            &path,
            &[
                "frame.number",
                "can.id",
                "can.flags.xtd",
                "canopen.function_code",
                "canopen.sdo.main_idx",
                "canopen.sdo.abort_code",
                "canopen.em.err_code",
                "frame.time_epoch",
            ],
        );
        let _ = std::fs::remove_file(&path);
        println!("{out}");
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 6, "{out}");
        let line = |i: usize| lines.get(i).copied().unwrap_or_default();
        // can.id is printed in decimal; function codes: 0 NMT, 0xe NMT error control,
        // 0xc SDO rx, 0xb SDO tx, 0x1 EMCY.
        assert!(line(0).starts_with("1,0,0,0x00000000,"), "NMT: {out}");
        assert!(
            line(1).starts_with("2,1797,0,0x0000000e,"),
            "boot-up: {out}"
        );
        assert!(
            line(2).starts_with("3,1541,0,0x0000000c,0x1000,"),
            "SDO: {out}"
        );
        assert!(
            line(3).contains(",0x06020000,"),
            "abort code decoded: {out}"
        );
        assert!(line(4).contains(",0x8110,"), "EMCY code decoded: {out}");
        assert!(line(5).starts_with("6,305419896,1,"), "extended id: {out}");
        assert!(
            line(0).ends_with(",1700000000.000000000"),
            "timestamp: {out}"
        );
        assert!(
            line(1).ends_with(",1700000000.001000000"),
            "timestamp: {out}"
        );
    }

    #[test]
    fn tshark_reads_candump_log() {
        if tshark().is_none() {
            println!("SKIPPED: tshark not installed (apt-get install tshark)");
            return;
        }
        let mut w = CandumpWriter::new(Vec::new(), "vcan0");
        for (i, frame) in canopen_sample().iter().enumerate() {
            w.write_frame_at(Duration::new(1_700_000_000, i as u32 * 1_000_000), frame)
                .expect("write");
        }
        let path = temp_path("trace.log");
        std::fs::write(&path, w.into_inner()).expect("write log");
        let out = run_tshark(
            &path,
            &[
                "frame.number",
                "can.id",
                "canopen.sdo.main_idx",
                "canopen.em.err_code",
            ],
        );
        let _ = std::fs::remove_file(&path);
        println!("{out}");
        assert_eq!(out.lines().count(), 6, "{out}");
        assert!(out.contains("0x1000"), "{out}");
        assert!(out.contains("0x8110"), "{out}");
    }

    #[tokio::test]
    async fn record_pcap_from_tap() {
        let bus = crate::can::bus::Bus::new(64);
        let tap = bus.tap();
        let task = tokio::spawn(record_pcap(tap, PcapWriter::new(Vec::new()).expect("hdr")));
        let port = bus.port();
        port.send(f(0x181, &[1, 2, 3]));
        port.send(f(0x182, &[4]));
        drop(port);
        drop(bus);
        let bytes = task.await.expect("join").expect("io");
        assert_eq!(bytes.len(), 24 + 2 * 32);
        assert_eq!(bytes.get(24 + 16..24 + 20), Some(&[0, 0, 0x01, 0x81][..]));
    }
}
