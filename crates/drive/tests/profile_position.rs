//! The profile-position set-point handshake (CMMP-AS §7.3 Fig. 7.4–7.6): single set-point,
//! change immediately, buffered next set-point, relative moves.

use drive::profile_position::{Job, Request, SetPoints};

fn job(target: f64) -> Job {
    Job {
        target,
        velocity: 1000.0,
        end_velocity: 0.0,
        acceleration: 1e4,
        deceleration: 1e4,
    }
}

fn req(target: f64, relative: bool, immediately: bool) -> Request {
    Request {
        target,
        relative,
        immediately,
        job: job(0.0),
    }
}

#[test]
fn single_set_point_handshake() {
    let mut sp = SetPoints::default();
    // [2] bit 4 rises → [3] accepted, bit 12 set.
    assert!(sp.update(true, 0.0, || req(1000.0, false, false)));
    assert!(sp.acknowledge);
    assert_eq!(sp.active.map(|j| j.target), Some(1000.0));
    // Bit 4 stays high: no second job, bit 12 stays.
    assert!(!sp.update(true, 0.0, || panic!("no new edge")));
    assert!(sp.acknowledge);
    // [5] bit 4 low → [6] bit 12 drops (buffer free).
    assert!(!sp.update(false, 0.0, || panic!()));
    assert!(!sp.acknowledge);
    sp.finished();
    assert_eq!(sp.active, None);
    assert_eq!(sp.last_target, Some(1000.0));
}

#[test]
fn buffered_next_set_point_starts_when_the_first_is_done() {
    let mut sp = SetPoints::default();
    sp.update(true, 0.0, || req(1000.0, false, false));
    sp.update(false, 0.0, || panic!());
    // Second job while the first runs: buffered, bit 12 stays set while the buffer is full.
    assert!(sp.update(true, 10.0, || req(2000.0, false, false)));
    sp.update(false, 10.0, || panic!());
    assert!(
        sp.acknowledge,
        "buffer full: the drive cannot take another job"
    );
    assert_eq!(sp.buffered.map(|j| j.target), Some(2000.0));
    // A third new_set_point now is ignored (the host must wait for bit 12 = 0).
    assert!(!sp.update(true, 20.0, || req(3000.0, false, false)));
    sp.update(false, 20.0, || panic!());
    sp.finished();
    assert_eq!(sp.active.map(|j| j.target), Some(2000.0));
    sp.update(false, 1000.0, || panic!());
    assert!(!sp.acknowledge, "the buffered job started: bit 12 drops");
}

#[test]
fn change_set_immediately_replaces_the_running_job() {
    let mut sp = SetPoints::default();
    sp.update(true, 0.0, || req(1000.0, false, false));
    sp.update(false, 0.0, || panic!());
    assert!(sp.update(true, 400.0, || req(-500.0, false, true)));
    assert_eq!(sp.active.map(|j| j.target), Some(-500.0));
    assert_eq!(sp.buffered, None);
}

#[test]
fn relative_moves_count_from_the_set_point() {
    let mut sp = SetPoints::default();
    // Nothing running: relative to the present demand position.
    sp.update(true, 250.0, || req(100.0, true, false));
    assert_eq!(sp.active.map(|j| j.target), Some(350.0));
    sp.update(false, 300.0, || panic!());
    // Buffered relative job: from the target of the job before it.
    sp.update(true, 300.0, || req(100.0, true, false));
    assert_eq!(sp.buffered.map(|j| j.target), Some(450.0));
}

#[test]
fn continuous_positioning_keeps_the_end_velocity_only_with_a_follower() {
    let mut sp = SetPoints::default();
    let r = Request {
        job: Job {
            end_velocity: 500.0,
            ..job(0.0)
        },
        ..req(1000.0, false, false)
    };
    sp.update(true, 0.0, || r);
    assert_eq!(sp.end_velocity(), 0.0, "no follower: stop at the target");
    sp.update(false, 0.0, || panic!());
    sp.update(true, 0.0, || req(2000.0, false, false));
    assert_eq!(sp.end_velocity(), 500.0);
}
