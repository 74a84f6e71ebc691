//! Uniform cubic B-spline with the keyframe positions as control points: C2 everywhere, smoother
//! than the interpolating methods, but approximating: it passes through the first and last
//! keyframe and, in general, through no interior one.
//!
//! The control sequence repeats each end point three times, `P0 P0 P0 P1 ... Pn-1 Pn-1 Pn-1`, so
//! the curve starts exactly at `P0` and ends exactly at `Pn-1`, at rest (zero velocity and
//! acceleration) at both. With `n` control points there are `n + 1` segments, spread uniformly
//! over `[start, end]` (uniform knots): the curve is C2 in time. Only the first and last keyframe
//! times are used; interior keyframe times play no part in a uniform B-spline.
//!
//! Each segment is `sum_k B_k(s) Q_{j+k}` with the uniform cubic basis
//! `B0 = (1-s)^3/6`, `B1 = (3s^3 - 6s^2 + 4)/6`, `B2 = (-3s^3 + 3s^2 + 3s + 1)/6`, `B3 = s^3/6`.

use super::{Curve, Sample, TrajectoryError};
use crate::Real;
use nalgebra::SVector;

/// Samples the uniform cubic B-spline with control points `control` spread over `[start, end]`.
/// Before `start` and after `end` it holds the end point at rest, as [`Curve::sample`] does.
///
/// Errors: [`TrajectoryError::Empty`] without control points, [`TrajectoryError::NonFinite`] for a
/// NaN or infinite point (its index) or time (index 0), and
/// [`TrajectoryError::TimesNotIncreasing`] (index 1) when `end <= start` with more than one point.
/// For a validated [`Curve`], [`Curve::bspline_sample`] cannot fail.
pub fn bspline_sample<T: Real, const J: usize>(
    control: &[SVector<T, J>],
    start: T,
    end: T,
    t: T,
) -> Result<Sample<T, J>, TrajectoryError> {
    if control.is_empty() {
        return Err(TrajectoryError::Empty);
    }
    if let Some(index) = control.iter().position(|p| !p.iter().all(|x| x.finite())) {
        return Err(TrajectoryError::NonFinite { index });
    }
    if !(start.finite() && end.finite() && t.finite()) {
        return Err(TrajectoryError::NonFinite { index: 0 });
    }
    if control.len() > 1 && end <= start {
        return Err(TrajectoryError::TimesNotIncreasing { index: 1 });
    }
    Ok(sample(control, start, end, t))
}

impl<T: Real, const J: usize, const K: usize> Curve<T, J, K> {
    /// Samples the uniform cubic B-spline whose control points are this curve's keyframe positions
    /// over `[start(), end()]` (see the module documentation). Independent of the curve's
    /// interpolation and velocities.
    pub fn bspline_sample(&self, t: T) -> Sample<T, J> {
        sample(self.positions(), self.start(), self.end(), t)
    }
}

/// Number of segments of the clamped uniform B-spline on `n` control points.
fn segments(n: usize) -> usize {
    n + 1
}

/// The unchecked sampler: `control` non-empty and finite, `end > start` unless one point.
fn sample<T: Real, const J: usize>(control: &[SVector<T, J>], start: T, end: T, t: T) -> Sample<T, J> {
    let n = control.len();
    let hold = |p: SVector<T, J>| Sample { position: p, velocity: SVector::zeros(), acceleration: SVector::zeros() };
    match (control.first(), control.last()) {
        (Some(&first), Some(&last)) => {
            if n == 1 || t <= start {
                return hold(first);
            }
            if t >= end {
                return hold(last);
            }
        }
        _ => return hold(SVector::zeros()),
    }
    let m = segments(n);
    let width = (end - start) / T::of(m as f64);
    let u = (t - start) / width;
    // Saturating float-to-int conversion; the min keeps the last knot in the last segment.
    let j = (u.to_f64().max(0.0) as usize).min(m - 1);
    segment_sample(control, j, u - T::of(j as f64), width)
}

/// Segment `j` (in `0..n + 1`) at local parameter `s`, with `width` seconds per segment.
pub(crate) fn segment_sample<T: Real, const J: usize>(
    control: &[SVector<T, J>],
    j: usize,
    s: T,
    width: T,
) -> Sample<T, J> {
    let n = control.len();
    // Extended control point k is `control[k - 2]` clamped to the ends (the tripled end points).
    let q =
        |k: usize| control.get(k.saturating_sub(2).min(n.saturating_sub(1))).copied().unwrap_or_else(SVector::zeros);
    let sixth = T::one() / T::of(6.0);
    let half = T::of(0.5);
    let (one, two, three, four) = (T::one(), T::of(2.0), T::of(3.0), T::of(4.0));
    let (s2, s3, r) = (s * s, s * s * s, T::one() - s);
    let b = [
        r * r * r * sixth,
        (three * s3 - T::of(6.0) * s2 + four) * sixth,
        (-three * s3 + three * s2 + three * s + one) * sixth,
        s3 * sixth,
    ];
    let d1 = [-r * r * half, (three * s2 - four * s) * half, (-three * s2 + two * s + one) * half, s2 * half];
    let d2 = [r, three * s - two, one - three * s, s];
    let combine = |w: [T; 4]| q(j) * w[0] + q(j + 1) * w[1] + q(j + 2) * w[2] + q(j + 3) * w[3];
    Sample { position: combine(b), velocity: combine(d1) / width, acceleration: combine(d2) / (width * width) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector1;

    fn points() -> [SVector<f64, 1>; 5] {
        [0.0, 2.0, -1.0, 3.0, 1.0].map(Vector1::new)
    }

    #[test]
    fn joins_are_c2() {
        let p = points();
        for j in 0..segments(p.len()) - 1 {
            let (l, r) = (segment_sample(&p, j, 1.0, 0.7), segment_sample(&p, j + 1, 0.0, 0.7));
            assert!((l.position - r.position).norm() < 1e-14, "position at join {j}");
            assert!((l.velocity - r.velocity).norm() < 1e-13, "velocity at join {j}");
            assert!((l.acceleration - r.acceleration).norm() < 1e-12, "acceleration at join {j}");
        }
    }

    #[test]
    fn starts_and_ends_at_the_end_points_at_rest() {
        let p = points();
        let first = segment_sample(&p, 0, 0.0, 1.0);
        let last = segment_sample(&p, segments(p.len()) - 1, 1.0, 1.0);
        assert!((first.position[0] - 0.0).abs() < 1e-15 && (last.position[0] - 1.0).abs() < 1e-15);
        for s in [first, last] {
            assert!(s.velocity.norm() < 1e-15 && s.acceleration.norm() < 1e-14);
        }
    }

    #[test]
    fn refuses_bad_input() {
        let p = points();
        assert_eq!(bspline_sample::<f64, 1>(&[], 0.0, 1.0, 0.5).unwrap_err(), TrajectoryError::Empty);
        assert_eq!(bspline_sample(&p, 1.0, 1.0, 0.5).unwrap_err(), TrajectoryError::TimesNotIncreasing { index: 1 });
        assert_eq!(bspline_sample(&p, 0.0, 1.0, f64::NAN).unwrap_err(), TrajectoryError::NonFinite { index: 0 });
        assert!(bspline_sample(&p[..1], 1.0, 1.0, 0.5).is_ok());
    }
}
