//! The CiA 402 factor group (6093h position_factor, 6094h velocity_encoder_factor, 6097h
//! acceleration_factor, each numerator sub 01 / divisor sub 02, and 607Eh polarity):
//! conversion between the user units of the bus objects and the drive's internal units.
//!
//! # Internal units
//!
//! CiA 402 leaves the internal units to the drive. Decision: the engine's are those of the
//! first drive it served (the CMMP-AS, its §5.3 Tab. 5.3, kept beside the project as the
//! manual's extract), so that its factor-group objects are the device's own and its worked
//! examples (vectors `CMMP-FG-*`) check the conversions; every other drive converts to them.
//!
//! | Quantity     | Internal unit                                  |
//! |--------------|------------------------------------------------|
//! | position     | increments, 65536 per motor revolution         |
//! | velocity     | 1/4096 min⁻¹ ("revolutions per 4096 minutes")  |
//! | acceleration | 1/256 min⁻¹/s                                  |
//!
//! # Direction
//!
//! `internal = user × numerator / divisor` on write, the inverse on read: 6093h converts
//! position units into increments. With 6093h = 4096/225 (user unit 1/10°) the user value
//! 3600 (360.0°) is 3600 × 4096 / 225 = 65536 increments, one revolution.
//!
//! # Rounding policy (CiA 402 states none)
//!
//! Every conversion is computed exactly in `i128` and rounded once, **to the nearest integer,
//! ties away from zero**. Because the rule is symmetric in sign, flipping a polarity flag
//! negates the result exactly. Consequences:
//! * with a factor ≥ 1 (every position/velocity example of the `CMMP-FG-*` vectors except 1/100 rev/min²),
//!   user → internal → user returns the user value unchanged;
//! * with a factor ≤ 1, internal → user → internal returns the internal value unchanged.
//!
//! # Range policy
//!
//! The typed conversions never fail: a result outside the target type **saturates** at the
//! type's edge (a read of a value that does not fit INT32 yields `i32::MAX` / `i32::MIN`, a
//! UINT32 object yields `0` / `u32::MAX`). A factor with a zero numerator or divisor, which
//! [`FactorGroup::validate`] refuses but which the public fields can still hold, acts as an
//! infinite factor: the result saturates by the sign of the value (0 stays 0). No input panics.
//! For error-returning arithmetic use [`Ratio::scale`] / [`Ratio::unscale`].
//!
//! # Polarity 607Eh
//!
//! Bit 7 (80h) position polarity, bit 6 (40h) velocity polarity (CiA 402 607Eh polarity); a
//! set bit multiplies by −1 on every read and write. CiA 402 applies the flags to signed
//! set-points and actual values only:
//! * position flag → signed position values: 607Ah target_position, 6062h
//!   position_demand_value, 6064h position_actual_value, 60F4h following_error_actual_value,
//!   60C1h:01 ip_data_position — use [`FactorGroup::position_to_internal`] /
//!   [`FactorGroup::position_from_internal`];
//! * velocity flag → signed velocity values: 60FFh target_velocity, 606Bh
//!   velocity_demand_value, 606Ch velocity_actual_value, 60FAh control_effort — use
//!   [`FactorGroup::velocity_to_internal`] / [`FactorGroup::velocity_from_internal`];
//! * no flag on magnitudes (UINT32 windows and speeds: 6065h, 6067h, 6081h, 6082h, 607Fh,
//!   6099h, 60FBh:04) — use the `*_magnitude_*` conversions — nor on accelerations (6083h,
//!   6084h, 6085h, 609Ah).
//!
//! The flags act on access only: values already stored internally are not converted when
//! 607Eh or a factor changes. [`FactorGroup::validate`] accepts 0, 40h, 80h, C0h and refuses
//! the reserved bits 0–5.
//!
//! # Limits
//!
//! CiA 402 gives each factor two UNSIGNED32 and no bound on their quotient; a zero divisor is
//! refused for all three objects, and so is a zero numerator (a zero factor cannot be
//! inverted on read). A drive whose manual bounds the quotient says so through its vendor's
//! hook ([`Vendor`](crate::personality::Vendor)'s `factor_limit`), which the
//! `*_within` checks take.

use core::fmt;

