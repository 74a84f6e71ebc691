//! Per-joint position, velocity and acceleration limits, and a trajectory checked against them.
//!
//! [`JointLimits::check`] finds the exact extrema of every Hermite segment per joint: position is
//! a cubic (its extrema are the roots of the quadratic velocity), velocity is a quadratic (one
//! interior extremum where the linear acceleration crosses zero) and acceleration is linear (its
//! extrema are the segment ends). No sampling, so nothing slips between samples.
//!
//! [`time_scale`] makes a Hermite trajectory (keyframes and one velocity per keyframe) satisfy the
//! limits without moving any keyframe:
//!
//! 1. **Position range.** Keyframes must lie inside the range. A segment's cubic can still
//!    overshoot between two keyframes; the velocity components that push it outward are then
//!    reduced (as monotone interpolation does) until the overshoot is gone. The reduction is made
//!    against the worst case over every later reduction of any tangent by a factor in `[0, 1]`, so
//!    neither a neighbour's clamp nor the time scaling below can bring the overshoot back.
//! 2. **Velocity and acceleration.** Segment `i` gets a stretch factor `k_i >= 1`: its duration
//!    becomes `k_i h_i`. Keyframe `j` is shared by two segments, so its velocity is divided by
//!    `K_j = max(k_{j-1}, k_j)`; the curve stays C1. Stretching a segment by `k` with its
//!    tangents (velocity times duration) unchanged divides its velocities by `k` and its
//!    accelerations by `k^2`; a segment whose neighbour is stretched more sees its tangent at the
//!    shared keyframe shrink instead, which changes its shape. So the factors are found by
//!    iteration: every sweep stretches each offending segment by exactly what its current shape
//!    needs (plus a margin of 0.1 %), for at most [`MAX_SWEEPS`] sweeps. Each `k_i` is capped by a
//!    bound that holds for *any* shrinking of its tangents (|dp/ds| <= 1.5|Δ| + |m0| + |m1| and
//!    |d²p/ds²| <= 6|Δ| + 4|m0| + 4|m1| on the unit interval); segments still failing after the
//!    sweeps are set to that cap, which always passes, so the procedure terminates with a valid
//!    trajectory.

use super::{Curve, HermiteSegment, Interpolation, Keyframe, TrajectoryError};
use crate::Real;
use heapless::Vec;
use nalgebra::SVector;

/// Velocity/acceleration sweeps in [`time_scale`] before falling back to the guaranteed caps.
pub const MAX_SWEEPS: usize = 32;

/// Per-joint limits. Velocity and acceleration limits are magnitudes (symmetric).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits<T: Real, const J: usize> {
    /// Lowest position of each joint.
    pub lower: SVector<T, J>,
    /// Highest position of each joint.
    pub upper: SVector<T, J>,
    /// Largest |velocity| of each joint (> 0).
    pub max_velocity: SVector<T, J>,
    /// Largest |acceleration| of each joint (> 0).
    pub max_acceleration: SVector<T, J>,
}

/// Which limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// Below the lower position limit.
    Lower,
    /// Above the upper position limit.
    Upper,
    /// |velocity| above the velocity limit.
    Velocity,
    /// |acceleration| above the acceleration limit.
    Acceleration,
    /// The limits themselves are unusable for this joint: NaN or infinite, `lower > upper`, or a
    /// velocity or acceleration limit that is not positive.
    Invalid,
}

/// Where on a curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// At keyframe `i`.
    Keyframe(usize),
    /// Between keyframes `i` and `i + 1`.
    Segment(usize),
}

/// The first limit a curve breaks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Violation<T: Real> {
    /// Keyframe or segment.
    pub location: Location,
    /// Joint index.
    pub joint: usize,
    /// Which limit.
    pub limit: Limit,
    /// Time of the worst value (s).
    pub time: T,
    /// The position, |velocity| or |acceleration| found there.
    pub value: T,
    /// How far beyond the limit the value is (> 0).
    pub excess: T,
}

impl<T: Real> core::fmt::Display for Violation<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{:?}, joint {}: {:?} limit exceeded by {:?} at t = {:?}",
            self.location, self.joint, self.limit, self.excess, self.time
        )
    }
}

