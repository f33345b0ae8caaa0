//! The CMMO-ST parameter channel (EFPC, manual App. C) end to end on the device: 16-byte
//! output images in, FPCS and the answer out, one FHPP cycle per exchange.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
use drive::vendors::festo_cmmo_st::diagnostic_memory::EventType;
use drive::vendors::festo_cmmo_st::fhpp::parameter_channel::{
    ErrorCode, FileDirection, FileError, FileResponse, Packet, PacketKind, ParameterRequest,
    ParameterResponse, Request, Response,
};
use drive::vendors::festo_cmmo_st::fhpp::parameter_file::{self, FormatError, CRC_LEN, HEADER_LEN};
use drive::vendors::festo_cmmo_st::fhpp::parameter_file_transfer::{
    DOWNLOAD_INTERVAL_MS, PACKET_TIMEOUT_MS,
};
use drive::vendors::festo_cmmo_st::fhpp::{Authority, Ccon, Cpos, OutputData};
use drive::vendors::festo_cmmo_st::seven_segment::SevenSegment;
use od::{Instant, ObjectAccess, ObjectDictionary};

const ENABLED: Ccon = Ccon(0x03); // ENABLE + STOP
const SCON_FAULT: u8 = 0x08;
const DIAG_E27: u8 = 0x27;

struct Bench {
    dev: FhppDevice<Vec<u8>>,
    t_ms: u64,
    fhpp: [u8; 8],
}

impl Bench {
    fn new() -> Self {
        let desc = &devices::CMMO_ST;
        let od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).unwrap();
        let mut b = Bench {
            dev: FhppDevice::new(od, FhppSettings::default()),
            t_ms: 0,
            fhpp: [0; 8],
        };
        b.run(1);
        b
    }

    fn run(&mut self, ms: u64) {
        for _ in 0..ms {
            self.dev.step(Instant::from_millis(self.t_ms));
            self.t_ms += 1;
        }
    }

    /// One exchange: the FHPP bytes and `fpc` out, one cycle, the 8 FPC input bytes back.
    fn exchange(&mut self, fpc: [u8; 8]) -> [u8; 8] {
        let mut image = [0u8; 16];
        image[..8].copy_from_slice(&self.fhpp);
        image[8..].copy_from_slice(&fpc);
        self.dev.set_outputs(&image).unwrap();
        self.run(1);
        self.fpc_in()
    }

    fn fpc_in(&self) -> [u8; 8] {
        let i = self.dev.inputs_fpc();
        i[8..].try_into().unwrap()
    }

    fn scon(&self) -> u8 {
        self.dev.inputs()[0]
    }

    /// "No task" (parameter mode), then the job: the manual's C.3.2 sequence.
    fn job(&mut self, req: ParameterRequest) -> ParameterResponse {
        assert_eq!(self.exchange([0x10, 0, 0, 0, 0, 0, 0, 0])[0], 0x10);
        let r = self.exchange(req.encode());
        ParameterResponse::decode(&r).unwrap_or_else(|e| panic!("{req:?}: {e} {r:02X?}"))
    }

    fn read(&mut self, pnu: u16, subindex: u8) -> Result<u32, ErrorCode> {
        match self.job(ParameterRequest::Read { pnu, subindex }) {
            ParameterResponse::Value {
                pnu: p,
                subindex: s,
                value,
            } => {
                assert_eq!((p, s), (pnu, subindex));
                Ok(value)
            }
            ParameterResponse::Error { code, .. } => Err(code),
        }
    }

    fn write(&mut self, pnu: u16, subindex: u8, value: u32) -> Result<u32, ErrorCode> {
        match self.job(ParameterRequest::Write {
            pnu,
            subindex,
            value,
        }) {
            ParameterResponse::Value { value, .. } => Ok(value),
            ParameterResponse::Error { code, .. } => Err(code),
        }
    }

    /// New FHPP bytes; the FPC bytes stay as they are.
    fn fhpp_out(&mut self, fhpp: [u8; 8]) {
        self.fhpp = fhpp;
        self.dev.set_outputs(&fhpp).unwrap();
    }

    fn enable(&mut self) {
        self.fhpp_out(OutputData::record(ENABLED, Cpos::HALT, 0).to_bytes());
        self.run(5);
        assert!(
            self.dev.fhpp().output_stage_on(),
            "enabled: {:02X?} {:?}",
            self.dev.inputs(),
            self.dev.fhpp().state()
        );
    }

    fn disable(&mut self) {
        self.fhpp_out([0; 8]);
        self.run(5);
        assert!(!self.dev.fhpp().output_stage_on());
    }

    fn file_packet(&mut self, direction: FileDirection, packet: Packet) -> Response {
        let r = self.exchange(Request::File { direction, packet }.encode());
        Response::decode(&r).unwrap_or_else(|e| panic!("{packet:?}: {e} {r:02X?}"))
    }

    /// Sends a file packet and expects the handshake: FPCS 43h with the same packet ID.
    fn ack(&mut self, direction: FileDirection, packet: Packet) -> Packet {
        match self.file_packet(direction, packet) {
            Response::File(FileResponse::Active(p)) => {
                assert_eq!(p.id(), packet.id(), "handshake echoes the packet ID");
                p
            }
            r => panic!("{packet:?}: {r:?}"),
        }
    }

    fn no_task_file(&mut self) {
        assert_eq!(self.exchange([0x40, 0, 0, 0, 0, 0, 0, 0])[0], 0x40);
    }

    /// A whole upload, as a PLC runs it (C.4.5).
    fn upload(&mut self) -> Vec<u8> {
        let up = FileDirection::Upload;
        self.no_task_file();
        let size = self.ack(up, Packet::empty(PacketKind::Start, 0)).size() as usize;
        let mut file = Vec::new();
        let mut seq = 0;
        while file.len() < size {
            seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
            let p = self.ack(up, Packet::data(seq, [0; 6]));
            file.extend_from_slice(&p.data);
        }
        assert!(file[size..].iter().all(|b| *b == 0), "zero padding");
        file.truncate(size);
        self.ack(up, Packet::empty(PacketKind::Stop, 0));
        self.no_task_file();
        file
    }

    /// A whole download; the error packet of the drive if there is one.
    fn download(&mut self, file: &[u8]) -> Result<(), Packet> {
        let down = FileDirection::Download;
        self.no_task_file();
        let mut seq = 0;
        let mut packets = vec![Packet::start(file.len() as u32)];
        for chunk in file.chunks(6) {
            seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
            let mut d = [0u8; 6];
            d[..chunk.len()].copy_from_slice(chunk);
            packets.push(Packet::data(seq, d));
        }
        packets.push(Packet::empty(PacketKind::Stop, 7));
        for p in packets {
            match self.file_packet(down, p) {
                Response::File(FileResponse::Active(r)) if r.kind == PacketKind::Error => {
                    return Err(r)
                }
                Response::File(FileResponse::Active(r)) => assert_eq!(r.id(), p.id()),
                r => panic!("{p:?}: {r:?}"),
            }
        }
        self.no_task_file();
        Ok(())
    }

    fn od_u8(&self, pnu: u16, sub: u8) -> u8 {
        self.dev.read_u8(0x2000 + pnu, sub).unwrap()
    }
}

