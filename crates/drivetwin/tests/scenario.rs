//! The example scenarios on the virtual clock. Each runs twice: the reports and the traces are
//! equal bit for bit; the passing one passes (a limit switch and a broken cable leading to the
//! drive's fault and the EMCYs), the one meant to fail fails with a report that names the
//! expectation.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::PathBuf;

use drivetwin::scenario::runner;
use drivetwin::scenario::virtual_rig::VirtualRig;
use drivetwin::scenario::{Report, Scenario};

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/scenarios")
        .join(name)
}

/// Runs the example once; its report and its trace's bytes.
fn run(name: &str, run: u32) -> (Report, Vec<u8>) {
    let s = Scenario::load(&example(name)).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let trace =
        std::env::temp_dir().join(format!("scenario-{}-{name}-{run}.pcap", std::process::id()));
    rig.trace_to(&trace).expect("trace");
    let report = runner::run(&s, &mut rig);
    rig.finish().expect("trace written");
    let bytes = std::fs::read(&trace).expect("trace");
    let _ = std::fs::remove_file(&trace);
    (report, bytes)
}

#[test]
fn the_examples_give_the_same_report_and_trace_twice() {
    for name in [
        "limit_switch.toml",
        "must_fail.toml",
        "stopped_sync.toml",
        "diagnostic.toml",
        "plant_physics.toml",
        "two_buses.toml",
        "cmmo_st_modbus.toml",
    ] {
        let (a, trace_a) = run(name, 1);
        let (b, trace_b) = run(name, 2);
        assert_eq!(a.text(), b.text(), "{name}");
        assert_eq!(a, b, "{name}");
        assert!(trace_a.len() > 24, "{name}: frames traced");
        assert_eq!(trace_a, trace_b, "{name}: the traces are equal bit for bit");
    }
}

#[test]
fn a_limit_switch_and_a_broken_cable_lead_to_faults_and_emcys() {
    let (report, _) = run("limit_switch.toml", 0);
    assert!(report.passed, "{}", report.text());
    let names: Vec<&str> = report
        .expectations
        .iter()
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "the drive is enabled",
            "the limit switch faults the drive",
            "the drive reports the limit switch",
            "no heartbeat of node 1 while its cable is cut",
            "node 2 misses node 1's heartbeat",
            "node 1 beats again once the cable is whole",
        ]
    );
    let emcy = &report.expectations[4];
    assert!(
        emcy.detail.contains("082#3081"),
        "CiA 301 8130h: {}",
        emcy.detail
    );
}

/// A diagnostic message raised by its number in the timeline: the EMCY, the fault, the refused
/// reset while it stays raised, the acknowledgement once cleared.
#[test]
fn a_diagnostic_raised_by_number_faults_the_drive_until_cleared() {
    let (report, _) = run("diagnostic.toml", 0);
    assert!(report.passed, "{}", report.text());
    assert_eq!(report.expectations.len(), 5);
    let emcy = &report.expectations[1];
    assert!(
        emcy.detail.contains("081#1451"),
        "EMCY 5114h: {}",
        emcy.detail
    );
}

#[test]
fn a_stopped_sync_stops_the_sync_tpdo() {
    let (report, _) = run("stopped_sync.toml", 0);
    assert!(report.passed, "{}", report.text());
    assert_eq!(report.expectations.len(), 3);
}

#[test]
fn the_scenario_meant_to_fail_fails_naming_its_expectation() {
    let (report, _) = run("must_fail.toml", 0);
    assert!(!report.passed);
    let failed: Vec<&str> = report
        .expectations
        .iter()
        .filter(|o| !o.passed)
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(
        failed,
        ["the drive stays enabled with its limit switch closed"]
    );
    let text = report.text();
    assert!(text.starts_with("scenario a drive that ignores its limit switch (must fail): FAIL"));
    assert!(
        text.contains("FAIL  the drive stays enabled with its limit switch closed: not met from 0.350000s to 0.450000s; last seen 6041:00 = "),
        "{text}"
    );
}