/// Internal position increments per motor revolution.
pub const INCREMENTS_PER_REVOLUTION: u32 = 65_536;
/// Internal velocity units per min⁻¹ (internal unit 1/4096 min⁻¹).
pub const VELOCITY_UNITS_PER_RPM: u32 = 4096;
/// Internal acceleration units per min⁻¹/s (internal unit 1/256 min⁻¹/s).
pub const ACCELERATION_UNITS_PER_RPM_PER_S: u32 = 256;
/// 607Eh bit 7: position_polarity_flag.
pub const POSITION_POLARITY_FLAG: u8 = 0x80;
/// 607Eh bit 6: velocity_polarity_flag.
pub const VELOCITY_POLARITY_FLAG: u8 = 0x40;

/// time_factor_v for speeds per minute: 1 min⁻¹ = 4096 internal.
pub const TIME_FACTOR_V_PER_MINUTE: Ratio = Ratio::new(VELOCITY_UNITS_PER_RPM, 1);
/// time_factor_v for speeds per second: 1 s⁻¹ = 60 min⁻¹ = 60 × 4096 internal.
pub const TIME_FACTOR_V_PER_SECOND: Ratio = Ratio::new(60 * VELOCITY_UNITS_PER_RPM, 1);
/// time_factor_a for min⁻¹/s: 1 min⁻¹/s = 256 internal.
pub const TIME_FACTOR_A_PER_MINUTE_PER_SECOND: Ratio =
    Ratio::new(ACCELERATION_UNITS_PER_RPM_PER_S, 1);
/// time_factor_a for s⁻²: 1 s⁻² = 60 min⁻¹/s = 60 × 256 internal.
pub const TIME_FACTOR_A_PER_SECOND_SQUARED: Ratio =
    Ratio::new(60 * ACCELERATION_UNITS_PER_RPM_PER_S, 1);
/// time_factor_a for min⁻²: 1 min⁻² = 1/60 min⁻¹/s = 256/60 internal.
pub const TIME_FACTOR_A_PER_MINUTE_SQUARED: Ratio =
    Ratio::new(ACCELERATION_UNITS_PER_RPM_PER_S, 60);

/// One of the three factor objects, named in errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FactorObject {
    /// 6093h position_factor.
    Position,
    /// 6094h velocity_encoder_factor.
    Velocity,
    /// 6097h acceleration_factor.
    Acceleration,
}

impl FactorObject {
    /// The object index (6093h, 6094h, 6097h).
    pub const fn index(self) -> u16 {
        match self {
            Self::Position => 0x6093,
            Self::Velocity => 0x6094,
            Self::Acceleration => 0x6097,
        }
    }

    /// The object name as CiA 402 prints it.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Position => "position_factor",
            Self::Velocity => "velocity_encoder_factor",
            Self::Acceleration => "acceleration_factor",
        }
    }
}

/// Why a factor, a polarity or a unit description is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FactorError {
    /// The divisor (subindex 02) is 0.
    DivisorZero(FactorObject),
    /// The numerator (subindex 01) is 0.
    NumeratorZero(FactorObject),
    /// numerator / divisor exceeds the drive's limit (the second field; a vendor's
    /// `factor_limit` ([`Vendor`](crate::personality::Vendor))).
    ExceedsLimit(FactorObject, u32),
    /// The unit description gives a fraction whose reduced numerator or divisor needs more
    /// than 32 bits.
    NotRepresentable(FactorObject),
    /// 607Eh with any of the reserved bits 0–5 set (the value is carried).
    PolarityReservedBits(u8),
}

impl fmt::Display for FactorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::DivisorZero(o) => write!(f, "{:04X}h {}: divisor is 0", o.index(), o.name()),
            Self::NumeratorZero(o) => {
                write!(f, "{:04X}h {}: numerator is 0", o.index(), o.name())
            }
            Self::ExceedsLimit(o, limit) if limit.is_power_of_two() => write!(
                f,
                "{:04X}h {}: factor exceeds 2^{}",
                o.index(),
                o.name(),
                limit.trailing_zeros()
            ),
            Self::ExceedsLimit(o, limit) => {
                write!(f, "{:04X}h {}: factor exceeds {limit}", o.index(), o.name())
            }
            Self::NotRepresentable(o) => write!(
                f,
                "{:04X}h {}: reduced fraction does not fit 32-bit numerator/divisor",
                o.index(),
                o.name()
            ),
            Self::PolarityReservedBits(v) => {
                write!(
                    f,
                    "607Eh polarity: {v:02X}h sets reserved bits (allowed 0, 40h, 80h, C0h)"
                )
            }
        }
    }
}

