//! Interpolating cubic splines (C2): the keyframe velocities that make the second derivative
//! continuous, found by one tridiagonal solve shared by all joints.
//!
//! With `h_i = t_{i+1} - t_i` and `d_i` the mean slope of segment `i`, continuity of the second
//! derivative of the Hermite segments at an interior keyframe `i` reads
//! `h_i v_{i-1} + 2 (h_{i-1} + h_i) v_i + h_{i-1} v_{i+1} = 3 (h_i d_{i-1} + h_{i-1} d_i)`
//! (the usual form multiplied by `h_{i-1} h_i`, which keeps `1/h` out of the matrix). The natural
//! end rows `2 v_0 + v_1 = 3 d_0` and `v_{n-2} + 2 v_{n-1} = 3 d_{n-2}` set the end accelerations to
//! zero; the clamped rows fix the end velocities. The matrix is strictly diagonally dominant, so
//! the Thomas algorithm needs no pivoting and never divides by zero. Unlike the tangent methods
//! every keyframe moves every velocity: the spline is global.
//!
//! Scratch arrays have the curve's capacity `K`; nothing is allocated. Panics: none (keyframes are
//! checked before the solve).

use super::tangents::{check, slope};
use super::{Curve, Keyframe, TrajectoryError};
use crate::Real;
use nalgebra::SVector;

/// How the first and last rows of the system are closed.
#[derive(Clone, Copy)]
enum Ends<T: Real, const J: usize> {
    Natural,
    Clamped(SVector<T, J>, SVector<T, J>),
}

impl<T: Real, const J: usize, const K: usize> Curve<T, J, K> {
    /// The natural cubic spline: C2 through every keyframe, zero acceleration at both ends. One
    /// keyframe is a hold; two give the straight line.
    pub fn natural_spline(keyframes: &[Keyframe<T, J>]) -> Result<Self, TrajectoryError> {
        Self::spline(keyframes, Ends::Natural)
    }

    /// The clamped cubic spline: C2 through every keyframe, leaving the first keyframe at
    /// `start_velocity` and arriving at the last at `end_velocity` (per second).
    pub fn clamped_spline(
        keyframes: &[Keyframe<T, J>],
        start_velocity: SVector<T, J>,
        end_velocity: SVector<T, J>,
    ) -> Result<Self, TrajectoryError> {
        Self::spline(keyframes, Ends::Clamped(start_velocity, end_velocity))
    }

    fn spline(keyframes: &[Keyframe<T, J>], ends: Ends<T, J>) -> Result<Self, TrajectoryError> {
        check::<T, J, K>(keyframes)?;
        let n = keyframes.len();
        let mut v = [SVector::<T, J>::zeros(); K];
        if n >= 2 {
            solve::<T, J, K>(keyframes, ends, &mut v[..n]);
        } else if let Ends::Clamped(start, end) = ends {
            // A hold ignores the given velocities, but a NaN among them is still an error.
            if !start.iter().chain(end.iter()).all(|x| x.finite()) {
                return Err(TrajectoryError::NonFinite { index: 0 });
            }
        }
        Self::with_velocities(keyframes, &v[..n])
    }
}

/// Solves the spline system for the velocities `v` (one per keyframe, `2 <= v.len() <= K`).
fn solve<T: Real, const J: usize, const K: usize>(
    keyframes: &[Keyframe<T, J>],
    ends: Ends<T, J>,
    v: &mut [SVector<T, J>],
) {
    let n = v.len();
    let (two, three) = (T::of(2.0), T::of(3.0));
    let h = |i: usize| keyframes[i + 1].time - keyframes[i].time;
    // Row i is `sub_i v_{i-1} + diag_i v_i + sup_i v_{i+1} = rhs_i`.
    let row = |i: usize| -> (T, T, T, SVector<T, J>) {
        let (zero, one) = (T::zero(), T::one());
        match (i, ends) {
            (0, Ends::Natural) => (zero, two, one, slope(keyframes, 0) * three),
            (0, Ends::Clamped(start, _)) => (zero, one, zero, start),
            (i, Ends::Natural) if i == n - 1 => (one, two, zero, slope(keyframes, n - 2) * three),
            (i, Ends::Clamped(_, end)) if i == n - 1 => (zero, one, zero, end),
            (i, _) => {
                let (a, b) = (h(i - 1), h(i));
                (b, two * (a + b), a, (slope(keyframes, i - 1) * b + slope(keyframes, i) * a) * three)
            }
        }
    };
    // Thomas algorithm: forward elimination into `sup` (the normalised superdiagonal) and `v`
    // (the normalised right-hand side), then back substitution in place.
    let mut sup = [T::zero(); K];
    for i in 0..n {
        let (a, b, c, d) = row(i);
        let (pivot, rhs) = if i == 0 { (b, d) } else { (b - a * sup[i - 1], d - v[i - 1] * a) };
        sup[i] = c / pivot;
        v[i] = rhs / pivot;
    }
    for i in (0..n - 1).rev() {
        let next = v[i + 1];
        v[i] -= next * sup[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector1;

    fn keys(points: &[(f64, f64)]) -> heapless::Vec<Keyframe<f64, 1>, 8> {
        points.iter().map(|&(time, p)| Keyframe { time, position: Vector1::new(p) }).collect()
    }

    #[test]
    fn reproduces_a_cubic_when_clamped_with_its_end_slopes() {
        // A cubic spline reproduces any cubic exactly given its true end slopes.
        let f = |t: f64| 0.5 * t * t * t - t * t + 2.0 * t - 1.0;
        let df = |t: f64| 1.5 * t * t - 2.0 * t + 2.0;
        let times = [0.0, 0.3, 1.1, 1.5, 2.75];
        let k: heapless::Vec<_, 8> =
            times.iter().map(|&t| Keyframe { time: t, position: Vector1::new(f(t)) }).collect();
        let c = Curve::<f64, 1, 8>::clamped_spline(&k, Vector1::new(df(0.0)), Vector1::new(df(2.75))).unwrap();
        for (t, v) in times.iter().zip(c.leaving()) {
            assert!((v[0] - df(*t)).abs() < 1e-12, "{t}: {} vs {}", v[0], df(*t));
        }
    }

    #[test]
    fn two_keyframes_natural_is_a_line() {
        let c = Curve::<f64, 1, 8>::natural_spline(&keys(&[(0.0, 1.0), (2.0, 2.0)])).unwrap();
        assert!((c.leaving()[0][0] - 0.5).abs() < 1e-15 && (c.leaving()[1][0] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn single_keyframe_is_a_hold_and_non_finite_clamp_is_refused() {
        let k = keys(&[(0.0, 1.0)]);
        let c = Curve::<f64, 1, 8>::clamped_spline(&k, Vector1::new(3.0), Vector1::new(3.0)).unwrap();
        assert_eq!(c.sample(5.0).velocity[0], 0.0);
        let bad = Curve::<f64, 1, 8>::clamped_spline(&k, Vector1::new(f64::NAN), Vector1::new(0.0));
        assert_eq!(bad.unwrap_err(), TrajectoryError::NonFinite { index: 0 });
    }
}
