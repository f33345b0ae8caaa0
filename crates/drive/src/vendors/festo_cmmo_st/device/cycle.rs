// ---- the cycle
//!
//! # Decisions
//!
//! - **Record list.** Built from PNU 401…442 at construction and rebuilt at the next cycle
//!   after any write to one of those PNUs through [`ObjectAccess`] (so a record changed over
//!   the parameter channel is used by the next start, as the manual's record list is).

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// Runs every FHPP cycle due up to `now` (the first call starts the clock); returns when
    /// the next one is due.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        let cycle = if self.settings.cycle.is_zero() {
            Duration::from_millis(1)
        } else {
            self.settings.cycle
        };
        let mut next = self.next.unwrap_or(now);
        let mut n = 0;
        while next <= now {
            if n == 1000 {
                // More than a second behind (a stalled host): skip, do not spiral.
                next = now + cycle;
                break;
            }
            self.cycle(cycle.as_secs_f64());
            next = next + cycle;
            n += 1;
        }
        self.next = Some(next);
        self.next
    }

    pub(super) fn cycle(&mut self, dt: f64) {
        if self.params_dirty {
            self.refresh();
        }
        if self.records_dirty != 0 {
            self.rebuild_records();
        }
        let mut events: heapless::Vec<Event, 24> = heapless::Vec::new();
        let status = self.status;
        if let Some(next) = self.telegrams.pop() {
            self.applied = next;
        }
        let input = self.fhpp.cycle(&self.applied, &self.records, &status, |e| {
            let _ = events.push(e);
        });
        self.inputs = input.to_bytes();
        for e in events {
            match e {
                Event::Motion(m) => self.execute(m),
                Event::Refused(r) => self.raise_once(r.diagnostic()),
                Event::Teach { record, position } => self.teach(record, position),
                Event::Transition(_) => {}
            }
        }
        self.serve_parameter_channel();
        if let Task::Delayed {
            number,
            mode,
            until,
        } = self.task
        {
            if self.cycles >= until {
                self.begin_record(number, mode);
            }
        }
        self.advance(dt);
        self.measure_velocity(dt);
        self.supervise_plant(dt);
        self.compare();
        self.check_chain();
        self.cycles += 1;
        self.status = self.motion_status();
        self.diagnose();
        self.publish();
        if self.memory_dirty {
            self.mirror_memory();
        }
    }

    pub(super) fn refresh(&mut self) {
        self.params_dirty = false;
        let od = &self.od;
        let g = |pnu, sub| get_i64(od, pnu, sub);
        let pos = |v: i64| v.max(0) as f64;
        let ratio = |n: i64, d: i64| {
            if n > 0 && d > 0 {
                n as f64 / d as f64
            } else {
                1.0
            }
        };
        let enc = ratio(g(1001, 1), g(1001, 2));
        let gear = ratio(g(1002, 1), g(1002, 2));
        let axis = ratio(g(1005, 2), g(1005, 3));
        let feed = ratio(g(1003, 1), g(1003, 2));
        let old = self.params.einc_per_sinc;
        let einc_per_sinc = enc * gear * axis / feed;
        let acc = |v: i64| pos(v).max(1.0);
        self.params = Params {
            einc_per_sinc,
            polarity: if g(1000, 1) & 0x80 != 0 { -1.0 } else { 1.0 },
            project_zero: g(500, 1),
            az_offset: g(1010, 1),
            max_velocity: pos(g(502, 1)),
            jog_slow: pos(g(530, 1)),
            jog_fast: pos(g(531, 1)),
            jog_accel: acc(g(532, 1)),
            jog_time_ms: g(534, 1).max(0) as u64,
            jog_fe_window: pos(g(538, 1)),
            jog_fe_time_ms: g(539, 1).max(0) as u64,
            direct_accel: acc(g(541, 1)),
            direct_decel: acc(g(542, 1)),
            direct_fe_window: pos(g(549, 1)),
            velocity_target_window: pos(g(561, 1)),
            velocity_fe_window: pos(g(568, 1)),
            stroke_velocity: pos(g(566, 1)),
            target_window: pos(g(1022, 1)),
            target_window_ms: g(1023, 1).max(0) as u64,
            standstill_window: pos(g(1042, 1)),
            standstill_ms: g(1043, 1).max(0) as u64,
            fe_timeout_ms: g(1045, 1).max(0) as u64,
            quick_stop: acc(g(1029, 1)),
            homing_method: g(1011, 1),
            homing_accel: acc(g(1013, 1)),
            homing_search: pos(g(1012, 1)),
            homing_drive: pos(g(1012, 2)),
            homing_crawl: pos(g(1012, 3)),
            homing_torque: pos(g(1015, 1)),
            block_velocity: pos(g(1016, 1)),
            block_ms: g(1017, 1).max(0) as u64,
            base_acceleration: pos(g(560, 1)),
            base_force_ma: pos(g(555, 1)),
            force_stroke: pos(g(510, 1)),
            direct_comparators: Comparators::from_pnus(585, |pnu| g(pnu, 1)),
            force_window: pos(g(552, 1)),
            soft_lower: g(501, 1),
            soft_upper: g(501, 2),
            velocity_filter_s: pos(g(1024, 6)) * 1e-3,
        };
        let cfg = self.fhpp.config_mut();
        cfg.base_velocity = u32::try_from(g(540, 1).max(0)).unwrap_or(u32::MAX);
        cfg.base_acceleration = u32::try_from(g(560, 1).max(0)).unwrap_or(u32::MAX);
        cfg.start_condition =
            StartBehaviour::from_bits(g(583, 1) as u8).unwrap_or(StartBehaviour::Ignore);
        cfg.relative_to_actual = g(524, 1) & 1 != 0;
        cfg.teach_record = g(400, 1).clamp(0, 255) as u8;
        cfg.force_actual1_torque = g(523, 7) != 0;
        cfg.force_actual2_torque = g(523, 8) != 0;
        if old != 0.0 && old != einc_per_sinc {
            // A new scaling: the set-point follows the actual position in the new unit.
            self.traj = Trajectory::at(self.raw_actual());
            self.motion = Motion::Hold;
        }
    }

    pub(super) fn rebuild_records(&mut self) {
        let od = &self.od;
        let mut dirty = core::mem::take(&mut self.records_dirty);
        while dirty != 0 {
            let n = dirty.trailing_zeros() as u8 + 1;
            dirty &= dirty - 1;
            let g = |pnu| get_i64(od, pnu, n);
            let Some(r) = self.records.get_mut(n) else {
                continue;
            };
            *r = Record::from_pnus(g);
        }
    }
}
