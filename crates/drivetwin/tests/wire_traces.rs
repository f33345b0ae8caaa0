//! Recorded wire traces, one per personality and front end: a scripted master drives the cell
//! on the virtual clock, and every byte that crosses a wire in either direction, with its
//! virtual time, must equal the golden file in `tests/data/traces/<name>.trace`. The CANopen
//! and CoE scripts cover the start-up (NMT or AL state changes, SDO reads and writes, PDO
//! mapping and SYNC on CAN), the enable sequence 06h / 07h / 0Fh, a profile-position move, an
//! SDO abort, and a drive error with its reset (on EtherCAT an AL state error and its
//! acknowledge); the FHPP script enables, homes and moves in FHPP telegrams, with an error
//! and CCON.RESET; the serial script enables and moves over RS232 and Modbus RTU, with a bad
//! checksum and a register the map lacks as its errors.
//!
//! The traces pin the wire behaviour, so a change to the code that is meant to keep every
//! byte shows here with the first line that differs. A change that is meant to alter the
//! wire rewrites the files with
//!
//! ```text
//! DRIVETWIN_BLESS=1 cargo test -p drivetwin --test wire_traces
//! ```
//!
//! and the diff of the golden files shows what changed. Each trace is recorded twice per test
//! run: the two must be equal before they are compared with the file (the virtual clock is
//! deterministic).
//!
//! File format, one event a line: the virtual time in seconds with nanoseconds, `>` for bytes
//! into the cell (the master's) or `<` for bytes out of it (the cell's, and on CAN every
//! frame of the drives), the wire (`can`, `ecat`, `mbtcp`, `rs232`, `rs485`), then on CAN
//! the identifier and the data bytes, elsewhere the bytes, in hex. Lines starting with `#`
//! are comments.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "support/ecat_inputs.rs"]
mod ecat_inputs;
use ecat_inputs::{
    brd, bwr, coe, coe_download, fprd, fpwr, mailbox_counters, mailbox_sms, set_station,
};

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::CellFile;
use drivetwin::cell::station::Station;
use drivetwin::cell::stations::StationId;
use drivetwin::cell_loop::virtual_clock::{run_virtual_lines, Input, Output};
use drivetwin::ecat::chain::{own_drive, SlaveChain};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::serial::line::VirtualLine;
use drivetwin::serial::Kind;
use drivetwin::serial::LineRequest;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;

/// Whether to rewrite the golden files instead of comparing with them.
const BLESS: &str = "DRIVETWIN_BLESS";

fn ms(t: u64) -> Duration {
    Duration::from_millis(t)
}

/// A scripted master: inputs at times on the virtual clock.
#[derive(Default)]
struct Script {
    inputs: Vec<(Duration, Input)>,
}

impl Script {
    fn push(&mut self, t: u64, input: Input) {
        self.inputs.push((ms(t), input));
    }

    fn can(&mut self, t: u64, id: u16, data: &[u8]) {
        self.push(t, Input::Can(CanFrame::new(id, data).expect("CAN frame")));
    }

    /// Expedited SDO download (CiA 301 §7.2.4.3.3: 2Fh / 2Bh / 23h for 1 / 2 / 4 bytes).
    fn sdo_write(&mut self, t: u64, node: u8, index: u16, sub: u8, value: &[u8]) {
        let cs = match value.len() {
            1 => 0x2F,
            2 => 0x2B,
            _ => 0x23,
        };
        let [lo, hi] = index.to_le_bytes();
        let mut data = [cs, lo, hi, sub, 0, 0, 0, 0];
        let n = value.len().min(4);
        data[4..4 + n].copy_from_slice(&value[..n]);
        self.can(t, 0x600 + u16::from(node), &data);
    }

    fn sdo_write_u32(&mut self, t: u64, node: u8, index: u16, sub: u8, value: u32) {
        self.sdo_write(t, node, index, sub, &value.to_le_bytes());
    }

    /// SDO initiate upload (CiA 301 §7.2.4.3.6).
    fn sdo_read(&mut self, t: u64, node: u8, index: u16, sub: u8) {
        let [lo, hi] = index.to_le_bytes();
        self.can(t, 0x600 + u16::from(node), &[0x40, lo, hi, sub, 0, 0, 0, 0]);
    }