/// Why [`time_scale`] (or a limit-aware constructor) refused its input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LimitError<T: Real> {
    /// The keyframes or velocities are malformed.
    Trajectory(TrajectoryError),
    /// The limits of `joint` are unusable (see [`Limit::Invalid`]).
    InvalidLimits {
        /// Offending joint.
        joint: usize,
    },
    /// A keyframe lies outside the position range: no timing or tangent can fix that.
    KeyframeOutOfRange {
        /// Offending keyframe.
        keyframe: usize,
        /// Offending joint.
        joint: usize,
        /// Its position.
        value: T,
    },
    /// The stretched times overflowed (absurdly large input).
    Overflow,
}

impl<T: Real> From<TrajectoryError> for LimitError<T> {
    fn from(e: TrajectoryError) -> Self {
        LimitError::Trajectory(e)
    }
}

impl<T: Real> core::fmt::Display for LimitError<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LimitError::Trajectory(e) => write!(f, "{e}"),
            LimitError::InvalidLimits { joint } => write!(f, "joint {joint}: unusable limits"),
            LimitError::KeyframeOutOfRange { keyframe, joint, value } => {
                write!(f, "keyframe {keyframe}, joint {joint}: position {value:?} outside the joint range")
            }
            LimitError::Overflow => write!(f, "time scaling overflowed"),
        }
    }
}

/// A trajectory made to fit the limits by [`time_scale`].
#[derive(Clone, Debug)]
pub struct Retimed<T: Real, const J: usize, const K: usize> {
    /// The keyframes: positions unchanged, times stretched (the first time is kept).
    pub keyframes: Vec<Keyframe<T, J>, K>,
    /// The velocity at each keyframe (range clamp and time scaling applied).
    pub velocities: Vec<SVector<T, J>, K>,
    /// Per segment, how much longer it now lasts (>= 1; 1 = untouched).
    pub stretch: Vec<T, K>,
    /// Per keyframe and joint, the factor in `[0, 1]` its velocity was multiplied by so that no
    /// segment overshoots the position range (1 = untouched), before time scaling.
    pub range_factors: Vec<SVector<T, J>, K>,
}

impl<T: Real, const J: usize, const K: usize> Retimed<T, J, K> {
    /// The retimed Hermite curve.
    pub fn curve(&self) -> Result<Curve<T, J, K>, TrajectoryError> {
        Curve::with_velocities(&self.keyframes, &self.velocities)
    }

    /// True if any segment was slowed down.
    pub fn slowed(&self) -> bool {
        self.stretch.iter().any(|&k| k > T::one())
    }

    /// True if any velocity was reduced to keep a segment inside the position range.
    pub fn range_clamped(&self) -> bool {
        self.range_factors.iter().any(|f| f.iter().any(|&x| x < T::one()))
    }
}

/// One joint of one segment on the unit interval: `p(s) = p0 + m0 s + c s^2 + d s^3`, where the
/// tangents `m = v h` are velocities scaled by the duration `h`.
#[derive(Clone, Copy, Debug)]
struct Cubic<T: Real> {
    p0: T,
    m0: T,
    c: T,
    d: T,
}

impl<T: Real> Cubic<T> {
    fn new(p0: T, m0: T, p1: T, m1: T) -> Self {
        let delta = p1 - p0;
        let (two, three) = (T::of(2.0), T::of(3.0));
        Cubic { p0, m0, c: three * delta - two * m0 - m1, d: m0 + m1 - two * delta }
    }

    fn position(&self, s: T) -> T {
        self.p0 + s * (self.m0 + s * (self.c + s * self.d))
    }

    fn slope(&self, s: T) -> T {
        self.m0 + s * (T::of(2.0) * self.c + T::of(3.0) * self.d * s)
    }

    fn curvature(&self, s: T) -> T {
        T::of(2.0) * self.c + T::of(6.0) * self.d * s
    }

    /// `(min, s_min, max, s_max)` of the position on `[0, 1]`: the ends and the roots of the
    /// slope `3d s^2 + 2c s + m0` that fall inside (computed without cancellation).
    fn position_range(&self) -> (T, T, T, T) {
        let (a, b, c) = (T::of(3.0) * self.d, T::of(2.0) * self.c, self.m0);
        let mut candidates = [T::zero(), T::one(), T::zero(), T::one()];
        let disc = b * b - T::of(4.0) * a * c;
        if disc >= T::zero() {
            let root = disc.sqrt();
            let q = -(b + if b < T::zero() { -root } else { root }) / T::of(2.0);
            candidates[2] = q / a;
            candidates[3] = c / q;
        }
        let (mut lo, mut s_lo) = (self.p0, T::zero());
        let (mut hi, mut s_hi) = (self.p0, T::zero());
        for s in candidates {
            // NaN and out-of-range roots (from a = 0 or q = 0) fail this test.
            if s >= T::zero() && s <= T::one() {
                let p = self.position(s);
                if p < lo {
                    (lo, s_lo) = (p, s);
                }
                if p > hi {
                    (hi, s_hi) = (p, s);
                }
            }
        }
        (lo, s_lo, hi, s_hi)
    }

