//! FHPP cyclic data and state machine of the CMMO-ST (manual ch. 5, 6): every vector of the vector
//! catalogue kept beside the project §2.1 (FHPP-CB-01 … FHPP-CB-16, Examples 1–6) and
//! §2.2 (FHPP-ST-01 … FHPP-ST-19, Tab. 5.2/5.3), each test naming its IDs in full, the reference
//! status values of the manual's extract kept beside the project (§4.3, §8.1), and the handshakes.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::vendors::festo_cmmo_st::fhpp::control_bytes::{percent_of, Edges};
use drive::vendors::festo_cmmo_st::fhpp::record_table::RecordSelect;
use drive::vendors::festo_cmmo_st::fhpp::{
    Ack, Authority, AuthorityError, BitPattern, Ccon, Cdir, ChainCondition, Config, ControlMode,
    Cpos, Event, Fault, Fhpp, InputData, MotionCommand, MotionStatus, OpState, OperatingMode,
    OutputData, Rcb1, Reaction, RecordTable, Refusal, RelativeTo, Rsb, Scon, Sdir, Spos,
    StartBehaviour, State, Transition,
};

const BASE_VELOCITY: u32 = 200_000; // PNU 540 [SINC/s]
const BASE_ACCELERATION: u32 = 1_000_000; // PNU 560 [SINC/s²]

/// The CMMO-ST's records, as its device file says (`[device.fhpp] records`).
fn cmmo_st_records() -> u8 {
    devices::CMMO_ST.fhpp.map_or(0, |f| f.records)
}

/// The state machine, a record table, a hand-driven motion status and the events of the last
/// cycle.
struct Rig {
    fhpp: Fhpp,
    records: RecordTable,
    status: MotionStatus,
    events: Vec<Event>,
    out: OutputData,
}

impl Rig {
    fn new() -> Self {
        let config = Config {
            base_velocity: BASE_VELOCITY,
            base_acceleration: BASE_ACCELERATION,
            ..Config::default()
        };
        let mut records = RecordTable::new(cmmo_st_records());
        for n in 1..=64u8 {
            let r = records.get_mut(n).unwrap();
            r.target = i32::from(n) * 1000;
            r.velocity = 50_000;
        }
        // Record 5: a velocity record; record 6: invalid (COM = 11).
        records.get_mut(5).unwrap().rcb1 = Rcb1::COM2;
        records.get_mut(6).unwrap().rcb1 = Rcb1::COM1 | Rcb1::COM2;
        Rig {
            fhpp: Fhpp::new(config),
            records,
            status: MotionStatus::default(),
            events: Vec::new(),
            out: OutputData::default(),
        }
    }

    fn cycle(&mut self, out: OutputData) -> InputData {
        self.out = out;
        self.events.clear();
        let events = &mut self.events;
        self.fhpp
            .cycle(&out, &self.records, &self.status, |e| events.push(e))
    }

    /// A record-selection telegram.
    fn rec(&mut self, ccon: u8, cpos: u8, record: u8) -> InputData {
        self.cycle(OutputData::record(Ccon(ccon), Cpos(cpos), record))
    }

    /// A direct-mode telegram.
    fn dir(&mut self, ccon: u8, cpos: u8, cdir: u8, sp1: u8, sp2: i32) -> InputData {
        self.cycle(OutputData::direct(
            Ccon(ccon),
            Cpos(cpos),
            Cdir(cdir),
            sp1,
            sp2,
        ))
    }

    /// The same telegram again (levels held, no edges).
    fn again(&mut self) -> InputData {
        self.cycle(self.out)
    }

    fn transitions(&self) -> Vec<Transition> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Transition(t) => Some(*t),
                _ => None,
            })
            .collect()
    }

    fn motions(&self) -> Vec<MotionCommand> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Motion(m) => Some(*m),
                _ => None,
            })
            .collect()
    }

    /// The motion layer took a task: the axis moves, MC condition false.
    fn moving(&mut self) {
        self.status.moving = true;
        self.status.motion_complete = false;
    }

    /// The motion layer finished the task (or the halt / stop): at rest, MC condition true.
    fn settled(&mut self) {
        self.status.moving = false;
        self.status.motion_complete = true;
    }

    /// Power-on, enabled in record selection (S4, SA1), referenced.
    fn enabled_referenced() -> Self {
        let mut rig = Rig::new();
        rig.status.referenced = true;
        rig.status.motion_complete = true;
        let i = rig.rec(0x03, 0x01, 0);
        assert_eq!((i.scon.0, i.spos.0), (0x13, 0x85));
        rig
    }

    /// Enabled in direct mode (S4, SA1), referenced.
    fn direct_referenced() -> Self {
        let mut rig = Rig::new();
        rig.status.referenced = true;
        rig.status.motion_complete = true;
        let i = rig.dir(0x43, 0x01, 0x00, 0, 0);
        assert_eq!((i.scon.0, i.spos.0), (0x53, 0x85));
        rig
    }

    /// S4, SA2: record `n` started and running, START still held.
    fn record_running(n: u8) -> Self {
        let mut rig = Rig::enabled_referenced();
        rig.rec(0x03, 0x01, n);
        rig.rec(0x03, 0x03, n);
        assert_eq!(rig.transitions(), [Transition::TA1]);
        rig.moving();
        rig.again();
        rig
    }
}

fn minor(code: u8) -> Fault {
    Fault {
        code,
        reaction: Reaction::F,
        ack: Ack::Immediately,
    }
}

fn serious(code: u8) -> Fault {
    Fault {
        code,
        reaction: Reaction::B,
        ack: Ack::AfterCause,
    }
}

fn show(i: &InputData) -> String {
    format!("SCON {} SPOS {}", i.scon, i.spos)
}

// ---------------------------------------------------------------------------------------------
// Byte layouts (Tab. 5.11–5.28)

#[test]
fn control_byte_bits_as_tab_5_12() {
    assert_eq!(
        [
            Ccon::ENABLE,
            Ccon::STOP,
            Ccon::BRAKE,
            Ccon::RESET,
            Ccon::LOCK,
            Ccon::OPM1,
            Ccon::OPM2
        ]
        .map(|b| b.0),
        [0x01, 0x02, 0x04, 0x08, 0x20, 0x40, 0x80]
    );
    assert_eq!(
        [
            Cpos::HALT,
            Cpos::START,
            Cpos::HOM,
            Cpos::JOGP,
            Cpos::JOGN,
            Cpos::TEACH,
            Cpos::CLEAR
        ]
        .map(|b| b.0),
        [0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40]
    );
    assert_eq!(
        [Cdir::ABS, Cdir::COM1, Cdir::COM2, Cdir::XLIM].map(|b| b.0),
        [1, 2, 4, 0x20]
    );
    assert_eq!(Ccon(0x43).operating_mode(), OperatingMode::Direct);
    assert_eq!(Ccon(0x03).operating_mode(), OperatingMode::RecordSelection);
    assert_eq!(Ccon(0x83).operating_mode(), OperatingMode::Reserved(2));
    assert_eq!(
        Ccon(0x03).with_operating_mode(OperatingMode::Direct),
        Ccon(0x43)
    );
    assert_eq!(Cdir(0x00).control_mode(), Some(ControlMode::Position));
    assert_eq!(Cdir(0x02).control_mode(), Some(ControlMode::Force));
    assert_eq!(Cdir(0x04).control_mode(), Some(ControlMode::Velocity));
    assert_eq!(Cdir(0x06).control_mode(), None);
    assert_eq!(
        Cdir::EMPTY.with_control_mode(ControlMode::Velocity),
        Cdir(0x04)
    );
    assert!(Cdir(0x01).relative());
}

#[test]
fn status_byte_bits_as_tab_5_13() {
    assert_eq!(
        [
            Scon::ENABLED,
            Scon::OPEN,
            Scon::WARN,
            Scon::FAULT,
            Scon::VLOAD,
            Scon::FCT_MMI
        ]
        .map(|b| b.0),
        [0x01, 0x02, 0x04, 0x08, 0x10, 0x20]
    );
    assert_eq!((Scon::OPM1.0, Scon::OPM2.0), (0x40, 0x80));
    assert_eq!(
        [
            Spos::HALT,
            Spos::ACK,
            Spos::MC,
            Spos::TEACH,
            Spos::MOV,
            Spos::FOLERR,
            Spos::STILL,
            Spos::REF
        ]
        .map(|b| b.0),
        [0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80]
    );
    assert_eq!(
        [Sdir::ABS, Sdir::COM1, Sdir::COM2, Sdir::VLIM, Sdir::XLIM].map(|b| b.0),
        [1, 2, 4, 0x10, 0x20]
    );
    assert_eq!(
        [Rsb::RC1, Rsb::RCC, Rsb::VLIM, Rsb::XLIM].map(|b| b.0),
        [1, 2, 0x10, 0x20]
    );
    assert_eq!(Scon(0x53).operating_mode(), OperatingMode::Direct);
    assert_eq!(Sdir(0x04).control_mode(), Some(ControlMode::Velocity));
    assert_eq!(format!("{}", BitPattern(0x13)), "0001.0011");
    assert_eq!(format!("{}", Scon(0x13)), "VLOAD|OPEN|ENABLED (0001.0011)");
    assert_eq!(format!("{}", Spos(0x05)), "MC|HALT (0000.0101)");
    assert_eq!(format!("{}", Spos(0x00)), "- (0000.0000)");
}

