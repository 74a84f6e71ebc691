//! Tangents chosen from the keyframes alone: Catmull-Rom, Kochanek-Bartels and monotone
//! (Fritsch-Carlson), with a choice of end conditions.
//!
//! Each constructor only assigns velocities and hands them to [`Curve::with_velocities`] or
//! [`Curve::with_tangents`]; the curve between two keyframes stays the cubic Hermite segment.
//! Every tangent depends on its keyframe and the two neighbours only, so moving one keyframe
//! changes at most the two segments on either side of it.
//!
//! Panics: none. Keyframes are checked (count, finiteness, increasing times) before any tangent is
//! computed, and every index stays below the checked length. A finite input whose velocities
//! overflow is refused as [`TrajectoryError::NonFinite`].

use super::curve::usable_interval;
use super::{Curve, Keyframe, TrajectoryError};
use crate::Real;
use nalgebra::SVector;

/// The velocity at the first and the last keyframe, which have only one neighbour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EndCondition<T: Real, const J: usize> {
    /// Start and end at rest.
    ZeroVelocity,
    /// Start and end with the given velocities (per second).
    Clamped {
        /// Velocity leaving the first keyframe.
        start: SVector<T, J>,
        /// Velocity arriving at the last keyframe.
        end: SVector<T, J>,
    },
    /// The end velocity that makes the end segment's second derivative zero at the end keyframe:
    /// `v0 = (3 d - v1) / 2` at the start and `v1 = (3 d - v0) / 2` at the end, with `d` the end
    /// segment's mean slope and the other velocity that of its interior keyframe. With two
    /// keyframes and both ends natural the curve is the straight line.
    Natural,
}

/// Kochanek-Bartels (TCB) parameters, each usually in [-1, 1]; all zero is Catmull-Rom.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KochanekBartels<T: Real> {
    /// Tension: 1 shrinks the tangents to zero, -1 doubles them.
    pub tension: T,
    /// Continuity: non-zero gives a keyframe different arriving and leaving velocities (a corner).
    pub continuity: T,
    /// Bias: positive leans the tangent towards the incoming segment, negative towards the outgoing.
    pub bias: T,
}

/// Refuses keyframes the same way (and in the same order) as the curve builder, so that no tangent
/// is computed from a NaN or a zero-length interval and the error names the offending keyframe.
pub(super) fn check<T: Real, const J: usize, const K: usize>(
    keyframes: &[Keyframe<T, J>],
) -> Result<(), TrajectoryError> {
    if keyframes.is_empty() {
        return Err(TrajectoryError::Empty);
    }
    if keyframes.len() > K {
        return Err(TrajectoryError::TooMany { capacity: K });
    }
    let mut previous: Option<T> = None;
    for (index, k) in keyframes.iter().enumerate() {
        if !(k.time.finite() && k.position.iter().all(|x| x.finite())) {
            return Err(TrajectoryError::NonFinite { index });
        }
        if previous.is_some_and(|p| !usable_interval(p, k.time)) {
            return Err(TrajectoryError::TimesNotIncreasing { index });
        }
        previous = Some(k.time);
    }
    Ok(())
}

/// Mean slope of segment `i` (per second). `i + 1` must be a keyframe index.
pub(super) fn slope<T: Real, const J: usize>(keyframes: &[Keyframe<T, J>], i: usize) -> SVector<T, J> {
    let (a, b) = (&keyframes[i], &keyframes[i + 1]);
    (b.position - a.position) / (b.time - a.time)
}

/// Start velocity making the acceleration zero at the start of a segment of mean slope `d` whose
/// end velocity is `v1`.
fn natural_start<T: Real, const J: usize>(d: SVector<T, J>, v1: SVector<T, J>) -> SVector<T, J> {
    (d * T::of(3.0) - v1) * T::of(0.5)
}

impl<T: Real, const J: usize, const K: usize> Curve<T, J, K> {
    /// Non-uniform Catmull-Rom: the velocity at an interior keyframe is the slope of the chord
    /// between its neighbours, `u_i = (f_{i+1} - f_{i-1}) / (t_{i+1} - t_{i-1})`; the ends follow
    /// `ends`. C1. One keyframe is a hold.
    pub fn catmull_rom(keyframes: &[Keyframe<T, J>], ends: EndCondition<T, J>) -> Result<Self, TrajectoryError> {
        check::<T, J, K>(keyframes)?;
        let mut v = [SVector::<T, J>::zeros(); K];
        let n = keyframes.len();
        for i in 1..n.saturating_sub(1) {
            let (a, b) = (&keyframes[i - 1], &keyframes[i + 1]);
            v[i] = (b.position - a.position) / (b.time - a.time);
        }
        let mut w = v;
        apply_ends(keyframes, ends, &mut v, &mut w)?;
        Self::with_tangents(keyframes, &v[..n], &w[..n])
    }