/// numerator / divisor, both UINT32 as in subindices 01 and 02 of 6093h/6094h/6097h.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Ratio {
    /// Subindex 01.
    pub numerator: u32,
    /// Subindex 02.
    pub divisor: u32,
}

impl Ratio {
    /// numerator / divisor, stored as given (not reduced).
    pub const fn new(numerator: u32, divisor: u32) -> Self {
        Self { numerator, divisor }
    }

    /// The same fraction in lowest terms (0/0 stays 0/0, 0/d becomes 0/1, n/0 becomes 1/0).
    pub const fn reduced(self) -> Self {
        let g = gcd(self.numerator as u128, self.divisor as u128);
        if g == 0 {
            return self;
        }
        // Dividing by a common divisor never grows a value, so the casts are exact.
        Self {
            numerator: (self.numerator as u128 / g) as u32,
            divisor: (self.divisor as u128 / g) as u32,
        }
    }

    /// Checks this fraction as the value of `object` as CiA 402 has it: divisor and
    /// numerator non-zero, any quotient.
    pub const fn check(self, object: FactorObject) -> Result<(), FactorError> {
        self.check_within(object, None)
    }

    /// Checks this fraction as the value of `object`: divisor and numerator non-zero and
    /// numerator / divisor ≤ `limit` where the drive has one (CiA 402 sets none; the
    /// vendor's hook `factor_limit`).
    pub const fn check_within(
        self,
        object: FactorObject,
        limit: Option<u32>,
    ) -> Result<(), FactorError> {
        if self.divisor == 0 {
            return Err(FactorError::DivisorZero(object));
        }
        if self.numerator == 0 {
            return Err(FactorError::NumeratorZero(object));
        }
        if let Some(limit) = limit {
            if self.numerator as u64 > limit as u64 * self.divisor as u64 {
                return Err(FactorError::ExceedsLimit(object, limit));
            }
        }
        Ok(())
    }

    /// `value × numerator / divisor` (user → internal), rounded to nearest, ties away from
    /// zero. `None` if the divisor is 0 or the result does not fit `i64`.
    pub fn scale(self, value: i64) -> Option<i64> {
        let q = div_round(
            i128::from(value) * i128::from(self.numerator),
            i128::from(self.divisor),
        )?;
        i64::try_from(q).ok()
    }

    /// `value × divisor / numerator` (internal → user), rounded to nearest, ties away from
    /// zero. `None` if the numerator is 0 or the result does not fit `i64`.
    pub fn unscale(self, value: i64) -> Option<i64> {
        let q = div_round(
            i128::from(value) * i128::from(self.divisor),
            i128::from(self.numerator),
        )?;
        i64::try_from(q).ok()
    }
}

/// The factor group: 6093h, 6094h, 6097h and 607Eh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FactorGroup {
    /// 6093h position_factor: position_units → increments.
    pub position: Ratio,
    /// 6094h velocity_encoder_factor: speed_units → 1/4096 min⁻¹.
    pub velocity: Ratio,
    /// 6097h acceleration_factor: acceleration_units → 1/256 min⁻¹/s.
    pub acceleration: Ratio,
    /// 607Eh polarity: bit 7 position, bit 6 velocity.
    pub polarity: u8,
}

impl Default for FactorGroup {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl FactorGroup {
    /// The factors of a drive whose dictionary sets none: user units increments, min⁻¹ and
    /// min⁻¹/s (6093h = 1/1, 6094h = 4096/1, 6097h = 256/1), 607Eh = 0. Decision: CiA 402
    /// prints no default for the factors; these are the CMMP-AS's delivery state (§5.3) and
    /// keep a drive without them in the units its speeds are written in.
    pub const DEFAULT: Self = Self {
        position: Ratio::new(1, 1),
        velocity: TIME_FACTOR_V_PER_MINUTE,
        acceleration: TIME_FACTOR_A_PER_MINUTE_PER_SECOND,
        polarity: 0,
    };

    /// The ratio of one factor object.
    pub const fn factor(&self, object: FactorObject) -> Ratio {
        match object {
            FactorObject::Position => self.position,
            FactorObject::Velocity => self.velocity,
            FactorObject::Acceleration => self.acceleration,
        }
    }

