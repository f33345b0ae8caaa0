//! `f64` → integer rounding for the control cycle, exact and without `libm`'s software
//! `floor` / `round` (the baseline x86-64 target has no rounding instruction, and the plant
//! reads its encoder several times per cycle). Every function gives bit for bit what
//! `libm::floor(x) as i64` resp. `libm::round(x) as i64` gives, saturation and NaN (→ 0)
//! included: the truncating cast is exact, and for |x| ≥ 2⁵² every `f64` is an integer
//! already, so the correction below never sees a fraction it cannot represent.

/// `⌊x⌋` as `i64` (saturating; NaN → 0), equal to `libm::floor(x) as i64`.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    // Integral already, infinite or NaN (then the cast saturated or gave 0).
    if x.abs() >= INTEGRAL || x.is_nan() {
        return t;
    }
    // Branch-free: the sign of a fraction is as likely one way as the other.
    t - i64::from((t as f64) > x)
}

/// `x` rounded to the nearest integer, halves away from zero, as `i64` (saturating;
/// NaN → 0), equal to `libm::round(x) as i64`.
#[inline(always)]
pub fn round_i64(x: f64) -> i64 {
    let t = x as i64;
    // Integral already, infinite or NaN (then the cast saturated or gave 0).
    if x.abs() >= INTEGRAL || x.is_nan() {
        return t;
    }
    let frac = x - t as f64;
    // Branch-free: which way a fraction rounds is as likely one way as the other.
    t + i64::from(frac >= 0.5) - i64::from(frac <= -0.5)
}

/// `⌊x⌋` (as `floor`) for |x| < 2⁵⁰, in floating point: `x` rounded to the nearest integer
/// by adding and taking away 1.5·2⁵² (exact below 2⁵¹), less one where that is above `x`.
/// No conversion to an integer and back: the encoders' readings sit on the plant's
/// dependent chain. `None` for a larger |x| or a NaN.
#[inline(always)]
pub fn floor_small(x: f64) -> Option<f64> {
    if x.abs() < SMALL {
        let r = (x + ROUND_MAGIC) - ROUND_MAGIC;
        Some(r - if r > x { 1.0 } else { 0.0 })
    } else {
        None
    }
}

/// 1.5·2⁵²: `(x + ROUND_MAGIC) − ROUND_MAGIC` is `x` rounded to the nearest integer (ties
/// to even) for |x| < 2⁵¹.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

/// [`floor_small`]'s range (2⁵⁰).
const SMALL: f64 = 1_125_899_906_842_624.0;

/// Below this magnitude an `f64` may have a fraction; at and above it every one is an
/// integer (2⁵²).
const INTEGRAL: f64 = 4_503_599_627_370_496.0;

/// `⌊x⌋`, bit for bit `libm::floor(x)`.
#[inline(always)]
pub fn floor(x: f64) -> f64 {
    if x != 0.0 && x.abs() < INTEGRAL {
        floor_i64(x) as f64
    } else {
        x
    }
}

/// `x` rounded to the nearest integer, halves away from zero: bit for bit `libm::round(x)`
/// (a result of zero keeps the sign of `x`).
#[inline(always)]
pub fn round(x: f64) -> f64 {
    if x.abs() < INTEGRAL {
        let r = round_i64(x) as f64;
        if r == 0.0 {
            libm::copysign(0.0, x)
        } else {
            r
        }
    } else {
        x
    }
}

/// ⌊angle / rad_per_inc⌋ (an encoder's reading), as `i64` and as `f64`, bit for bit the floored
/// quotient. By a multiplication with `inc_per_rad` (a division's latency on the plant's
/// dependent chain is what it saves): the product differs from the quotient by a few ulp, which
/// changes the floor only within them of a whole increment; there (and for a NaN, an infinity
/// or beyond 2⁵⁰, where the tolerance exceeds an increment) the division decides. The floor is
/// taken in floating point ([`floor_small`]), without a conversion to an integer and back.
#[inline(always)]
pub fn floored_quotient(angle: f64, inc_per_rad: f64, rad_per_inc: f64) -> (i64, f64) {
    let y = angle * inc_per_rad;
    if let Some(f) = floor_small(y) {
        let frac = y - f;
        let tol = 8.0 * f64::EPSILON * libm::fabs(y);
        if frac > tol && frac < 1.0 - tol {
            return (f as i64, f);
        }
    }
    let f = floor_i64(angle / rad_per_inc);
    (f, f as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(x: f64) {
        match floor_small(x) {
            // The same integer (a zero's sign aside: it is used as an integer and in y − ⌊y⌋
            // as `floor_i64`'s +0.0).
            Some(f) => {
                assert!(x.abs() < SMALL, "floor_small {x}");
                assert_eq!(f, libm::floor(x), "floor_small {x}");
                assert_eq!(
                    f.to_bits(),
                    (floor_i64(x) as f64).to_bits(),
                    "floor_small {x}"
                );
            }
            None => assert!(x.is_nan() || x.abs() >= SMALL, "floor_small {x}"),
        }
        assert_eq!(floor_i64(x), libm::floor(x) as i64, "floor {x}");
        assert_eq!(round_i64(x), libm::round(x) as i64, "round {x}");
        if !x.is_nan() {
            assert_eq!(floor(x).to_bits(), libm::floor(x).to_bits(), "floor {x}");
            assert_eq!(round(x).to_bits(), libm::round(x).to_bits(), "round {x}");
        }
    }

    #[test]
    fn equal_to_libm() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            -4503599627370495.5,
            4503599627370497.0,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            123456.999999,
            -123456.000001,
            -0.3,
            1125899906842623.5,
            -1125899906842623.5,
            1125899906842624.0,
            -1125899906842624.5,
        ] {
            check(x);
        }
        // A sweep over many magnitudes and fractions, both signs.
        let mut x = 1e-3;
        while x < 1e19 {
            for f in [0.0, 0.25, 0.5, 0.75, 0.999_999_9] {
                check(x + f);
                check(-(x + f));
            }
            x *= 1.37;
        }
    }
}