#[test]
fn telegram_layout_is_big_endian_and_8_or_16_bytes() {
    // FHPP-MB-01 data: ENABLE + STOP, HALT, record 1.
    let (o, fpc) = OutputData::parse(&[0x03, 0x01, 0x01, 0, 0, 0, 0, 0]).unwrap();
    assert_eq!(fpc, None);
    assert_eq!(
        (o.ccon, o.cpos, o.record_number()),
        (Ccon(0x03), Cpos(0x01), 1)
    );
    // §8.2 b: direct mode, absolute position 10000 SINC at 100 %.
    let (o, _) = OutputData::parse(&[0x43, 0x03, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10]).unwrap();
    assert_eq!(
        (o.cdir(), o.setpoint1(), o.setpoint2),
        (Cdir(0), 100, 10_000)
    );
    assert_eq!(
        o.to_bytes(),
        [0x43, 0x03, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10]
    );
    // FHPP-MB-04: 16 bytes, EFPC in bytes 9…16.
    let image = [
        0x43, 0x01, 0, 0, 0, 0, 0, 0, 0x16, 0x01, 0x04, 0x11, 0, 0, 0, 0,
    ];
    let (o, fpc) = OutputData::parse(&image).unwrap();
    assert_eq!(o.ccon, Ccon(0x43));
    assert_eq!(fpc, Some([0x16, 0x01, 0x04, 0x11, 0, 0, 0, 0]));
    for len in [0, 4, 7, 9, 12, 15, 17, 24] {
        assert_eq!(OutputData::parse(&vec![0; len]), None, "length {len}");
    }
    let i = InputData {
        scon: Scon(0x53),
        spos: Spos(0x83),
        byte3: 0,
        byte4: 100,
        actual2: -400_000,
    };
    assert_eq!(
        i.to_bytes(),
        [0x53, 0x83, 0x00, 0x64, 0xFF, 0xF9, 0xE5, 0x80]
    );
    assert_eq!(InputData::from_bytes(i.to_bytes()), i);
}

#[test]
fn edges_p_and_n() {
    let e = Edges::between(0x01, 0x03);
    assert!(e.rose(0x02) && !e.rose(0x01) && !e.fell(0x01));
    let e = Edges::between(0x03, 0x02);
    assert!(e.fell(0x01) && !e.rose(0x02));
}

// ---------------------------------------------------------------------------------------------
// §2.1 Control and status bytes (Examples 1–6)

/// FHPP-CB-01: power-on with load voltage, CCON 00h → SCON 10h, SPOS 04h (MC).
#[test]
fn fhpp_cb_01_power_on() {
    let mut rig = Rig::new();
    assert_eq!(rig.fhpp.state(), State::ControllerSwitchedOn);
    let i = rig.rec(0x00, 0x00, 0);
    assert_eq!(rig.transitions(), [Transition::T1]);
    assert_eq!(rig.fhpp.state(), State::DriveBlocked);
    assert_eq!((i.scon.0, i.spos.0), (0x10, 0x04), "{}", show(&i));
    // CCON 0000.0x00: BRAKE is "x"; with BRAKE the brake is released while disabled.
    let i = rig.rec(0x04, 0x00, 0);
    assert_eq!((i.scon.0, i.spos.0), (0x10, 0x04));
    assert_eq!(rig.motions(), [MotionCommand::ManualBrake { open: true }]);
}

/// FHPP-CB-02: CCON.LOCK (20h) → SCON 10h (FCT/MMI = 0), SPOS 04h; FCT cannot take control.
#[test]
fn fhpp_cb_02_lock() {
    let mut rig = Rig::new();
    rig.rec(0x00, 0x00, 0);
    let i = rig.rec(0x20, 0x00, 0);
    assert_eq!((i.scon.0, i.spos.0), (0x10, 0x04));
    assert!(!i.scon.contains(Scon::FCT_MMI));
    // LOCK stops FCT from taking device control.
    assert_eq!(
        rig.fhpp.request_local_control(Authority::Fct),
        Err(AuthorityError::Locked)
    );
    assert_eq!(rig.fhpp.authority(), Authority::Fieldbus);
    rig.rec(0x00, 0x00, 0);
    assert_eq!(rig.fhpp.request_local_control(Authority::Fct), Ok(()));
}

/// FHPP-CB-03: CCON 23h / 27h / 03h, CPOS 01h → SCON 13h, SPOS 05h.
#[test]
fn fhpp_cb_03_enable_record_selection() {
    for ccon in [0x23, 0x27, 0x03] {
        let mut rig = Rig::new();
        rig.rec(0x00, 0x00, 0);
        let i = rig.rec(ccon, 0x01, 0);
        assert_eq!(
            (i.scon.0, i.spos.0),
            (0x13, 0x05),
            "CCON {ccon:02X}: {}",
            show(&i)
        );
        assert_eq!(rig.transitions(), [Transition::T2, Transition::T3]);
        assert_eq!(rig.fhpp.state(), State::OperationEnabled);
        assert_eq!(rig.fhpp.op_state(), OpState::Ready);
        // BRAKE (27h) has no effect once the controller is enabled.
        assert_eq!(rig.motions(), [MotionCommand::Enable]);
    }
}

/// FHPP-CB-04: direct mode, CCON 43h / 63h, CPOS 01h → SCON 53h, SPOS 05h.
#[test]
fn fhpp_cb_04_enable_direct_mode() {
    for ccon in [0x43, 0x63] {
        let mut rig = Rig::new();
        rig.rec(0x00, 0x00, 0);
        let i = rig.dir(ccon, 0x01, 0, 0, 0);
        assert_eq!(
            (i.scon.0, i.spos.0),
            (0x53, 0x05),
            "CCON {ccon:02X}: {}",
            show(&i)
        );
        assert_eq!(rig.fhpp.operating_mode(), OperatingMode::Direct);
    }
}

/// FHPP-CB-05: a fault while a task runs → SCON.FAULT = 1, SPOS.MC = 0 during the reaction (as
/// printed in Example 3), MC = 1 once in S6 (Tab. 5.22).
#[test]
fn fhpp_cb_05_fault_while_a_task_runs() {
    let mut rig = Rig::record_running(1);
    rig.status.fault = Some(minor(0x2F));
    let i = rig.again();
    assert_eq!(rig.transitions(), [Transition::T7]);
    assert_eq!(rig.motions(), [MotionCommand::Stop]); // reaction F: deceleration ramp
    assert_eq!(rig.fhpp.state(), State::FaultReaction);
    // Example 3 step 3.1: SCON xxxx.1xxx, SPOS xxxx.x0xx while the reaction brakes.
    assert!(i.scon.contains(Scon::FAULT), "{}", show(&i));
    assert!(!i.spos.contains(Spos::MC), "{}", show(&i));
    assert!(!i.scon.contains(Scon::OPEN));
    // The drive stops: T8 to S6, and (Tab. 5.22) MC = 1 "task complete, or error".
    rig.settled();
    let i = rig.again();
    assert_eq!(rig.transitions(), [Transition::T8]);
    assert_eq!(rig.fhpp.state(), State::Fault);
    assert!(i.scon.contains(Scon::FAULT));
    assert!(i.spos.contains(Spos::MC));
    // Reaction F keeps the output stage on.
    assert!(i.scon.contains(Scon::ENABLED));
}

/// FHPP-CB-06: a warning → SCON.WARN = 1, SPOS.MC = 0 (the task goes on); clears with its cause.
#[test]
fn fhpp_cb_06_warning() {
    let mut rig = Rig::record_running(1);
    rig.status.warning = true;
    let i = rig.again();
    // SCON xxxx.x1xx; SPOS xxxx.x0xx: a warning does not stop the task.
    assert!(
        i.scon.contains(Scon::WARN) && !i.scon.contains(Scon::FAULT),
        "{}",
        show(&i)
    );
    assert!(!i.spos.contains(Spos::MC));
    assert_eq!(rig.fhpp.op_state(), OpState::TaskActive);
    assert!(rig.transitions().is_empty());
    // Warnings clear without acknowledgement once the cause is gone.
    rig.status.warning = false;
    assert!(!rig.again().scon.contains(Scon::WARN));
}

