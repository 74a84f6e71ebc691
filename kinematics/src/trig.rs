//! Sine and cosine of an `f32` computed in `f32`. The `libm` crate's `sincosf` (musl's) reduces and
//! evaluates in `f64`, which the Cortex-M4F's single-precision FPU runs in software: about 2,400
//! instructions per call (`armctl bench mcu`), most of a forward kinematics pass. Here the argument
//! is reduced by Cody-Waite with a three-part pi/2 and the minimax polynomials of Cephes' `sinf` and
//! `cosf` are evaluated on [-pi/4, pi/4]: all single precision, no table, no branch but the
//! quadrant's.
//!
//! Accuracy (checked against `f64` in the tests): within 2.5e-7 absolute for |x| <= 100, 1e-6 up
//! to 8192. Beyond 8192 rad (no joint angle; a continuous joint's accumulated angle after thousands
//! of turns) the argument is first wrapped to one turn in `f32` ([`crate::wrap_angle`]), which
//! costs about |x| * 2e-7.

use core::f32::consts::FRAC_2_PI;

/// pi/2 in three parts: the first has 8 significant bits, so `k * PIO2_1` is exact for |k| < 2^16,
/// and the rest of pi/2 is carried by the next two (Cephes' DP1..DP3, doubled).
const PIO2_1: f32 = 1.570_312_5;
const PIO2_2: f32 = 4.837_513e-4;
const PIO2_3: f32 = 7.549_79e-8;
/// Where the three-part reduction stops being accurate to an ulp.
const REDUCTION_LIMIT: f32 = 8192.0;

/// sin(r) for |r| <= pi/4 (Cephes `sinf` coefficients).
fn sin_kernel(r: f32) -> f32 {
    let z = r * r;
    let p = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z;
    r + r * p
}

/// cos(r) for |r| <= pi/4 (Cephes `cosf` coefficients).
fn cos_kernel(r: f32) -> f32 {
    let z = r * r;
    let p = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z;
    1.0 - 0.5 * z + p
}

/// `(sin x, cos x)`; NaN for NaN and infinities.
pub fn sin_cos(x: f32) -> (f32, f32) {
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    let x = if x.abs() > REDUCTION_LIMIT { crate::wrap_angle(x) } else { x };
    // The nearest quadrant: |k| <= 8192 * 2/pi + 1, well inside i32 and the exact range of PIO2_1.
    let k = (x * FRAC_2_PI + 0.5f32.copysign(x)) as i32;
    let kf = k as f32;
    let r = ((x - kf * PIO2_1) - kf * PIO2_2) - kf * PIO2_3;
    let (s, c) = (sin_kernel(r), cos_kernel(r));
    match k & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn worst_error(from: f32, to: f32, steps: u32) -> f64 {
        let mut worst = 0.0f64;
        for i in 0..=steps {
            let x = from + (to - from) * i as f32 / steps as f32;
            let (s, c) = sin_cos(x);
            let (es, ec) = (f64::from(x).sin(), f64::from(x).cos());
            worst = worst.max((f64::from(s) - es).abs()).max((f64::from(c) - ec).abs());
        }
        worst
    }

    #[test]
    fn matches_f64_within_stated_tolerances() {
        assert!(worst_error(-std::f32::consts::PI, std::f32::consts::PI, 200_000) <= 1.5e-7);
        assert!(worst_error(-100.0, 100.0, 400_000) <= 2.5e-7);
        assert!(worst_error(-8192.0, 8192.0, 400_000) <= 1e-6);
    }

    #[test]
    fn exact_where_it_matters_and_nan_for_non_finite() {
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        let (s, c) = sin_cos(core::f32::consts::FRAC_PI_2);
        assert!((s - 1.0).abs() <= f32::EPSILON && c.abs() <= 1e-7);
        let (s, c) = sin_cos(-core::f32::consts::PI);
        assert!(s.abs() <= 1e-7 && (c + 1.0).abs() <= f32::EPSILON);
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan());
        }
    }

    #[test]
    fn large_arguments_degrade_as_documented() {
        for x in [1e4f32, -3e4, 1e5, 1e6] {
            let (s, c) = sin_cos(x);
            let bound = f64::from(x.abs()) * 2e-7 + 1e-6;
            assert!((f64::from(s) - f64::from(x).sin()).abs() <= bound, "sin {x}");
            assert!((f64::from(c) - f64::from(x).cos()).abs() <= bound, "cos {x}");
        }
    }

    #[test]
    fn pythagoras_holds() {
        for i in 0..10_000 {
            let x = -50.0 + i as f32 * 0.01;
            let (s, c) = sin_cos(x);
            assert!((s * s + c * c - 1.0).abs() <= 3.0 * f32::EPSILON, "{x}");
        }
    }
}
