//! Profile position mode (CiA 402 §12; CMMP-AS §7.3): the set-point handshake with
//! controlword bits 4, 5, 6 and statusword bit 12, and the one-deep set-point buffer.

/// One positioning job, in internal units (increments, increments/s, increments/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Job {
    pub target: f64,
    pub velocity: f64,
    pub end_velocity: f64,
    pub acceleration: f64,
    pub deceleration: f64,
}

/// The set-point handshake state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SetPoints {
    /// The job the trajectory generator runs.
    pub active: Option<Job>,
    /// The next job, started when the active one is done (CMMP-AS Fig. 7.6).
    pub buffered: Option<Job>,
    /// Statusword bit 12.
    pub acknowledge: bool,
    /// Controlword bit 4 as last seen.
    new_set_point: bool,
    /// The last job that ran to its end: relative moves count from it.
    pub last_target: Option<f64>,
    /// A new set-point while the buffer is full replaces the buffered one (Nanotec ch. 4: "the
    /// newest (queued) job is overwritten"); otherwise it is not taken (CMMP-AS).
    pub overwrite_buffered: bool,
}

/// What the new-set-point edge carried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// Target as written (user units converted to increments), absolute or relative.
    pub target: f64,
    pub relative: bool,
    pub immediately: bool,
    pub job: Job,
}

impl SetPoints {
    /// No job; `overwrite_buffered` as the drive's manual says.
    pub fn overwriting(overwrite_buffered: bool) -> Self {
        SetPoints {
            overwrite_buffered,
            ..SetPoints::default()
        }
    }

    /// Controlword bit 4 as it is now. On the rising edge `request` is taken: into the active
    /// slot when free or when `immediately` (bit 5) is set, else into the buffer if that is
    /// free. Returns whether a new job was accepted (target reached must then clear).
    /// `demand` is the present position set-point (relative moves count from the set-point,
    /// CMMP-AS §6.1.3 bit 6: "relative to position_demand_value").
    pub fn update(&mut self, bit4: bool, demand: f64, request: impl FnOnce() -> Request) -> bool {
        let rising = self.rising(bit4);
        self.new_set_point = bit4;
        let mut accepted = false;
        let replace = self.overwrite_buffered && self.buffered.is_some();
        if rising && (!self.acknowledge || replace) {
            let r = request();
            let queue_behind = self.active.is_some() && !r.immediately;
            if !(queue_behind && self.buffered.is_some()) || replace {
                // A buffered relative job counts from the target of the job before it.
                let base = if queue_behind {
                    self.active.map(|j| j.target).unwrap_or(demand)
                } else {
                    demand
                };
                let target = if r.relative {
                    base + r.target
                } else {
                    r.target
                };
                let job = Job { target, ..r.job };
                if queue_behind {
                    self.buffered = Some(job);
                } else {
                    self.active = Some(job);
                    self.buffered = None;
                }
                self.acknowledge = true;
                accepted = true;
            }
        }
        // Bit 12 drops once bit 4 is back to 0 and the drive can take a new job (the buffer
        // is free): CMMP-AS §7.3 steps 5–6.
        if self.acknowledge && !bit4 && self.buffered.is_none() {
            self.acknowledge = false;
        }
        accepted
    }

    /// Whether controlword bit 4 at `bit4` is its rising edge: the only time
    /// [`SetPoints::update`] takes a request.
    pub fn rising(&self, bit4: bool) -> bool {
        bit4 && !self.new_set_point
    }

    /// The active job reached its target: the buffered one (if any) starts.
    pub fn finished(&mut self) {
        if let Some(j) = self.active.take() {
            self.last_target = Some(j.target);
        }
        self.active = self.buffered.take();
    }

    /// Halt, quick stop, mode change or disable: every job is dropped.
    pub fn abort(&mut self) {
        self.active = None;
        self.buffered = None;
    }

    /// The end velocity to use for the active job: non-zero only when a buffered job follows
    /// (continuous positioning, CMMP-AS Fig. 7.6).
    pub fn end_velocity(&self) -> f64 {
        match (self.active, self.buffered) {
            (Some(a), Some(_)) => a.end_velocity,
            _ => 0.0,
        }
    }
}