/// FHPP-CB-07: cause removed, CCON 03h → 0Bh → SCON & 0Dh = 01h, SPOS & 06h = 04h.
#[test]
fn fhpp_cb_07_acknowledge_with_enable() {
    let mut rig = Rig::record_running(1);
    rig.status.fault = Some(minor(0x2F));
    rig.again();
    rig.settled();
    rig.again();
    rig.status.fault = None; // cause removed
    rig.rec(0x03, 0x01, 1); // START back to 0
    let i = rig.rec(0x0B, 0x01, 1); // RESET rising, ENABLE = 1
    assert_eq!(rig.transitions(), [Transition::T10, Transition::T3]);
    assert_eq!(i.scon.0 & 0x0D, 0x01, "{}", show(&i));
    assert_eq!(i.spos.0 & 0x06, 0x04, "{}", show(&i));
}

/// FHPP-CB-08, FHPP-CB-09, FHPP-CB-10: homing by CPOS.HOM: SPOS & 07h = 03h, then MOV, then MC +
/// REF (SPOS & 84h = 84h).
#[test]
fn fhpp_cb_08_to_10_homing() {
    let mut rig = Rig::new();
    rig.rec(0x03, 0x01, 0);
    assert!(!rig.fhpp.inputs().spos.contains(Spos::REF));
    // 4.1: HOM rising with HALT = 1.
    let i = rig.rec(0x03, 0x05, 0);
    assert_eq!(rig.transitions(), [Transition::TA7]);
    assert_eq!(rig.motions(), [MotionCommand::Home]);
    assert!(i.scon.contains(Scon::ENABLED | Scon::OPEN));
    assert_eq!(i.spos.0 & 0x07, 0x03, "{}", show(&i));
    // 4.2 (FHPP-CB-09): HOM kept at 1 while homing runs: MOV.
    rig.moving();
    let i = rig.again();
    assert_eq!(i.spos.0 & 0x10, 0x10);
    assert!(i.spos.contains(Spos::ACK));
    // 4.3 (FHPP-CB-10): homing finished: MC and REF.
    rig.settled();
    rig.status.referenced = true;
    let i = rig.again();
    assert_eq!(rig.transitions(), [Transition::TA8]);
    assert_eq!(i.spos.0 & 0x84, 0x84, "{}", show(&i));
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    // HOM back to 0: ACK falls.
    let i = rig.rec(0x23, 0x01, 0);
    assert_eq!(i.spos.0, 0x85);
}

/// FHPP-CB-11, FHPP-CB-12, FHPP-CB-13: record-selection handshake (ACK 1 / MC 0, MOV and byte 3 =
/// N, ACK 0 / MC 1 / MOV 0).
#[test]
fn fhpp_cb_11_to_13_record_selection_handshake() {
    let mut rig = Rig::enabled_referenced();
    // Record 3 ran before.
    rig.rec(0x03, 0x01, 3);
    rig.rec(0x03, 0x03, 3);
    rig.settled();
    rig.rec(0x03, 0x01, 3);
    assert_eq!(rig.fhpp.inputs().record_number(), 3);
    // 5.1: preselect record 7: byte 3 still shows the previous record (the vector's "still
    // shows the previous record number" is this step; §6.5 step 2: the number is taken at the
    // START edge).
    let i = rig.rec(0x03, 0x01, 7);
    assert_eq!(i.record_number(), 3);
    assert!(i.spos.contains(Spos::MC) && !i.spos.contains(Spos::ACK));
    // 5.2 (FHPP-CB-11): START rising, HALT = 1: ACK = 1, MC = 0.
    let i = rig.rec(0x03, 0x03, 7);
    assert_eq!(rig.transitions(), [Transition::TA1]);
    assert_eq!(
        rig.motions(),
        [MotionCommand::Record {
            number: 7,
            mode: ControlMode::Position
        }]
    );
    assert!(i.scon.contains(Scon::ENABLED | Scon::OPEN));
    assert_eq!(i.spos.0 & 0x07, 0x03, "{}", show(&i));
    // 5.3 (FHPP-CB-12): START kept at 1 while the record runs: MOV, byte 3 = N.
    rig.moving();
    let i = rig.again();
    assert!(i.spos.contains(Spos::MOV | Spos::ACK));
    assert_eq!(i.record_number(), 7);
    // 5.4 (FHPP-CB-13): START := 0, record finished: ACK = 0, MC = 1, MOV = 0.
    let i = rig.rec(0x03, 0x01, 7);
    assert!(
        !i.spos.contains(Spos::ACK),
        "ACK falls when START goes away"
    );
    assert!(
        !i.spos.contains(Spos::MC),
        "the task carries on without START"
    );
    rig.settled();
    let i = rig.again();
    assert_eq!(rig.transitions(), [Transition::TA2]);
    assert_eq!(i.spos.0 & 0x16, 0x04, "{}", show(&i));
    assert_eq!(i.record_number(), 7);
    assert_eq!(i.actual2, rig.status.actual_position);
}

/// FHPP-CB-14: direct-mode positioning, absolute and relative (CDIR.ABS = S), feedback bytes 4…8
/// and the handshake.
#[test]
fn fhpp_cb_14_direct_mode_positioning() {
    for s in [0u8, 1] {
        let mut rig = Rig::direct_referenced();
        rig.status.actual_position = 1234;
        rig.status.actual_velocity = 0;
        // 6.1: velocity 50 % in byte 4, position in bytes 5…8, CDIR.ABS = S.
        rig.dir(0x43, 0x01, s, 50, 10_000);
        // 6.2: START rising.
        let i = rig.dir(0x43, 0x03, s, 50, 10_000);
        assert_eq!(rig.transitions(), [Transition::TA1]);
        let expected = if s == 0 {
            MotionCommand::MoveAbsolute {
                target: 10_000,
                velocity: BASE_VELOCITY / 2,
                velocity_percent: 50,
            }
        } else {
            MotionCommand::MoveRelative {
                distance: 10_000,
                velocity: BASE_VELOCITY / 2,
                velocity_percent: 50,
                reference: RelativeTo::ActualPosition, // PNU 524 bit 0 default
            }
        };
        assert_eq!(rig.motions(), [expected]);
        assert_eq!(i.spos.0 & 0x07, 0x03);
        assert_eq!(i.sdir().0 & 0x01, s, "SDIR.ABS mirrors CDIR.ABS");
        // 6.3: running: MOV, actual velocity % and position.
        rig.moving();
        rig.status.actual_velocity = i32::try_from(BASE_VELOCITY / 2).unwrap();
        rig.status.actual_position = 5000;
        let i = rig.again();
        assert!(i.spos.contains(Spos::MOV | Spos::ACK));
        assert_eq!((i.actual1(), i.actual2), (50, 5000));
        // 6.4: START := 0, done.
        rig.dir(0x43, 0x01, s, 50, 10_000);
        rig.settled();
        rig.status.actual_velocity = 0;
        rig.status.actual_position = 10_000;
        let i = rig.again();
        assert_eq!(i.spos.0 & 0x16, 0x04);
        assert_eq!((i.actual1(), i.actual2), (0, 10_000));
        assert_eq!(i.sdir().0 & 0x01, s);
    }
}

/// FHPP-CB-15: direct-mode byte 4 = 0 / 64h / FFh → no velocity / 100 % / 100 % of PNU 540.
#[test]
fn fhpp_cb_15_velocity_percent_byte() {
    assert_eq!(percent_of(0, BASE_VELOCITY), 0);
    assert_eq!(percent_of(100, BASE_VELOCITY), BASE_VELOCITY);
    assert_eq!(
        percent_of(255, BASE_VELOCITY),
        BASE_VELOCITY,
        "internally limited to 100 %"
    );
    for (byte, velocity, percent) in [
        (0u8, 0, 0u8),
        (0x64, BASE_VELOCITY, 100),
        (0xFF, BASE_VELOCITY, 100),
    ] {
        let mut rig = Rig::direct_referenced();
        rig.dir(0x43, 0x03, 0x00, byte, 500);
        assert_eq!(
            rig.motions(),
            [MotionCommand::MoveAbsolute {
                target: 500,
                velocity,
                velocity_percent: percent
            }]
        );
    }
}

