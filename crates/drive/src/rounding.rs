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

#[cfg(test)]
mod tests {
    use super::*;

    fn check(x: f64) {
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