    /// Largest |slope| on `[0, 1]` and where: the ends, or the vertex `-c / 3d`.
    fn slope_peak(&self) -> (T, T) {
        let vertex = -self.c / (T::of(3.0) * self.d);
        let mut best = (self.slope(T::zero()).abs(), T::zero());
        for s in [T::one(), vertex] {
            if s >= T::zero() && s <= T::one() {
                let v = self.slope(s).abs();
                if v > best.0 {
                    best = (v, s);
                }
            }
        }
        best
    }

    /// Largest |curvature| on `[0, 1]` and where (always an end: it is linear).
    fn curvature_peak(&self) -> (T, T) {
        let (a0, a1) = (self.curvature(T::zero()).abs(), self.curvature(T::one()).abs());
        if a1 > a0 {
            (a1, T::one())
        } else {
            (a0, T::zero())
        }
    }
}

/// Slack allowed when comparing a computed value with a limit (rounding only).
fn slack<T: Real>(limit: T) -> T {
    T::EPSILON * T::of(64.0) * (T::one() + limit.abs())
}

impl<T: Real, const J: usize> JointLimits<T, J> {
    /// Limits from their four vectors, checked (see [`Limit::Invalid`]).
    pub fn new(
        lower: SVector<T, J>,
        upper: SVector<T, J>,
        max_velocity: SVector<T, J>,
        max_acceleration: SVector<T, J>,
    ) -> Result<Self, LimitError<T>> {
        let limits = Self { lower, upper, max_velocity, max_acceleration };
        limits.validate()?;
        Ok(limits)
    }

    /// Limits that hold every joint at zero (the position range is that one point; speed and
    /// acceleration 1): valid without a check, for a player or controller before it has an arm.
    pub fn still() -> Self {
        let (zero, one) = (SVector::zeros(), SVector::repeat(T::one()));
        Self { lower: zero, upper: zero, max_velocity: one, max_acceleration: one }
    }

    /// Every joint's limits are finite, `lower <= upper`, and the velocity and acceleration
    /// limits are positive.
    pub fn validate(&self) -> Result<(), LimitError<T>> {
        for joint in 0..J {
            let (lo, hi, v, a) =
                (self.lower[joint], self.upper[joint], self.max_velocity[joint], self.max_acceleration[joint]);
            let finite = lo.finite() && hi.finite() && v.finite() && a.finite();
            if !(finite && lo <= hi && v > T::zero() && a > T::zero()) {
                return Err(LimitError::InvalidLimits { joint });
            }
        }
        Ok(())
    }

    /// The first limit `curve` breaks, in time order (keyframe positions first, then each segment:
    /// position, velocity, acceleration), or `Ok`.
    ///
    /// Hermite curves are checked exactly between keyframes. A linear curve is checked for
    /// position and for each segment's constant velocity; its corners (and a stepped curve's
    /// jumps) are instantaneous, so only positions are checked for them otherwise. The hold
    /// before the first and after the last keyframe is not part of the check.
    pub fn check<const K: usize>(&self, curve: &Curve<T, J, K>) -> Result<(), Violation<T>> {
        if let Err(LimitError::InvalidLimits { joint }) = self.validate() {
            let zero = T::zero();
            let location = Location::Keyframe(0);
            return Err(Violation { location, joint, limit: Limit::Invalid, time: zero, value: zero, excess: zero });
        }
        let times = curve.times();
        for (i, p) in curve.positions().iter().enumerate() {
            self.check_position(Location::Keyframe(i), times[i], p)?;
        }
        for i in 0..times.len().saturating_sub(1) {
            match curve.interpolation() {
                Interpolation::Stepped => {}
                Interpolation::Linear => {
                    let h = times[i + 1] - times[i];
                    let velocity = (curve.positions()[i + 1] - curve.positions()[i]) / h;
                    for joint in 0..J {
                        let excess = velocity[joint].abs() - self.max_velocity[joint];
                        if excess > slack(self.max_velocity[joint]) {
                            let value = velocity[joint].abs();
                            let (location, limit, time) = (Location::Segment(i), Limit::Velocity, times[i]);
                            return Err(Violation { location, joint, limit, time, value, excess });
                        }
                    }
                }
                Interpolation::Hermite => self.check_segment(i, &curve.segment(i))?,
            }
        }
        Ok(())
    }

