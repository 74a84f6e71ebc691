//! The cubic Hermite segment: the curve between two keyframes given their values and first
//! derivatives, on a non-uniform time interval.
//!
//! With `h = t1 - t0` and `s = (t - t0) / h` in [0, 1]:
//! `p(t) = H0(s) p0 + H1(s) h v0 + H2(s) h v1 + H3(s) p1` with the basis
//! `H0 = 2s^3 - 3s^2 + 1`, `H1 = s^3 - 2s^2 + s`, `H2 = s^3 - s^2`, `H3 = -2s^3 + 3s^2`.
//! Velocities are in units per second, so they are scaled by `h` into the unit interval and the
//! derivatives are scaled back by `1/h` and `1/h^2`.

use crate::Real;
use nalgebra::SVector;

/// Position, velocity and acceleration of every joint at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<T: Real, const J: usize> {
    /// Value (rad or m).
    pub position: SVector<T, J>,
    /// First time derivative (per second).
    pub velocity: SVector<T, J>,
    /// Second time derivative (per second squared).
    pub acceleration: SVector<T, J>,
}

/// The Hermite basis `[H0, H1, H2, H3]` at `s`, and its first and second derivatives in `s`.
pub fn basis<T: Real>(s: T) -> [[T; 4]; 3] {
    let (two, three, four, six) = (T::of(2.0), T::of(3.0), T::of(4.0), T::of(6.0));
    let s2 = s * s;
    let s3 = s2 * s;
    [
        [two * s3 - three * s2 + T::one(), s3 - two * s2 + s, s3 - s2, -two * s3 + three * s2],
        [six * s2 - six * s, three * s2 - four * s + T::one(), three * s2 - two * s, -six * s2 + six * s],
        [T::of(12.0) * s - six, six * s - four, six * s - two, -T::of(12.0) * s + six],
    ]
}

/// One cubic Hermite segment from `(t0, p0, v0)` to `(t1, p1, v1)`, `t1 > t0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HermiteSegment<T: Real, const J: usize> {
    /// Start time (s).
    pub t0: T,
    /// End time (s).
    pub t1: T,
    /// Value at `t0`.
    pub p0: SVector<T, J>,
    /// Velocity leaving `t0`.
    pub v0: SVector<T, J>,
    /// Value at `t1`.
    pub p1: SVector<T, J>,
    /// Velocity arriving at `t1`.
    pub v1: SVector<T, J>,
}

impl<T: Real, const J: usize> HermiteSegment<T, J> {
    /// Evaluates at `t`, clamped to `[t0, t1]` (a segment never extrapolates).
    #[inline]
    pub fn sample(&self, t: T) -> Sample<T, J> {
        let h = self.t1 - self.t0;
        let s = ((t - self.t0) / h).max(T::zero()).min(T::one());
        let [b, d1, d2] = basis(s);
        let hh = h * h;
        // One pass over the joints, each value computed as the vector form would (same
        // operations, same order, so the same bits): vector expressions would make a pass, and a
        // temporary, per term, which costs a quarter of a player tick on the M4F.
        let mut out = Sample { position: SVector::zeros(), velocity: SVector::zeros(), acceleration: SVector::zeros() };
        for j in 0..J {
            let (p0, m0, m1, p1) = (self.p0[j], self.v0[j] * h, self.v1[j] * h, self.p1[j]);
            let combine = |w: &[T; 4]| p0 * w[0] + m0 * w[1] + m1 * w[2] + p1 * w[3];
            out.position[j] = combine(&b);
            out.velocity[j] = combine(&d1) / h;
            out.acceleration[j] = combine(&d2) / hh;
        }
        out
    }
}
