//! A serial chain of N joints and a fixed tool frame, built from a URDF-style joint list or from a
//! Denavit-Hartenberg table (standard or modified), validated once at construction so that every
//! algorithm downstream can trust it.

use crate::{Joint, JointKind, Limits, Pose, Real};
use nalgebra::{Matrix3, SVector, Vector3};

/// Why a chain description was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChainError {
    /// The joint's axis has zero length (or is not finite), so it defines no motion.
    ZeroAxis {
        /// Index of the joint, from the base.
        joint: usize,
    },
    /// An origin or the tool frame contains NaN or infinity, or its rotation is not orthonormal.
    BadFrame {
        /// Index of the joint, or `None` for the tool frame.
        joint: Option<usize>,
    },
    /// Limits are NaN or infinite, or the lower limit exceeds the upper one.
    BadLimits {
        /// Index of the joint.
        joint: usize,
    },
}

impl core::fmt::Display for ChainError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ChainError::ZeroAxis { joint } => write!(f, "joint {joint} has a zero or non-finite axis"),
            ChainError::BadFrame { joint: Some(j) } => {
                write!(f, "joint {j} has a non-finite or non-orthonormal origin")
            }
            ChainError::BadFrame { joint: None } => write!(f, "the tool frame is non-finite or non-orthonormal"),
            ChainError::BadLimits { joint } => {
                write!(f, "joint {joint} has non-finite limits or lower > upper")
            }
        }
    }
}

/// One row of a Denavit-Hartenberg table. For a revolute joint `theta` is the offset added to the
/// joint value; for a prismatic joint `d` is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhRow<T: Real> {
    /// Link length (m).
    pub a: T,
    /// Link twist (rad).
    pub alpha: T,
    /// Link offset (m).
    pub d: T,
    /// Joint angle offset (rad).
    pub theta: T,
    /// Revolute or prismatic (a continuous joint is revolute with wrapping).
    pub kind: JointKind,
    /// Joint limits.
    pub limits: Limits<T>,
}

/// A validated serial chain: N joints from the base, then the fixed tool frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain<T: Real, const N: usize> {
    joints: [Joint<T>; N],
    tool: Pose<T>,
    /// Per-joint constants that let FK apply origin and motion in one product (see `fk.rs`).
    pub(crate) motion: [JointMotion<T>; N],
}

/// A joint's `origin * motion(q)` split into constant parts:
/// rotation `c * cos_part + s * sin_part + fixed_part` (Rodrigues' formula pre-multiplied by the
/// origin rotation), translation `origin.translation + q * slide` (`slide` is zero for a revolute
/// joint).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct JointMotion<T: Real> {
    pub(crate) cos_part: Matrix3<T>,
    pub(crate) sin_part: Matrix3<T>,
    pub(crate) fixed_part: Matrix3<T>,
    pub(crate) slide: Vector3<T>,
}

impl<T: Real> JointMotion<T> {
    fn of(joint: &Joint<T>) -> Self {
        let r = joint.origin.rotation;
        let a = joint.axis;
        let u = r * a;
        match joint.kind {
            // Rot(a, q) = cos q (I - a a^T) + sin q [a]x + a a^T
            JointKind::Revolute | JointKind::Continuous => Self {
                cos_part: r - u * a.transpose(),
                sin_part: r * a.cross_matrix(),
                fixed_part: u * a.transpose(),
                slide: Vector3::zeros(),
            },
            JointKind::Prismatic => {
                Self { cos_part: Matrix3::zeros(), sin_part: Matrix3::zeros(), fixed_part: r, slide: u }
            }
            JointKind::Fixed => {
                Self { cos_part: Matrix3::zeros(), sin_part: Matrix3::zeros(), fixed_part: r, slide: Vector3::zeros() }
            }
        }
    }
}

impl<T: Real, const N: usize> Chain<T, N> {
    /// Builds a chain from a URDF-style joint list (each origin relative to the previous joint's
    /// moving frame) and the tool frame relative to the last joint. Axes are normalised.
    pub fn new(joints: [Joint<T>; N], tool: Pose<T>) -> Result<Self, ChainError> {
        let mut chain = Self::motionless();
        chain.set(|i| joints.get(i).copied().unwrap_or_else(|| Joint::fixed(Pose::identity())), tool)?;
        Ok(chain)
    }

    /// Makes this the chain [`Chain::new`] builds from joints `joint(0)` to `joint(N - 1)` and
    /// `tool`, in place: a firmware keeps its chains in static memory and has no stack for
    /// another. Every joint is checked before anything changes, so a refused chain leaves this
    /// one as it was (`joint` is called twice per joint).
    pub fn set(&mut self, joint: impl Fn(usize) -> Joint<T>, tool: Pose<T>) -> Result<(), ChainError> {
        for i in 0..N {
            checked(joint(i), i)?;
        }
        if !frame_is_valid(&tool) {
            return Err(ChainError::BadFrame { joint: None });
        }
        for (i, (slot, motion)) in self.joints.iter_mut().zip(self.motion.iter_mut()).enumerate() {
            *slot = checked(joint(i), i)?;
            *motion = JointMotion::of(slot);
        }
        self.tool = tool;
        Ok(())
    }

    /// A chain that does not move: every joint fixed at the identity, and the tool at the last
    /// joint. What a controller holds before it is given an arm, built without a check that could
    /// fail.
    pub fn motionless() -> Self {
        let joint = Joint::fixed(Pose::identity());
        Self { joints: [joint; N], tool: Pose::identity(), motion: [JointMotion::of(&joint); N] }
    }