    fn check_position(&self, location: Location, time: T, p: &SVector<T, J>) -> Result<(), Violation<T>> {
        for joint in 0..J {
            let (lo, hi) = (self.lower[joint], self.upper[joint]);
            if lo - p[joint] > slack(lo) {
                let (limit, value, excess) = (Limit::Lower, p[joint], lo - p[joint]);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
            if p[joint] - hi > slack(hi) {
                let (limit, value, excess) = (Limit::Upper, p[joint], p[joint] - hi);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
        }
        Ok(())
    }

    /// Checks one Hermite segment (reported as segment `index`) exactly: position range between
    /// its keyframes, peak |velocity| and peak |acceleration| per joint.
    pub fn check_segment(&self, index: usize, seg: &HermiteSegment<T, J>) -> Result<(), Violation<T>> {
        let h = seg.t1 - seg.t0;
        let location = Location::Segment(index);
        for joint in 0..J {
            let cubic = Cubic::new(seg.p0[joint], seg.v0[joint] * h, seg.p1[joint], seg.v1[joint] * h);
            let (lo, s_lo, hi, s_hi) = cubic.position_range();
            let (lower, upper) = (self.lower[joint], self.upper[joint]);
            if lower - lo > slack(lower) {
                let (limit, time, value, excess) = (Limit::Lower, seg.t0 + s_lo * h, lo, lower - lo);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
            if hi - upper > slack(upper) {
                let (limit, time, value, excess) = (Limit::Upper, seg.t0 + s_hi * h, hi, hi - upper);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
            let (slope, s_v) = cubic.slope_peak();
            let (value, vmax) = (slope / h, self.max_velocity[joint]);
            if value - vmax > slack(vmax) {
                let (limit, time, excess) = (Limit::Velocity, seg.t0 + s_v * h, value - vmax);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
            let (curvature, s_a) = cubic.curvature_peak();
            let (value, amax) = (curvature / (h * h), self.max_acceleration[joint]);
            if value - amax > slack(amax) {
                let (limit, time, excess) = (Limit::Acceleration, seg.t0 + s_a * h, value - amax);
                return Err(Violation { location, joint, limit, time, value, excess });
            }
        }
        Ok(())
    }

    /// The time a constant deceleration within the acceleration limits needs to bring `velocity`
    /// to rest with every joint stopping together: `max_j |v_j| / a_max_j` (0 at rest).
    pub fn stopping_time(&self, velocity: &SVector<T, J>) -> T {
        let mut t = T::zero();
        for joint in 0..J {
            t = t.max(velocity[joint].abs() / self.max_acceleration[joint]);
        }
        t
    }

    /// The shortest time a rest-to-rest cubic (smoothstep) from `from` to `to` takes within the
    /// limits: it peaks at `1.5 Δ / T` in velocity and `6 Δ / T²` in acceleration, so
    /// `T = max_j max(1.5 |Δ_j| / v_max_j, sqrt(6 |Δ_j| / a_max_j))` (0 for no change).
    pub fn rest_to_rest_time(&self, from: &SVector<T, J>, to: &SVector<T, J>) -> T {
        let mut t = T::zero();
        for joint in 0..J {
            let delta = (to[joint] - from[joint]).abs();
            t = t.max(T::of(1.5) * delta / self.max_velocity[joint]);
            t = t.max((T::of(6.0) * delta / self.max_acceleration[joint]).sqrt());
        }
        t
    }

    /// The factor (>= 1, or <= 1 when the segment has room) by which a segment of duration `h`
    /// with tangents `m0`, `m1` (velocity times `h`) must be stretched to meet the velocity and
    /// acceleration limits.
    fn required_stretch(
        &self,
        p0: &SVector<T, J>,
        m0: &SVector<T, J>,
        p1: &SVector<T, J>,
        m1: &SVector<T, J>,
        h: T,
    ) -> T {
        let mut k = T::zero();
        for joint in 0..J {
            let cubic = Cubic::new(p0[joint], m0[joint], p1[joint], m1[joint]);
            let velocity = cubic.slope_peak().0 / h / self.max_velocity[joint];
            let acceleration = (cubic.curvature_peak().0 / self.max_acceleration[joint]).sqrt() / h;
            k = k.max(velocity).max(acceleration);
        }
        k
    }

    /// A stretch that meets the limits whatever factor in `[0, 1]` later shrinks the tangents.
    fn guaranteed_stretch(
        &self,
        p0: &SVector<T, J>,
        m0: &SVector<T, J>,
        p1: &SVector<T, J>,
        m1: &SVector<T, J>,
        h: T,
    ) -> T {
        let mut k = T::one();
        for joint in 0..J {
            let (delta, a, b) = ((p1[joint] - p0[joint]).abs(), m0[joint].abs(), m1[joint].abs());
            let slope = T::of(1.5) * delta + a + b;
            let curvature = T::of(6.0) * delta + T::of(4.0) * (a + b);
            k = k.max(slope / h / self.max_velocity[joint]);
            k = k.max((curvature / self.max_acceleration[joint]).sqrt() / h);
        }
        k
    }
}

/// The factor `alpha` in `[0, 1]` for the outward-pushing tangents of a cubic from `p0` to `p1`
/// (both inside `[.., bound]` when `upper`, `[bound, ..]` otherwise) so that even with every
/// outward tangent at full strength the cubic stays inside. 1 when it already does.
fn range_factor<T: Real>(p0: T, m0: T, p1: T, m1: T, bound: T, upper: bool) -> T {
    // The worst case over shrinking either tangent: keep only the components that push outward
    // (H1 >= 0 multiplies m0, H2 <= 0 multiplies m1).
    let (m0, m1) = if upper { (m0.max(T::zero()), m1.min(T::zero())) } else { (m0.min(T::zero()), m1.max(T::zero())) };
    let outside = |alpha: T| {
        let (lo, _, hi, _) = Cubic::new(p0, alpha * m0, p1, alpha * m1).position_range();
        if upper {
            hi > bound
        } else {
            lo < bound
        }
    };
    if !outside(T::one()) {
        return T::one();
    }
    // alpha = 0 is the straight blend of two in-range keyframes: inside.
    let (mut lo, mut hi) = (T::zero(), T::one());
    for _ in 0..48 {
        let mid = (lo + hi) / T::of(2.0);
        if outside(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

/// Makes a Hermite trajectory meet `limits` without moving its keyframes: tangents that would
/// overshoot the position range are reduced, then segments too fast or too sharp are slowed.
/// See the module documentation for the method and its guarantees; the result always passes
/// [`JointLimits::check`].
pub fn time_scale<T: Real, const J: usize, const K: usize>(
    keyframes: &[Keyframe<T, J>],
    velocities: &[SVector<T, J>],
    limits: &JointLimits<T, J>,
) -> Result<Retimed<T, J, K>, LimitError<T>> {
    limits.validate()?;
    // Validates count, capacity, finiteness and time order.
    Curve::<T, J, K>::with_velocities(keyframes, velocities)?;
    let n = keyframes.len();
    for (keyframe, k) in keyframes.iter().enumerate() {
        for joint in 0..J {
            let value = k.position[joint];
            if value < limits.lower[joint] || value > limits.upper[joint] {
                return Err(LimitError::KeyframeOutOfRange { keyframe, joint, value });
            }
        }
    }
    let one = T::one();
    let mut factors: Vec<SVector<T, J>, K> = (0..n).map(|_| SVector::repeat(one)).collect();
    let duration = |i: usize| keyframes[i + 1].time - keyframes[i].time;

    // 1. Position range, robust to any later shrinking of the tangents.
    for i in 0..n - 1 {
        let h = duration(i);
        for joint in 0..J {
            let (p0, p1) = (keyframes[i].position[joint], keyframes[i + 1].position[joint]);
            let m0 = velocities[i][joint] * factors[i][joint] * h;
            let m1 = velocities[i + 1][joint] * factors[i + 1][joint] * h;
            for (bound, upper) in [(limits.upper[joint], true), (limits.lower[joint], false)] {
                let alpha = range_factor(p0, m0, p1, m1, bound, upper);
                if alpha < one {
                    // Only the outward-pushing tangents are reduced.
                    let pushes_out0 = if upper { m0 > T::zero() } else { m0 < T::zero() };
                    let pushes_out1 = if upper { m1 < T::zero() } else { m1 > T::zero() };
                    if pushes_out0 {
                        factors[i][joint] *= alpha;
                    }
                    if pushes_out1 {
                        factors[i + 1][joint] *= alpha;
                    }
                }
            }
        }
    }
    let base: Vec<SVector<T, J>, K> = velocities.iter().zip(factors.iter()).map(|(v, f)| v.component_mul(f)).collect();

    // 2. Velocity and acceleration: stretch factors per segment.
    let margin = T::of(1.001);
    let mut stretch: Vec<T, K> = (0..n - 1).map(|_| one).collect();
    let caps: Vec<T, K> = (0..n - 1)
        .map(|i| {
            let h = duration(i);
            let (p0, p1) = (&keyframes[i].position, &keyframes[i + 1].position);
            limits.guaranteed_stretch(p0, &(base[i] * h), p1, &(base[i + 1] * h), h) * margin
        })
        .collect();
    let keyframe_stretch = |stretch: &[T], j: usize| {
        let before = if j > 0 { stretch[j - 1] } else { one };
        let after = if j + 1 < n { stretch[j] } else { one };
        before.max(after)
    };
    let required = |stretch: &[T], i: usize| {
        let h = duration(i) * stretch[i];
        let v0 = base[i] / keyframe_stretch(stretch, i);
        let v1 = base[i + 1] / keyframe_stretch(stretch, i + 1);
        let (p0, p1) = (&keyframes[i].position, &keyframes[i + 1].position);
        limits.required_stretch(p0, &(v0 * h), p1, &(v1 * h), h)
    };
    let mut done = false;
    for _ in 0..MAX_SWEEPS {
        done = true;
        for i in 0..n - 1 {
            let k = required(&stretch, i);
            if k > one {
                done = false;
                stretch[i] = (stretch[i] * k * margin).min(caps[i]).max(stretch[i]);
            }
        }
        if done {
            break;
        }
    }
    // Fallback: the caps pass whatever the neighbours do, so at most n - 1 rounds are needed.
    for _ in 0..n {
        if done {
            break;
        }
        done = true;
        for i in 0..n - 1 {
            if required(&stretch, i) > one && stretch[i] < caps[i] {
                done = false;
                stretch[i] = caps[i];
            }
        }
    }

    // 3. The new timing.
    let mut retimed =
        Retimed { keyframes: Vec::new(), velocities: Vec::new(), stretch: Vec::new(), range_factors: factors };
    let mut time = keyframes[0].time;
    for j in 0..n {
        if j > 0 {
            time += duration(j - 1) * stretch[j - 1];
        }
        if !time.finite() || (j > 0 && time <= retimed.keyframes[j - 1].time) {
            return Err(LimitError::Overflow);
        }
        // n <= K was checked when the curve was built: these pushes cannot fail.
        let _ = retimed.keyframes.push(Keyframe { time, position: keyframes[j].position });
        let _ = retimed.velocities.push(base[j] / keyframe_stretch(&stretch, j));
    }
    retimed.stretch = stretch;
    Ok(retimed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn limits() -> JointLimits<f64, 2> {
        JointLimits::new(
            Vector2::new(-1.0, -2.0),
            Vector2::new(1.0, 2.0),
            Vector2::new(1.0, 2.0),
            Vector2::new(4.0, 8.0),
        )
        .unwrap()
    }

    fn kf(time: f64, a: f64, b: f64) -> Keyframe<f64, 2> {
        Keyframe { time, position: Vector2::new(a, b) }
    }

    #[test]
    fn invalid_limits_are_refused() {
        let mut l = limits();
        l.max_velocity[1] = 0.0;
        assert_eq!(l.validate(), Err(LimitError::InvalidLimits { joint: 1 }));
        l = limits();
        l.lower[0] = f64::NAN;
        assert_eq!(l.validate(), Err(LimitError::InvalidLimits { joint: 0 }));
        let curve = Curve::<f64, 2, 4>::linear(&[kf(0.0, 0.0, 0.0)]).unwrap();
        assert_eq!(l.check(&curve).unwrap_err().limit, Limit::Invalid);
    }

    #[test]
    fn check_finds_interior_velocity_peak() {
        // Zero end velocities: the smoothstep peaks at 1.5 * delta / h mid-segment.
        let keys = [kf(0.0, 0.0, 0.0), kf(1.0, 0.8, 0.0)];
        let zero = [Vector2::zeros(); 2];
        let curve = Curve::<f64, 2, 4>::with_velocities(&keys, &zero).unwrap();
        let v = limits().check(&curve).unwrap_err();
        assert_eq!((v.location, v.joint, v.limit), (Location::Segment(0), 0, Limit::Velocity));
        assert!((v.value - 1.2).abs() < 1e-12 && (v.time - 0.5).abs() < 1e-12);
        assert!((v.excess - 0.2).abs() < 1e-12);
    }

    #[test]
    fn check_finds_overshoot_between_keyframes() {
        let keys = [kf(0.0, 0.9, 0.0), kf(4.0, 0.9, 0.0)];
        let vel = [Vector2::new(0.5, 0.0), Vector2::new(-0.5, 0.0)];
        let curve = Curve::<f64, 2, 4>::with_velocities(&keys, &vel).unwrap();
        let v = limits().check(&curve).unwrap_err();
        assert_eq!((v.location, v.limit), (Location::Segment(0), Limit::Upper));
        // p(s) = 0.9 + 2 s - 2 s^2 peaks at s = 1/2: 1.4.
        assert!((v.value - 1.4).abs() < 1e-12 && (v.time - 2.0).abs() < 1e-12);
    }

    #[test]
    fn check_reports_keyframe_out_of_range_and_acceleration() {
        let curve = Curve::<f64, 2, 4>::linear(&[kf(0.0, 0.0, 2.5)]).unwrap();
        let v = limits().check(&curve).unwrap_err();
        assert_eq!((v.location, v.joint, v.limit), (Location::Keyframe(0), 1, Limit::Upper));
        // Joint 0 out and back in 0.4 s: p = 0.4 s - 0.4 s^2, |slope| / h = 1 (at the limit),
        // acceleration 2 * 0.4 / 0.16 = 5 > 4 at both ends.
        let keys = [kf(0.0, 0.0, 0.0), kf(0.4, 0.0, 0.0)];
        let vel = [Vector2::new(1.0, 0.0), Vector2::new(-1.0, 0.0)];
        let curve = Curve::<f64, 2, 4>::with_velocities(&keys, &vel).unwrap();
        let v = limits().check(&curve).unwrap_err();
        assert_eq!((v.location, v.joint, v.limit), (Location::Segment(0), 0, Limit::Acceleration));
        assert!((v.value - 5.0).abs() < 1e-9 && (v.excess - 1.0).abs() < 1e-9 && v.time == 0.0);
    }

    #[test]
    fn time_scale_slows_and_clamps() {
        let keys = [kf(0.0, 0.0, 0.0), kf(0.5, 0.9, 1.0), kf(1.0, 0.95, -1.0)];
        let vel = [Vector2::zeros(), Vector2::new(3.0, 0.0), Vector2::zeros()];
        let r = time_scale::<f64, 2, 4>(&keys, &vel, &limits()).unwrap();
        assert!(r.slowed() && r.range_clamped());
        limits().check(&r.curve().unwrap()).unwrap();
        for (a, b) in r.keyframes.iter().zip(keys.iter()) {
            assert_eq!(a.position, b.position);
        }
        assert_eq!(r.keyframes[0].time, 0.0);
    }

    #[test]
    fn time_scale_leaves_a_feasible_trajectory_alone() {
        let keys = [kf(0.0, 0.0, 0.0), kf(2.0, 0.5, 0.5)];
        let vel = [Vector2::zeros(), Vector2::zeros()];
        let r = time_scale::<f64, 2, 4>(&keys, &vel, &limits()).unwrap();
        assert!(!r.slowed() && !r.range_clamped());
        assert_eq!(r.keyframes[1].time, 2.0);
    }

    #[test]
    fn time_scale_refuses_out_of_range_keyframes() {
        let keys = [kf(0.0, 0.0, 0.0), kf(2.0, 1.5, 0.5)];
        let vel = [Vector2::zeros(), Vector2::zeros()];
        let e = time_scale::<f64, 2, 4>(&keys, &vel, &limits()).unwrap_err();
        assert_eq!(e, LimitError::KeyframeOutOfRange { keyframe: 1, joint: 0, value: 1.5 });
        let e = time_scale::<f64, 2, 1>(&keys, &vel, &limits()).unwrap_err();
        assert_eq!(e, LimitError::Trajectory(TrajectoryError::TooMany { capacity: 1 }));
    }
}
