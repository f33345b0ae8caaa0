//! The record list of record selection (CMMO-ST manual §6.5.2 Tab. 6.7, PNU 401…442): as
//! many records as the device file's `[device.fhpp] records` (the CMMO-ST: 64), subindex =
//! record number; record number 0 in output byte 3 means homing.
//! This part holds the data; the device executes chains (RCB2, PNU 416, 425, 426).

use super::bit_byte;
use super::control_bytes::ControlMode;

/// The most records a table holds: the device keeps the records to rebuild as one 64-bit set.
pub const MAX_RECORDS: u8 = 64;

/// What record number byte 3 selects (§5.2.3 Example 5 step 5.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordSelect {
    /// 0 = homing.
    Homing,
    /// 1…`records` = a programmable motion record.
    Record(u8),
    /// Above `records`: no such record.
    Invalid(u8),
}

impl RecordSelect {
    /// What byte 3 selects on a device with `records` records.
    pub const fn from_byte(b: u8, records: u8) -> Self {
        match b {
            0 => RecordSelect::Homing,
            _ if b <= records => RecordSelect::Record(b),
            _ => RecordSelect::Invalid(b),
        }
    }
}

bit_byte! {
    /// RCB1, record control byte 1 (PNU 401).
    Rcb1 {
        /// Position mode: 0 = absolute, 1 = relative.
        ABS = 0x01, "ABS";
        /// Control mode, low bit.
        COM1 = 0x02, "COM1";
        /// Control mode, high bit.
        COM2 = 0x04, "COM2";
        /// Position mode: 0 = relative to the last set-point, 1 = to the actual position.
        REL = 0x10, "REL";
        /// Force / velocity: 1 = stroke monitoring inactive.
        XLIM = 0x20, "XLIM";
        /// Not supported by the CMMO-ST (reserved).
        FAST = 0x40, "FAST";
    }
}

impl Rcb1 {
    /// COM2/COM1; `None` = 11 = "invalid record" (diagnostic 3Fh when started).
    pub const fn control_mode(self) -> Option<ControlMode> {
        ControlMode::from_bits((self.0 >> 1) & 0x03)
    }
}

/// The switching condition of automatic record chaining, RCB2 bits 0…6 (PNU 402, Tab. 6.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChainCondition {
    /// 0: end of sequence, no record switch.
    None,
    /// 1: motion complete; PNU 426 is the delay after MC.
    MotionComplete,
    /// 20: position comparator.
    PositionComparator,
    /// 21: velocity comparator.
    VelocityComparator,
    /// 22: force comparator.
    ForceComparator,
    /// 23: time comparator.
    TimeComparator,
}

impl ChainCondition {
    /// From RCB2. `None` for any other value, and when the reserved bit 7 is set ("= 0!").
    pub const fn from_rcb2(rcb2: u8) -> Option<Self> {
        match rcb2 {
            0 => Some(ChainCondition::None),
            1 => Some(ChainCondition::MotionComplete),
            20 => Some(ChainCondition::PositionComparator),
            21 => Some(ChainCondition::VelocityComparator),
            22 => Some(ChainCondition::ForceComparator),
            23 => Some(ChainCondition::TimeComparator),
            _ => None,
        }
    }

    pub const fn rcb2(self) -> u8 {
        match self {
            ChainCondition::None => 0,
            ChainCondition::MotionComplete => 1,
            ChainCondition::PositionComparator => 20,
            ChainCondition::VelocityComparator => 21,
            ChainCondition::ForceComparator => 22,
            ChainCondition::TimeComparator => 23,
        }
    }
}

/// What a start command does while a task is active: RCB3 bits 1, 0 of the running record
/// (PNU 421) in record selection, PNU 583 in direct mode (§6.6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StartBehaviour {
    /// 00: ignore the start until the running task has finished (PNU 583 default).
    #[default]
    Ignore,
    /// 01: interrupt, switch to the new task at once.
    Interrupt,
    /// 10: wait, start the new task after MC.
    Wait,
}

impl StartBehaviour {
    /// From RCB3 bits 1, 0 or the PNU 583 value; `None` for the reserved 11 / other values.
    pub const fn from_bits(bits: u8) -> Option<Self> {
        match bits {
            0 => Some(StartBehaviour::Ignore),
            1 => Some(StartBehaviour::Interrupt),
            2 => Some(StartBehaviour::Wait),
            _ => None,
        }
    }