    /// Standard (distal) DH: `T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`, the joint moving about
    /// (or along) the z axis of frame i-1. `tool` follows the last DH frame.
    pub fn from_dh_standard(rows: [DhRow<T>; N], tool: Pose<T>) -> Result<Self, ChainError> {
        // The variable part of each row commutes to the front (Rz(q) and Tz(q) commute with
        // Rz(theta) Tz(d)), so row i's constant part becomes the origin of joint i+1.
        let mut previous = Pose::identity();
        let joints = rows.map(|row| {
            let joint = dh_joint(previous, &row);
            previous = standard_link(&row);
            joint
        });
        Self::new(joints, previous.compose(&tool))
    }

    /// Modified (proximal, Craig) DH: `T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`; row i
    /// holds `a_{i-1}`, `alpha_{i-1}`, `d_i`, `theta_i`. `tool` follows the last joint frame.
    pub fn from_dh_modified(rows: [DhRow<T>; N], tool: Pose<T>) -> Result<Self, ChainError> {
        let joints = rows.map(|row| dh_joint(modified_link(&row), &row));
        Self::new(joints, tool)
    }

    /// The joints, base first.
    pub fn joints(&self) -> &[Joint<T>; N] {
        &self.joints
    }

    /// The joints before the first fixed one: an arm's own joints, when fixed joints pad the chain
    /// for a build with room for more (see [`JointKind::Fixed`]).
    pub fn moving_joints(&self) -> usize {
        self.joints.iter().take_while(|j| j.kind != JointKind::Fixed).count()
    }

    /// The tool frame relative to the last joint frame.
    pub fn tool(&self) -> &Pose<T> {
        &self.tool
    }

    /// The middle of every joint's range: the conventional IK seed.
    pub fn middle(&self) -> SVector<T, N> {
        SVector::from_fn(|i, _| match self.joints[i].kind {
            JointKind::Continuous => T::zero(),
            _ => self.joints[i].limits.middle(),
        })
    }

    /// Brings every joint value into its range (see [`Joint::normalise`]).
    pub fn normalise(&self, q: &mut SVector<T, N>) {
        for (v, j) in q.iter_mut().zip(self.joints.iter()) {
            *v = j.normalise(*v);
        }
    }

    /// True if every value is admissible for its joint.
    pub fn admits(&self, q: &SVector<T, N>) -> bool {
        q.iter().zip(self.joints.iter()).all(|(v, j)| j.admits(*v))
    }
}

/// Joint `i` with its axis normalised, if it is valid: a non-zero finite axis, a valid frame,
/// ordered finite limits (but for a continuous joint).
pub(crate) fn checked<T: Real>(mut j: Joint<T>, i: usize) -> Result<Joint<T>, ChainError> {
    let n = j.axis.norm();
    if !n.finite() || n <= T::EPSILON {
        return Err(ChainError::ZeroAxis { joint: i });
    }
    j.axis /= n;
    if !frame_is_valid(&j.origin) {
        return Err(ChainError::BadFrame { joint: Some(i) });
    }
    let l = j.limits;
    let limits_ok = l.lower.finite() && l.upper.finite() && l.lower <= l.upper;
    if j.kind != JointKind::Continuous && !limits_ok {
        return Err(ChainError::BadLimits { joint: i });
    }
    Ok(j)
}

fn dh_joint<T: Real>(origin: Pose<T>, row: &DhRow<T>) -> Joint<T> {
    Joint { origin, axis: Vector3::z(), kind: row.kind, limits: row.limits }
}

/// `Rz(theta) Tz(d) Tx(a) Rx(alpha)` as one transform.
fn standard_link<T: Real>(row: &DhRow<T>) -> Pose<T> {
    let (st, ct) = row.theta.sin_cos_fast();
    let rz = Matrix3::new(ct, -st, T::zero(), st, ct, T::zero(), T::zero(), T::zero(), T::one());
    Pose { rotation: rz * rx(row.alpha), translation: Vector3::new(row.a * ct, row.a * st, row.d) }
}

/// `Rx(alpha) Tx(a) Rz(theta) Tz(d)` as one transform.
fn modified_link<T: Real>(row: &DhRow<T>) -> Pose<T> {
    let (st, ct) = row.theta.sin_cos_fast();
    let (sa, ca) = row.alpha.sin_cos_fast();
    let rz = Matrix3::new(ct, -st, T::zero(), st, ct, T::zero(), T::zero(), T::zero(), T::one());
    Pose { rotation: rx(row.alpha) * rz, translation: Vector3::new(row.a, -row.d * sa, row.d * ca) }
}

fn rx<T: Real>(alpha: T) -> Matrix3<T> {
    let (s, c) = alpha.sin_cos_fast();
    Matrix3::new(T::one(), T::zero(), T::zero(), T::zero(), c, -s, T::zero(), s, c)
}

pub(crate) fn frame_is_valid<T: Real>(p: &Pose<T>) -> bool {
    if !p.rotation.iter().chain(p.translation.iter()).all(|v| v.finite()) {
        return false;
    }
    // Orthonormal to well within what an rpy or DH conversion in f32 produces.
    let defect = (p.rotation.transpose() * p.rotation - Matrix3::identity()).amax();
    defect <= T::of(1e-4)
}