    /// Checks all three factors and the polarity as CiA 402 has them (no bound on a
    /// quotient); the first problem found is returned, in the order 6093h, 6094h, 6097h,
    /// 607Eh.
    pub const fn validate(&self) -> Result<(), FactorError> {
        if let Err(e) = self.position.check(FactorObject::Position) {
            return Err(e);
        }
        if let Err(e) = self.velocity.check(FactorObject::Velocity) {
            return Err(e);
        }
        if let Err(e) = self.acceleration.check(FactorObject::Acceleration) {
            return Err(e);
        }
        check_polarity(self.polarity)
    }

    /// [`FactorGroup::validate`] with each factor's quotient limited by `limit` (CiA 402
    /// sets none; the vendor's hook `factor_limit`).
    pub fn validate_within(
        &self,
        limit: impl Fn(FactorObject) -> Option<u32>,
    ) -> Result<(), FactorError> {
        for (object, ratio) in [
            (FactorObject::Position, self.position),
            (FactorObject::Velocity, self.velocity),
            (FactorObject::Acceleration, self.acceleration),
        ] {
            ratio.check_within(object, limit(object))?;
        }
        check_polarity(self.polarity)
    }

    /// Replaces one factor if it passes [`Ratio::check_within`] with `limit`; on error
    /// nothing changes.
    pub fn set_factor_within(
        &mut self,
        object: FactorObject,
        ratio: Ratio,
        limit: Option<u32>,
    ) -> Result<(), FactorError> {
        ratio.check_within(object, limit)?;
        match object {
            FactorObject::Position => self.position = ratio,
            FactorObject::Velocity => self.velocity = ratio,
            FactorObject::Acceleration => self.acceleration = ratio,
        }
        Ok(())
    }

    /// Replaces one factor if it passes [`Ratio::check`] (CiA 402's rule); on error nothing
    /// changes.
    pub fn set_factor(&mut self, object: FactorObject, ratio: Ratio) -> Result<(), FactorError> {
        ratio.check(object)?;
        match object {
            FactorObject::Position => self.position = ratio,
            FactorObject::Velocity => self.velocity = ratio,
            FactorObject::Acceleration => self.acceleration = ratio,
        }
        Ok(())
    }

    /// Writes 607Eh if only bits 6 and 7 are set; on error nothing changes. Stored internal
    /// values are not touched.
    pub fn set_polarity(&mut self, polarity: u8) -> Result<(), FactorError> {
        check_polarity(polarity)?;
        self.polarity = polarity;
        Ok(())
    }

    /// Whether 607Eh bit 7 (position_polarity_flag) is set.
    pub const fn position_inverted(&self) -> bool {
        self.polarity & POSITION_POLARITY_FLAG != 0
    }

    /// Whether 607Eh bit 6 (velocity_polarity_flag) is set.
    pub const fn velocity_inverted(&self) -> bool {
        self.polarity & VELOCITY_POLARITY_FLAG != 0
    }

    /// Signed position write (e.g. 607Ah): position_units → increments, with the
    /// position_polarity_flag.
    pub fn position_to_internal(&self, user: i32) -> i64 {
        let v = signed(i128::from(user), self.position_inverted());
        sat_i64(to_internal(v, self.position))
    }

    /// Signed position read (e.g. 6064h): increments → position_units, with the
    /// position_polarity_flag; saturates at the INT32 edges.
    pub fn position_from_internal(&self, internal: i64) -> i32 {
        let v = signed(i128::from(internal), self.position_inverted());
        sat_i32(from_internal(v, self.position))
    }

    /// Position magnitude write (UINT32 windows, e.g. 6065h, 6067h): no polarity.
    pub fn position_magnitude_to_internal(&self, user: u32) -> i64 {
        sat_i64(to_internal(i128::from(user), self.position))
    }

    /// Position magnitude read: no polarity; saturates at 0 and `u32::MAX`.
    pub fn position_magnitude_from_internal(&self, internal: i64) -> u32 {
        sat_u32(from_internal(i128::from(internal), self.position))
    }

    /// Signed velocity write (e.g. 60FFh): speed_units → 1/4096 min⁻¹, with the
    /// velocity_polarity_flag.
    pub fn velocity_to_internal(&self, user: i32) -> i64 {
        let v = signed(i128::from(user), self.velocity_inverted());
        sat_i64(to_internal(v, self.velocity))
    }