    fn sorted(mut self) -> Vec<(Duration, Input)> {
        self.inputs.sort_by_key(|(t, _)| *t);
        self.inputs
    }
}

/// How a CANopen script provokes an error of the device (its reset is common).
type Fault = fn(&mut Script, u64, u8) -> u64;

/// A device's own set-up before the common script: (index, sub, value) written by SDO.
type Setup = &'static [(u16, u8, &'static [u8])];

/// What differs between the CANopen devices' scripts.
struct Device {
    /// Written by SDO before the PDO mapping.
    setup: Setup,
    /// The position actual value the master reads and maps: 6064h, or the Kinco's 6063h
    /// (its dictionary has no 6064h).
    position: u16,
    fault: Fault,
}

/// The CANopen master's script for node `node`: identity reads in pre-operational, the
/// device's `setup`, RPDO1
/// (6040h) and TPDO1 (6041h, 6064h, on every SYNC) mapped, NMT start, SYNC every 10 ms, the
/// enable 06h / 07h / 0Fh, a PP move started by RPDO1, position reads, an SDO abort, the
/// device's error from `fault`, the fault reset 80h and the enable again.
fn canopen_script(node: u8, device: &Device) -> Vec<(Duration, Input)> {
    let position = u32::from(device.position);
    let n = u32::from(node);
    let rpdo = 0x200 + u16::from(node);
    let mut s = Script::default();
    let clock = std::cell::Cell::new(5u64);
    let next = |step: u64| {
        clock.set(clock.get() + step);
        clock.get()
    };
    s.sdo_read(next(0), node, 0x1000, 0);
    s.sdo_read(next(5), node, 0x1018, 1);
    s.sdo_read(next(5), node, 0x6041, 0);
    s.sdo_read(next(5), node, 0x6502, 0);
    for (index, sub, value) in device.setup {
        s.sdo_write(next(5), node, *index, *sub, value);
    }
    // PDO mapping in pre-operational (CiA 301 §7.5.2.35-38: invalid, count 0, entries,
    // count, valid).
    s.sdo_write_u32(next(5), node, 0x1400, 1, 0x8000_0200 + n);
    s.sdo_write(next(5), node, 0x1600, 0, &[0]);
    s.sdo_write_u32(next(5), node, 0x1600, 1, 0x6040_0010);
    s.sdo_write(next(5), node, 0x1600, 0, &[1]);
    s.sdo_write(next(5), node, 0x1400, 2, &[0xFF]);
    s.sdo_write_u32(next(5), node, 0x1400, 1, 0x200 + n);
    s.sdo_write_u32(next(5), node, 0x1800, 1, 0x8000_0180 + n);
    s.sdo_write(next(5), node, 0x1A00, 0, &[0]);
    s.sdo_write_u32(next(5), node, 0x1A00, 1, 0x6041_0010);
    s.sdo_write_u32(next(5), node, 0x1A00, 2, position << 16 | 0x20);
    s.sdo_write(next(5), node, 0x1A00, 0, &[2]);
    s.sdo_write(next(5), node, 0x1800, 2, &[1]);
    s.sdo_write_u32(next(5), node, 0x1800, 1, 0x180 + n);
    // NMT start, then SYNC every 10 ms to the end.
    let start = next(5);
    s.can(start, 0x000, &[0x01, node]);
    for i in 0..120 {
        s.can(start + 3 + 10 * i, 0x080, &[]);
    }
    // Profile position: mode, profile, enable, a target started by RPDO1.
    s.sdo_write(next(7), node, 0x6060, 0, &[1]);
    s.sdo_write_u32(next(5), node, 0x6081, 0, 20_000);
    s.sdo_write_u32(next(5), node, 0x6083, 0, 200_000);
    s.sdo_write_u32(next(5), node, 0x6084, 0, 200_000);
    for cw in [0x06u8, 0x07, 0x0F] {
        s.sdo_write(next(5), node, 0x6040, 0, &[cw, 0]);
    }
    s.sdo_read(next(5), node, 0x6041, 0);
    s.sdo_write_u32(next(5), node, 0x607A, 0, 4_000);
    s.can(next(5), rpdo, &[0x1F, 0]);
    s.can(next(5), rpdo, &[0x0F, 0]);
    for _ in 0..8 {
        s.sdo_read(next(25), node, device.position, 0);
    }
    // An SDO abort: an object no device here has (06020000h).
    s.sdo_read(next(5), node, 0x5FFF, 0);
    clock.set((device.fault)(&mut s, next(5), node));
    s.sdo_read(next(5), node, 0x6041, 0);
    s.sdo_read(next(5), node, 0x603F, 0);
    s.sdo_read(next(5), node, 0x1001, 0);
    // Fault reset (CiA 402 controlword bit 7) and the enable again.
    s.can(next(5), rpdo, &[0x80, 0]);
    s.can(next(5), rpdo, &[0x00, 0]);
    for cw in [0x06u8, 0x07, 0x0F] {
        s.can(next(5), rpdo, &[cw, 0]);
    }
    s.sdo_read(next(5), node, 0x6041, 0);
    s.sdo_read(next(5), node, 0x1001, 0);
    assert!(
        clock.get() < start + 1200,
        "the script ends while SYNC runs"
    );
    s.sorted()
}

