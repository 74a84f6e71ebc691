//! Forward kinematics: every joint frame and the tool pose in one pass from the base.

use crate::{Chain, Joint, JointKind, Pose, Real};
use nalgebra::{SMatrix, SVector, Vector3};

/// World poses of every joint frame (after its motion) and of the tool, for one joint vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frames<T: Real, const N: usize> {
    /// Frame of joint k after its motion, in the base frame.
    pub joints: [Pose<T>; N],
    /// Tool frame in the base frame.
    pub tool: Pose<T>,
}

impl<T: Real, const N: usize> Chain<T, N> {
    /// Forward kinematics: O(N), one 3x3 product per joint (origin and motion are pre-combined,
    /// see `JointMotion`), and no sine or cosine for prismatic joints.
    pub fn forward(&self, q: &SVector<T, N>) -> Frames<T, N> {
        let mut current = Pose::identity();
        let joints = core::array::from_fn(|k| {
            let local = self.local_pose(k, q[k]);
            // The base frame is the identity: the first joint's pose is its local one.
            current = if k == 0 { local } else { current.compose(&local) };
            current
        });
        Frames { joints, tool: current.compose(self.tool()) }
    }

    /// Tool pose only: the same products as [`Chain::forward`] without keeping every frame (on the
    /// M4F the stores of N poses are a fifth of the pass).
    pub fn tool_pose(&self, q: &SVector<T, N>) -> Pose<T> {
        let mut current = Pose::identity();
        for k in 0..N {
            let local = self.local_pose(k, q[k]);
            current = if k == 0 { local } else { current.compose(&local) };
        }
        current.compose(self.tool())
    }

    /// Joint `k`'s frame relative to its parent at joint value `q`.
    #[inline]
    pub(crate) fn local_pose(&self, k: usize, q: T) -> Pose<T> {
        let (Some(joint), Some(m)) = (self.joints().get(k), self.motion.get(k)) else { return Pose::identity() };
        match joint.kind {
            JointKind::Prismatic => {
                Pose { rotation: m.fixed_part, translation: joint.origin.translation + m.slide * q }
            }
            JointKind::Fixed => Pose { rotation: m.fixed_part, translation: joint.origin.translation },
            JointKind::Revolute | JointKind::Continuous => {
                let (s, c) = q.sin_cos_fast();
                Pose {
                    // One pass over the nine entries: written as three matrix operations, the sum
                    // builds two temporaries (a third of FK's time on the M4F).
                    rotation: m.cos_part.zip_zip_map(&m.sin_part, &m.fixed_part, |a, b, f| a * c + b * s + f),
                    translation: joint.origin.translation,
                }
            }
        }
    }

    /// Geometric Jacobian of the tool frame at `q`: rows linear x, y, z then angular x, y, z (base
    /// frame); column k is `[a_k x (p_tool - p_k); a_k]` for a revolute joint, `[a_k; 0]` for a
    /// prismatic one, where `a_k` is the joint axis and `p_k` its origin in the base frame.
    pub fn jacobian(&self, q: &SVector<T, N>) -> SMatrix<T, 6, N> {
        self.jacobian_of(&self.forward(q))
    }

    /// The Jacobian from frames already computed (the IK solvers reuse the FK of their last step).
    pub fn jacobian_of(&self, frames: &Frames<T, N>) -> SMatrix<T, 6, N> {
        self.point_jacobian(frames, N, &frames.tool.translation)
    }

    /// Jacobian of a point fixed to the frame of joint `upto - 1` (or to the tool when `upto == N`),
    /// given in the base frame: only the first `upto` joints move it, so later columns are zero.
    pub fn point_jacobian(&self, frames: &Frames<T, N>, upto: usize, point: &Vector3<T>) -> SMatrix<T, 6, N> {
        let mut j = SMatrix::<T, 6, N>::zeros();
        for (k, (joint, frame)) in self.joints().iter().zip(frames.joints.iter()).enumerate().take(upto) {
            write_column(&mut j, k, joint, frame, point);
        }
        j
    }
}

/// Column `k` of a geometric Jacobian, for `joint` whose moving frame is `frame` (base frame), at
/// `point`: `[a x (point - p); a]` for a revolute joint, `[a; 0]` for a prismatic one, where `a` is
/// the joint axis and `p` the frame's origin. A fixed joint moves nothing: its column is left
/// as it is (zero). The chain's and the tree's Jacobians are made of these.
#[inline]
pub(crate) fn write_column<T: Real, const N: usize>(
    j: &mut SMatrix<T, 6, N>,
    k: usize,
    joint: &Joint<T>,
    frame: &Pose<T>,
    point: &Vector3<T>,
) {
    let axis = frame.rotation * joint.axis;
    let linear = match joint.kind {
        JointKind::Prismatic => axis,
        JointKind::Revolute | JointKind::Continuous => axis.cross(&(point - frame.translation)),
        JointKind::Fixed => return,
    };
    j.fixed_view_mut::<3, 1>(0, k).copy_from(&linear);
    if joint.kind != JointKind::Prismatic {
        j.fixed_view_mut::<3, 1>(3, k).copy_from(&axis);
    }
}