    /// Signed velocity read (e.g. 606Ch): 1/4096 min⁻¹ → speed_units, with the
    /// velocity_polarity_flag; saturates at the INT32 edges.
    pub fn velocity_from_internal(&self, internal: i64) -> i32 {
        let v = signed(i128::from(internal), self.velocity_inverted());
        sat_i32(from_internal(v, self.velocity))
    }

    /// Velocity magnitude write (UINT32 speeds, e.g. 6081h, 6099h): no polarity.
    pub fn velocity_magnitude_to_internal(&self, user: u32) -> i64 {
        sat_i64(to_internal(i128::from(user), self.velocity))
    }

    /// Velocity magnitude read: no polarity; saturates at 0 and `u32::MAX`.
    pub fn velocity_magnitude_from_internal(&self, internal: i64) -> u32 {
        sat_u32(from_internal(i128::from(internal), self.velocity))
    }

    /// Acceleration write (UINT32: 6083h, 6084h, 6085h, 609Ah): acceleration_units →
    /// 1/256 min⁻¹/s. No polarity. Saturates at `i64::MAX`.
    pub fn acceleration_to_internal(&self, user: u32) -> i64 {
        sat_i64(to_internal(i128::from(user), self.acceleration))
    }

    /// Acceleration read: 1/256 min⁻¹/s → acceleration_units. No polarity; saturates at 0
    /// and `u32::MAX`.
    pub fn acceleration_from_internal(&self, internal: i64) -> u32 {
        sat_u32(from_internal(i128::from(internal), self.acceleration))
    }
}

/// position_factor from a gear ratio and a feed constant (CiA 402: position encoder
/// resolution × gear ratio / feed constant, the resolution the engine's 65536 increments per
/// motor revolution): `gear_ratio × 65536 / feed_constant`, in lowest terms.
///
/// * `gear` = R_IN / R_OUT (motor revolutions per output revolution), e.g. 2/3;
/// * `feed_constant` = user position units per output revolution, already multiplied by
///   10^decimals (see [`feed_constant`]), e.g. 3600 for 1/10° or 6315/10 for 1/10 mm at 63.15 mm.
///
/// The result passes [`Ratio::check`] for 6093h (otherwise the error says why); a drive's own
/// bound on the quotient is its caller's to check.
pub fn position_factor(gear: Ratio, feed_constant: Ratio) -> Result<Ratio, FactorError> {
    compose(
        FactorObject::Position,
        gear,
        Ratio::new(INCREMENTS_PER_REVOLUTION, 1),
        feed_constant,
    )
}

/// velocity_encoder_factor (CiA 402: velocity encoder resolution × gear ratio / feed
/// constant, per the user's time unit): `gear_ratio × time_factor_v /
/// feed_constant`, reduced. `time_factor_v` is the user time unit in internal units, e.g.
/// [`TIME_FACTOR_V_PER_MINUTE`] or [`TIME_FACTOR_V_PER_SECOND`]. There is no 65536 term: the
/// internal velocity unit counts revolutions (1/4096 min⁻¹), not increments.
pub fn velocity_factor(
    gear: Ratio,
    feed_constant: Ratio,
    time_factor_v: Ratio,
) -> Result<Ratio, FactorError> {
    compose(FactorObject::Velocity, gear, time_factor_v, feed_constant)
}

/// acceleration_factor (as [`velocity_factor`], per the user's time unit squared):
/// `gear_ratio × time_factor_a /
/// feed_constant`, reduced. `time_factor_a` e.g. [`TIME_FACTOR_A_PER_MINUTE_PER_SECOND`],
/// [`TIME_FACTOR_A_PER_SECOND_SQUARED`], [`TIME_FACTOR_A_PER_MINUTE_SQUARED`].
pub fn acceleration_factor(
    gear: Ratio,
    feed_constant: Ratio,
    time_factor_a: Ratio,
) -> Result<Ratio, FactorError> {
    compose(
        FactorObject::Acceleration,
        gear,
        time_factor_a,
        feed_constant,
    )
}

/// A feed constant in user units of 10^−`decimals` of a unit: position units per output
/// revolution × 10^decimals (360° at one decimal place → 3600). `per_output_revolution` is in whole user
/// units, e.g. 360/1 for degrees or 6315/100 for 63.15 mm. Returns the fraction in lowest
/// terms, or `None` if it does not fit 32 bits or has a zero divisor.
pub fn feed_constant(per_output_revolution: Ratio, decimals: u8) -> Option<Ratio> {
    if per_output_revolution.divisor == 0 {
        return None;
    }
    let mut scale: u128 = 1;
    for _ in 0..decimals {
        scale = scale.checked_mul(10)?;
    }
    let n = u128::from(per_output_revolution.numerator).checked_mul(scale)?;
    reduce_u128(n, u128::from(per_output_revolution.divisor))
}

/// gear × time / feed (time = 65536 for position), reduced and checked for `object` as CiA
/// 402 has it.
fn compose(
    object: FactorObject,
    gear: Ratio,
    time: Ratio,
    feed: Ratio,
) -> Result<Ratio, FactorError> {
    if gear.divisor == 0 || time.divisor == 0 || feed.divisor == 0 || feed.numerator == 0 {
        return Err(FactorError::DivisorZero(object));
    }
    // Each product has three u32 factors (< 2^96), so u128 cannot overflow.
    let n = u128::from(gear.numerator) * u128::from(time.numerator) * u128::from(feed.divisor);
    let d = u128::from(gear.divisor) * u128::from(time.divisor) * u128::from(feed.numerator);
    if n == 0 {
        return Err(FactorError::NumeratorZero(object));
    }
    let r = reduce_u128(n, d).ok_or(FactorError::NotRepresentable(object))?;
    r.check(object)?;
    Ok(r)
}

fn reduce_u128(n: u128, d: u128) -> Option<Ratio> {
    let g = gcd(n, d);
    if g == 0 {
        return None;
    }
    let numerator = u32::try_from(n / g).ok()?;
    let divisor = u32::try_from(d / g).ok()?;
    Some(Ratio::new(numerator, divisor))
}

const fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        let t = a % b;
        a = b;
        b = t;
    }
    a
}

