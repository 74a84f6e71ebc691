//! A piecewise curve through timed keyframes: the one evaluator every interpolation method feeds.
//!
//! Every C1 method in this module (Catmull-Rom, Kochanek-Bartels, monotone, natural and clamped
//! splines, given velocities) differs only in the velocities it assigns to the keyframes; the
//! curve between two keyframes is then always the cubic Hermite segment. Kochanek-Bartels with
//! non-zero continuity gives a keyframe different arriving and leaving velocities, so both are kept.

use super::{HermiteSegment, Sample};
use crate::Real;
use heapless::Vec;
use nalgebra::SVector;

/// A timed joint vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe<T: Real, const J: usize> {
    /// Time (s).
    pub time: T,
    /// Joint values.
    pub position: SVector<T, J>,
}

/// Why keyframes were refused. Indices count keyframes from 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajectoryError {
    /// No keyframe at all.
    Empty,
    /// More keyframes than the fixed capacity.
    TooMany {
        /// The capacity.
        capacity: usize,
    },
    /// Keyframe `index` is not later than the one before it, or so little later that the
    /// interval's square underflows (the curve's acceleration would not be finite).
    TimesNotIncreasing {
        /// Offending keyframe.
        index: usize,
    },
    /// Keyframe `index` (its time, a position or a velocity) is NaN or infinite.
    NonFinite {
        /// Offending keyframe.
        index: usize,
    },
    /// The velocity list does not have one entry per keyframe.
    VelocityCount,
}

impl core::fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TrajectoryError::Empty => write!(f, "no keyframes"),
            TrajectoryError::TooMany { capacity } => write!(f, "more than {capacity} keyframes"),
            TrajectoryError::TimesNotIncreasing { index } => {
                write!(f, "keyframe {index}: time is not later than the previous keyframe's by a usable interval")
            }
            TrajectoryError::NonFinite { index } => write!(f, "keyframe {index}: NaN or infinite value"),
            TrajectoryError::VelocityCount => write!(f, "need exactly one velocity per keyframe"),
        }
    }
}

/// How the curve passes between keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Hold each keyframe's value until the next keyframe's time.
    Stepped,
    /// Straight lines (constant velocity between keyframes).
    Linear,
    /// Cubic Hermite segments with the stored velocities.
    Hermite,
}

/// Up to `K` keyframes of `J` joints and the velocities at them.
#[derive(Clone, Debug)]
pub struct Curve<T: Real, const J: usize, const K: usize> {
    interpolation: Interpolation,
    times: Vec<T, K>,
    positions: Vec<SVector<T, J>, K>,
    /// Velocity arriving at keyframe i (the end of segment i - 1).
    arriving: Vec<SVector<T, J>, K>,
    /// Velocity leaving keyframe i (the start of segment i).
    leaving: Vec<SVector<T, J>, K>,
}

impl<T: Real, const J: usize, const K: usize> Curve<T, J, K> {
    /// Holds each keyframe until the next.
    pub fn stepped(keyframes: &[Keyframe<T, J>]) -> Result<Self, TrajectoryError> {
        let zeros = Self::zeros(keyframes.len());
        Self::build(Interpolation::Stepped, keyframes, &zeros, &zeros)
    }

    /// Straight lines between keyframes.
    pub fn linear(keyframes: &[Keyframe<T, J>]) -> Result<Self, TrajectoryError> {
        let zeros = Self::zeros(keyframes.len());
        Self::build(Interpolation::Linear, keyframes, &zeros, &zeros)
    }

    /// Hermite segments through the keyframes with one velocity per keyframe (C1).
    pub fn with_velocities(
        keyframes: &[Keyframe<T, J>],
        velocities: &[SVector<T, J>],
    ) -> Result<Self, TrajectoryError> {
        Self::build(Interpolation::Hermite, keyframes, velocities, velocities)
    }

    /// Hermite segments with separate arriving and leaving velocities per keyframe (C0 where they
    /// differ, as Kochanek-Bartels continuity asks).
    pub fn with_tangents(
        keyframes: &[Keyframe<T, J>],
        arriving: &[SVector<T, J>],
        leaving: &[SVector<T, J>],
    ) -> Result<Self, TrajectoryError> {
        Self::build(Interpolation::Hermite, keyframes, arriving, leaving)
    }

    fn zeros(n: usize) -> Vec<SVector<T, J>, K> {
        (0..n.min(K)).map(|_| SVector::zeros()).collect()
    }