/// CMMP-AS: the following-error hard limit 6510h:22 (§5.7) of 1 increment, then a long move
/// at once: the output stage switches off with error 17-0. The limit back to 0 afterwards.
fn cmmp_fault(s: &mut Script, t: u64, node: u8) -> u64 {
    s.sdo_write_u32(t, node, 0x6510, 0x22, 1);
    s.sdo_write_u32(t + 5, node, 0x607A, 0, 400_000);
    s.sdo_write(t + 10, node, 0x6040, 0, &[0x1F, 0]);
    s.sdo_write(t + 15, node, 0x6040, 0, &[0x0F, 0]);
    s.sdo_write_u32(t + 60, node, 0x6510, 0x22, 0);
    t + 60
}

/// Nanotec: a PP target beyond the software limits 607Dh is refused with EMCY 0800h (§4.1).
fn nanotec_fault(s: &mut Script, t: u64, node: u8) -> u64 {
    s.sdo_write_u32(t, node, 0x607D, 1, (-10_000i32) as u32);
    s.sdo_write_u32(t + 5, node, 0x607D, 2, 10_000);
    s.sdo_write_u32(t + 10, node, 0x607A, 0, 50_000);
    s.sdo_write(t + 15, node, 0x6040, 0, &[0x1F, 0]);
    s.sdo_write(t + 20, node, 0x6040, 0, &[0x0F, 0]);
    t + 25
}

/// Kinco: the following error beyond 6065h with its check on (2FF0h:0Eh) sends EMCY 8611h
/// (KINCO-DIAG-03): a move with no ramp jumps ahead of the motor.
fn kinco_fault(s: &mut Script, t: u64, node: u8) -> u64 {
    s.sdo_write(t, node, 0x2FF0, 0x0E, &[1, 0]);
    s.sdo_write_u32(t + 5, node, 0x6065, 0, 100);
    s.sdo_write_u32(t + 10, node, 0x6083, 0, 0);
    // 3000 rpm in DEC (rpm × 512 × 10 000 / 1875, Kinco FD/CD manual §6 item 12).
    s.sdo_write_u32(t + 12, node, 0x6081, 0, 8_192_000);
    s.sdo_write_u32(t + 15, node, 0x607A, 0, 2_000_000);
    s.sdo_write(t + 20, node, 0x6040, 0, &[0x3F, 0]);
    s.sdo_write(t + 25, node, 0x6040, 0, &[0x2F, 0]);
    s.sdo_write_u32(t + 85, node, 0x6083, 0, 200_000);
    t + 85
}

const CMMP_AS: Device = Device {
    setup: &[],
    position: 0x6064,
    fault: cmmp_fault,
};

const NANOTEC: Device = Device {
    setup: &[],
    position: 0x6064,
    fault: nanotec_fault,
};

/// Kinco: a bus master's set-up, no DIN owns the controlword or the mode (Din1_Function
/// 2010h:03 and Din3_Function 2010h:05 = 0, Tab. 6-1).
const KINCO: Device = Device {
    setup: &[(0x2010, 0x03, &[0, 0]), (0x2010, 0x05, &[0, 0])],
    position: 0x6063,
    fault: kinco_fault,
};