const fn check_polarity(polarity: u8) -> Result<(), FactorError> {
    if polarity & !(POSITION_POLARITY_FLAG | VELOCITY_POLARITY_FLAG) != 0 {
        Err(FactorError::PolarityReservedBits(polarity))
    } else {
        Ok(())
    }
}

fn signed(v: i128, inverted: bool) -> i128 {
    if inverted {
        -v
    } else {
        v
    }
}

/// `n / d` rounded to nearest, ties away from zero; `None` if `d == 0`. Requires `d ≥ 0`
/// (always true here: `d` comes from a `u32`).
fn div_round(n: i128, d: i128) -> Option<i128> {
    if d == 0 {
        return None;
    }
    if d == 1 {
        return Some(n);
    }
    // The common case fits 64 bits, where division is an order of magnitude cheaper than
    // i128's (this runs in every control cycle). |r| < |d| ≤ 2³², so 2·|r| cannot overflow.
    if let (Ok(n64), Ok(d64)) = (i64::try_from(n), i64::try_from(d)) {
        let q = n64 / d64;
        let r = n64 % d64;
        let q = if 2 * r.unsigned_abs() >= d64.unsigned_abs() {
            q + n64.signum()
        } else {
            q
        };
        return Some(i128::from(q));
    }
    let q = n / d;
    let r = n % d; // same sign as n
    if 2 * r.abs() >= d {
        Some(q + n.signum())
    } else {
        Some(q)
    }
}

/// `v × num / div`; a zero divisor acts as an infinite factor (saturates by sign).
fn to_internal(v: i128, r: Ratio) -> i128 {
    div_round(v * i128::from(r.numerator), i128::from(r.divisor)).unwrap_or(infinite(v))
}

/// `v × div / num`; a zero numerator acts as an infinite factor (saturates by sign).
fn from_internal(v: i128, r: Ratio) -> i128 {
    div_round(v * i128::from(r.divisor), i128::from(r.numerator)).unwrap_or(infinite(v))
}

fn infinite(v: i128) -> i128 {
    v.signum() * i128::MAX
}

fn sat_i64(v: i128) -> i64 {
    i64::try_from(v).unwrap_or(if v < 0 { i64::MIN } else { i64::MAX })
}

fn sat_i32(v: i128) -> i32 {
    i32::try_from(v).unwrap_or(if v < 0 { i32::MIN } else { i32::MAX })
}

fn sat_u32(v: i128) -> u32 {
    u32::try_from(v).unwrap_or(if v < 0 { 0 } else { u32::MAX })
}