    fn build(
        interpolation: Interpolation,
        keyframes: &[Keyframe<T, J>],
        arriving: &[SVector<T, J>],
        leaving: &[SVector<T, J>],
    ) -> Result<Self, TrajectoryError> {
        if keyframes.is_empty() {
            return Err(TrajectoryError::Empty);
        }
        if keyframes.len() > K {
            return Err(TrajectoryError::TooMany { capacity: K });
        }
        if arriving.len() != keyframes.len() || leaving.len() != keyframes.len() {
            return Err(TrajectoryError::VelocityCount);
        }
        let mut curve =
            Self { interpolation, times: Vec::new(), positions: Vec::new(), arriving: Vec::new(), leaving: Vec::new() };
        for (index, k) in keyframes.iter().enumerate() {
            let finite = |v: &SVector<T, J>| v.iter().all(|x| x.finite());
            if !(k.time.finite() && finite(&k.position) && finite(&arriving[index]) && finite(&leaving[index])) {
                return Err(TrajectoryError::NonFinite { index });
            }
            if index > 0 && !usable_interval(keyframes[index - 1].time, k.time) {
                return Err(TrajectoryError::TimesNotIncreasing { index });
            }
            // Capacity was checked above, so these pushes cannot fail.
            let _ = curve.times.push(k.time);
            let _ = curve.positions.push(k.position);
            let _ = curve.arriving.push(arriving[index]);
            let _ = curve.leaving.push(leaving[index]);
        }
        Ok(curve)
    }

    /// How the curve passes between keyframes.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Keyframe times.
    pub fn times(&self) -> &[T] {
        &self.times
    }

    /// Keyframe positions.
    pub fn positions(&self) -> &[SVector<T, J>] {
        &self.positions
    }

    /// Velocities arriving at each keyframe.
    pub fn arriving(&self) -> &[SVector<T, J>] {
        &self.arriving
    }

    /// Velocities leaving each keyframe.
    pub fn leaving(&self) -> &[SVector<T, J>] {
        &self.leaving
    }

    /// Time of the first keyframe.
    pub fn start(&self) -> T {
        self.times[0]
    }

    /// Time of the last keyframe.
    pub fn end(&self) -> T {
        self.times[self.times.len() - 1]
    }

    /// The index of the segment containing `t` (clamped to the first and last segment).
    pub fn segment_index(&self, t: T) -> usize {
        let n = self.times.len();
        if n < 2 {
            return 0;
        }
        let after = self.times.partition_point(|&x| x <= t);
        after.saturating_sub(1).min(n - 2)
    }

    /// Segment `i` (between keyframes i and i + 1) as a Hermite segment with the stored
    /// velocities (for a stepped or linear curve, use [`Curve::sample`], which applies its rule).
    /// An index past the last segment gives the last segment; a one-keyframe curve gives a
    /// one-second hold at its keyframe.
    pub fn segment(&self, i: usize) -> HermiteSegment<T, J> {
        let n = self.times.len();
        if n < 2 {
            let p = self.positions[0];
            let t0 = self.times[0];
            return HermiteSegment { t0, t1: t0 + T::one(), p0: p, v0: SVector::zeros(), p1: p, v1: SVector::zeros() };
        }
        let i = i.min(n - 2);
        HermiteSegment {
            t0: self.times[i],
            t1: self.times[i + 1],
            p0: self.positions[i],
            v0: self.leaving[i],
            p1: self.positions[i + 1],
            v1: self.arriving[i + 1],
        }
    }

    /// Position, velocity and acceleration at `t`. Before the first keyframe and after the last
    /// the curve holds that keyframe with zero velocity and acceleration.
    pub fn sample(&self, t: T) -> Sample<T, J> {
        let n = self.times.len();
        let hold =
            |p: SVector<T, J>| Sample { position: p, velocity: SVector::zeros(), acceleration: SVector::zeros() };
        if n == 1 || t <= self.start() {
            return hold(self.positions[0]);
        }
        if t >= self.end() {
            return hold(self.positions[n - 1]);
        }
        let i = self.segment_index(t);
        let (t0, t1) = (self.times[i], self.times[i + 1]);
        let (p0, p1) = (self.positions[i], self.positions[i + 1]);
        match self.interpolation {
            Interpolation::Stepped => hold(p0),
            Interpolation::Linear => {
                let s = (t - t0) / (t1 - t0);
                let velocity = (p1 - p0) / (t1 - t0);
                Sample { position: p0 + (p1 - p0) * s, velocity, acceleration: SVector::zeros() }
            }
            Interpolation::Hermite => self.segment(i).sample(t),
        }
    }
}

/// True if `t` is later than `previous` by an interval whose square is a normal positive number,
/// so that a segment's velocity and acceleration (divided by `h` and `h^2`) stay finite.
pub(super) fn usable_interval<T: Real>(previous: T, t: T) -> bool {
    let h = t - previous;
    h > T::zero() && (T::one() / (h * h)).finite()
}