/// The generic CiA 402 drive (an EDS, no vendor module): a move with a near step of
/// acceleration runs ahead of the motor beyond the following error window 6065h, and the
/// statusword shows bit 13 (following error in profile position) until the motor catches up;
/// CiA 402 leaves any further reaction to the manufacturer.
fn cia402_fault(s: &mut Script, t: u64, node: u8) -> u64 {
    s.sdo_write_u32(t, node, 0x6065, 0, 100);
    s.sdo_write_u32(t + 2, node, 0x6081, 0, 5_000_000);
    s.sdo_write_u32(t + 5, node, 0x6083, 0, 1_000_000_000);
    s.sdo_write_u32(t + 10, node, 0x607A, 0, 2_000_000);
    s.sdo_write(t + 15, node, 0x6040, 0, &[0x3F, 0]);
    s.sdo_write(t + 20, node, 0x6040, 0, &[0x2F, 0]);
    s.sdo_write_u32(t + 80, node, 0x6083, 0, 200_000);
    s.sdo_write_u32(t + 82, node, 0x6081, 0, 20_000);
    t + 85
}

const CIA402: Device = Device {
    setup: &[],
    position: 0x6064,
    fault: cia402_fault,
};

/// The EDS the generic drive's trace runs: written after the EPOS4's public object list
/// (tests/interop/data/eds/epos4_like.eds).
fn epos4_like_eds() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/interop/data/eds/epos4_like.eds")
}

/// A CAN cell of one generic drive as `drivetwin run --eds FILE --node N` builds it.
fn eds_cell(eds: &Path, node: u8) -> CanCell {
    cell_of(CellFile::single_eds(eds, Some(node)).expect("the EDS"))
}

/// A CAN cell of one drive as `drivetwin run --device NAME --node N` builds it.
fn can_cell(device: &str, node: u8) -> CanCell {
    cell_of(CellFile::single(device, node))
}

/// A CAN cell of the one drive of `file`.
fn cell_of(file: CellFile) -> CanCell {
    let spec = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("a cell of one drive")
        .remove(0);
    let drive = Station::with_settings(
        spec.desc,
        spec.node,
        None,
        spec.commissioning,
        spec.settings,
    )
    .expect("the drive");
    CanCell::one_bus(vec![drive])
}

fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{b:02X}");
    }
    s
}

fn stamp(t: Duration) -> String {
    format!("{}.{:09}", t.as_secs(), t.subsec_nanos())
}

/// What crosses the wires, in the order it crosses.
struct Recorder {
    lines: Vec<String>,
    /// The CAN inputs, in order: the runtime hands each back as a bus frame when it is fed.
    can_inputs: Vec<(Duration, CanFrame)>,
    next_can: usize,
}

impl Recorder {
    fn new(inputs: &[(Duration, Input)]) -> Self {
        let can_inputs = inputs
            .iter()
            .filter_map(|(t, i)| match i {
                Input::Can(f) => Some((*t, *f)),
                _ => None,
            })
            .collect();
        Recorder {
            lines: Vec::new(),
            can_inputs,
            next_can: 0,
        }
    }

    fn input(&mut self, t: Duration, input: &Input) {
        let line = match input {
            Input::Can(_) => return,
            Input::Modbus { bytes, .. } => format!("> mbtcp {}", hex(bytes)),
            Input::Ethercat { frame, .. } => format!("> ecat {}", hex(frame)),
            Input::Serial { line, bytes } => format!("> {} {}", serial_wire(*line), hex(bytes)),
        };
        self.lines.push(format!("{} {line}", stamp(t)));
    }

    fn output(&mut self, t: Duration, o: Output<'_>) {
        let line = match o {
            Output::Can(f) => {
                let dir = match self.can_inputs.get(self.next_can) {
                    Some((at, input)) if *at == t && input == f => {
                        self.next_can += 1;
                        '>'
                    }
                    _ => '<',
                };
                format!("{dir} can {:03X} {}", f.id, hex(f.payload()))
            }
            Output::Modbus { bytes, .. } => format!("< mbtcp {}", hex(bytes)),
            Output::Ethercat { frame, .. } => format!("< ecat {}", hex(frame)),
            Output::Serial { line, bytes } => format!("< {} {}", serial_wire(line), hex(bytes)),
        };
        self.lines.push(format!("{} {line}", stamp(t)));
    }
}

fn serial_wire(line: usize) -> &'static str {
    if line == 0 {
        "rs232"
    } else {
        "rs485"
    }
}