fn pwe(v: i32) -> u32 {
    v as u32
}

// ---- parameter mode ------------------------------------------------------------------------

#[test]
fn manual_fig_c1_write_pnu_440_2_with_4660() {
    // English manual Fig. C.1 (the Chinese seed lost the figure): FPCC 0001 1000, sub 2,
    // PNU 0000 0001 1011 1000, PWE 0x1234 → FPCS 0001 0101 with the same bytes.
    let mut b = Bench::new();
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x18, 0x02, 0x01, 0xB8, 0x00, 0x00, 0x12, 0x34]);
    assert_eq!(r, [0x15, 0x02, 0x01, 0xB8, 0x00, 0x00, 0x12, 0x34]);
    assert_eq!(b.dev.read_u32(0x2000 + 440, 2), Some(4660));
    assert_eq!(b.read(440, 2), Ok(4660));
}

/// FHPP-FPC-01, FHPP-FPC-04: `16 01 04 11 …` → `15 01 04 11 <actual position>`; PNU 999 → `17 01 03
/// E7 00 00 00 00`.
#[test]
fn spec_8_2_c_read_pnu_1041_and_the_error_layout() {
    // FHPP-FPC-01, fhpp §8.2 c: `16 01 04 11 00 00 00 00` → `15 01 04 11 <int32 BE>`.
    let mut b = Bench::new();
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x16, 0x01, 0x04, 0x11, 0, 0, 0, 0]);
    assert_eq!(r[..4], [0x15, 0x01, 0x04, 0x11]);
    let actual = i32::from_be_bytes(r[4..].try_into().unwrap());
    assert_eq!(actual, b.dev.motion_status().actual_position);
    // FHPP-FPC-04, the error layout of §8.2 c: FPCS 17h, code 0 in bytes 5–8 (PNU 999).
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x16, 0x01, 0x03, 0xE7, 0, 0, 0, 0]);
    assert_eq!(r, [0x17, 0x01, 0x03, 0xE7, 0, 0, 0, 0]);
}

#[test]
fn read_and_write_8_16_32_bit_and_array_pnus() {
    let mut b = Bench::new();
    // uint8 array, one character per subindex (PNU 121 user device name, rw1).
    assert_eq!(b.write(121, 1, u32::from(b'A')), Ok(0x41));
    assert_eq!(b.write(121, 2, u32::from(b'B')), Ok(0x42));
    assert_eq!(b.read(121, 1), Ok(0x41));
    assert_eq!(b.read(121, 2), Ok(0x42));
    assert_eq!(b.read(121, 3), Ok(0));
    assert_eq!(b.write(121, 3, 0x100), Err(ErrorCode::LimitExceeded), "u8");
    // uint16 array, read-only (PNU 101 firmware version 1.5.2.0).
    let version: Vec<u32> = (1..=4).map(|s| b.read(101, s).unwrap()).collect();
    assert_eq!(version, [1, 5, 2, 0]);
    // uint16 var (PNU 1023 target window time, rw2, stage off).
    assert_eq!(b.read(1023, 1), Ok(10));
    assert_eq!(b.write(1023, 1, 25), Ok(25));
    assert_eq!(b.dev.read_u16(0x2000 + 1023, 1), Some(25));
    assert_eq!(b.write(1023, 1, 0x1_0000), Err(ErrorCode::LimitExceeded));
    // uint32 record array (PNU 440 time comparator max).
    assert_eq!(b.write(440, 64, 0xDEAD_BEEF), Ok(0xDEAD_BEEF));
    assert_eq!(b.read(440, 64), Ok(0xDEAD_BEEF));
    assert_eq!(b.read(440, 65), Err(ErrorCode::WrongSubindex));
    // int8 (PNU 600 = −2), sign-extended to 32 bits both ways.
    assert_eq!(b.read(600, 1), Ok(pwe(-2)));
    assert_eq!(b.write(600, 1, pwe(-3)), Ok(pwe(-3)));
    assert_eq!(b.read(600, 1), Ok(0xFFFF_FFFD));
    assert_eq!(
        b.write(600, 1, 0xFD),
        Err(ErrorCode::LimitExceeded),
        "not sign-extended"
    );
    assert_eq!(b.write(600, 1, pwe(-2)), Ok(pwe(-2)));
    // int16 with the dictionary's limits 0…1000 (PNU 418:5 torque limit, record 5).
    assert_eq!(b.write(418, 5, 999), Ok(999));
    assert_eq!(b.read(418, 5), Ok(999));
    assert_eq!(b.write(418, 5, 1001), Err(ErrorCode::LimitExceeded));
    assert_eq!(b.write(418, 5, pwe(-1)), Err(ErrorCode::LimitExceeded));
    // int32 record array (PNU 404:3 target position of record 3).
    assert_eq!(b.write(404, 3, pwe(-100_000)), Ok(pwe(-100_000)));
    assert_eq!(b.read(404, 3), Ok(pwe(-100_000)));
}

