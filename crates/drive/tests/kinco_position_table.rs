//! The Kinco position table (manual §6.4.1) through the drive: Start PosTable, the task modes A /
//! RN / RA, NEXT with the delay, a Cond0 level waited for, Cur_Indexof_Table 3044h, the PosTable
//! Active output, the loop count and StartCond.

mod kinco_rig;

use drive::vendors::kinco::table::{PositionTable, Task};
use kinco_rig::Rig;

const START: i64 = 1 << 3; // DIN4: Start PosTable
const COND0: i64 = 1 << 4; // DIN5: PosTable Cond0
const NEXT: u16 = 0x0100;
const COND0_ON: u16 = 0x0200;
const RELATIVE_TARGET: u16 = 0x1000;
const RELATIVE_ACTUAL: u16 = 0x2000;

fn task(ctl: u16, position: i32, delay_ms: u32) -> Task {
    Task {
        ctl,
        position,
        speed_rpm: 600,
        delay_ms,
        acc: 0,
        dec: 0,
        loops: 0,
    }
}

/// Mode 1, DIN4 Start PosTable, DIN5 Cond0, OUT1 PosTable Active; `table` written.
fn rig(table: PositionTable) -> Rig {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x9004);
    r.w16(0x2010, 0x07, 0x9001);
    r.w16(0x2010, 0x0F, 0x9001);
    r.d.set_position_table(table);
    r.enable_in(1);
    r
}

fn run_until_idle(r: &mut Rig, ms: u64) -> bool {
    for _ in 0..ms / 5 {
        r.run_ms(5);
        if r.i(0x2010, 0x14) & 1 == 0 {
            return true;
        }
    }
    false
}

#[test]
fn flow_through_three_tasks() {
    let mut t = PositionTable::default();
    t.tasks[0] = task(NEXT | 1, 20_000, 100);
    t.tasks[1] = task(NEXT | COND0_ON | RELATIVE_TARGET | 2, 5_000, 0);
    t.tasks[2] = task(RELATIVE_ACTUAL, -30_000, 0);
    let mut r = rig(t);
    assert_eq!(r.i(0x2010, 0x14) & 1, 0, "not active");
    r.w16(0x2010, 0x02, START);
    r.run_ms(10);
    assert_eq!(r.i(0x2010, 0x14) & 1, 1, "PosTable Active");
    assert_eq!(r.i(0x3044, 0), 0);
    // Task 0: 20 000 increments at 600 rpm (100 000 inc/s) with 6000 rpm/s ramps take
    // 0.3 s; then the 100 ms delay.
    r.run_ms(340);
    assert!(
        (r.position() - 20_000).abs() <= 20,
        "task 0: {}",
        r.position()
    );
    r.run_ms(600);
    assert_eq!(r.i(0x3044, 0), 1);
    assert!(
        (r.position() - 25_000).abs() <= 20,
        "task 1 (RN): {}",
        r.position()
    );
    r.run_ms(500);
    assert!((r.position() - 25_000).abs() <= 20, "waits for Cond0");
    assert_eq!(r.i(0x2010, 0x14) & 1, 1, "still active");
    r.w16(0x2010, 0x02, START | COND0);
    assert!(
        run_until_idle(&mut r, 3000),
        "the flow ends after task 2 (STOP)"
    );
    assert_eq!(r.i(0x3044, 0), 2);
    assert!(
        (r.position() + 5_000).abs() <= 20,
        "task 2 (RA): {}",
        r.position()
    );
}

/// Loops: tasks 3 ↔ 4 with Loops = 2 on task 3 run 3, 4, 3 and stop there: "the flow stops
/// when the loop count = Loops".
#[test]
fn loop_count_ends_the_flow() {
    let mut t = PositionTable::default();
    t.tasks[3] = Task {
        loops: 2,
        ..task(NEXT | 4, 10_000, 0)
    };
    t.tasks[4] = task(NEXT | 3, 0, 0);
    let mut r = rig(t);
    // Start index = BCD of PosTable Idx0..2: Idx0 and Idx1 on DIN6 / DIN7, both active = 3.
    r.w16(0x2010, 0x08, 0x9008);
    r.w16(0x2010, 0x09, 0x9010);
    r.w16(0x2010, 0x02, (1 << 5) | (1 << 6));
    r.run_ms(5);
    r.w16(0x2010, 0x02, START | (1 << 5) | (1 << 6));
    let mut visits = Vec::new();
    for _ in 0..1000 {
        r.run_ms(5);
        let i = r.i(0x3044, 0);
        if visits.last() != Some(&i) {
            visits.push(i);
        }
        if r.i(0x2010, 0x14) & 1 == 0 {
            break;
        }
    }
    assert_eq!(visits, vec![3, 4, 3]);
    assert!((r.position() - 10_000).abs() <= 20, "{}", r.position());
}

/// StartCond 2 (abort): a start during a task aborts it and runs the new one at once;
/// StartCond 0 (ignore): the start is ignored.
#[test]
fn start_condition_abort_and_ignore() {
    for (cond, want) in [(2u16, -10_000i64), (0, 100_000)] {
        let mut t = PositionTable::default();
        t.tasks[0] = task(cond << 14, 100_000, 0);
        let mut r = rig(t);
        r.w16(0x2010, 0x02, START);
        r.run_ms(100);
        t.tasks[0] = task(cond << 14, -10_000, 0);
        r.d.set_position_table(t);
        r.w16(0x2010, 0x02, 0);
        r.run_ms(5);
        r.w16(0x2010, 0x02, START);
        assert!(run_until_idle(&mut r, 5000));
        assert!(
            (r.position() - want).abs() <= 20,
            "StartCond {cond}: {}",
            r.position()
        );
    }
}