/// FHPP-CB-16: record-selection byte 3 = 0 starts homing, 1…64 select a record, others are refused.
#[test]
fn fhpp_cb_16_record_number_byte() {
    let records = cmmo_st_records();
    assert_eq!(RecordSelect::from_byte(0, records), RecordSelect::Homing);
    assert_eq!(RecordSelect::from_byte(1, records), RecordSelect::Record(1));
    assert_eq!(
        RecordSelect::from_byte(64, records),
        RecordSelect::Record(64)
    );
    assert_eq!(
        RecordSelect::from_byte(65, records),
        RecordSelect::Invalid(65)
    );
    // 0 + START starts homing (TA7), even before the axis is referenced.
    let mut rig = Rig::new();
    rig.rec(0x03, 0x01, 0);
    let i = rig.rec(0x03, 0x03, 0);
    assert_eq!(rig.transitions(), [Transition::TA7]);
    assert_eq!(rig.motions(), [MotionCommand::Home]);
    assert_eq!(rig.fhpp.op_state(), OpState::Homing);
    assert_eq!(i.spos.0 & 0x07, 0x03);
    // 1…64 select a record.
    for n in [1u8, 64] {
        let mut rig = Rig::enabled_referenced();
        rig.rec(0x03, 0x03, n);
        assert_eq!(
            rig.motions(),
            [MotionCommand::Record {
                number: n,
                mode: ControlMode::Position
            }]
        );
    }
    // 65 and a record with COM = 11: refused, diagnostic 3Fh, no ACK.
    for n in [65u8, 6] {
        let mut rig = Rig::enabled_referenced();
        let i = rig.rec(0x03, 0x03, n);
        assert_eq!(rig.events, [Event::Refused(Refusal::InvalidRecord(n))]);
        assert_eq!(Refusal::InvalidRecord(n).diagnostic(), 0x3F);
        assert!(!i.spos.contains(Spos::ACK) && i.spos.contains(Spos::MC));
    }
}

// ---------------------------------------------------------------------------------------------
// §2.2 State transitions (Tab. 5.2, 5.3)

/// FHPP-ST-01: T2, S2 (SCON 10h) with CCON 00h → 01h → S3, SCON 11h.
#[test]
fn fhpp_st_01_t2() {
    let mut rig = Rig::new();
    assert_eq!(rig.rec(0x00, 0x00, 0).scon.0, 0x10);
    let i = rig.rec(0x01, 0x00, 0);
    assert_eq!(rig.transitions(), [Transition::T2]);
    assert_eq!(rig.motions(), [MotionCommand::Enable]);
    assert_eq!(rig.fhpp.state(), State::DriveEnabled);
    assert_eq!(i.scon.0, 0x11);
}

/// FHPP-ST-02: T3, S3 with CCON 01h → 03h → S4, SCON 13h.
#[test]
fn fhpp_st_02_t3() {
    let mut rig = Rig::new();
    rig.rec(0x01, 0x01, 0);
    let i = rig.rec(0x03, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T3]);
    assert_eq!(rig.fhpp.state(), State::OperationEnabled);
    assert_eq!(i.scon.0, 0x13);
}

/// FHPP-ST-03: T4, S4 with CCON 03h → 01h → S3, SCON 11h, the running task stops with Quick Stop.
#[test]
fn fhpp_st_03_t4_quick_stop() {
    let mut rig = Rig::record_running(2);
    let i = rig.rec(0x01, 0x03, 2);
    assert_eq!(rig.transitions(), [Transition::T4]);
    assert_eq!(rig.motions(), [MotionCommand::QuickStop]);
    assert_eq!(rig.fhpp.state(), State::DriveEnabled);
    assert_eq!(i.scon.0, 0x11);
    // The task is reset: no ACK; MC once the axis has stopped.
    assert!(!i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC));
    rig.settled();
    assert!(rig.again().spos.contains(Spos::MC));
    // STOP back to 1: S4 again, SA1, the old task is gone and START (held) does not restart.
    let i = rig.rec(0x03, 0x03, 2);
    assert_eq!(rig.transitions(), [Transition::T3]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    assert_eq!(i.spos.0 & 0x07, 0x05);
}

/// FHPP-ST-04: T5 / T6, S3 or S4 with CCON → 00h → S2, SCON 10h.
#[test]
fn fhpp_st_04_t5_t6() {
    let mut rig = Rig::new();
    rig.rec(0x01, 0x00, 0);
    let i = rig.rec(0x00, 0x00, 0);
    assert_eq!(rig.transitions(), [Transition::T5]);
    assert_eq!(rig.motions(), [MotionCommand::Disable]);
    assert_eq!(i.scon.0, 0x10);

    let mut rig = Rig::record_running(1);
    let i = rig.rec(0x00, 0x01, 1);
    assert_eq!(rig.transitions(), [Transition::T6]);
    assert_eq!(
        rig.motions(),
        [MotionCommand::QuickStop, MotionCommand::Disable]
    );
    assert_eq!(rig.fhpp.state(), State::DriveBlocked);
    assert_eq!(i.scon.0, 0x10);
}

/// Enabled, then a fault raised and its reaction completed: S6.
fn in_s6(fault: Fault) -> Rig {
    let mut rig = Rig::enabled_referenced();
    rig.fhpp.raise_fault(fault);
    rig.again();
    assert_eq!(rig.transitions(), [Transition::T7, Transition::T8]);
    assert_eq!(rig.fhpp.state(), State::Fault);
    rig
}

/// FHPP-ST-05: T9, serious fault, cause gone, CCON 00h → 08h → S2, SCON.FAULT = 0.
#[test]
fn fhpp_st_05_t9_serious() {
    let mut rig = in_s6(serious(0x1A));
    assert!(
        !rig.fhpp.output_stage_on(),
        "reaction B switches the stage off"
    );
    assert_eq!(
        rig.motions(),
        [MotionCommand::QuickStop, MotionCommand::Disable]
    );
    rig.fhpp.fault_cause_gone(0x1A);
    rig.rec(0x00, 0x01, 0);
    assert!(rig.transitions().is_empty());
    let i = rig.rec(0x08, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T9]);
    assert_eq!(rig.fhpp.state(), State::DriveBlocked);
    assert!(!i.scon.contains(Scon::FAULT) && !i.scon.contains(Scon::ENABLED));
    assert_eq!(i.scon.0, 0x10);
}

/// FHPP-ST-05: a serious fault is not acknowledged with ENABLE = 1 (T9 needs ENABLE = 0).
#[test]
fn fhpp_st_05_serious_fault_needs_enable_0() {
    let mut rig = in_s6(serious(0x1A));
    rig.fhpp.fault_cause_gone(0x1A);
    rig.rec(0x03, 0x01, 0);
    let i = rig.rec(0x0B, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T11]);
    assert!(i.scon.contains(Scon::FAULT));
}

/// FHPP-ST-06 (corrected: ENABLE = 1): T10, minor fault, CCON 03h → 0Bh → FAULT = 0, ENABLED = 1,
/// the controller stays on.
#[test]
fn fhpp_st_06_t10_minor() {
    let mut rig = in_s6(minor(0x2F));
    assert!(rig.fhpp.output_stage_on(), "reaction F keeps the stage on");
    let i = rig.rec(0x0B, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T10, Transition::T3]);
    assert!(!i.scon.contains(Scon::FAULT) && i.scon.contains(Scon::ENABLED));
    assert_eq!(i.scon.0, 0x13);
    // STOP = 0 while acknowledging stays in S3.
    let mut rig = in_s6(minor(0x2F));
    rig.rec(0x01, 0x01, 0);
    let i = rig.rec(0x09, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T10]);
    assert_eq!(rig.fhpp.state(), State::DriveEnabled);
    assert_eq!(i.scon.0, 0x11);
}

/// FHPP-ST-07: T11, RESET rising while the fault is still present → stays in S6, SCON.FAULT = 1.
#[test]
fn fhpp_st_07_t11() {
    let mut rig = Rig::enabled_referenced();
    let f = Fault {
        code: 0x15,
        reaction: Reaction::F,
        ack: Ack::AfterCause,
    };
    rig.status.fault = Some(f);
    rig.again();
    assert_eq!(rig.fhpp.state(), State::Fault);
    let i = rig.rec(0x0B, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T11]);
    assert_eq!(rig.fhpp.state(), State::Fault);
    assert!(i.scon.contains(Scon::FAULT));
    // RESET held: no second acknowledge even after the cause has gone.
    rig.status.fault = None;
    rig.again();
    assert!(rig.transitions().is_empty());
    assert_eq!(rig.fhpp.state(), State::Fault);
    // A new rising edge acknowledges.
    rig.rec(0x03, 0x01, 0);
    let i = rig.rec(0x0B, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T10, Transition::T3]);
    assert!(!i.scon.contains(Scon::FAULT));
}