#[test]
fn a_written_record_is_used_by_the_record_list_at_the_next_cycle() {
    let mut b = Bench::new();
    assert_eq!(b.write(404, 7, pwe(-4321)), Ok(pwe(-4321)));
    b.run(1);
    assert_eq!(b.dev.records().get(7).unwrap().target, -4321);
}

#[test]
fn every_tab_c7_error_code() {
    let mut b = Bench::new();
    // 00h illegal PNU: no such object, and a PNU past the index range.
    assert_eq!(b.read(99, 1), Err(ErrorCode::IllegalPnu));
    assert_eq!(b.read(0xFFFF, 1), Err(ErrorCode::IllegalPnu));
    assert_eq!(b.write(3000, 1, 0), Err(ErrorCode::IllegalPnu));
    // 01h cannot be changed: read-only.
    assert_eq!(b.write(100, 1, 0), Err(ErrorCode::CannotChange));
    // 02h limit: PNU 127:2 takes only 1; PNU 125 only 1.
    assert_eq!(b.write(127, 2, 2), Err(ErrorCode::LimitExceeded));
    assert_eq!(b.write(125, 1, 0), Err(ErrorCode::LimitExceeded));
    // 03h wrong subindex: past the last one, and 0 (not an FHPP subindex).
    assert_eq!(b.read(101, 9), Err(ErrorCode::WrongSubindex));
    assert_eq!(b.read(101, 0), Err(ErrorCode::WrongSubindex));
    // 66h write-only: PNU 204:3 "delete diagnostic memory".
    assert_eq!(b.read(204, 3), Err(ErrorCode::WriteOnly));
    // 11h: an rw2 PNU with the output stage on; fine again when it is off.
    b.enable();
    assert_eq!(b.write(1023, 1, 20), Err(ErrorCode::NotInThisState));
    assert_eq!(b.write(127, 2, 1), Err(ErrorCode::NotInThisState));
    assert_eq!(b.write(121, 1, 0x43), Ok(0x43), "rw1 while enabled");
    b.disable();
    assert_eq!(b.write(1023, 1, 20), Ok(20));
    // 0Bh: FCT holds control; reading still works, PNU 125 := 1 answers 11h (§3.1.1).
    b.dev
        .fhpp_mut()
        .request_local_control(Authority::Fct)
        .unwrap();
    b.run(1);
    assert_eq!(b.write(121, 1, 0x44), Err(ErrorCode::NoAuthority));
    assert_eq!(b.read(121, 1), Ok(0x43));
    assert_eq!(b.write(125, 1, 1), Err(ErrorCode::NotInThisState));
    b.dev.fhpp_mut().release_local_control();
    b.run(1);
    assert_eq!(b.write(121, 1, 0x44), Ok(0x44));
    // 65h ReqID not supported: in parameter mode (ID 4), file mode (ID 6), a reserved mode.
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x14, 0x01, 0x00, 0x65, 0, 0, 0, 0]);
    assert_eq!(r, [0x17, 0x01, 0x00, 0x65, 0, 0, 0, 0x65]);
    assert_eq!(
        ParameterResponse::decode(&r),
        Ok(ParameterResponse::Error {
            pnu: 101,
            subindex: 1,
            code: ErrorCode::RequestNotSupported
        })
    );
    b.exchange([0x40, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x46, 0x20, 0, 0, 0, 0, 0, 0]);
    assert_eq!(r, [0x47, 0x20, 0x65, 0, 0, 0, 0, 0]);
    b.exchange([0x00, 0, 0, 0, 0, 0, 0, 0]);
    let r = b.exchange([0x26, 0x01, 0x00, 0x65, 0, 0, 0, 0]);
    assert_eq!(r, [0x27, 0, 0, 0, 0, 0, 0, 0x65]);
    assert_eq!(
        Response::decode(&r),
        Ok(Response::Unsupported {
            mode: 2,
            code: ErrorCode::RequestNotSupported
        })
    );
}

/// FHPP-FPC-02.
#[test]
fn zero_request_a_new_job_is_only_taken_after_no_task() {
    let mut b = Bench::new();
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    let first = ParameterRequest::Write {
        pnu: 121,
        subindex: 1,
        value: 0x31,
    };
    let answer = b.exchange(first.encode());
    assert_eq!(answer, [0x15, 1, 0, 121, 0, 0, 0, 0x31]);
    // The same job repeated: the answer stays, the write is not made again.
    b.dev.write(0x2000 + 121, 1, &[0x39]).unwrap();
    assert_eq!(b.exchange(first.encode()), answer);
    b.run(5);
    assert_eq!(b.fpc_in(), answer);
    assert_eq!(b.od_u8(121, 1), 0x39, "not written twice");
    // A new job without "no task": ignored, the old answer stays (its PNU tells them apart).
    let second = ParameterRequest::Write {
        pnu: 121,
        subindex: 2,
        value: 0x32,
    };
    assert_eq!(b.exchange(second.encode()), answer);
    b.run(3);
    assert_eq!(b.fpc_in(), answer);
    assert_eq!(b.od_u8(121, 2), 0, "not carried out");
    // "No task" → response ID 0 in the same mode; then the job is taken.
    assert_eq!(
        b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]),
        [0x10, 0, 0, 0, 0, 0, 0, 0]
    );
    assert_eq!(b.exchange([0x00, 0, 0, 0, 0, 0, 0, 0]), [0; 8]);
    assert_eq!(b.exchange(second.encode())[0], 0x15);
    assert_eq!(b.od_u8(121, 2), 0x32);
    // An error answer also holds until "no task".
    let bad = ParameterRequest::Read {
        pnu: 99,
        subindex: 1,
    };
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(b.exchange(bad.encode())[0], 0x17);
    assert_eq!(b.exchange(first.encode())[0], 0x17);
}