    /// Kochanek-Bartels (TCB) tangents generalised to non-uniform times.
    ///
    /// With `t, c, b` the parameters, `D = t_{i+1} - t_{i-1}` and the chords `a = f_i - f_{i-1}`,
    /// `e = f_{i+1} - f_i`, the velocities at an interior keyframe are
    ///
    /// - arriving: `(1-t) [(1+b)(1-c) a + (1-b)(1+c) e] / D`,
    /// - leaving: `(1-t) [(1+b)(1+c) a + (1-b)(1-c) e] / D`.
    ///
    /// On uniform unit times `D = 2` and these are the textbook TCB tangents; with `t = c = b = 0`
    /// both are the non-uniform Catmull-Rom velocity. Where `c != 0` the curve has a corner (C0);
    /// otherwise it is C1. The ends follow `ends` (arriving equals leaving there).
    pub fn kochanek_bartels(
        keyframes: &[Keyframe<T, J>],
        tcb: KochanekBartels<T>,
        ends: EndCondition<T, J>,
    ) -> Result<Self, TrajectoryError> {
        check::<T, J, K>(keyframes)?;
        let one = T::one();
        let KochanekBartels { tension, continuity: c, bias: b } = tcb;
        let scale = one - tension;
        let (in_a, in_e) = (scale * (one + b) * (one - c), scale * (one - b) * (one + c));
        let (out_a, out_e) = (scale * (one + b) * (one + c), scale * (one - b) * (one - c));
        let mut arriving = [SVector::<T, J>::zeros(); K];
        let mut leaving = [SVector::<T, J>::zeros(); K];
        let n = keyframes.len();
        for i in 1..n.saturating_sub(1) {
            let (p, k, q) = (&keyframes[i - 1], &keyframes[i], &keyframes[i + 1]);
            let span = q.time - p.time;
            let (a, e) = ((k.position - p.position) / span, (q.position - k.position) / span);
            arriving[i] = a * in_a + e * in_e;
            leaving[i] = a * out_a + e * out_e;
        }
        apply_ends(keyframes, ends, &mut arriving, &mut leaving)?;
        Self::with_tangents(keyframes, &arriving[..n], &leaving[..n])
    }

    /// Monotone cubic interpolation (Fritsch-Carlson), joint by joint: never overshoots between
    /// keyframes, so each segment stays within its two keyframe values.
    ///
    /// Each interior velocity starts as the Catmull-Rom one; it is zero where the neighbouring
    /// slopes `d0`, `d1` differ in sign or one is zero (a local extremum or a flat stretch), and it
    /// is limited to `3 min(|d0|, |d1|)`. That keeps every segment's `(alpha, beta) = (v0 / d,
    /// v1 / d)` in the square `[0, 3]^2`, one of Fritsch and Carlson's sufficient regions for a
    /// monotone cubic (SIAM J. Numer. Anal. 17, 1980, step 5); being a per-keyframe limit, it keeps
    /// the method as local as Catmull-Rom. The ends are one-sided: the velocity there is the end
    /// segment's slope. C1.
    pub fn monotone(keyframes: &[Keyframe<T, J>]) -> Result<Self, TrajectoryError> {
        check::<T, J, K>(keyframes)?;
        let mut v = [SVector::<T, J>::zeros(); K];
        let n = keyframes.len();
        if n >= 2 {
            v[0] = slope(keyframes, 0);
            v[n - 1] = slope(keyframes, n - 2);
        }
        let three = T::of(3.0);
        for i in 1..n.saturating_sub(1) {
            let (d0, d1) = (slope(keyframes, i - 1), slope(keyframes, i));
            let (p, q) = (&keyframes[i - 1], &keyframes[i + 1]);
            let chord = (q.position - p.position) / (q.time - p.time);
            for j in 0..J {
                let (a, b) = (d0[j], d1[j]);
                let same_sign = (a > T::zero() && b > T::zero()) || (a < T::zero() && b < T::zero());
                v[i][j] = if same_sign {
                    let limit = three * a.abs().min(b.abs());
                    let m = chord[j];
                    if m.abs() > limit {
                        limit.copysign(m)
                    } else {
                        m
                    }
                } else {
                    T::zero()
                };
            }
        }
        Self::with_velocities(keyframes, &v[..n])
    }
}

