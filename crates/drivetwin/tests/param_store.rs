//! Stored parameter sets: round trip through the state directory, atomic replacement, and
//! clear errors for damaged files.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drivetwin::cell::param_store::ParamStore;
use drivetwin::cell::station::{Commissioning, Station};
use od::{ObjectAccess, Value};

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("drivetwin-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn drive(dir: &std::path::Path) -> Station {
    let store = ParamStore::new(dir, "testbench", 1);
    let hb = Commissioning {
        index: 0x1017,
        sub: 0,
        bytes: vec![0xE8, 0x03],
    };
    Station::new(&devices::TESTBENCH, 1, Some(store), vec![hb]).unwrap()
}

#[test]
fn saved_values_survive_a_restart_and_win_over_commissioning() {
    let dir = tmpdir("roundtrip");
    let mut d = drive(&dir);
    assert_eq!(d.od().get_unsigned(0x1017, 0), Some(1000), "commissioned");
    d.model.write(0x1017, 0, &[0xFA, 0x00]).unwrap();
    d.model.write(0x2001, 0, b"kept across restarts").unwrap();
    d.model.write(0x1010, 1, b"save").unwrap();
    d.poll(od::Instant::ZERO, &mut |_| {});
    let files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        files.len(),
        1,
        "one complete file, no temporary left: {files:?}"
    );

    let d2 = drive(&dir);
    assert_eq!(d2.od().get_unsigned(0x1017, 0), Some(250));
    let mut buf = [0u8; 64];
    let n = d2.model.read(0x2001, 0, &mut buf).unwrap();
    assert_eq!(&buf[..n], b"kept across restarts");
}

#[test]
fn a_save_interrupted_before_the_rename_leaves_the_old_set() {
    let dir = tmpdir("interrupted");
    let mut d = drive(&dir);
    d.model.write(0x2003, 0, &[7, 0]).unwrap();
    d.model.write(0x1010, 1, b"save").unwrap();
    d.poll(od::Instant::ZERO, &mut |_| {});
    // A kill between writing the temporary file and the rename leaves a half-written
    // temporary next to the complete set.
    std::fs::write(dir.join("testbench-node1.params.tmp"), "2003:00=0").unwrap();
    let d2 = drive(&dir);
    assert_eq!(d2.od().value(0x2003, 0), Some(Value::Signed(7)));
}

#[test]
fn a_damaged_file_is_a_clear_error() {
    let dir = tmpdir("damaged");
    std::fs::write(
        dir.join("testbench-node1.params"),
        "2003:00=07\nthis is not a line\n",
    )
    .unwrap();
    let store = ParamStore::new(&dir, "testbench", 1);
    let err = Station::new(&devices::TESTBENCH, 1, Some(store), vec![])
        .err()
        .expect("refused");
    let text = err.to_string();
    assert!(text.contains("testbench-node1.params:2"), "{text}");
}

#[test]
fn reset_application_reloads_the_stored_set_and_boots() {
    let dir = tmpdir("reset");
    let mut d = drive(&dir);
    let mut out = Vec::new();
    d.boot(od::Instant::ZERO, &mut |f| out.push(f));
    d.model.write(0x2003, 0, &[9, 0]).unwrap();
    d.model.write(0x1010, 1, b"save").unwrap();
    d.poll(od::Instant::ZERO, &mut |_| {});
    d.model.write(0x2003, 0, &[50, 0]).unwrap();
    out.clear();
    let nmt = canopen::CanFrame::new(0, &[0x81, 1]).unwrap();
    d.on_can_frame(od::Instant::ZERO, &nmt, &mut |f| out.push(f));
    assert_eq!(
        d.od().value(0x2003, 0),
        Some(Value::Signed(9)),
        "stored value back"
    );
    assert_eq!(out.len(), 1);
    assert_eq!(
        (out[0].id, out[0].payload()),
        (0x701, &[0u8][..]),
        "boot-up"
    );
}

/// A device's permanent memory (the CMMO-ST's parameter file) is kept byte for byte,
/// replaced whole, and removed when the device deletes it.
#[test]
fn a_permanent_memory_is_kept_replaced_and_removed() {
    let dir = tmpdir("memory");
    let store = ParamStore::new(&dir, "cmmo-st", 1);
    assert_eq!(store.load_memory().unwrap(), None, "nothing stored yet");
    store.save_memory(Some(&[1, 2, 3, 4])).unwrap();
    assert_eq!(store.load_memory().unwrap(), Some(vec![1, 2, 3, 4]));
    store.save_memory(Some(&[9; 100])).unwrap();
    assert_eq!(store.load_memory().unwrap(), Some(vec![9; 100]));
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "no temporary file left behind");
    store.save_memory(None).unwrap();
    assert_eq!(store.load_memory().unwrap(), None);
    store.save_memory(None).unwrap(); // deleting twice is no error
}