/// FHPP-FPC-03, FHPP-FPC-12: PNU 127:2 := 1 saves (`18 02 00 7F …` → `15 02 00 7F …`), 127:4
/// reloads, reads of PNU 127 give the trigger values.
#[test]
fn writes_are_volatile_until_pnu_127_2_and_127_4_reloads_the_saved_values() {
    let mut b = Bench::new();
    assert!(b.dev.parameter_channel().memory().is_factory());
    assert_eq!(b.write(121, 1, 0x53), Ok(0x53)); // 'S'
                                                 // Not saved: the upload carries the permanent memory (C.4.3), still the factory 0.
    let desc = &devices::CMMO_ST;
    let mut factory = parameter_file::FileBuffer::new();
    parameter_file::factory(desc, &mut factory).unwrap();
    assert_eq!(b.upload(), factory.as_slice());
    // Save (FHPP-FPC-03, fhpp §8.2 d: `18 02 00 7F 00 00 00 01` → `15 02 00 7F …`).
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        b.exchange([0x18, 0x02, 0x00, 0x7F, 0, 0, 0, 1])[..4],
        [0x15, 2, 0, 0x7F]
    );
    assert!(!b.dev.parameter_channel().memory().is_factory());
    let saved = b.upload();
    assert_ne!(saved, factory.as_slice());
    // FHPP-FPC-12: reading PNU 127 gives the value that triggers each function (§3.1.2).
    let magic: Vec<_> = (1..=4).map(|s| b.read(127, s)).collect();
    assert_eq!(magic, [Ok(0x10), Ok(0x01), Ok(0x10), Ok(0x10)]);
    // Change, then 127:4 = 10h: the saved value comes back…
    assert_eq!(b.write(121, 1, 0x58), Ok(0x58));
    // …except error management (C.4.4): PNU 246:40 changed after the save stays.
    let em = b.read(246, 40).unwrap();
    assert_eq!(b.write(246, 40, em ^ 0x80), Ok(em ^ 0x80));
    assert_eq!(b.write(127, 4, 0x10), Ok(0x10));
    assert_eq!(b.od_u8(121, 1), 0x53);
    assert_eq!(b.read(246, 40), Ok(em ^ 0x80));
    // 127:3 (reset: EEPROM → active) loads error management as well.
    assert_eq!(b.write(127, 3, 0x10), Ok(0x10));
    assert_eq!(b.read(246, 40), Ok(em));
    // 127:1 deletes the EEPROM: the factory file again.
    assert_eq!(b.write(127, 1, 0x10), Ok(0x10));
    assert_eq!(b.upload(), factory.as_slice());
}

#[test]
fn a_parameter_job_while_a_file_transfer_runs_is_refused_with_11h() {
    let mut b = Bench::new();
    b.no_task_file();
    b.ack(FileDirection::Upload, Packet::empty(PacketKind::Start, 0));
    let r = b.exchange(
        ParameterRequest::Read {
            pnu: 101,
            subindex: 1,
        }
        .encode(),
    );
    assert_eq!(r, [0x17, 1, 0, 101, 0, 0, 0, 0x11]);
}

// ---- file mode ---------------------------------------------------------------------------

#[test]
fn the_file_format_round_trips_and_refuses_bad_files() {
    let desc = &devices::CMMO_ST;
    let mut f = parameter_file::FileBuffer::new();
    parameter_file::factory(desc, &mut f).unwrap();
    let h = parameter_file::check(desc, &f).unwrap();
    assert_eq!(f.len(), h.file_len());
    assert_eq!(&f[..4], b"FHPF");
    assert_eq!(h.file_len(), HEADER_LEN + h.data_len as usize + CRC_LEN);
    let mut bad = f.clone();
    let n = bad.len();
    bad[n - 1] ^= 1;
    assert_eq!(parameter_file::check(desc, &bad), Err(FormatError::Crc));
    let mut bad = f.clone();
    bad[16] ^= 1; // layout fingerprint
    assert_eq!(
        parameter_file::check(desc, &bad),
        Err(FormatError::Incompatible)
    );
    assert_eq!(
        parameter_file::check(desc, &f[..100]),
        Err(FormatError::Size(100))
    );
}

/// FHPP-FPC-14 with the real file (7577 bytes: 1263 data packets, the last one 5 bytes and
/// zero-padded); the vector's 100-byte file is shorter than this format's header and CRC,
/// so its start is refused with 05h (see `every_type_2_error_and_its_effect`).
#[test]
fn upload_download_round_trip_and_activation_by_127_4() {
    let mut b = Bench::new();
    assert_eq!(b.write(121, 1, 0x46), Ok(0x46)); // 'F'
    assert_eq!(b.write(404, 2, pwe(-777)), Ok(pwe(-777)));
    assert_eq!(b.write(127, 2, 1), Ok(1));
    let file = b.upload();
    assert_eq!(
        parameter_file::check(&devices::CMMO_ST, &file)
            .unwrap()
            .file_len(),
        file.len()
    );
    // Forget it: factory settings in the EEPROM and active.
    assert_eq!(b.write(127, 1, 0x10), Ok(0x10));
    assert_eq!(b.write(127, 3, 0x10), Ok(0x10));
    assert_eq!(b.od_u8(121, 1), 0);
    // Download: stored, not active yet (C.4.4).
    b.download(&file).unwrap();
    assert_eq!(b.upload(), file);
    assert_eq!(b.od_u8(121, 1), 0, "active values unchanged");
    assert_eq!(b.write(127, 4, 0x10), Ok(0x10));
    assert_eq!(b.od_u8(121, 1), 0x46);
    assert_eq!(b.read(404, 2), Ok(pwe(-777)));
    b.run(1);
    assert_eq!(b.dev.records().get(2).unwrap().target, -777);
    assert_eq!(b.scon() & SCON_FAULT, 0);
}