/// What one personality's trace runs: the cell's parts and the master's script.
struct Rig {
    cell: CanCell,
    modbus: Vec<ModbusDrive>,
    chains: Vec<SlaveChain>,
    lines: Vec<VirtualLine>,
    inputs: Vec<(Duration, Input)>,
    until: Duration,
}

/// Runs `rig` and returns its trace. Inputs other than CAN frames are written as they are
/// fed, before what the cell sends at the same instant.
fn record(mut rig: Rig) -> Vec<String> {
    let mut rec = Recorder::new(&rig.inputs);
    let mut fed = 0;
    let inputs = rig.inputs.clone();
    run_virtual_lines(
        &mut rig.cell,
        &mut rig.modbus,
        &mut rig.chains,
        &mut rig.lines,
        &rig.inputs,
        rig.until,
        &mut |t, o| {
            while let Some((at, input)) = inputs.get(fed) {
                if *at > t {
                    break;
                }
                rec.input(*at, input);
                fed += 1;
            }
            rec.output(t, o);
        },
    );
    for (at, input) in inputs.iter().skip(fed) {
        if *at <= rig.until {
            rec.input(*at, input);
        }
    }
    assert_eq!(
        rec.next_can,
        rec.can_inputs.len(),
        "every CAN input was seen on the bus"
    );
    rec.lines
}

fn golden(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/traces")
        .join(format!("{name}.trace"))
}

/// Records `rig()` twice, checks the runs are equal, and compares with (or with
/// `DRIVETWIN_BLESS=1` writes) the golden file `name`.
fn check(name: &str, title: &str, rig: fn() -> Rig) {
    let first = record(rig());
    let second = record(rig());
    assert_eq!(
        first.len(),
        second.len(),
        "{name}: two runs, the same length"
    );
    if let Some((i, (a, b))) = first
        .iter()
        .zip(&second)
        .enumerate()
        .find(|(_, (a, b))| a != b)
    {
        panic!("{name}: two runs differ at event {}:\n  {a}\n  {b}", i + 1);
    }
    let path = golden(name);
    let header = format!(
        "# {title}\n# Recorded by crates/drivetwin/tests/wire_traces.rs; rewrite with {BLESS}=1.\n\
         # time_s dir wire bytes (dir: > into the cell, < out of it)\n"
    );
    let text = first.iter().fold(header, |mut s, l| {
        s.push_str(l);
        s.push('\n');
        s
    });
    if std::env::var_os(BLESS).is_some_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().expect("traces dir")).expect("traces dir");
        std::fs::write(&path, text).expect("write the golden trace");
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; record it with {BLESS}=1 cargo test -p drivetwin --test wire_traces",
            path.display()
        )
    });
    // (line number in the file, event)
    let want: Vec<(usize, &str)> = want
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#'))
        .map(|(i, l)| (i + 1, l))
        .collect();
    for ((line, w), g) in want.iter().zip(&first) {
        assert!(
            *w == g.as_str(),
            "{name}: the first difference is at {}:{line}\n  golden: {w}\n  now:    {g}",
            path.display()
        );
    }
    assert_eq!(
        want.len(),
        first.len(),
        "{name}: {} events in {}, {} now (the first {} equal)",
        want.len(),
        path.display(),
        first.len(),
        want.len().min(first.len())
    );
}

fn canopen_rig(name: &str, node: u8, device: &Device) -> Rig {
    Rig {
        cell: can_cell(name, node),
        modbus: Vec::new(),
        chains: Vec::new(),
        lines: Vec::new(),
        inputs: canopen_script(node, device),
        until: ms(1500),
    }
}

#[test]
fn cmmp_as_on_canopen() {
    check("cmmp-as-canopen", "CMMP-AS, node 1, CANopen", || {
        canopen_rig("cmmp-as", 1, &CMMP_AS)
    });
}

#[test]
fn nanotec_pd4n_on_canopen() {
    check(
        "nanotec-pd4n-canopen",
        "Nanotec PD4-N, node 2, CANopen",
        || canopen_rig("nanotec-pd4n", 2, &NANOTEC),
    );
}

#[test]
fn nanotec_smci47s_on_canopen() {
    check(
        "nanotec-smci47s-canopen",
        "Nanotec SMCI47-S, node 34, CANopen",
        || canopen_rig("nanotec-smci47s", 34, &NANOTEC),
    );
}

