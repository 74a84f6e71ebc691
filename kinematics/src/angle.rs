//! Angles as turns: wrapping a rotary joint's value to one turn.

use crate::Real;

/// Wraps an angle to (-pi, pi].
///
/// Whole turns come off by the floor form, `w - 2 pi floor((w + pi) / 2 pi)`, which for |q| below
/// 2 pi is exact up to the one rounding of the subtracted turns. A huge angle (beyond about 1e7 in
/// `f32`, 1e16 in `f64`) leaves a rounding error of its own size after one pass, so the pass
/// repeats: each divides the magnitude by the type's precision (2^24 or 2^53), and a few reach
/// (-pi, pi] from any finite value. The result is then the same angle up to the rounding of `q`
/// itself, which at that size is more than a turn anyway. No `%`: IEEE fmod on `f32` would link
/// 700 bytes of `fmodf` and a 64-bit division into the firmware for angles no joint reaches.
pub fn wrap_angle<T: Real>(q: T) -> T {
    let (pi, two_pi, half, two) = (T::pi(), T::two_pi(), T::of(0.5), T::of(2.0));
    let mut w = q;
    // NaN and infinities fail the test (or turn to NaN in one pass) and come out NaN, as from fmod.
    for _pass in 0..64 {
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(w.abs() > pi) {
            break;
        }
        let turns = ((w + pi) / two_pi).floor();
        // `w - turns * 2 pi`, halved and doubled (exact) so that `turns * 2 pi` cannot overflow
        // for |w| near the largest finite value: the same bits otherwise.
        w = (w * half - turns * pi) * two;
    }
    // floor puts -pi exactly at -pi; map it to +pi so the interval is half-open at the bottom.
    if w <= -pi {
        w += two_pi;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::{PI, TAU};

    /// Small angles: the remainder the old `%` form gave, exactly (one subtraction of whole turns
    /// rounded once), and the interval's edges.
    #[test]
    fn one_turn_or_less_wraps_exactly() {
        for q in [0.0, 1.0, -1.0, 3.0, -3.0, 4.0, -4.0, 6.0, -6.2, PI, -PI, TAU - 1e-9] {
            let expected = {
                let r = q % TAU;
                let w = r - TAU * ((r + PI) / TAU).floor();
                if w <= -PI {
                    w + TAU
                } else {
                    w
                }
            };
            assert_eq!(wrap_angle(q), expected, "{q}");
        }
        assert_eq!(wrap_angle(-PI), PI);
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(core::f32::consts::PI), core::f32::consts::PI);
    }

    /// Any finite angle lands in (-pi, pi], within the rounding of its own size of the true
    /// remainder; non-finite ones give NaN.
    #[test]
    fn huge_angles_land_in_one_turn() {
        for q in [1e3, -7.5e5, 1e7, 1e12, -1e16, 1e20, 1e100, -1e300, f64::MAX, f64::MIN] {
            let w = wrap_angle(q);
            assert!(w > -PI && w <= PI, "{q}: {w}");
        }
        for q in [1e3f32, -7.5e5, 1e7, 1e12, -1e30, f32::MAX, f32::MIN] {
            let w = wrap_angle(q);
            assert!(w > -core::f32::consts::PI && w <= core::f32::consts::PI, "{q}: {w}");
        }
        for q in [1e3f64, -7.5e5, 123_456.789] {
            let exact = {
                let r = q % TAU;
                if r > PI {
                    r - TAU
                } else if r <= -PI {
                    r + TAU
                } else {
                    r
                }
            };
            assert!((wrap_angle(q) - exact).abs() <= q.abs() * f64::EPSILON, "{q}");
        }
        for q in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(wrap_angle(q).is_nan());
        }
        assert!(wrap_angle(f32::INFINITY).is_nan());
    }
}