/// FHPP-ST-07: a not-acknowledgeable fault stays in S6 on RESET (T11).
#[test]
fn not_ackable_fault_stays() {
    let mut rig = in_s6(Fault {
        code: 0x01,
        reaction: Reaction::A,
        ack: Ack::NotAckable,
    });
    rig.fhpp.fault_cause_gone(0x01);
    rig.rec(0x00, 0x01, 0);
    rig.rec(0x08, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::T11]);
}

/// FHPP-ST-08: TA1, SA1 referenced, CPOS 01h → 03h → SA2, ACK = 1, MC = 0; unreferenced: refused
/// with 28h.
#[test]
fn fhpp_st_08_ta1() {
    let mut rig = Rig::enabled_referenced();
    let i = rig.rec(0x03, 0x03, 1);
    assert_eq!(rig.transitions(), [Transition::TA1]);
    assert_eq!(rig.fhpp.op_state(), OpState::TaskActive);
    assert_eq!(i.spos.0 & 0x06, 0x02);
    // Not referenced: the start is refused with 28h "homing required".
    let mut rig = Rig::new();
    rig.rec(0x03, 0x01, 1);
    let i = rig.rec(0x03, 0x03, 1);
    assert_eq!(rig.events, [Event::Refused(Refusal::NotReferenced)]);
    assert_eq!(Refusal::NotReferenced.diagnostic(), 0x28);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    assert_eq!(i.spos.0 & 0x06, 0x04);
}