#[test]
fn kinco_fd3_on_canopen() {
    check("kinco-fd3-canopen", "Kinco FD3, node 1, CANopen", || {
        canopen_rig("kinco-fd3", 1, &KINCO)
    });
}

#[test]
fn generic_cia402_drive_from_an_eds_on_canopen() {
    check(
        "cia402-eds-canopen",
        "CiA 402 drive from an EDS (epos4_like.eds), node 5, CANopen",
        || Rig {
            cell: eds_cell(&epos4_like_eds(), 5),
            modbus: Vec::new(),
            chains: Vec::new(),
            lines: Vec::new(),
            inputs: canopen_script(5, &CIA402),
            until: ms(1500),
        },
    );
}

// ---- Kinco FD3 on its serial lines ----

/// An RS232 telegram to node 1: `cmd`, index, sub, 4 data bytes, the negated sum
/// (Kinco FD/CD manual §2.1).
fn kinco_telegram(cmd: u8, index: u16, sub: u8, value: u32) -> Input {
    let [i0, i1] = index.to_le_bytes();
    let d = value.to_le_bytes();
    let mut t = vec![1, cmd, i0, i1, sub, d[0], d[1], d[2], d[3]];
    let sum = t.iter().fold(0u8, |a, b| a.wrapping_add(*b));
    t.push(sum.wrapping_neg());
    Input::Serial { line: 0, bytes: t }
}

/// A Modbus RTU request to station 2, CRC low byte first (Kinco FD/CD manual §2.3).
fn rtu(pdu: &[u8]) -> Input {
    let mut f = vec![2];
    f.extend_from_slice(pdu);
    f.extend_from_slice(&modbus::rtu::crc_bytes(&f));
    Input::Serial { line: 1, bytes: f }
}

/// Node 1 on RS232 enabled and moved in PP, node 2 on RS485 (Modbus RTU) enabled in mode 3,
/// their positions polled; a telegram with a bad checksum and an RTU read of a register the
/// map lacks are the errors.
fn kinco_serial() -> Rig {
    let desc = devices::by_name("kinco-fd3").expect("kinco-fd3");
    let drives = (1..=2)
        .map(|n| {
            Station::with_settings(desc, n, None, vec![], Some(Default::default())).expect("drive")
        })
        .collect();
    let cell = CanCell::one_bus(drives);
    let requests = [
        LineRequest {
            kind: Kind::Rs232,
            path: PathBuf::from("rs232"),
            drive: StationId::from_index(0),
        },
        LineRequest {
            kind: Kind::Rs485,
            path: PathBuf::from("rs485"),
            drive: StationId::from_index(1),
        },
    ];
    let lines =
        (drivetwin::vendors::VENDORS.serial_lines.virtual_lines)(&requests, &cell).expect("lines");
    let mut s = Script::default();
    s.can(2, 0x000, &[0x01, 0x00]);
    for (i, (cmd, index, sub, value)) in [
        (0x40, 0x1000, 0x00, 0),
        (0x2B, 0x2010, 0x03, 0),
        (0x2B, 0x2010, 0x05, 0),
        (0x2F, 0x6060, 0x00, 1),
        (0x23, 0x6081, 0x00, 819_200),
        (0x23, 0x6083, 0x00, 16_384),
        (0x23, 0x6084, 0x00, 16_384),
        (0x2B, 0x6040, 0x00, 0x06),
        (0x2B, 0x6040, 0x00, 0x07),
        (0x2B, 0x6040, 0x00, 0x0F),
        (0x23, 0x607A, 0x00, 20_000),
        (0x2B, 0x6040, 0x00, 0x1F),
        (0x2B, 0x6040, 0x00, 0x0F),
    ]
    .into_iter()
    .enumerate()
    {
        s.push(10 + 10 * i as u64, kinco_telegram(cmd, index, sub, value));
    }
    // A telegram whose checksum is off by one.
    let Input::Serial { bytes: mut bad, .. } = kinco_telegram(0x40, 0x6041, 0, 0) else {
        unreachable!()
    };
    bad[9] = bad[9].wrapping_add(1);
    s.push(
        150,
        Input::Serial {
            line: 0,
            bytes: bad,
        },
    );
    // Node 2: Din3_Function over CAN (it has no register), then over RTU (the registers of
    // the device file, §2.3): Din1_Function 0830h, mode 3500h, target velocity 6F00h (FC 10h,
    // low word first), controlword 3100h.
    s.sdo_write(5, 2, 0x2010, 0x05, &[0, 0]);
    let writes: [&[u8]; 5] = [
        &[0x06, 0x08, 0x30, 0x00, 0x00],
        &[0x06, 0x35, 0x00, 0x00, 0x03],
        &[0x10, 0x6F, 0x00, 0x00, 0x02, 0x04, 0x80, 0x00, 0x00, 0x0C],
        &[0x06, 0x31, 0x00, 0x00, 0x06],
        &[0x06, 0x31, 0x00, 0x00, 0x0F],
    ];
    for (i, pdu) in writes.into_iter().enumerate() {
        s.push(15 + 10 * i as u64, rtu(pdu));
    }
    // A register the map lacks: exception.
    s.push(165, rtu(&[0x03, 0x7F, 0xFF, 0x00, 0x01]));
    for i in 0..20u64 {
        s.push(180 + 25 * i, kinco_telegram(0x40, 0x6063, 0, 0));
        s.push(182 + 25 * i, rtu(&[0x03, 0x32, 0x00, 0x00, 0x01]));
        s.push(192 + 25 * i, rtu(&[0x03, 0x37, 0x00, 0x00, 0x02]));
    }
    Rig {
        cell,
        modbus: Vec::new(),
        chains: Vec::new(),
        lines,
        inputs: s.sorted(),
        until: ms(750),
    }
}

