//! The recursive Newton-Euler algorithm (Luh, Walker and Paul, 1980), in each joint's own frame:
//! velocities and accelerations outward from the base, forces and moments inward from the tips,
//! for a chain or a tree alike (each joint's parent is looked up, and a link passes its forces to
//! its parent's). Gravity enters as an upward acceleration of the base, so one pass gives the
//! whole torque. The mass matrix is built a column at a time from the same pass (Walker and
//! Orin's first method: no velocity, no gravity, a unit acceleration of one joint), O(N²) for the
//! arms here.

use nalgebra::{SMatrix, SVector, Vector3};

use super::inertia::{Inertia, InertiaError};
use crate::tree::Tree;
use crate::{Chain, Joint, JointKind, Pose, Real};

/// What the dynamics needs of an arm: its joints, each joint's parent (a chain's is the joint
/// before; a tree's any earlier one) and each joint's frame relative to its parent's at a value.
/// Implemented by [`Chain`] and [`Tree`].
pub trait Linkage<T: Real, const N: usize> {
    /// The joints, parents before children.
    fn joints(&self) -> &[Joint<T>; N];
    /// Joint `k`'s parent, or `None` when it hangs from the base.
    fn parent(&self, k: usize) -> Option<usize>;
    /// Joint `k`'s moving frame relative to its parent's at value `q`.
    fn local_pose(&self, k: usize, q: T) -> Pose<T>;
}

impl<T: Real, const N: usize> Linkage<T, N> for Chain<T, N> {
    fn joints(&self) -> &[Joint<T>; N] {
        Chain::joints(self)
    }
    fn parent(&self, k: usize) -> Option<usize> {
        k.checked_sub(1)
    }
    fn local_pose(&self, k: usize, q: T) -> Pose<T> {
        Chain::local_pose(self, k, q)
    }
}

impl<T: Real, const N: usize, const E: usize> Linkage<T, N> for Tree<T, N, E> {
    fn joints(&self) -> &[Joint<T>; N] {
        Tree::joints(self)
    }
    fn parent(&self, k: usize) -> Option<usize> {
        self.parents().get(k).copied().flatten()
    }
    fn local_pose(&self, k: usize, q: T) -> Pose<T> {
        self.joints().get(k).map_or_else(Pose::identity, |j| j.origin.compose(&j.motion(q)))
    }
}

/// Standard gravity (m/s²), as ISO 80000-3 defines it.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// An arm's mass properties: each joint's link (in that joint's moving frame, as URDF's child
/// link) and gravity (in the base frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dynamics<T: Real, const N: usize> {
    links: [Inertia<T>; N],
    gravity: Vector3<T>,
}

impl<T: Real, const N: usize> Dynamics<T, N> {
    /// The links' mass properties, each checked ([`Inertia::validated`]), with standard gravity
    /// along the base's -z.
    pub fn new(links: [Inertia<T>; N]) -> Result<Self, InertiaError> {
        for link in &links {
            link.validated()?;
        }
        Ok(Self { links, gravity: Vector3::new(T::zero(), T::zero(), -T::of(STANDARD_GRAVITY)) })
    }

    /// The same with gravity `g` (m/s², in the base frame): an arm mounted on a wall or upside
    /// down, or none. Refused when a component is not finite.
    pub fn with_gravity(mut self, g: Vector3<T>) -> Result<Self, InertiaError> {
        if !g.iter().all(|x| x.finite()) {
            return Err(InertiaError::NotFinite);
        }
        self.gravity = g;
        Ok(self)
    }

    /// The same carrying `payload` (in a chain's tool frame) rigidly with the last link.
    pub fn with_payload(mut self, chain: &Chain<T, N>, payload: &Inertia<T>) -> Result<Self, InertiaError> {
        let payload = payload.validated()?.moved(&chain.tool().rotation, &chain.tool().translation);
        if let Some(last) = self.links.last_mut() {
            *last = last.combined(&payload);
        }
        Ok(self)
    }

    /// The links.
    pub fn links(&self) -> &[Inertia<T>; N] {
        &self.links
    }

    /// Gravity, in the base frame.
    pub fn gravity(&self) -> Vector3<T> {
        self.gravity
    }

    /// The joint torques (N m; N for a prismatic joint) that give the arm (a chain or a tree) at
    /// `q` moving at `qd` the accelerations `qdd`, gravity included.
    pub fn inverse<A: Linkage<T, N>>(
        &self,
        arm: &A,
        q: &SVector<T, N>,
        qd: &SVector<T, N>,
        qdd: &SVector<T, N>,
    ) -> SVector<T, N> {
        self.newton_euler(arm, q, qd, qdd, &self.gravity)
    }

