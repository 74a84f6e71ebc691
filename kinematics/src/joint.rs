//! One joint of a serial chain, as URDF describes it: a fixed origin from the parent frame, then a
//! motion about (or along) an axis given in the joint's own frame.

use crate::{wrap_angle, Pose, Real};
use nalgebra::Vector3;

/// How a joint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, kept within `[lower, upper]`.
    Revolute,
    /// Rotation about the axis without limits; values wrap to (-pi, pi].
    Continuous,
    /// Translation along the axis, kept within `[lower, upper]` (metres).
    Prismatic,
    /// No motion: the frame stays at its origin whatever the value, which the limits keep (as
    /// URDF's `fixed`). A firmware built for more joints than an arm has pads the chain with these,
    /// so one build drives any joint count: their Jacobian columns are zero, so no solver moves them.
    Fixed,
}

/// Position limits of a joint (radians or metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits<T: Real> {
    /// Lowest allowed value.
    pub lower: T,
    /// Highest allowed value.
    pub upper: T,
}

impl<T: Real> Limits<T> {
    /// Limits `[lower, upper]`.
    pub fn new(lower: T, upper: T) -> Self {
        Self { lower, upper }
    }

    /// Limits given in f64 (a file, a table), rounded *inward* to `T`: a value within the `T`
    /// limits is then within the f64 ones too, so narrowing to f32 never admits a joint value the
    /// arm's description forbids.
    pub fn from_f64(lower: f64, upper: f64) -> Self {
        let inward = |v: f64, up: bool| {
            let t = T::of(v);
            let widened = if up { t.to_f64() < v } else { t.to_f64() > v };
            if !widened {
                return t;
            }
            // One rounding step inward; T::EPSILON * |t| is at least one ulp of t.
            let step = t.abs().max(T::EPSILON) * T::EPSILON;
            if up {
                t + step
            } else {
                t - step
            }
        };
        Self { lower: inward(lower, true), upper: inward(upper, false) }
    }

    /// Symmetric limits `[-m, m]`.
    pub fn symmetric(m: T) -> Self {
        Self { lower: -m, upper: m }
    }

    /// The middle of the range: the conventional IK seed.
    pub fn middle(&self) -> T {
        (self.lower + self.upper) * T::of(0.5)
    }

    /// Width of the range.
    pub fn span(&self) -> T {
        self.upper - self.lower
    }

    /// True if `v` lies within the limits.
    pub fn contains(&self, v: T) -> bool {
        v >= self.lower && v <= self.upper
    }
}

/// A joint: parent-to-joint origin, unit axis in the joint frame, kind and limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint<T: Real> {
    /// Transform from the parent (previous joint's moving frame, or the base) to this joint's frame
    /// at zero joint value.
    pub origin: Pose<T>,
    /// Motion axis in the joint frame (normalised by [`crate::Chain::new`]).
    pub axis: Vector3<T>,
    /// Revolute, continuous or prismatic.
    pub kind: JointKind,
    /// Position limits; ignored for continuous joints.
    pub limits: Limits<T>,
}

impl<T: Real> Joint<T> {
    /// A revolute joint.
    pub fn revolute(origin: Pose<T>, axis: [T; 3], limits: Limits<T>) -> Self {
        Self { origin, axis: Vector3::from(axis), kind: JointKind::Revolute, limits }
    }

    /// A continuous (unlimited revolute) joint.
    pub fn continuous(origin: Pose<T>, axis: [T; 3]) -> Self {
        let pi = T::pi();
        Self { origin, axis: Vector3::from(axis), kind: JointKind::Continuous, limits: Limits::symmetric(pi) }
    }

    /// A fixed joint at `origin`: no motion, its value held at zero.
    pub fn fixed(origin: Pose<T>) -> Self {
        let zero = Limits { lower: T::zero(), upper: T::zero() };
        Self { origin, axis: Vector3::z(), kind: JointKind::Fixed, limits: zero }
    }

    /// A prismatic joint.
    pub fn prismatic(origin: Pose<T>, axis: [T; 3], limits: Limits<T>) -> Self {
        Self { origin, axis: Vector3::from(axis), kind: JointKind::Prismatic, limits }
    }

    /// The joint's motion for value `q` (rotation about or translation along the axis).
    #[inline]
    pub fn motion(&self, q: T) -> Pose<T> {
        match self.kind {
            JointKind::Prismatic => Pose::from_translation(self.axis * q),
            JointKind::Revolute | JointKind::Continuous => Pose::from_axis_angle(&self.axis, q),
            JointKind::Fixed => Pose::identity(),
        }
    }

    /// Brings `q` into the joint's range without changing the pose it produces where possible:
    /// continuous joints wrap to (-pi, pi]; a revolute value outside its limits is first shifted by
    /// whole turns (same pose) and only clamped when no turn lands inside.
    #[inline]
    pub fn normalise(&self, q: T) -> T {
        self.saturate(q).0
    }

    /// [`Joint::normalise`], also telling whether the value had to be clamped to a limit (which,
    /// unlike a wrap or a whole-turn shift, changes the pose).
    #[inline]
    pub fn saturate(&self, q: T) -> (T, bool) {
        let two_pi = T::two_pi();
        match self.kind {
            JointKind::Continuous => (wrap_angle(q), false),
            JointKind::Prismatic | JointKind::Fixed => (clamp(q, self.limits), !self.limits.contains(q)),
            JointKind::Revolute => {
                if self.limits.contains(q) {
                    return (q, false);
                }
                // The turn count that brings q closest to the middle of the range.
                let turns = ((self.limits.middle() - q) / two_pi).round();
                let shifted = q + turns * two_pi;
                if self.limits.contains(shifted) {
                    (shifted, false)
                } else {
                    (clamp(q, self.limits), true)
                }
            }
        }
    }

    /// True if `q` is an admissible value for this joint (continuous joints admit any finite value).
    pub fn admits(&self, q: T) -> bool {
        match self.kind {
            JointKind::Continuous => q.finite(),
            _ => self.limits.contains(q),
        }
    }
}

fn clamp<T: Real>(q: T, l: Limits<T>) -> T {
    q.max(l.lower).min(l.upper)
}