#[test]
fn kinco_fd3_on_rs232_and_rs485() {
    check(
        "kinco-fd3-serial",
        "Kinco FD3, node 1 on RS232, node 2 on RS485 (Modbus RTU)",
        kinco_serial,
    );
}

// ---- CMMO-ST on Modbus TCP ----

/// One FHPP telegram, FC 17h: write the 8 output bytes, read the 8 input bytes (CMMO-ST
/// §5.3.2).
fn fhpp(tid: u16, out: [u8; 8]) -> Input {
    let [t0, t1] = tid.to_be_bytes();
    let mut bytes = vec![t0, t1, 0, 0, 0, 19, 1, 0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8];
    bytes.extend_from_slice(&out);
    Input::Modbus { drive: 0, bytes }
}

/// Enable, a direct-mode start before homing (an error) and the fault reset by CCON.RESET,
/// homing, a direct-mode positioning task, a Modbus exception; FHPP telegrams every 10 ms.
fn cmmo_st() -> Rig {
    let spec = CellFile::single("cmmo-st", 1)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("a CMMO-ST cell")
        .remove(0);
    let settings = spec.fhpp.expect("an FHPP drive").settings;
    let od =
        od::ObjectDictionary::new(spec.desc, 1, vec![0u8; spec.desc.storage_size]).expect("od");
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, settings);
    let modbus = vec![ModbusDrive::without_listener(
        Box::new(FhppModbus::new(dev, None)),
        ModbusConfig::default(),
    )];
    // CCON ENABLE | STOP | OPM1 (direct); CPOS as given; CDIR 0 (absolute position);
    // velocity 50 %; the position in SINC, high byte first on Modbus (Tab. 5.12, §5.3.1).
    let direct = |cpos: u8, position: i32| {
        let p = position.to_be_bytes();
        [0x43, cpos, 0x00, 50, p[0], p[1], p[2], p[3]]
    };
    let mut s = Script::default();
    let mut tid = 0u16;
    let mut push = |s: &mut Script, t: u64, out: [u8; 8]| {
        s.push(t, fhpp(tid, out));
        tid = tid.wrapping_add(1);
    };
    let mut t = 10;
    let mut step = |out: [u8; 8], n: u64, s: &mut Script| {
        for _ in 0..n {
            push(s, t, out);
            t += 10;
        }
    };
    step([0x00; 8], 3, &mut s);
    step([0x03, 0x01, 0, 0, 0, 0, 0, 0], 5, &mut s);
    // Direct mode, START before homing: refused with an error.
    step([0x43, 0x01, 0, 0, 0, 0, 0, 0], 3, &mut s);
    step(direct(0x03, 2_000), 3, &mut s);
    step(direct(0x01, 2_000), 3, &mut s);
    // CCON.RESET rising edge, then enabled again.
    step([0x4B, 0x01, 0, 0, 0, 0, 0, 0], 3, &mut s);
    step([0x43, 0x01, 0, 0, 0, 0, 0, 0], 3, &mut s);
    // Homing: CPOS.HOM rising edge, held until MC.
    step([0x43, 0x05, 0, 0, 0, 0, 0, 0], 30, &mut s);
    step([0x43, 0x01, 0, 0, 0, 0, 0, 0], 3, &mut s);
    // Positioning: START rising edge with the set-point, held, released.
    step(direct(0x01, 2_000), 2, &mut s);
    step(direct(0x03, 2_000), 30, &mut s);
    step(direct(0x01, 2_000), 5, &mut s);
    // FC 03h of a register the FHPP map lacks: exception.
    s.push(
        t,
        Input::Modbus {
            drive: 0,
            bytes: vec![0xFF, 0x00, 0, 0, 0, 6, 1, 0x03, 0x7F, 0xFF, 0x00, 0x01],
        },
    );
    let until = ms(t + 20);
    Rig {
        cell: CanCell::new(),
        modbus,
        chains: Vec::new(),
        lines: Vec::new(),
        inputs: s.sorted(),
        until,
    }
}