    /// The torques that hold the arm still at `q` against gravity.
    pub fn gravity_torques<A: Linkage<T, N>>(&self, arm: &A, q: &SVector<T, N>) -> SVector<T, N> {
        let zero = SVector::zeros();
        self.newton_euler(arm, q, &zero, &zero, &self.gravity)
    }

    /// The joint-space mass matrix at `q` (symmetric, positive definite for an arm whose every
    /// moving joint carries mass): torque = M q̈ + velocity terms + gravity.
    pub fn mass_matrix<A: Linkage<T, N>>(&self, arm: &A, q: &SVector<T, N>) -> SMatrix<T, N, N> {
        let zero = SVector::zeros();
        let mut m = SMatrix::<T, N, N>::zeros();
        for j in 0..N {
            let unit = SVector::<T, N>::from_fn(|i, _| if i == j { T::one() } else { T::zero() });
            m.set_column(j, &self.newton_euler(arm, q, &zero, &unit, &Vector3::zeros()));
        }
        m
    }

    fn newton_euler<A: Linkage<T, N>>(
        &self,
        arm: &A,
        q: &SVector<T, N>,
        qd: &SVector<T, N>,
        qdd: &SVector<T, N>,
        gravity: &Vector3<T>,
    ) -> SVector<T, N> {
        // Indexed through `get` (within N, which the compiler cannot always see): a firmware links
        // no panic path.
        let at = |v: &SVector<T, N>, k: usize| v.get(k).copied().unwrap_or_else(T::zero);
        let local: [Pose<T>; N] = core::array::from_fn(|k| arm.local_pose(k, at(q, k)));
        // Outward, parents first: each frame's angular velocity and acceleration and its origin's
        // linear acceleration, in its own axes; then the force and moment its link needs. The
        // base moves up at gravity's rate, so gravity needs no term of its own.
        let mut motion = [(Vector3::<T>::zeros(), Vector3::<T>::zeros(), Vector3::<T>::zeros()); N];
        let mut force = [Vector3::<T>::zeros(); N];
        let mut moment = [Vector3::<T>::zeros(); N];
        for k in 0..N {
            let (Some(joint), Some(pose), Some(link)) = (arm.joints().get(k), local.get(k), self.links.get(k)) else {
                continue;
            };
            let (w, dw, a) = match arm.parent(k).and_then(|p| motion.get(p)) {
                Some(&parent) => parent,
                None => (Vector3::zeros(), Vector3::zeros(), -gravity),
            };
            let back = pose.rotation.transpose();
            let p = pose.translation;
            // The parent's origin acceleration carried to this joint's origin, in this frame.
            let a_here = back * (a + dw.cross(&p) + w.cross(&w.cross(&p)));
            let (w_parent, dw_parent) = (back * w, back * dw);
            let z = joint.axis;
            let (w, dw, a) = match joint.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    let spin = z * at(qd, k);
                    (w_parent + spin, dw_parent + w_parent.cross(&spin) + z * at(qdd, k), a_here)
                }
                JointKind::Prismatic => {
                    let slide = z * at(qd, k);
                    (w_parent, dw_parent, a_here + w_parent.cross(&slide) * T::of(2.0) + z * at(qdd, k))
                }
                JointKind::Fixed => (w_parent, dw_parent, a_here),
            };
            let a_com = a + dw.cross(&link.com) + w.cross(&w.cross(&link.com));
            if let (Some(m), Some(f), Some(n)) = (motion.get_mut(k), force.get_mut(k), moment.get_mut(k)) {
                *m = (w, dw, a);
                *f = a_com * link.mass;
                // About the frame's origin: the spin's moment and the force's at the centre of mass.
                *n = link.tensor * dw + w.cross(&(link.tensor * w)) + link.com.cross(f);
            }
        }
        // Inward, children first: each link's force and moment with what its children pass it,
        // the joint's share of it, and what it passes to its parent (at its own origin, in the
        // parent's axes).
        let mut tau = SVector::<T, N>::zeros();
        for k in (0..N).rev() {
            // `force[k]` and `moment[k]` hold the link's own needs and, added as each was done,
            // its children's (a child's index is above its parent's).
            let (Some(joint), Some(pose), Some(&f), Some(&n)) =
                (arm.joints().get(k), local.get(k), force.get(k), moment.get(k))
            else {
                continue;
            };
            if let Some(t) = tau.get_mut(k) {
                *t = match joint.kind {
                    JointKind::Revolute | JointKind::Continuous => joint.axis.dot(&n),
                    JointKind::Prismatic => joint.axis.dot(&f),
                    JointKind::Fixed => T::zero(),
                };
            }
            if let Some(p) = arm.parent(k) {
                let f_out = pose.rotation * f;
                let n_out = pose.rotation * n + pose.translation.cross(&f_out);
                if let (Some(fp), Some(np)) = (force.get_mut(p), moment.get_mut(p)) {
                    *fp += f_out;
                    *np += n_out;
                }
            }
        }
        tau
    }
}