/// FHPP-FPC-14, the frames of the vector: a 100-byte download starts with FPCC 45h, packet ID
/// 20h and the size little-endian (`45 20 64 00 00 00 00 00`), takes 17 data packets with IDs
/// 01h…11h (16 × 6 bytes + 4, the last one zero-padded) and stops with 40h + sequence; the
/// drive acknowledges each packet with the same packet ID (the device part runs with the
/// real file in `upload_download_round_trip_and_activation_by_127_4`).
#[test]
fn fhpp_fpc_14_frames_of_a_100_byte_download() {
    let down = FileDirection::Download;
    let start = Request::File {
        direction: down,
        packet: Packet::start(100),
    };
    assert_eq!(start.encode(), [0x45, 0x20, 0x64, 0, 0, 0, 0, 0]);
    let file: Vec<u8> = (1..=100).collect();
    let mut seq = 0;
    let mut ids = Vec::new();
    let mut last = [0u8; 8];
    for chunk in file.chunks(6) {
        seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
        let mut d = [0u8; 6];
        d[..chunk.len()].copy_from_slice(chunk);
        last = Request::File {
            direction: down,
            packet: Packet::data(seq, d),
        }
        .encode();
        assert_eq!(last[0], 0x45);
        ids.push(last[1]);
    }
    assert_eq!(ids, (0x01..=0x11).collect::<Vec<u8>>(), "17 data packets");
    assert_eq!(last[2..], [97, 98, 99, 100, 0, 0], "4 bytes, zero-padded");
    let stop = Request::File {
        direction: down,
        packet: Packet::empty(PacketKind::Stop, 0x12),
    };
    assert_eq!(stop.encode()[..2], [0x45, 0x52]);
    // The drive's acknowledgement of a packet carries the same ID (FPCS 43h: response mode).
    let ack = Response::File(FileResponse::Active(Packet::data(0x11, [0; 6]))).encode();
    assert_eq!(ack[..2], [0x43, 0x11]);
}

#[test]
fn sequence_numbers_run_1_to_31_then_0() {
    let mut b = Bench::new();
    let up = FileDirection::Upload;
    b.no_task_file();
    b.ack(up, Packet::empty(PacketKind::Start, 0));
    let mut seen = Vec::new();
    let mut seq = 0;
    for _ in 0..33 {
        seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
        seen.push(b.ack(up, Packet::data(seq, [0; 6])).sequence);
    }
    assert_eq!(seen[..31], (1..=31).collect::<Vec<u8>>()[..]);
    assert_eq!(seen[31..], [0, 1]);
}

/// Runs `f`, expecting the drive's error packet with `e`; checks the abort effects.
fn expect_type2(b: &mut Bench, r: Response, e: FileError) {
    match r {
        Response::File(FileResponse::Active(p)) => {
            assert_eq!(p.kind, PacketKind::Error, "{r:?}");
            assert_eq!(p.error_code(), e.code(), "{r:?}");
        }
        r => panic!("expected type-2 {e:?}, got {r:?}"),
    }
    b.run(3);
    if e.aborts() {
        assert!(!b.dev.parameter_channel().transfer().is_active());
        assert_eq!(b.scon() & SCON_FAULT, SCON_FAULT, "E27 for {e:?}");
        assert_eq!(b.dev.fault_number(), DIAG_E27);
        // FHPP-FPC-15: the 7-segment display shows "E27", the memory has its entry.
        assert_eq!(b.dev.seven_segment().to_string(), "E27");
        let newest = b.dev.diagnostic_memory().get(0).copied();
        assert_eq!(
            newest.map(|e| (e.event, e.number)),
            Some((EventType::Fault, u16::from(DIAG_E27)))
        );
    } else {
        assert!(b.dev.parameter_channel().transfer().is_active());
        assert_eq!(b.scon() & SCON_FAULT, 0, "no fault for {e:?}");
    }
}

/// Acknowledges E27 (CCON.RESET rising edge) and sends "no task".
fn acknowledge(b: &mut Bench) {
    b.fhpp_out([0x08, 0, 0, 0, 0, 0, 0, 0]);
    b.run(3);
    b.fhpp_out([0; 8]);
    b.run(3);
    assert_eq!(b.scon() & SCON_FAULT, 0, "acknowledged");
    assert_eq!(b.dev.seven_segment(), SevenSegment::NoMessage);
    b.no_task_file();
}