/// FHPP-ST-09: TA3, HALT falling in SA2 → SA3, SPOS.HALT = 0, MC = 0 (position task kept; velocity
/// task ended).
#[test]
fn fhpp_st_09_ta3_halt() {
    let mut rig = Rig::record_running(1);
    let i = rig.rec(0x03, 0x02, 1);
    assert_eq!(rig.transitions(), [Transition::TA3]);
    assert_eq!(rig.motions(), [MotionCommand::Halt]);
    assert_eq!(rig.fhpp.op_state(), OpState::IntermediateStop);
    assert!(!i.spos.contains(Spos::HALT) && !i.spos.contains(Spos::MC));
    // The axis stops; MC stays 0 (Fig. 6.4: the task is kept).
    rig.settled();
    let i = rig.again();
    assert!(!i.spos.contains(Spos::MC));
    assert_eq!(rig.fhpp.op_state(), OpState::IntermediateStop);

    // A velocity record: HALT ends the task.
    let mut rig = Rig::record_running(5);
    rig.rec(0x03, 0x02, 5);
    assert_eq!(rig.transitions(), [Transition::TA3]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    rig.settled();
    assert!(rig.again().spos.contains(Spos::MC));
}

/// FHPP-ST-10: TA4, SA3 with CPOS 00h → 01h → 03h → SA2, the task continues, SPOS.HALT = 1, ACK =
/// 1.
#[test]
fn fhpp_st_10_ta4_continue() {
    let mut rig = Rig::record_running(1);
    rig.rec(0x03, 0x02, 1);
    rig.settled();
    let i = rig.rec(0x03, 0x00, 1);
    assert_eq!(rig.fhpp.op_state(), OpState::IntermediateStop);
    assert!(!i.spos.contains(Spos::HALT));
    // HALT back to 1 alone does not continue: SPOS.HALT stays 0 until START.
    let i = rig.rec(0x03, 0x01, 1);
    assert!(rig.transitions().is_empty());
    assert!(!i.spos.contains(Spos::HALT));
    let i = rig.rec(0x03, 0x03, 1);
    assert_eq!(rig.transitions(), [Transition::TA4]);
    assert_eq!(rig.motions(), [MotionCommand::Continue]);
    assert_eq!(rig.fhpp.op_state(), OpState::TaskActive);
    assert!(i.spos.contains(Spos::HALT | Spos::ACK));
    rig.moving();
    rig.again();
    rig.settled();
    let i = rig.rec(0x03, 0x01, 1);
    assert_eq!(rig.transitions(), [Transition::TA2]);
    assert_eq!(i.spos.0 & 0x07, 0x05);
}

/// FHPP-ST-11: TA6, SA3 with CPOS 00h → 40h (CLEAR rising) → SA1, remaining path deleted, MC = 1.
#[test]
fn fhpp_st_11_ta6_clear() {
    let mut rig = Rig::record_running(1);
    rig.rec(0x03, 0x02, 1);
    rig.settled();
    rig.rec(0x03, 0x00, 1);
    let i = rig.rec(0x03, 0x40, 1);
    assert_eq!(rig.transitions(), [Transition::TA6]);
    assert_eq!(rig.motions(), [MotionCommand::Clear]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    assert!(i.spos.contains(Spos::MC));
    // START with CLEAR held does not continue (TA4 needs CLEAR = 0). CLEAR rises in SA2, where
    // it means nothing, and is held through the halt.
    let mut rig = Rig::record_running(1);
    rig.rec(0x03, 0x43, 1);
    assert!(rig.transitions().is_empty());
    rig.rec(0x03, 0x42, 1);
    assert_eq!(rig.transitions(), [Transition::TA3]);
    rig.settled();
    rig.rec(0x03, 0x40, 1);
    rig.rec(0x03, 0x41, 1);
    rig.rec(0x03, 0x43, 1);
    assert!(rig.transitions().is_empty());
    assert_eq!(rig.fhpp.op_state(), OpState::IntermediateStop);
}

/// FHPP-ST-12 (corrected: HOM rising): TA7, SA1 with CPOS 01h → 05h → SA4 homing, ACK = 1, MC = 0.
#[test]
fn fhpp_st_12_ta7() {
    let mut rig = Rig::enabled_referenced();
    let i = rig.rec(0x03, 0x05, 0);
    assert_eq!(rig.transitions(), [Transition::TA7]);
    assert_eq!(rig.fhpp.op_state(), OpState::Homing);
    assert_eq!(i.spos.0 & 0x06, 0x02);
}

/// FHPP-ST-13: TA8, SA4 with CPOS 05h → 04h (HALT falling) → homing aborted, SA1.
#[test]
fn fhpp_st_13_ta8_abort_by_halt() {
    let mut rig = Rig::enabled_referenced();
    rig.rec(0x03, 0x05, 0);
    rig.moving();
    rig.again();
    let i = rig.rec(0x03, 0x04, 0);
    assert_eq!(rig.transitions(), [Transition::TA8]);
    assert_eq!(rig.motions(), [MotionCommand::Halt]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    assert!(!i.spos.contains(Spos::MC));
    rig.status.moving = false;
    assert!(rig.again().spos.contains(Spos::MC));
}

/// FHPP-ST-14 (corrected pattern 0xx0.Pxx1), FHPP-ST-15: TA9 by JOGP rising (CPOS 01h → 09h), jog
/// level-controlled while held, TA10 by JOGP falling or HALT falling.
#[test]
fn fhpp_st_14_15_jog_positive() {
    let mut rig = Rig::enabled_referenced();
    let i = rig.rec(0x03, 0x09, 0);
    assert_eq!(rig.transitions(), [Transition::TA9]);
    assert_eq!(rig.motions(), [MotionCommand::Jog { positive: true }]);
    assert_eq!(rig.fhpp.op_state(), OpState::JogPositive);
    assert!(!i.spos.contains(Spos::MC));
    rig.moving();
    // Level-controlled: moves while the bit is 1.
    for _ in 0..3 {
        let i = rig.again();
        assert!(rig.events.is_empty());
        assert!(i.spos.contains(Spos::MOV) && !i.spos.contains(Spos::MC));
    }
    // TA10 by JOGP falling.
    rig.rec(0x03, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::TA10]);
    assert_eq!(rig.motions(), [MotionCommand::Halt]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    rig.settled();
    assert_eq!(rig.again().spos.0 & 0x07, 0x05);
    // TA10 by HALT falling; JOGP still held does not restart the jog.
    rig.rec(0x03, 0x09, 0);
    rig.rec(0x03, 0x08, 0);
    assert_eq!(rig.transitions(), [Transition::TA10]);
    rig.rec(0x03, 0x09, 0);
    assert!(rig.transitions().is_empty(), "JOGP held is no rising edge");
}

/// FHPP-ST-16, FHPP-ST-17: TA11 by JOGN rising (CPOS 01h → 11h), jog level-controlled while held,
/// TA12 by JOGN falling or HALT falling.
#[test]
fn fhpp_st_16_17_jog_negative() {
    let mut rig = Rig::enabled_referenced();
    rig.rec(0x03, 0x11, 0);
    assert_eq!(rig.transitions(), [Transition::TA11]);
    assert_eq!(rig.motions(), [MotionCommand::Jog { positive: false }]);
    assert_eq!(rig.fhpp.op_state(), OpState::JogNegative);
    rig.moving();
    // Level-controlled: moves while the bit is 1.
    for _ in 0..3 {
        let i = rig.again();
        assert!(rig.events.is_empty());
        assert!(i.spos.contains(Spos::MOV) && !i.spos.contains(Spos::MC));
        assert_eq!(rig.fhpp.op_state(), OpState::JogNegative);
    }
    // TA12 by JOGN falling.
    rig.rec(0x03, 0x01, 0);
    assert_eq!(rig.transitions(), [Transition::TA12]);
    assert_eq!(rig.motions(), [MotionCommand::Halt]);
    rig.settled();
    assert_eq!(rig.again().spos.0 & 0x07, 0x05);
    // TA12 by HALT falling; JOGN still held does not restart the jog.
    rig.rec(0x03, 0x11, 0);
    rig.rec(0x03, 0x10, 0);
    assert_eq!(rig.transitions(), [Transition::TA12]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);
    rig.rec(0x03, 0x11, 0);
    assert!(rig.transitions().is_empty(), "JOGN held is no rising edge");
}

/// FHPP-ST-18: TA5, direct mode, new set-point + START rising while a task runs → replaces it
/// subject to PNU 583.
#[test]
fn fhpp_st_18_ta5_direct_new_task() {
    for (condition, restarts) in [
        (StartBehaviour::Ignore, false),
        (StartBehaviour::Interrupt, true),
        (StartBehaviour::Wait, false),
    ] {
        let mut rig = Rig::direct_referenced();
        rig.fhpp.config_mut().start_condition = condition;
        rig.dir(0x43, 0x03, 0x00, 100, 10_000);
        rig.moving();
        rig.dir(0x43, 0x01, 0x00, 100, 10_000);
        let i = rig.dir(0x43, 0x03, 0x00, 100, 20_000);
        let new = MotionCommand::MoveAbsolute {
            target: 20_000,
            velocity: BASE_VELOCITY,
            velocity_percent: 100,
        };
        if restarts {
            assert_eq!(rig.transitions(), [Transition::TA5], "{condition:?}");
            assert_eq!(rig.motions(), [new]);
        } else {
            assert!(rig.events.is_empty(), "{condition:?}");
        }
        assert_eq!(
            i.spos.contains(Spos::ACK),
            condition != StartBehaviour::Ignore,
            "{condition:?}"
        );
        assert!(!i.spos.contains(Spos::MC));
        // MC of the first task.
        rig.dir(0x43, 0x01, 0x00, 100, 20_000);
        rig.settled();
        rig.again();
        if condition == StartBehaviour::Wait {
            // "Wait": the new task starts after MC, with the set-points taken at its START.
            assert_eq!(rig.transitions(), [Transition::TA5]);
            assert_eq!(rig.motions(), [new]);
            let spos = rig.fhpp.inputs().spos;
            assert!(!spos.contains(Spos::MC));
            assert!(
                !spos.contains(Spos::ACK),
                "acknowledged when queued, START is 0 by now"
            );
        } else {
            assert_eq!(rig.transitions(), [Transition::TA2], "{condition:?}");
        }
    }
}

/// FHPP-ST-19: SA1, CCON 03h → 43h → SCON 53h (direct mode); not while a task runs.
#[test]
fn fhpp_st_19_operating_mode_change() {
    let mut rig = Rig::enabled_referenced();
    let i = rig.dir(0x43, 0x01, 0, 0, 0);
    assert_eq!(i.scon.0, 0x53);
    assert_eq!(rig.fhpp.operating_mode(), OperatingMode::Direct);
    // Back to record selection in SA1.
    assert_eq!(rig.rec(0x03, 0x01, 0).scon.0, 0x13);
    // Not while a task runs: the feedback keeps OPM = 00.
    let mut rig = Rig::record_running(1);
    let i = rig.dir(0x43, 0x03, 0, 0, 0);
    assert_eq!(i.scon.0, 0x13);
    assert_eq!(rig.fhpp.operating_mode(), OperatingMode::RecordSelection);
    // Reserved modes 10 / 11 are not accepted.
    let mut rig = Rig::enabled_referenced();
    assert_eq!(rig.rec(0x83, 0x01, 0).scon.0, 0x13);
    assert_eq!(rig.rec(0xC3, 0x01, 0).scon.0, 0x13);
}

// ---------------------------------------------------------------------------------------------
// Sequences and handshakes

#[test]
fn enable_sequence_step_by_step() {
    let mut rig = Rig::new();
    let steps: [(u8, u8, u8, u8, &[Transition]); 5] = [
        (0x00, 0x00, 0x10, 0x04, &[Transition::T1]),
        (0x20, 0x00, 0x10, 0x04, &[]),
        (0x21, 0x00, 0x11, 0x04, &[Transition::T2]),
        (0x23, 0x00, 0x13, 0x04, &[Transition::T3]),
        (0x23, 0x01, 0x13, 0x05, &[]),
    ];
    for (ccon, cpos, scon, spos, transitions) in steps {
        let i = rig.rec(ccon, cpos, 0);
        assert_eq!(
            (i.scon.0, i.spos.0),
            (scon, spos),
            "CCON {ccon:02X} CPOS {cpos:02X}: {}",
            show(&i)
        );
        assert_eq!(rig.transitions(), transitions);
    }
    assert_eq!(rig.fhpp.state(), State::OperationEnabled);
    assert_eq!(rig.fhpp.state().number(), 4);
    assert_eq!(rig.fhpp.op_state().number(), 1);
}

#[test]
fn enable_needs_load_voltage_and_safety() {
    let mut rig = Rig::new();
    rig.fhpp.set_load_voltage(false);
    let i = rig.rec(0x03, 0x01, 0);
    assert_eq!(i.scon.0, 0x00);
    assert_eq!(rig.fhpp.state(), State::DriveBlocked);
    rig.fhpp.set_load_voltage(true);
    rig.fhpp.set_safety_ok(false);
    assert_eq!(rig.again().scon.0, 0x10);
    rig.fhpp.set_safety_ok(true);
    // ENABLE and STOP are levels: held, they enable as soon as the conditions hold.
    assert_eq!(rig.again().scon.0, 0x13);
}

/// FHPP-MB-03: the direct-mode handshake behind the FC 17h cycles (SPOS 83h, then MOV, then MC).
#[test]
fn direct_mode_move_handshake_fhpp_mb_03() {
    let mut rig = Rig::new();
    rig.status.referenced = true;
    rig.status.motion_complete = true;
    // Cycle 1: CCON 43h, CPOS 01h, absolute, 100 %, 10000 SINC.
    let i = rig.dir(0x43, 0x01, 0x00, 0x64, 10_000);
    assert_eq!((i.scon.0, i.spos.0), (0x53, 0x85));
    // Cycle 2: START: SCON 53h, SPOS 83h = REF + ACK + HALT.
    let i = rig.dir(0x43, 0x03, 0x00, 0x64, 10_000);
    assert_eq!((i.scon.0, i.spos.0), (0x53, 0x83), "{}", show(&i));
    assert_eq!(
        rig.motions(),
        [MotionCommand::MoveAbsolute {
            target: 10_000,
            velocity: BASE_VELOCITY,
            velocity_percent: 100
        }]
    );
    // Moving: SPOS 93h.
    rig.moving();
    assert_eq!(rig.again().spos.0, 0x93);
    // START back to 0, target reached: SPOS & 07h = 05h.
    rig.dir(0x43, 0x01, 0x00, 0x64, 10_000);
    rig.settled();
    rig.status.actual_position = 10_000;
    let i = rig.again();
    assert_eq!(i.spos.0 & 0x07, 0x05);
    assert_eq!(
        i.to_bytes(),
        [0x53, 0x85, 0x00, 0x00, 0x00, 0x00, 0x27, 0x10]
    );
}

#[test]
fn direct_velocity_and_force_modes() {
    // Velocity mode: byte 4 = ramp % of PNU 560, bytes 5…8 signed SINC/s, ABS ignored.
    let mut rig = Rig::direct_referenced();
    rig.dir(0x43, 0x03, 0x05, 10, -30_000);
    assert_eq!(
        rig.motions(),
        [MotionCommand::Velocity {
            velocity: -30_000,
            ramp: BASE_ACCELERATION / 10,
            ramp_percent: 10,
            stroke_monitoring: true
        }]
    );
    rig.moving();
    rig.status.actual_velocity = -30_000;
    let i = rig.again();
    assert_eq!(i.sdir().control_mode(), Some(ControlMode::Velocity));
    assert_eq!(
        (i.actual1(), i.actual2),
        (0, 30_000),
        "actual value 2 = |velocity|"
    );
    // Speed reached: MC = 1, but the task keeps running in SA2 until HALT.
    rig.status.motion_complete = true;
    let i = rig.again();
    assert!(i.spos.contains(Spos::MC | Spos::MOV));
    assert_eq!(rig.fhpp.op_state(), OpState::TaskActive);
    rig.dir(0x43, 0x00, 0x05, 10, -30_000);
    assert_eq!(rig.transitions(), [Transition::TA3]);
    assert_eq!(rig.fhpp.op_state(), OpState::Ready);

    // Force mode: byte 4 = velocity limit % of PNU 540, bytes 5…8 ‰ of PNU 555; XLIM = 1 turns
    // stroke monitoring off; actual value 1 = torque %, 2 = position (PNU 523:7/8 factory).
    let mut rig = Rig::direct_referenced();
    rig.dir(0x43, 0x03, 0x22, 20, 500);
    assert_eq!(
        rig.motions(),
        [MotionCommand::Force {
            setpoint: 500,
            velocity_limit: BASE_VELOCITY / 5,
            velocity_percent: 20,
            stroke_monitoring: false
        }]
    );
    rig.status.actual_force = 480;
    rig.status.actual_position = 777;
    rig.status.stroke_limit = true;
    let i = rig.again();
    assert_eq!(i.sdir(), Sdir::COM1 | Sdir::XLIM);
    assert_eq!((i.actual1(), i.actual2), (48, 777));
    // CDIR.COM = 11 is refused.
    let mut rig = Rig::direct_referenced();
    rig.dir(0x43, 0x03, 0x06, 20, 500);
    assert_eq!(rig.events, [Event::Refused(Refusal::InvalidControlMode)]);
}

#[test]
fn direct_relative_to_last_setpoint() {
    let mut rig = Rig::direct_referenced();
    rig.fhpp.config_mut().relative_to_actual = false;
    rig.dir(0x43, 0x03, 0x01, 100, -250);
    assert_eq!(
        rig.motions(),
        [MotionCommand::MoveRelative {
            distance: -250,
            velocity: BASE_VELOCITY,
            velocity_percent: 100,
            reference: RelativeTo::LastSetpoint
        }]
    );
}

#[test]
fn record_start_behaviour_rcb3() {
    // RCB3 = 01 (interrupt) on the running record: a new START switches at once.
    let mut rig = Rig::enabled_referenced();
    rig.records.get_mut(1).unwrap().rcb3 = 0x01;
    rig.rec(0x03, 0x03, 1);
    rig.moving();
    rig.rec(0x03, 0x01, 1);
    let i = rig.rec(0x03, 0x03, 2);
    assert_eq!(rig.transitions(), [Transition::TA5]);
    assert_eq!(
        rig.motions(),
        [MotionCommand::Record {
            number: 2,
            mode: ControlMode::Position
        }]
    );
    assert_eq!(i.record_number(), 2);
    // RCB3 = 00 (ignore, the default).
    let mut rig = Rig::record_running(1);
    rig.rec(0x03, 0x01, 1);
    rig.rec(0x03, 0x03, 2);
    assert!(rig.events.is_empty());
    assert_eq!(rig.fhpp.inputs().record_number(), 1);
}

#[test]
fn held_bits_are_not_edges() {
    // START held from before the enable does not start anything.
    let mut rig = Rig::new();
    rig.status.referenced = true;
    rig.rec(0x00, 0x03, 1);
    let i = rig.rec(0x03, 0x03, 1);
    assert_eq!(rig.transitions(), [Transition::T2, Transition::T3]);
    assert_eq!(i.spos.0 & 0x07, 0x05);
    // HOM held likewise; only a new rising edge starts.
    rig.rec(0x03, 0x07, 1);
    assert_eq!(rig.transitions(), [Transition::TA7]);
    // START held through a completed task does not restart it.
    let mut rig = Rig::record_running(1);
    rig.settled();
    rig.again();
    assert_eq!(rig.transitions(), [Transition::TA2]);
    rig.moving();
    rig.status.motion_complete = false;
    for _ in 0..3 {
        rig.again();
        assert!(rig.events.is_empty());
    }
    assert!(
        rig.fhpp.inputs().spos.contains(Spos::ACK),
        "ACK stays while START is held"
    );
    // RESET held across a new fault does not acknowledge it.
    let mut rig = in_s6(minor(0x2F));
    rig.rec(0x0B, 0x01, 0);
    assert_eq!(rig.fhpp.state(), State::OperationEnabled);
    rig.fhpp.raise_fault(minor(0x2F));
    rig.again();
    assert_eq!(rig.fhpp.state(), State::Fault);
    rig.again();
    assert_eq!(rig.fhpp.state(), State::Fault);
    // Jog and homing have priority over START (Tab. 6.6).
    let mut rig = Rig::enabled_referenced();
    rig.rec(0x03, 0x07, 1);
    assert_eq!(rig.transitions(), [Transition::TA7]);
    let mut rig = Rig::enabled_referenced();
    rig.rec(0x03, 0x0B, 1);
    assert_eq!(rig.transitions(), [Transition::TA9]);
    // Starts need HALT = 1.
    let mut rig = Rig::enabled_referenced();
    rig.rec(0x03, 0x00, 1);
    rig.rec(0x03, 0x02, 1);
    rig.rec(0x03, 0x04, 1);
    rig.rec(0x03, 0x08, 1);
    assert!(rig.events.is_empty());
    // Reserved bits are ignored.
    let mut rig = Rig::enabled_referenced();
    assert_eq!(rig.rec(0x13, 0x81, 0).scon.0, 0x13);
}

#[test]
fn fault_priority_and_reactions() {
    // A serious fault overrides a minor one (T7 from S5/S6).
    let mut rig = in_s6(minor(0x2F));
    rig.fhpp.raise_fault(serious(0x1A));
    rig.again();
    assert_eq!(rig.transitions(), [Transition::T7, Transition::T8]);
    assert_eq!(rig.fhpp.fault().map(|f| f.code), Some(0x1A));
    // A minor one does not replace a serious one.
    rig.fhpp.raise_fault(minor(0x2F));
    rig.again();
    assert!(rig.transitions().is_empty());
    assert_eq!(rig.fhpp.fault().map(|f| f.code), Some(0x1A));

    // Reaction A: free-wheeling, stage off at once.
    let mut rig = Rig::record_running(1);
    rig.fhpp.raise_fault(Fault {
        code: 0x0D,
        reaction: Reaction::A,
        ack: Ack::NotAckable,
    });
    let i = rig.again();
    assert_eq!(rig.motions(), [MotionCommand::Disable]);
    assert!(!i.scon.contains(Scon::ENABLED) && i.scon.contains(Scon::FAULT));
    assert_eq!(rig.fhpp.state(), State::FaultReaction);

    // Reaction B: Quick-Stop ramp, then stage off (T8).
    let mut rig = Rig::record_running(1);
    rig.fhpp.raise_fault(serious(0x1A));
    rig.again();
    assert_eq!(rig.motions(), [MotionCommand::QuickStop]);
    rig.settled();
    rig.again();
    assert_eq!(rig.transitions(), [Transition::T8]);
    assert_eq!(rig.motions(), [MotionCommand::Disable]);

    // Reaction G: the record is finished first.
    let mut rig = Rig::record_running(1);
    rig.fhpp.raise_fault(Fault {
        code: 0x27,
        reaction: Reaction::G,
        ack: Ack::Immediately,
    });
    rig.again();
    assert!(rig.motions().is_empty());
    assert_eq!(rig.fhpp.state(), State::FaultReaction);
    rig.settled();
    rig.again();
    assert_eq!(rig.transitions(), [Transition::T8]);
    assert!(rig.fhpp.output_stage_on());

    // T7 in S2: nothing moves, S6 at once.
    let mut rig = Rig::new();
    rig.rec(0x00, 0x00, 0);
    rig.fhpp.raise_fault(minor(0x22));
    let i = rig.again();
    assert_eq!(rig.transitions(), [Transition::T7, Transition::T8]);
    assert_eq!((i.scon.0, i.spos.0), (0x18, 0x04));
    // An acknowledge with ENABLE = 1 of a fault raised while disabled: T10, then T2 and T3.
    let i = rig.rec(0x0B, 0x01, 0);
    assert_eq!(
        rig.transitions(),
        [Transition::T10, Transition::T2, Transition::T3]
    );
    assert_eq!(i.scon.0, 0x13);
}

#[test]
fn control_authority() {
    let mut rig = Rig::new();
    rig.rec(0x00, 0x00, 0);
    assert_eq!(rig.fhpp.control_logic(), 1);
    // FCT takes control: SCON.FCT/MMI = 1, the PLC cannot enable.
    rig.fhpp.request_local_control(Authority::Fct).unwrap();
    let i = rig.rec(0x03, 0x01, 0);
    assert_eq!(i.scon.0, 0x30);
    assert_eq!(rig.fhpp.state(), State::DriveBlocked);
    assert_eq!(rig.fhpp.control_logic(), 0);
    // PNU 125 := 1 cannot take control away from FCT: error 17.
    assert_eq!(
        rig.fhpp.write_control_logic(1),
        Err(AuthorityError::FctHasControl)
    );
    assert_eq!(AuthorityError::FctHasControl.fpc_error(), 0x11);
    assert_eq!(
        rig.fhpp.write_control_logic(0),
        Err(AuthorityError::InvalidValue)
    );
    // FCT gives it back: ENABLE and STOP are levels and act at once; the START the PLC set while
    // FCT had control is no edge.
    rig.rec(0x03, 0x03, 0);
    rig.fhpp.release_local_control();
    let i = rig.rec(0x03, 0x03, 0);
    assert_eq!(i.scon.0, 0x13);
    assert_eq!(rig.transitions(), [Transition::T2, Transition::T3]);
    // The web server: PNU 125 := 1 takes control back.
    rig.fhpp
        .request_local_control(Authority::WebServer)
        .unwrap();
    assert!(rig.again().scon.contains(Scon::FCT_MMI));
    assert_eq!(rig.fhpp.write_control_logic(1), Ok(()));
    assert!(!rig.again().scon.contains(Scon::FCT_MMI));
    // LOCK also keeps the web server out.
    rig.rec(0x23, 0x01, 0);
    assert_eq!(
        rig.fhpp.request_local_control(Authority::WebServer),
        Err(AuthorityError::Locked)
    );
}

#[test]
fn teach_handshake() {
    let mut rig = Rig::enabled_referenced();
    rig.status.actual_position = 4242;
    // TEACH = 1: SPOS.TEACH = 0 (ready).
    let i = rig.rec(0x03, 0x21, 9);
    assert!(!i.spos.contains(Spos::TEACH));
    assert!(rig.events.is_empty());
    // Falling edge: value taken into record 9 (byte 3 in record selection), SPOS.TEACH = 1.
    let i = rig.rec(0x03, 0x01, 9);
    assert_eq!(
        rig.events,
        [Event::Teach {
            record: 9,
            position: 4242
        }]
    );
    assert!(i.spos.contains(Spos::TEACH));
    // Next teach: ready again on TEACH = 1.
    assert!(!rig.rec(0x03, 0x21, 9).spos.contains(Spos::TEACH));
    // Direct mode: the record comes from PNU 400:1.
    let mut rig = Rig::direct_referenced();
    rig.fhpp.config_mut().teach_record = 12;
    rig.status.actual_position = -5;
    rig.dir(0x43, 0x21, 0, 0, 0);
    rig.dir(0x43, 0x01, 0, 0, 0);
    assert_eq!(
        rig.events,
        [Event::Teach {
            record: 12,
            position: -5
        }]
    );
}

#[test]
fn manual_brake_only_while_disabled() {
    let mut rig = Rig::new();
    rig.rec(0x04, 0x00, 0);
    assert_eq!(rig.motions(), [MotionCommand::ManualBrake { open: true }]);
    rig.rec(0x05, 0x00, 0);
    assert_eq!(
        rig.motions(),
        [
            MotionCommand::Enable,
            MotionCommand::ManualBrake { open: false }
        ]
    );
    rig.rec(0x04, 0x00, 0);
    assert_eq!(
        rig.motions(),
        [
            MotionCommand::Disable,
            MotionCommand::ManualBrake { open: true }
        ]
    );
    rig.rec(0x00, 0x00, 0);
    assert_eq!(rig.motions(), [MotionCommand::ManualBrake { open: false }]);
}

#[test]
fn record_table_data() {
    let mut t = RecordTable::new(cmmo_st_records());
    assert!(t.get(0).is_none() && t.get(65).is_none());
    assert!(t.get(1).is_some() && t.get(64).is_some());
    assert_eq!(t.iter().count(), 64);
    let r = t.get_mut(64).unwrap();
    r.rcb1 = Rcb1::ABS | Rcb1::REL;
    r.rcb2 = 20;
    r.rcb3 = 2;
    r.following_record = 3;
    assert_eq!(r.control_mode(), Some(ControlMode::Position));
    assert_eq!(
        r.chain_condition(),
        Some(ChainCondition::PositionComparator)
    );
    assert_eq!(r.start_behaviour(), Some(StartBehaviour::Wait));
    assert!(r.is_valid());
    r.rcb2 = 0x81; // bit 7 reserved
    assert!(!r.is_valid());
    for (v, c) in [
        (0, ChainCondition::None),
        (1, ChainCondition::MotionComplete),
        (20, ChainCondition::PositionComparator),
        (21, ChainCondition::VelocityComparator),
        (22, ChainCondition::ForceComparator),
        (23, ChainCondition::TimeComparator),
    ] {
        assert_eq!(ChainCondition::from_rcb2(v), Some(c));
        assert_eq!(c.rcb2(), v);
    }
    assert_eq!(ChainCondition::from_rcb2(2), None);
    assert_eq!(StartBehaviour::from_bits(3), None);
    assert_eq!((Rcb1::COM1 | Rcb1::COM2).control_mode(), None);
    assert_eq!(Rcb1::COM1.control_mode(), Some(ControlMode::Force));
    // FHPP-SC-02 comparator: −50 mm … −40 mm at 0.1 µm per SINC.
    let c = drive::vendors::festo_cmmo_st::fhpp::Comparator {
        min: -500_000,
        max: -400_000,
        window_time_ms: 0,
    };
    assert!(c.contains(-450_000) && !c.contains(-399_999) && !c.contains(-500_001));
    let never = drive::vendors::festo_cmmo_st::fhpp::Comparator {
        min: 1,
        max: 0,
        window_time_ms: 0,
    };
    assert!(!never.contains(0) && !never.contains(1));
    assert_eq!(Reaction::from_bit(0x20), Some(Reaction::F));
    assert_eq!(Reaction::E.bit(), 0x10);
}

// ---- record chaining (§6.5.3) --------------------------------------------------------------

/// The motion layer met record 1's switching condition and started record 2: byte 3 shows 2,
/// RSB.RC1 = 1, MC stays 0 (PNU 425 = 0); at record 2's MC, RCC = 1 (chain completed).
#[test]
fn record_chained_updates_feedback_rc1_and_rcc() {
    let mut rig = Rig::record_running(1);
    assert!(rig.fhpp.record_chained(2, ControlMode::Position, false));
    let i = rig.rec(0x03, 0x01, 1);
    assert_eq!(i.byte3, 2);
    assert_eq!(Rsb(i.byte4) & (Rsb::RC1 | Rsb::RCC), Rsb::RC1);
    assert!(!i.spos.contains(Spos::MC));
    rig.settled();
    let i = rig.again();
    assert!(i.spos.contains(Spos::MC));
    assert_eq!(rig.transitions(), [Transition::TA2]);
    assert_eq!(Rsb(i.byte4) & (Rsb::RC1 | Rsb::RCC), Rsb::RC1 | Rsb::RCC);
    assert_eq!(rig.fhpp.chain_status(), Rsb::RC1 | Rsb::RCC);
    // The next start clears both.
    rig.rec(0x03, 0x01, 3);
    let i = rig.rec(0x03, 0x03, 3);
    assert_eq!(Rsb(i.byte4) & (Rsb::RC1 | Rsb::RCC), Rsb::EMPTY);
}

/// PNU 425 = 1: MC is 1 in exactly one telegram at the switch, the task goes on (SA2).
#[test]
fn record_chained_with_mc_pulse_shows_mc_once() {
    let mut rig = Rig::record_running(1);
    assert!(rig.fhpp.record_chained(5, ControlMode::Velocity, true));
    let i = rig.rec(0x03, 0x01, 1);
    assert!(i.spos.contains(Spos::MC), "pulse");
    assert_eq!(rig.fhpp.op_state(), OpState::TaskActive);
    let i = rig.again();
    assert!(!i.spos.contains(Spos::MC));
}

/// No chaining outside a running record task (halted, direct mode, fault).
#[test]
fn record_chained_is_refused_without_a_running_record() {
    let mut rig = Rig::enabled_referenced();
    assert!(!rig.fhpp.record_chained(2, ControlMode::Position, false));
    let mut rig = Rig::direct_referenced();
    assert!(!rig.fhpp.record_chained(2, ControlMode::Position, false));
    rig.again();
    assert_eq!(rig.fhpp.chain_status(), Rsb::EMPTY);
}