    pub const fn bits(self) -> u8 {
        match self {
            StartBehaviour::Ignore => 0,
            StartBehaviour::Interrupt => 1,
            StartBehaviour::Wait => 2,
        }
    }
}

/// A comparator window: active while `min ≤ value ≤ max` (for at least the window time if one
/// is set). No plausibility check: with `min > max` it never activates (§6.7.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Comparator<T> {
    pub min: T,
    pub max: T,
    /// \[ms\]; 0 = no window time.
    pub window_time_ms: u16,
}

impl<T: PartialOrd + Copy> Comparator<T> {
    /// Whether `value` lies inside the window (the window time is the caller's business).
    pub fn contains(&self, value: T) -> bool {
        self.min <= value && value <= self.max
    }
}

/// The time comparator: the time since the task start in \[min, max\] ms (PNU 439/440).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TimeComparator {
    pub min_ms: u32,
    pub max_ms: u32,
}

/// The four comparators of a task (§6.7.4 Tab. 6.19/6.20), eleven consecutive PNUs: a
/// record's PNU 430…440 or the direct-mode PNU 585…595.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Comparators {
    /// Position \[SINC\], always absolute (PZ-based): min, max, window time.
    pub position: Comparator<i32>,
    /// Velocity \[SINC/s\]: min, max, window time.
    pub velocity: Comparator<i32>,
    /// Force \[‰ of PNU 555\]: min, max, window time.
    pub force: Comparator<i16>,
    /// Time \[ms\]: min, max.
    pub time: TimeComparator,
}

impl Comparators {
    /// The comparators from PNU `first` on (`g(n)` = the value of PNU n).
    pub fn from_pnus(first: u16, g: impl Fn(u16) -> i64) -> Self {
        let p = |k: u16| g(first + k);
        Comparators {
            position: Comparator {
                min: p(0) as i32,
                max: p(1) as i32,
                window_time_ms: p(2) as u16,
            },
            velocity: Comparator {
                min: p(3) as i32,
                max: p(4) as i32,
                window_time_ms: p(5) as u16,
            },
            force: Comparator {
                min: p(6) as i16,
                max: p(7) as i16,
                window_time_ms: p(8) as u16,
            },
            time: TimeComparator {
                min_ms: p(9) as u32,
                max_ms: p(10) as u32,
            },
        }
    }
}

/// One motion record: the values with the same subindex in PNU 401…442 (Tab. 6.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Record {
    /// PNU 401 RCB1: absolute/relative, control mode, REL, XLIM.
    pub rcb1: Rcb1,
    /// PNU 402 RCB2: chaining condition (see [`ChainCondition::from_rcb2`]).
    pub rcb2: u8,
    /// PNU 404 set-point value (target position) \[SINC\], relative to the project zero point.
    pub target: i32,
    /// PNU 406 maximum velocity \[SINC/s\], always positive.
    pub velocity: i32,
    /// PNU 407 acceleration \[SINC/s²\].
    pub acceleration: i32,
    /// PNU 408 deceleration \[SINC/s²\].
    pub deceleration: i32,
    /// PNU 409 jerk of acceleration \[(SINC/s³)/10\]; 0 = maximum.
    pub jerk_acceleration: u32,
    /// PNU 410 load (mass) on top of the base load \[g\] or \[kg·m²·10⁻⁷\].
    pub load: u32,
    /// PNU 416 record to jump to when the switching condition is met.
    pub following_record: u8,
    /// PNU 417 jerk of deceleration \[(SINC/s³)/10\]; 0 = maximum.
    pub jerk_deceleration: u32,
    /// PNU 418 torque limit \[‰ of PNU 555\]: 1000 = the force base value.
    pub torque_limit: i16,
    /// PNU 421 RCB3: bits 1, 0 = start behaviour while this record runs.
    pub rcb3: u8,
    /// PNU 423 final velocity \[SINC/s\].
    pub final_velocity: i32,
    /// PNU 424 maximum deviation (following error) \[SINC\] or \[SINC/s\].
    pub max_deviation: i32,
    /// PNU 425 MC pulse when switching records: 0 = no, 1 = yes.
    pub mc_on_continuation: u8,
    /// PNU 426 start delay \[ms\] (with RCB2 = 1 also the delay after MC).
    pub start_delay_ms: u32,
    /// PNU 427 stroke limit \[SINC\] for velocity and force records.
    pub stroke_limit: i32,
    /// PNU 428 torque feed-forward factor \[‰\]: 1000 = fully active.
    pub torque_feed_forward: u16,
    /// PNU 430…440: the position, velocity, force and time comparators.
    pub comparators: Comparators,
    /// PNU 441 target velocity of a velocity record \[SINC/s\]; the sign gives the direction.
    pub setpoint_velocity: i32,
    /// PNU 442 target force of a force record \[‰ of PNU 555\]; the sign gives the direction.
    pub setpoint_force: i16,
}