/// FHPP-FPC-16: the 02h timeout between two packets is one of the aborting errors checked here.
///
/// FHPP-FPC-15 (aborting errors show E27 and need RESET; 01h, 03h and type 1 do not abort).
#[test]
fn every_type_2_error_and_its_effect() {
    let up = FileDirection::Upload;
    let down = FileDirection::Download;
    let desc = &devices::CMMO_ST;
    let mut good = parameter_file::FileBuffer::new();
    parameter_file::factory(desc, &mut good).unwrap();
    let mut b = Bench::new();

    // 01h wrong sequence number: does not abort; the right packet continues.
    b.no_task_file();
    b.ack(up, Packet::empty(PacketKind::Start, 0));
    let r = b.file_packet(up, Packet::data(5, [0; 6]));
    expect_type2(&mut b, r, FileError::Sequence);
    let p = b.ack(up, Packet::data(1, [0; 6]));
    assert_eq!(&p.data[..4], b"FHPF");
    // 03h invalid telegram format (reserved control bits 1xx): does not abort.
    let r = Response::decode(&b.exchange([0x44, 0x82, 0, 0, 0, 0, 0, 0])).unwrap();
    expect_type2(&mut b, r, FileError::Format);
    b.ack(up, Packet::data(2, [0; 6]));
    // Type 1, 11h: a download while the upload runs (does not abort).
    let r = b.file_packet(down, Packet::start(good.len() as u32));
    assert!(matches!(
        r,
        Response::File(FileResponse::Rejected {
            code: ErrorCode::NotInThisState,
            ..
        })
    ));
    // 00h: the PLC sends an error: aborts, E27.
    let r = b.file_packet(up, Packet::error(3, 0));
    expect_type2(&mut b, r, FileError::FromPlc);
    acknowledge(&mut b);

    // 04h a start while the transfer runs: aborts.
    b.ack(up, Packet::empty(PacketKind::Start, 0));
    b.ack(up, Packet::data(1, [0; 6]));
    let r = b.file_packet(up, Packet::empty(PacketKind::Start, 0));
    expect_type2(&mut b, r, FileError::CommandOrder);
    acknowledge(&mut b);

    // 02h timeout between two packets: aborts.
    b.ack(up, Packet::empty(PacketKind::Start, 0));
    b.run(PACKET_TIMEOUT_MS - 5);
    assert!(b.dev.parameter_channel().transfer().is_active());
    b.run(10);
    let r = Response::decode(&b.fpc_in()).unwrap();
    expect_type2(&mut b, r, FileError::Timeout);
    acknowledge(&mut b);

    // 07h an upload asked for more data than the file has: aborts.
    b.ack(up, Packet::empty(PacketKind::Start, 0));
    let packets = good.len().div_ceil(6);
    let mut seq = 0;
    for _ in 0..packets {
        seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
        b.ack(up, Packet::data(seq, [0; 6]));
    }
    seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
    let r = b.file_packet(up, Packet::data(seq, [0; 6]));
    expect_type2(&mut b, r, FileError::Amount);
    acknowledge(&mut b);

    // 05h invalid file length at the start of a download (FHPP-FPC-14's 100 bytes): aborts.
    let r = b.file_packet(down, Packet::start(100));
    expect_type2(&mut b, r, FileError::Read);
    acknowledge(&mut b);

    // 07h a download stopped before the announced size: aborts.
    b.ack(down, Packet::start(good.len() as u32));
    b.ack(down, Packet::data(1, good[..6].try_into().unwrap()));
    let r = b.file_packet(down, Packet::empty(PacketKind::Stop, 2));
    expect_type2(&mut b, r, FileError::Amount);
    acknowledge(&mut b);

    // 06h a file with a wrong CRC: refused at the stop, nothing stored.
    let mut bad = good.clone();
    let n = bad.len();
    bad[n - 2] ^= 0xFF;
    let e = b.download(&bad).unwrap_err();
    assert_eq!(e.error_code(), FileError::Write.code());
    b.run(3);
    assert_eq!(b.dev.fault_number(), DIAG_E27);
    assert!(b.dev.parameter_channel().memory().is_factory());
    acknowledge(&mut b);
    // 06h an incompatible header (another layout): refused right after the header.
    let mut bad = good.clone();
    bad[16] ^= 1;
    let down_packets_sent = {
        b.ack(down, Packet::start(bad.len() as u32));
        let mut seq = 0;
        let mut sent = 0;
        loop {
            seq = drive::vendors::festo_cmmo_st::fhpp::parameter_channel::next_sequence(seq);
            let at = sent * 6;
            let mut d = [0u8; 6];
            d.copy_from_slice(&bad[at..at + 6]);
            sent += 1;
            match b.file_packet(down, Packet::data(seq, d)) {
                Response::File(FileResponse::Active(p)) if p.kind == PacketKind::Error => {
                    assert_eq!(p.error_code(), FileError::Write.code());
                    break sent;
                }
                _ => {}
            }
        }
    };
    assert_eq!(
        down_packets_sent,
        HEADER_LEN.div_ceil(6),
        "checked after the header"
    );
    acknowledge(&mut b);

    // 08h a download without control authority: aborts.
    b.dev
        .fhpp_mut()
        .request_local_control(Authority::Fct)
        .unwrap();
    b.run(1);
    let r = b.file_packet(down, Packet::start(good.len() as u32));
    expect_type2(&mut b, r, FileError::Access);
    b.dev.fhpp_mut().release_local_control();
    acknowledge(&mut b);

    // 09h a start while a fault still needs acknowledging.
    b.dev.fault(0x2F);
    b.run(3);
    let r = b.file_packet(up, Packet::empty(PacketKind::Start, 0));
    match r {
        Response::File(FileResponse::Active(p)) => {
            assert_eq!(p.error_code(), FileError::AccessTimeout.code())
        }
        r => panic!("{r:?}"),
    }
    assert!(!b.dev.parameter_channel().transfer().is_active());
    b.dev.clear_fault(0x2F);
    acknowledge(&mut b);

    // A good download; a second one within 3 s is refused with type 1, 11h (diagnostic 38h).
    b.download(&good).unwrap();
    let r = b.file_packet(down, Packet::start(good.len() as u32));
    assert!(
        matches!(
            r,
            Response::File(FileResponse::Rejected {
                code: ErrorCode::NotInThisState,
                ..
            })
        ),
        "{r:?}"
    );
    b.run(DOWNLOAD_INTERVAL_MS);
    b.download(&good).unwrap();
    assert_eq!(b.scon() & SCON_FAULT, 0);
}

#[test]
fn a_data_packet_without_a_transfer_is_type_1_error_11h() {
    let mut b = Bench::new();
    b.no_task_file();
    let r = b.exchange([0x44, 0x01, 0, 0, 0, 0, 0, 0]);
    assert_eq!(r, [0x47, 0x01, 0x11, 0, 0, 0, 0, 0]);
    assert_eq!(b.scon() & SCON_FAULT, 0);
}