/// Fills the first and last entries of `arriving` and `leaving` by the end condition. The interior
/// entries must already hold their values (the natural end reads its neighbour's). With one
/// keyframe only checks a clamp for finiteness.
fn apply_ends<T: Real, const J: usize>(
    keyframes: &[Keyframe<T, J>],
    ends: EndCondition<T, J>,
    arriving: &mut [SVector<T, J>],
    leaving: &mut [SVector<T, J>],
) -> Result<(), TrajectoryError> {
    let n = keyframes.len().min(arriving.len()).min(leaving.len());
    if n < 2 {
        // A single keyframe is a hold: its velocity stays zero whatever the condition, but a NaN
        // clamp is refused as it would be with more keyframes.
        if let EndCondition::Clamped { start, end } = ends {
            if !start.iter().chain(end.iter()).all(|x| x.finite()) {
                return Err(TrajectoryError::NonFinite { index: 0 });
            }
        }
        return Ok(());
    }
    let last = n - 1;
    let (start, end) = match ends {
        EndCondition::ZeroVelocity => (SVector::zeros(), SVector::zeros()),
        EndCondition::Clamped { start, end } => (start, end),
        EndCondition::Natural => {
            let (first, final_) = (slope(keyframes, 0), slope(keyframes, last - 1));
            if n == 2 {
                // Both ends natural on one segment: the only cubic is the line.
                (first, final_)
            } else {
                (natural_start(first, arriving[1]), natural_start(final_, leaving[last - 1]))
            }
        }
    };
    arriving[0] = start;
    leaving[0] = start;
    arriving[last] = end;
    leaving[last] = end;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector1;

    fn keys(points: &[(f64, f64)]) -> heapless::Vec<Keyframe<f64, 1>, 8> {
        points.iter().map(|&(time, p)| Keyframe { time, position: Vector1::new(p) }).collect()
    }

    #[test]
    fn refuses_bad_keyframes_before_computing_tangents() {
        let ends = EndCondition::ZeroVelocity;
        assert_eq!(Curve::<f64, 1, 4>::catmull_rom(&[], ends).unwrap_err(), TrajectoryError::Empty);
        let k = keys(&[(0.0, 0.0), (1.0, 1.0), (1.0, 2.0), (2.0, f64::NAN)]);
        assert_eq!(
            Curve::<f64, 1, 4>::catmull_rom(&k, ends).unwrap_err(),
            TrajectoryError::TimesNotIncreasing { index: 2 }
        );
        assert_eq!(Curve::<f64, 1, 4>::monotone(&k).unwrap_err(), TrajectoryError::TimesNotIncreasing { index: 2 });
        let k = keys(&[(0.0, 0.0), (1.0, f64::INFINITY), (2.0, 2.0)]);
        let tcb = KochanekBartels::default();
        assert_eq!(
            Curve::<f64, 1, 4>::kochanek_bartels(&k, tcb, ends).unwrap_err(),
            TrajectoryError::NonFinite { index: 1 }
        );
        let k = keys(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]);
        assert_eq!(Curve::<f64, 1, 2>::monotone(&k).unwrap_err(), TrajectoryError::TooMany { capacity: 2 });
    }

    #[test]
    fn natural_end_has_zero_acceleration() {
        let k = keys(&[(0.0, 0.0), (0.5, 2.0), (2.0, 1.0), (2.25, 3.0)]);
        let c = Curve::<f64, 1, 8>::catmull_rom(&k, EndCondition::Natural).unwrap();
        let first = c.segment(0).sample(0.0).acceleration[0];
        let last = c.segment(2).sample(2.25).acceleration[0];
        assert!(first.abs() < 1e-12 && last.abs() < 1e-12, "{first} {last}");
    }

    #[test]
    fn two_natural_ends_make_a_line() {
        let k = keys(&[(1.0, 1.0), (3.0, 2.0)]);
        let c = Curve::<f64, 1, 8>::catmull_rom(&k, EndCondition::Natural).unwrap();
        assert_eq!(c.leaving()[0][0], 0.5);
        assert_eq!(c.arriving()[1][0], 0.5);
    }
}
