//! Nanotec units and scaling (Nanotec §1.2, §6.10, §8.4, 2004h):
//! encoder resolution, step angle, the step-mode limits table, torque current, the Hall
//! sensor assignment 2004h:0C and the load-angle support spacing 2004h:08.

/// 608Fh encoder increments of a quadrature encoder with `lines` per revolution (×4; §1.2:
/// 500 lines → 2000).
pub const fn encoder_increments(lines: u32) -> u32 {
    4 * lines
}

/// Step angle in degrees of a hybrid stepper with `pole_pairs` (2006h): 360° / (4 × pole
/// pairs); 50 → 1.8°, 100 → 0.9°.
pub fn step_angle_deg(pole_pairs: u16) -> f64 {
    360.0 / (4.0 * f64::from(pole_pairs.max(1)))
}

/// One row of the §1.2 table: the step mode, micro-steps per full step, the feed 6092h:01
/// that makes one user unit one micro-step on a 1.8° and a 0.9° motor, and the maximum
/// profile velocity 6081h and acceleration 6083h / 6084h.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepMode {
    pub name: &'static str,
    pub microsteps: u32,
    pub feed_1_8: u32,
    pub feed_0_9: u32,
    pub max_velocity: u32,
    pub max_acceleration: u32,
}

const fn row(
    name: &'static str,
    microsteps: u32,
    feed_1_8: u32,
    feed_0_9: u32,
    max_velocity: u32,
    max_acceleration: u32,
) -> StepMode {
    StepMode {
        name,
        microsteps,
        feed_1_8,
        feed_0_9,
        max_velocity,
        max_acceleration,
    }
}

/// §1.2, as printed (1.8° motor at 4800 min⁻¹, 0.9° at 2400 min⁻¹).
pub const STEP_MODES: [StepMode; 9] = [
    row("full step", 1, 200, 400, 16_000, 1_600_000),
    row("half step", 2, 400, 800, 32_000, 3_200_000),
    row("quarter step", 4, 800, 1600, 64_000, 6_400_000),
    row("fifth step", 5, 1000, 2000, 80_000, 8_000_000),
    row("eighth step", 8, 1600, 3200, 128_000, 12_800_000),
    row("tenth step", 10, 2000, 4000, 160_000, 16_000_000),
    row("1/16 step", 16, 3200, 6400, 256_000, 25_600_000),
    row("1/32 step", 32, 6400, 12_800, 512_000, 51_200_000),
    row("1/64 step", 64, 12_800, 25_600, 1_024_000, 102_400_000),
];

/// Full steps per revolution of a motor with `pole_pairs`: 4 × pole pairs (200 for 1.8°).
pub const fn full_steps_per_rev(pole_pairs: u16) -> u32 {
    4 * pole_pairs as u32
}

/// The highest speed in micro-steps/s at `max_rpm` (§1.2 "check": 200 × 4800 / 60 = 16000
/// for full steps on a 1.8° motor).
pub const fn max_velocity(pole_pairs: u16, microsteps: u32, max_rpm: u32) -> u32 {
    full_steps_per_rev(pole_pairs) * microsteps * max_rpm / 60
}

/// The highest acceleration: 100 × the highest velocity per second (§1.2).
pub const fn max_acceleration(max_velocity: u32) -> u32 {
    100 * max_velocity
}

/// The motor current for a torque set-point (§8.4): `6071h / 1000 × 2004h:01 % × I_rated`,
/// mA.
pub fn torque_current_ma(target_permille: i16, max_current_percent: u8, rated_ma: u32) -> f64 {
    f64::from(target_permille) / 1000.0 * f64::from(max_current_percent) / 100.0
        * f64::from(rated_ma)
}

/// Hall-sensor assignment of 2004h:0C, type 1 ("all Nanotec motors except DB42", §1.2): the
/// sector value of Hall index 1 … 6.
pub const HALL_TYPE_1: [u8; 6] = [1, 3, 0, 2, 5, 4];
/// Type 2. Decision: the manual's table labels it "DB47", but applied to the DB57 sequence it
/// gives exactly the 510342h §1.2 prints for DB42 motors; no DB47 exists in the manual.
pub const HALL_TYPE_2: [u8; 6] = [4, 0, 3, 5, 2, 1];

/// 2004h:0C for a motor's Hall sequence (H1, H2, H3 per step, from its data sheet): each
/// step's index H1 + 2·H2 + 4·H3 looked up in `table`, the first step in the highest of the
/// six hex digits. `None` for an index 0 or 7 (no valid Hall state).
pub fn hall_mode(sequence: &[(u8, u8, u8); 6], table: &[u8; 6]) -> Option<u32> {
    sequence.iter().try_fold(0u32, |acc, (h1, h2, h3)| {
        let index = usize::from(h1 & 1) + 2 * usize::from(h2 & 1) + 4 * usize::from(h3 & 1);
        let digit = table.get(index.checked_sub(1)?)?;
        Some(acc << 4 | u32::from(*digit))
    })
}

/// The load-angle support spacing 2004h:08 in min⁻¹: 8192 = 1000 min⁻¹, proportional.
pub fn load_angle_spacing_rpm(value: u16) -> f64 {
    f64::from(value) * 1000.0 / 8192.0
}