// ---- codec -------------------------------------------------------------------------------

#[test]
fn codec_round_trips_both_directions() {
    let requests = [
        Request::NoTask { mode: 1 },
        Request::NoTask { mode: 4 },
        Request::NoTask { mode: 0 },
        Request::Parameter(ParameterRequest::Read {
            pnu: 1041,
            subindex: 1,
        }),
        Request::Parameter(ParameterRequest::Write {
            pnu: 0xFFFF,
            subindex: 255,
            value: 0x8000_0001,
        }),
        Request::File {
            direction: FileDirection::Upload,
            packet: Packet::empty(PacketKind::Start, 0),
        },
        Request::File {
            direction: FileDirection::Download,
            packet: Packet::data(31, [1, 2, 3, 4, 5, 6]),
        },
        Request::File {
            direction: FileDirection::Download,
            packet: Packet::error(9, 0),
        },
    ];
    for r in requests {
        assert_eq!(Request::decode(&r.encode()), Ok(r), "{r:?}");
    }
    let mut responses = vec![
        Response::NoResponse { mode: 1 },
        Response::Parameter(ParameterResponse::Value {
            pnu: 404,
            subindex: 64,
            value: 0xFFFF_FFFF,
        }),
        Response::File(FileResponse::Active(Packet::start(7577))),
        Response::File(FileResponse::Active(Packet::error(3, 0x09))),
        Response::File(FileResponse::Rejected {
            packet_id: 0x21,
            code: ErrorCode::RequestNotSupported,
        }),
        Response::Unsupported {
            mode: 0xF,
            code: ErrorCode::RequestNotSupported,
        },
    ];
    for code in ErrorCode::ALL {
        responses.push(Response::Parameter(ParameterResponse::Error {
            pnu: 1,
            subindex: 1,
            code,
        }));
    }
    for r in responses {
        assert_eq!(Response::decode(&r.encode()), Ok(r), "{r:?}");
    }
    // Byte layout: PNU and PWE big-endian, file user data little-endian.
    assert_eq!(
        Request::Parameter(ParameterRequest::Write {
            pnu: 0x0102,
            subindex: 3,
            value: 0x0405_0607
        })
        .encode(),
        [0x18, 3, 1, 2, 4, 5, 6, 7]
    );
    assert_eq!(
        Response::File(FileResponse::Active(Packet::start(0x0102_0304))).encode(),
        [0x43, 0x20, 4, 3, 2, 1, 0, 0]
    );
}

#[test]
fn codec_refuses_reserved_values() {
    use drive::vendors::festo_cmmo_st::fhpp::parameter_channel::DecodeError;
    assert_eq!(
        Request::decode(&[0x26, 0, 0, 0, 0, 0, 0, 0]),
        Err(DecodeError::ReservedMode { mode: 2, id: 6 })
    );
    assert_eq!(
        Request::decode(&[0x14, 0, 0, 0, 0, 0, 0, 0]),
        Err(DecodeError::UnsupportedId { mode: 1, id: 4 })
    );
    assert_eq!(
        Request::decode(&[0x44, 0x80, 0, 0, 0, 0, 0, 0]),
        Err(DecodeError::ReservedPacketId(0x80))
    );
    assert_eq!(
        Response::decode(&[0x17, 1, 0, 1, 0, 0, 0, 0x42]),
        Err(DecodeError::UnknownErrorCode(0x42))
    );
    assert_eq!(
        ParameterResponse::decode(&[0x43, 0x20, 0, 0, 0, 0, 0, 0]),
        Err(DecodeError::NotParameterResponse(0x43))
    );
    // Tab. C.12: only 01h and 03h let a transfer continue.
    let continuing: Vec<u8> = FileError::ALL
        .iter()
        .filter(|e| !e.aborts())
        .map(|e| e.code())
        .collect();
    assert_eq!(continuing, [0x01, 0x03]);
}

// ---- spec vectors FHPP-FPC-05 … FHPP-FPC-11, FHPP-FPC-16 ----------------------------------------

/// Sends the vector's request bytes after a "no task"; returns the answer.
fn vector(b: &mut Bench, request: [u8; 8]) -> [u8; 8] {
    b.exchange([0x10, 0, 0, 0, 0, 0, 0, 0]);
    b.exchange(request)
}

/// FHPP-FPC-05, FHPP-FPC-06: PNU 1041:2 → error 3; a write to the read-only PNU 1041 → error 1.
#[test]
fn fhpp_fpc_05_06_wrong_subindex_and_read_only() {
    let mut b = Bench::new();
    let r = vector(&mut b, [0x16, 0x02, 0x04, 0x11, 0, 0, 0, 0]);
    assert_eq!(r, [0x17, 0x02, 0x04, 0x11, 0, 0, 0, 0x03], "FHPP-FPC-05");
    let r = vector(&mut b, [0x18, 0x01, 0x04, 0x11, 0, 0, 0, 0]);
    assert_eq!(r, [0x17, 0x01, 0x04, 0x11, 0, 0, 0, 0x01], "FHPP-FPC-06");
}

/// FHPP-FPC-07: with FCT in control, PNU 125 := 1 → `17 01 00 7D 00 00 00 11` (error 17); from the
/// web server it takes control back.
#[test]
fn fhpp_fpc_07_pnu_125_cannot_take_control_from_fct() {
    let mut b = Bench::new();
    b.dev
        .fhpp_mut()
        .request_local_control(Authority::Fct)
        .unwrap();
    b.run(1);
    let r = vector(&mut b, [0x18, 0x01, 0x00, 0x7D, 0, 0, 0, 1]);
    assert_eq!(r, [0x17, 0x01, 0x00, 0x7D, 0, 0, 0, 0x11]);
    // From the web server it does take control back.
    b.dev.fhpp_mut().release_local_control();
    b.dev
        .fhpp_mut()
        .request_local_control(Authority::WebServer)
        .unwrap();
    b.run(1);
    let r = vector(&mut b, [0x18, 0x01, 0x00, 0x7D, 0, 0, 0, 1]);
    assert_eq!(r, [0x15, 0x01, 0x00, 0x7D, 0, 0, 0, 1]);
    assert_eq!(b.dev.fhpp().authority(), Authority::Fieldbus);
}