#[test]
fn a_refused_action_fails_the_run() {
    let text = r#"
        [cell]
        [[cell.drive]]
        device = "cmmp-as"
        node = 1

        [[step]]
        at = "1ms"
        write = "1000:00"
        value = 1

        [[step]]
        at = "1ms"
        node = 9
        din = 3
    "#;
    let s = Scenario::parse(text, "refusals", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(!report.passed);
    assert_eq!(report.errors.len(), 2, "{}", report.text());
    assert!(
        report.errors[0].contains("1000:00 refused: SDO abort 0x06010002"),
        "{}",
        report.errors[0]
    );
    assert!(
        report.errors[1].contains("no node 9"),
        "{}",
        report.errors[1]
    );
}

/// `equals` below zero is compared in the object's width: 607Ah (INTEGER32) written -1000.
#[test]
fn a_negative_value_is_compared_in_the_objects_width() {
    let text = r#"
        [cell]
        [[cell.drive]]
        device = "cmmp-as"
        node = 1

        [[step]]
        at = "1ms"
        write = "607A:00"
        value = -1000

        [[step]]
        at = "1ms"
        expect = "607A:00"
        equals = -1000
        within = "1ms"
    "#;
    let s = Scenario::parse(text, "negative", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(report.passed, "{}", report.text());
    assert!(
        report.expectations[0]
            .detail
            .contains("607A:00 = 0xFFFFFC18"),
        "{}",
        report.text()
    );
}

/// The plant's physics in a timeline and in the cell file (`[cell.drive.thermal]`): a motor
/// heated by its current warns (18-0) and then faults (03-0, EMCY 4310h), a pulled encoder
/// cable is 08-0 (7380h), a limit switch actuated by name is found on its DIN (43-1, 8082h).
#[test]
fn the_plant_physics_raise_the_manuals_messages() {
    let (report, _) = run("plant_physics.toml", 0);
    assert!(report.passed, "{}", report.text());
    assert_eq!(report.expectations.len(), 7);
}

/// `[[drive.plant]]` in the cell file plans the same changes on the cell's clock; bad keys
/// are refused with the step's text.
#[test]
fn planned_plant_changes_in_the_cell_file() {
    let text = r#"
name = "planned encoder"
[cell]
[[cell.drive]]
device = "cmmp-as"
node = 1
[[cell.drive.plant]]
at_ms = 200
encoder = "disconnected"
[[cell.drive.diagnostic]]
at_ms = 100
number = "05-0"

[[step]]
at = "0s"
name = "the planned message"
expect_emcy = 0x5114
within = "150ms"

[[step]]
at = "150ms"
name = "the planned encoder fault"
expect_emcy = 0x7380
within = "100ms"
"#;
    let s = Scenario::parse(text, "planned", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(report.passed, "{}", report.text());
    let bad = text.replace("encoder = \"disconnected\"", "encoder = \"melted\"");
    let s = Scenario::parse(&bad, "bad", None).expect("scenario");
    let e = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("melted"), "{e}");
}

/// Two CAN buses on the virtual clock: a frame stays on its bus, a cable break on one bus
/// leaves the other alone, a node is found on its bus.
#[test]
fn two_buses_on_the_virtual_clock() {
    let (report, _) = run("two_buses.toml", 0);
    assert!(report.passed, "{}", report.text());
    assert_eq!(report.expectations.len(), 7);
}

/// A CMMO-ST on Modbus TCP beside a CMMP-AS on CAN on one virtual clock: the PLC's output
/// telegram and CCON.RESET sent as scripted Modbus requests, PNU 205 read as an expectation.
#[test]
fn a_cmmo_st_over_modbus_on_the_virtual_clock() {
    let (report, _) = run("cmmo_st_modbus.toml", 0);
    assert!(report.passed, "{}", report.text());
    assert_eq!(report.expectations.len(), 5);
}

/// The example conveyor FMU, built and packed from source (scripts/conveyor-fmu), where the
/// example cell file looks for it; once for all the tests of this binary.
fn conveyor_fmu() {
    static BUILT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let built = BUILT.get_or_init(|| {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
        std::process::Command::new(root.join("scripts/conveyor-fmu"))
            .current_dir(&root)
            .status()
            .is_ok_and(|s| s.success())
    });
    assert!(built, "scripts/conveyor-fmu");
}

#[test]
fn homing_on_the_conveyor_fmus_light_barrier_is_the_same_bit_for_bit_twice() {
    conveyor_fmu();
    let (a, trace_a) = run("conveyor_homing.toml", 1);
    let (b, trace_b) = run("conveyor_homing.toml", 2);
    assert!(a.passed, "{}", a.text());
    assert_eq!(a.text(), b.text());
    assert_eq!(a, b);
    assert_eq!(trace_a, trace_b, "the traces are equal bit for bit");
}

/// The same homing with the conveyor's FMI 2.0 build (the same model behind the FMI 2.0 C
/// functions): the same report and the same bus trace, bit for bit, as with the FMI 3.0 one.
#[test]
fn homing_with_the_fmi2_conveyor_is_the_same_as_with_the_fmi3_one() {
    conveyor_fmu();
    let (fmi3, trace3) = run("conveyor_homing.toml", 3);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let scenario = std::fs::read_to_string(example("conveyor_homing.toml")).expect("scenario");
    let cell = std::fs::read_to_string(root.join("examples/conveyor.toml")).expect("cell");
    let fmu2 = root.join("target/fmu/conveyor-fmi2.fmu");
    // The scenario's cell inline, its FMU the FMI 2.0 build; everything else as written.
    let cell = cell
        .replace("[[drive]]", "[[cell.drive]]")
        .replace("[drive.", "[cell.drive.")
        .replace(
            "\"../target/fmu/conveyor.fmu\"",
            &format!("{:?}", fmu2.display().to_string()),
        );
    let text = scenario.replace("cell = \"../conveyor.toml\"", "") + "\n[cell]\n" + &cell;
    let s = Scenario::parse(&text, "fmi2", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    assert_eq!(
        rig.load_fmi_version(1),
        Some("2.0"),
        "the FMI 2.0 build is coupled"
    );
    let trace = std::env::temp_dir().join(format!("scenario-{}-fmi2.pcap", std::process::id()));
    rig.trace_to(&trace).expect("trace");
    let fmi2 = runner::run(&s, &mut rig);
    rig.finish().expect("trace written");
    let trace2 = std::fs::read(&trace).expect("trace");
    let _ = std::fs::remove_file(&trace);
    assert!(fmi2.passed, "{}", fmi2.text());
    assert_eq!(fmi2.text(), fmi3.text());
    assert_eq!(trace2, trace3, "the traces are equal bit for bit");
}

#[test]
fn a_load_fmu_without_a_mapped_variable_is_refused_naming_it() {
    conveyor_fmu();
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fmu/conveyor.fmu");
    let text = format!(
        "name = \"missing\"\n[cell]\n[[cell.drive]]\ndevice = \"cmmp-as\"\n\
         [cell.drive.load]\nfmu = {:?}\nspeed = \"shaft_speed\"\nload_torque = \"belt_torque\"\n",
        fmu.display().to_string()
    );
    let s = Scenario::parse(&text, "missing", None).expect("scenario");
    let Err(e) = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    ) else {
        panic!("a load FMU without `belt_torque` was taken");
    };
    assert!(
        e.to_string()
            .contains("no variable `belt_torque` (mapped as `load_torque`)"),
        "{e}"
    );
}

#[test]
fn a_load_fmu_that_fails_stops_the_cell_with_its_error() {
    conveyor_fmu();
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fmu/conveyor.fmu");
    // A mass of -1 kg: the conveyor's doStep refuses it (and logs why).
    let text = format!(
        "name = \"failing load\"\nuntil = \"100ms\"\n[cell]\n[[cell.drive]]\ndevice = \"cmmp-as\"\n\
         [cell.drive.load]\nfmu = {:?}\nspeed = \"shaft_speed\"\nload_torque = \"load_torque\"\n\
         [cell.drive.load.parameters]\nmass = -1.0\n",
        fmu.display().to_string()
    );
    let s = Scenario::parse(&text, "failing", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(!report.passed);
    assert!(
        report
            .errors
            .iter()
            .any(|e| e.contains("the cell stopped") && e.contains("fmi3DoStep at t = 0 s")),
        "{}",
        report.text()
    );
}

/// A CMMO-ST (FHPP over Modbus) takes the conveyor as its load: its `home` switch is the
/// reference switch; a limit switch, which the CMMO-ST has no input for, is refused by name;
/// a failing load stops the cell with the FMU's error, as on a CiA 402 drive.
#[test]
fn a_cmmo_st_takes_a_load_fmu_and_refuses_a_limit_switch_by_name() {
    conveyor_fmu();
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fmu/conveyor.fmu");
    let cell = |switch: &str, mass: f64| {
        format!(
            "name = \"cmmo-st load\"\nuntil = \"300ms\"\n[cell]\n[[cell.drive]]\ndevice = \"cmmo-st\"\n\
             node = 30\n[cell.drive.load]\nfmu = {:?}\nangle = \"shaft_angle\"\nspeed = \"shaft_speed\"\n\
             load_torque = \"load_torque\"\n[cell.drive.load.switches]\n{switch} = \"light_barrier\"\n\
             [cell.drive.load.parameters]\nmass = {mass:?}\n\
             [[step]]\nat = \"10ms\"\nnode = 30\n\
             modbus_request = \"0001 0000 000F 01 10 0000 0004 08 03 09 00 00 00 00 00 00\"\n",
            fmu.display().to_string()
        )
    };
    let s = Scenario::parse(&cell("limit_positive", 0.5), "limit", None).expect("scenario");
    let e = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .err()
    .expect("refused");
    assert!(
        e.to_string()
            .contains("the CMMO-ST has no `limit_positive` input"),
        "{e}"
    );
    // Jogging positive (CCON ENABLE + STOP, CPOS HALT + JOGP) with the belt on the shaft.
    let s = Scenario::parse(&cell("home", 0.5), "home", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(report.passed, "{}", report.text());
    let p = rig.probe(30).expect("probe");
    assert!(p.position_rad > 0.0, "{p:?}");
    assert_eq!(p.status[0] & 0x03, 0x03, "SCON ENABLED and OPEN: {p:?}");
    let s = Scenario::parse(&cell("home", -1.0), "failing", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let report = runner::run(&s, &mut rig);
    assert!(
        report
            .errors
            .iter()
            .any(|e| e.contains("the cell stopped") && e.contains("node 30: load:")),
        "{}",
        report.text()
    );
}

/// A CMMO-ST's `[[drive.diagnostic]]` on the virtual clock: on the cell's one timeline with
/// the stations' plans, carried out by the rig at its time (SCON shows the message from
/// then on, not before).
#[test]
fn a_cmmo_sts_planned_message_on_the_virtual_clock() {
    use drive::vendors::festo_cmmo_st::fhpp::status_bytes::Scon;
    use drivetwin::scenario::runner::Rig;
    use drivetwin::scenario::virtual_rig::RigDrive;
    let file: drivetwin::cell::config::CellFile = toml::from_str(
        r#"
        [[drive]]
        device = "cmmo-st"
        node = 1
        [[drive.diagnostic]]
        at_ms = 50
        number = "2Fh"
        "#,
    )
    .expect("cell file");
    let mut rig = VirtualRig::new(&file, drivetwin::vendors::VENDORS.runtime).expect("rig");
    let scon = |rig: &VirtualRig| {
        let p = rig
            .probe_drive(RigDrive::RegisterImage(0))
            .expect("the CMMO-ST");
        Scon(p.status[0])
    };
    let shown = Scon::FAULT | Scon::WARN;
    rig.run_until(std::time::Duration::from_millis(49), &mut |_, _, _| {});
    assert!(
        !scon(&rig).intersects(shown),
        "before 50 ms: {}",
        scon(&rig)
    );
    rig.run_until(std::time::Duration::from_millis(60), &mut |_, _, _| {});
    assert!(scon(&rig).intersects(shown), "after 50 ms: {}", scon(&rig));
}

/// A drive read at the place the rig finds once (`VirtualRig::place`, what the cell FMU reads
/// its outputs at after each step) shows what it shows found by its node-ID and read through
/// its dictionary (`VirtualRig::probe`: 6041h, 6064h), for two vendors on two buses, at every
/// instant the scenario stops at while it enables both drives and turns them.
#[test]
fn a_drive_read_at_its_place_shows_what_its_dictionary_shows() {
    use drivetwin::scenario::file::Action;
    use drivetwin::scenario::runner::Rig;
    use drivetwin::scenario::virtual_rig::{Probe, RigDrive, RigPlace};
    use std::time::Duration;

    struct Compared<'a> {
        rig: &'a mut VirtualRig,
        places: Vec<(u8, RigPlace)>,
        /// Every drive's probes, read both ways, at each instant the run stopped at.
        seen: Vec<(u8, Probe)>,
    }
    impl Rig for Compared<'_> {
        fn run_until(
            &mut self,
            t: Duration,
            seen: &mut dyn FnMut(usize, Duration, &canopen::CanFrame),
        ) {
            self.rig.run_until(t, seen);
            for (node, place) in &self.places {
                let at_place = self.rig.probe_at(place).expect("a plant");
                let by_node = self.rig.probe(*node).expect("a plant");
                assert_eq!(at_place, by_node, "node {node} at {t:?}");
                // The words as a master's SDO upload reads them (`ObjectAccess::read`).
                let (statusword, _) = self.rig.read(Some(*node), 0x6041, 0).expect("6041h");
                assert_eq!(
                    u64::from(at_place.statusword),
                    statusword,
                    "node {node} at {t:?}"
                );
                // (a dictionary without 6064h, the Kinco's: 0)
                let position = self.rig.read(Some(*node), 0x6064, 0).map_or(0, |(v, _)| {
                    i32::from_le_bytes(u32::try_from(v).expect("4 bytes").to_le_bytes())
                });
                assert_eq!(at_place.position_actual, position, "node {node} at {t:?}");
                self.seen.push((*node, at_place));
            }
        }
        fn act(
            &mut self,
            action: &Action,
            seen: &mut dyn FnMut(usize, Duration, &canopen::CanFrame),
        ) -> Result<(), String> {
            self.rig.act(action, seen)
        }
        fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String> {
            self.rig.read(node, index, sub)
        }
    }

    let mut text = String::from(
        r#"
        name = "two drives enabled at speed"
        until = "600ms"
        [cell]
        [[cell.bus]]
        name = "a"
        channel = "vcan0"
        [[cell.bus]]
        name = "b"
        channel = "vcan1"
        [[cell.drive]]
        device = "cmmp-as"
        node = 1
        bus = "a"
        [[cell.drive]]
        device = "kinco-fd3"
        node = 2
        bus = "b"
        [[step]]
        at = "0s"
        nmt = "start"
        bus = 0
        [[step]]
        at = "0s"
        nmt = "start"
        bus = 1
        # The Kinco's controlword and mode to the bus (its factory inputs own them).
        [[step]]
        at = "2ms"
        node = 2
        bus = 1
        sdo_write = "2010:03"
        value = 0
        [[step]]
        at = "4ms"
        node = 2
        bus = 1
        sdo_write = "2010:05"
        value = 0
        "#,
    );
    for node in [1u32, 2] {
        for (ms, key, value) in [
            (10, "6060:00", 3),
            (20, "60FF:00", 2000),
            (40, "6040:00", 0x06),
            (60, "6040:00", 0x07),
            (80, "6040:00", 0x0F),
        ] {
            text.push_str(&format!(
                "[[step]]\nat = \"{}ms\"\nnode = {node}\nbus = {}\nsdo_write = \"{key}\"\nvalue = {value}\n",
                ms + node,
                node - 1
            ));
        }
    }
    for ms in (100..=600).step_by(25) {
        let node = 1 + ms / 25 % 2;
        text.push_str(&format!(
            "[[step]]\nat = \"{ms}ms\"\nnode = {node}\nload = 0.01\n"
        ));
    }
    let s = Scenario::parse(&text, "inline", None).expect("scenario");
    let mut rig = VirtualRig::new(
        s.cell.as_ref().expect("cell"),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("rig");
    let places = [1u8, 2]
        .iter()
        .map(|n| {
            (
                *n,
                rig.place(RigDrive::Node(*n)).expect("a node of the cell"),
            )
        })
        .collect();
    let mut compared = Compared {
        rig: &mut rig,
        places,
        seen: Vec::new(),
    };
    let report = runner::run(&s, &mut compared);
    assert!(report.passed, "{}", report.text());
    for node in [1u8, 2] {
        let probes: Vec<&Probe> = compared
            .seen
            .iter()
            .filter(|(n, _)| *n == node)
            .map(|(_, p)| p)
            .collect();
        assert!(probes.len() > 20, "node {node}: {} instants", probes.len());
        // The words change while the run goes: the comparison saw the drive enabled, not a
        // dictionary at its defaults.
        assert!(
            probes.iter().any(|p| p.statusword & 0x6F == 0x27),
            "node {node}: never operation enabled: {:?}",
            probes.last()
        );
    }
    // The CMMP-AS turns at its speed: its position actual value moves.
    let positions: Vec<i32> = compared
        .seen
        .iter()
        .filter(|(n, _)| *n == 1)
        .map(|(_, p)| p.position_actual)
        .collect();
    assert!(
        positions.windows(2).filter(|w| w[0] != w[1]).count() > 10,
        "node 1: the position actual value hardly moved: {positions:?}"
    );
}