/// CMMP-NMT-06: `000: 81 01` on a CMMP-AS reloads every object from the saved set (not the
/// defaults, not the unsaved current value), sends boot-up `701: 00` and waits in
/// Pre-Operational. The save is carried out before its SDO answer, so a reset after it
/// never finds one still running.
#[test]
fn cmmp_reset_application_reloads_the_saved_set() {
    let dir = tmpdir("cmmp-reset");
    let store = ParamStore::new(&dir, "cmmp-as", 1);
    let mut d = Station::new(&devices::CMMP_AS, 1, Some(store), vec![]).unwrap();
    let mut out = Vec::new();
    let t0 = od::Instant::ZERO;
    d.boot(t0, &mut |f| out.push(f));
    let sdo = |d: &mut Station, data: [u8; 8]| {
        let mut out = Vec::new();
        d.on_can_frame(t0, &canopen::CanFrame::full(0x601, data), &mut |f| {
            out.push(f)
        });
        out
    };
    // 1017h := 100 ms, saved; then 1017h := 250 ms, not saved.
    sdo(&mut d, [0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0]);
    let r = sdo(&mut d, [0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65]);
    assert_eq!(r[0].data, [0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0]);
    sdo(&mut d, [0x2B, 0x17, 0x10, 0x00, 0xFA, 0x00, 0, 0]);
    d.on_can_frame(
        t0,
        &canopen::CanFrame::new(0, &[0x01, 0x01]).unwrap(),
        &mut |_| {},
    );
    assert_eq!(
        d.canopen.as_ref().expect("a CANopen node").nmt_state(),
        canopen::NmtState::Operational
    );
    out.clear();
    d.on_can_frame(
        t0,
        &canopen::CanFrame::new(0, &[0x81, 0x01]).unwrap(),
        &mut |f| out.push(f),
    );
    assert_eq!(
        d.od().get_unsigned(0x1017, 0),
        Some(100),
        "saved value back"
    );
    assert_eq!(out.len(), 1, "{out:?}");
    assert_eq!(
        (out[0].id, out[0].payload()),
        (0x701, &[0u8][..]),
        "boot-up"
    );
    assert_eq!(
        d.canopen.as_ref().expect("a CANopen node").nmt_state(),
        canopen::NmtState::PreOperational
    );
}

/// Nanotec NT-SDO-01 with a state directory: "load" writes the defaults to the stored set at
/// once (§11.25), so the next power-on starts from them; 2005h and 2009h keep their values.
#[test]
fn nanotec_restore_writes_the_stored_set() {
    let dir = tmpdir("nanotec-restore");
    let open = || {
        let store = ParamStore::new(&dir, "nanotec-smci47s", 1);
        Station::new(&devices::NANOTEC_SMCI47S, 1, Some(store), vec![]).unwrap()
    };
    let mut d = open();
    d.model.write(0x1017, 0, &[0xFA, 0x00]).unwrap();
    d.model.write(0x2005, 0, &[132]).unwrap();
    d.model.write(0x1010, 1, b"save").unwrap();
    d.poll(od::Instant::ZERO, &mut |_| {});
    assert_eq!(open().od().get_unsigned(0x1017, 0), Some(250), "saved");

    d.model.write(0x1011, 1, b"load").unwrap();
    d.poll(od::Instant::ZERO, &mut |_| {});
    let d2 = open();
    assert_eq!(
        d2.od().get_unsigned(0x1017, 0),
        Some(0),
        "defaults stored at once"
    );
    assert_eq!(d2.od().get_unsigned(0x2005, 0), Some(132), "2005h kept");
}

/// A drive on EtherCAT alone is a station without a CANopen node: it sends no frame (no
/// boot-up, no heartbeat though 1017h is set), ignores CAN frames, a local write goes to the
/// dictionary, and a save still writes its parameter file.
#[test]
fn a_station_without_a_canopen_node_sends_nothing_and_still_saves() {
    let dir = tmpdir("no-canopen");
    let mut d = drive(&dir).without_canopen();
    assert!(d.canopen.is_none());
    assert_eq!(d.node_id(), 1, "the dictionary's node-ID");
    let mut out = Vec::new();
    let t0 = od::Instant::ZERO;
    d.boot(t0, &mut |f| out.push(f));
    d.on_can_frame(
        t0,
        &canopen::CanFrame::full(0x601, [0x40, 0x17, 0x10, 0, 0, 0, 0, 0]),
        &mut |f| out.push(f),
    );
    let t = od::Instant::from_millis(2500);
    for ms in (0..=2500).step_by(10) {
        d.poll(od::Instant::from_millis(ms), &mut |f| out.push(f));
    }
    assert!(out.is_empty(), "no CANopen frame: {out:?}");
    d.local_access(t, &mut |f| out.push(f), &mut |od| {
        od.write(0x1017, 0, &[0xFA, 0x00]).expect("a local write");
        od.write(0x1010, 1, b"save").expect("save");
    });
    assert!(out.is_empty(), "no CANopen frame: {out:?}");
    assert_eq!(d.od().get_unsigned(0x1017, 0), Some(250));
    let again = drive(&dir);
    assert_eq!(again.od().get_unsigned(0x1017, 0), Some(250), "saved");
}

/// A runtime's saver writes a job's file with the station's own save: a job for the loop is
/// done when `start` returns (a drive whose CANopen node writes the same file), its result the
/// stored set read back; the values are those of the copy taken when the save was asked for,
/// not those written after.
#[test]
fn a_saver_writes_the_values_of_the_moment_the_save_was_asked_for() {
    use drivetwin::cell::param_saver::{ParamSaver, SaveJob};
    let dir = tmpdir("saver");
    let mut d = drive(&dir);
    d.model.write(0x1017, 0, &[0xFA, 0x00]).unwrap();
    let job = SaveJob::new(
        ParamStore::new(&dir, "testbench", 1),
        d.od().clone(),
        1,
        true,
    );
    d.model.write(0x1017, 0, &[0x2C, 0x01]).unwrap();
    let mut saver = ParamSaver::default();
    saver.start(7usize, job);
    let (key, result) = saver.finished().expect("done on the loop");
    assert_eq!(key, 7);
    let stored = result.unwrap();
    let hb = stored
        .iter()
        .find(|v| (v.index, v.sub) == (0x1017, 0))
        .expect("1017h stored");
    assert_eq!(
        hb.bytes,
        [0xFA, 0x00],
        "the value when the save was asked for"
    );
    assert!(saver.finished().is_none(), "each save is reported once");
    assert_eq!(drive(&dir).od().get_unsigned(0x1017, 0), Some(250));
}