/// FHPP-FPC-08, FHPP-FPC-09, FHPP-FPC-10, FHPP-FPC-11: PNU 205 = FFFFh, PNU 230 = FFh without a
/// fault, PNU 234 = 0037h for A, B, C, E, F, PNU 1001 = 2000 increments per revolution.
#[test]
fn fhpp_fpc_08_to_11_reference_values() {
    let mut b = Bench::new();
    // FHPP-FPC-08: PNU 205 = FFFFh with no fault.
    let r = vector(&mut b, [0x16, 0x01, 0x00, 0xCD, 0, 0, 0, 0]);
    assert_eq!(r, [0x15, 0x01, 0x00, 0xCD, 0, 0, 0xFF, 0xFF]);
    // FHPP-FPC-09: PNU 230 = FFh with no fault.
    let r = vector(&mut b, [0x16, 0x01, 0x00, 0xE6, 0, 0, 0, 0]);
    assert_eq!(r, [0x15, 0x01, 0x00, 0xE6, 0, 0, 0, 0xFF]);
    // FHPP-FPC-10: PNU 234 of 11h (software limit positive, reactions A, B, C, E, F) =
    // 0037h, at subindex 11h + 1.
    assert_eq!(b.read(234, 0x12), Ok(0x0037));
    // FHPP-FPC-11: PNU 1001:1 = 7D0h increments per 1001:2 = 1 revolution.
    let r = vector(&mut b, [0x16, 0x01, 0x03, 0xE9, 0, 0, 0, 0]);
    assert_eq!(r, [0x15, 0x01, 0x03, 0xE9, 0, 0, 0x07, 0xD0]);
    assert_eq!(b.read(1001, 2), Ok(1));
}

/// FHPP-FPC-16: no packet within the packet timeout during a download → packet ID 60h + seq, byte 3
/// = 02h, transfer aborted, data discarded.
#[test]
fn fhpp_fpc_16_download_timeout_aborts_and_discards() {
    let mut b = Bench::new();
    let desc = &devices::CMMO_ST;
    let mut good = parameter_file::FileBuffer::new();
    parameter_file::factory(desc, &mut good).unwrap();
    let down = FileDirection::Download;
    b.no_task_file();
    b.ack(down, Packet::start(good.len() as u32));
    b.ack(down, Packet::data(1, good[..6].try_into().unwrap()));
    b.ack(down, Packet::data(2, good[6..12].try_into().unwrap()));
    b.run(PACKET_TIMEOUT_MS + 1);
    let r = b.fpc_in();
    assert_eq!(
        r[..3],
        [0x43, 0x60 | 3, 0x02],
        "packet ID 011x.xxxx, byte 3 = 02h"
    );
    assert!(!b.dev.parameter_channel().transfer().is_active());
    b.run(2);
    assert_eq!(b.dev.fault_number(), DIAG_E27);
    // The PLC's next packet is not taken (the error answer stays until "no task"); after
    // "no task" it finds no transfer: the data was discarded.
    let next = Request::File {
        direction: down,
        packet: Packet::data(3, [0; 6]),
    }
    .encode();
    assert_eq!(b.exchange(next)[..3], [0x43, 0x63, 0x02]);
    b.no_task_file();
    assert_eq!(b.exchange(next)[..3], [0x47, 0x03, 0x11]);
}

/// The permanent memory survives a restart when the host keeps it: what PNU 127:2 stored is
/// active again at the next power-on (error management included), every change of the stored
/// file shows in the generation, and a damaged file is refused without changing anything.
#[test]
fn the_saved_memory_is_active_after_a_power_on_from_it() {
    let mut a = Bench::new();
    let start = a.dev.permanent_memory().generation();
    assert_eq!(a.dev.permanent_memory().stored(), None, "factory settings");
    assert_eq!(a.write(121, 1, 0x53), Ok(0x53)); // 'S'
    let em = a.read(246, 40).unwrap();
    assert_eq!(a.write(246, 40, em ^ 0x80), Ok(em ^ 0x80));
    assert_eq!(
        a.dev.permanent_memory().generation(),
        start,
        "a write is volatile"
    );
    assert_eq!(a.write(127, 2, 1), Ok(1));
    assert_ne!(a.dev.permanent_memory().generation(), start);
    let file = a.dev.permanent_memory().stored().expect("saved").to_vec();

    let mut b = Bench::new();
    let mut damaged = file.clone();
    if let Some(byte) = damaged.get_mut(HEADER_LEN + 3) {
        *byte ^= 0x01;
    }
    assert!(b.dev.power_on_from_memory(&damaged).is_err());
    assert_eq!(b.od_u8(121, 1), 0, "a refused file changes nothing");
    assert_eq!(b.dev.permanent_memory().stored(), None);
    b.dev.power_on_from_memory(&file).expect("a saved file");
    b.run(1);
    assert_eq!(b.od_u8(121, 1), 0x53);
    assert_eq!(b.read(246, 40), Ok(em ^ 0x80));
    assert_eq!(b.dev.permanent_memory().stored(), Some(file.as_slice()));

    // 127:1 deletes it: nothing stored, a new generation.
    let saved = a.dev.permanent_memory().generation();
    assert_eq!(a.write(127, 1, 0x10), Ok(0x10));
    assert_eq!(a.dev.permanent_memory().stored(), None);
    assert_ne!(a.dev.permanent_memory().generation(), saved);
}