#[test]
fn cmmo_st_on_modbus_tcp() {
    check("cmmo-st-modbus-tcp", "CMMO-ST, Modbus TCP, FHPP", cmmo_st);
}

// ---- CMMP-AS on EtherCAT ----

/// The master's start-up to Pre-Op with the mailbox, AL status and identity reads, CoE
/// writes that enable the drive and start a PP move, 6064h / 6041h uploads, an upload of an
/// object the drive lacks (abort), a request for the unknown AL state 03h (refused with an
/// AL status code) and the error acknowledge; each mailbox answer read from SM1 1 ms later.
fn cmmp_ethercat() -> Rig {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let mut chain = SlaveChain::empty();
    let spec = CellFile::single("cmmp-as", 1)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("spec")
        .remove(0);
    chain
        .push(desc, own_drive(spec, None).expect("drive"))
        .expect("slave");
    let mut script = vec![
        brd(0x0000, 2),
        bwr(0x0120, &[0x11, 0]),
        set_station(),
        fprd(0x0130, 6),
        mailbox_sms(),
        fpwr(0x0120, &[0x02, 0x00]),
        fprd(0x0130, 6),
    ];
    let mut next = mailbox_counters();
    for (index, data) in [
        (0x6060u16, vec![1u8]),
        (0x6081, 20_000u32.to_le_bytes().to_vec()),
        (0x6040, vec![0x06, 0]),
        (0x6040, vec![0x07, 0]),
        (0x6040, vec![0x0F, 0]),
        (0x607A, 3_000i32.to_le_bytes().to_vec()),
        (0x6040, vec![0x1F, 0]),
        (0x6040, vec![0x0F, 0]),
    ] {
        script.push(coe_download(next(), index, 0, &data));
        script.push(fprd(0x1080, 0x80));
    }
    for _ in 0..10 {
        script.push(coe(next(), &[0x40, 0x64, 0x60, 0]));
        script.push(fprd(0x1080, 0x80));
    }
    script.push(coe(next(), &[0x40, 0x41, 0x60, 0]));
    script.push(fprd(0x1080, 0x80));
    script.push(coe(next(), &[0x40, 0xFF, 0x5F, 0]));
    script.push(fprd(0x1080, 0x80));
    // AL control 03h is no state: the slave keeps Pre-Op with the error flag and a code.
    script.push(fpwr(0x0120, &[0x03, 0x00]));
    script.push(fprd(0x0130, 6));
    script.push(fpwr(0x0120, &[0x12, 0x00]));
    script.push(fprd(0x0130, 6));
    let inputs: Vec<(Duration, Input)> = script
        .into_iter()
        .enumerate()
        .map(|(i, input)| (ms(5 + 10 * i as u64), input))
        .collect();
    let until = ms(5 + 10 * inputs.len() as u64 + 10);
    Rig {
        cell: CanCell::new(),
        modbus: Vec::new(),
        chains: vec![chain],
        lines: Vec::new(),
        inputs,
        until,
    }
}

#[test]
fn cmmp_as_on_ethercat() {
    check(
        "cmmp-as-ethercat",
        "CMMP-AS, EtherCAT slave at station 1001h, CoE",
        cmmp_ethercat,
    );
}