impl Record {
    /// The record as its PNUs 401…442 hold it (`g(n)` = the value of PNU n at this
    /// record's subindex), each PNU to its field.
    pub fn from_pnus(g: impl Fn(u16) -> i64) -> Record {
        Record {
            rcb1: Rcb1(g(401) as u8),
            rcb2: g(402) as u8,
            target: g(404) as i32,
            velocity: g(406) as i32,
            acceleration: g(407) as i32,
            deceleration: g(408) as i32,
            jerk_acceleration: g(409) as u32,
            load: g(410) as u32,
            following_record: g(416) as u8,
            jerk_deceleration: g(417) as u32,
            torque_limit: g(418) as i16,
            rcb3: g(421) as u8,
            final_velocity: g(423) as i32,
            max_deviation: g(424) as i32,
            mc_on_continuation: g(425) as u8,
            start_delay_ms: g(426) as u32,
            stroke_limit: g(427) as i32,
            torque_feed_forward: g(428) as u16,
            comparators: Comparators::from_pnus(430, &g),
            setpoint_velocity: g(441) as i32,
            setpoint_force: g(442) as i16,
        }
    }

    /// The control mode of RCB1; `None` = invalid record.
    pub const fn control_mode(&self) -> Option<ControlMode> {
        self.rcb1.control_mode()
    }

    /// The chaining condition of RCB2; `None` = invalid RCB2.
    pub const fn chain_condition(&self) -> Option<ChainCondition> {
        ChainCondition::from_rcb2(self.rcb2)
    }

    /// The start behaviour of RCB3; `None` = reserved value.
    pub const fn start_behaviour(&self) -> Option<StartBehaviour> {
        StartBehaviour::from_bits(self.rcb3 & 0x03)
    }

    /// Whether the record can be started: a defined control mode and a defined RCB2/RCB3
    /// (else diagnostic 3Fh "record invalid").
    pub const fn is_valid(&self) -> bool {
        self.control_mode().is_some()
            && self.chain_condition().is_some()
            && self.start_behaviour().is_some()
    }
}

/// The motion records, addressed 1…`count` as the PNU subindex and output byte 3 address
/// them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordTable {
    records: [Record; MAX_RECORDS as usize],
    count: u8,
}

impl RecordTable {
    /// A table of `count` records (the device file's `[device.fhpp] records`), at most
    /// [`MAX_RECORDS`].
    pub fn new(count: u8) -> Self {
        RecordTable {
            records: [Record::default(); MAX_RECORDS as usize],
            count: count.min(MAX_RECORDS),
        }
    }

    /// How many records there are.
    pub const fn count(&self) -> u8 {
        self.count
    }

    /// What record number `b` (output byte 3) selects.
    pub const fn select(&self, b: u8) -> RecordSelect {
        RecordSelect::from_byte(b, self.count)
    }

    /// Record `number` (1…count); `None` for 0 (homing, which has no record data) and above.
    pub fn get(&self, number: u8) -> Option<&Record> {
        self.records.get(self.slot(number)?)
    }

    /// Record `number` (1…count) for writing.
    pub fn get_mut(&mut self, number: u8) -> Option<&mut Record> {
        let slot = self.slot(number)?;
        self.records.get_mut(slot)
    }

    /// All records, record 1 first.
    pub fn iter(&self) -> impl Iterator<Item = (u8, &Record)> {
        self.records
            .iter()
            .zip(1u8..=self.count)
            .map(|(r, n)| (n, r))
    }

    fn slot(&self, number: u8) -> Option<usize> {
        (number <= self.count).then_some(usize::from(number).checked_sub(1)?)
    }
}
