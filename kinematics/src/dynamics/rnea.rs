//! The recursive Newton-Euler algorithm (Luh, Walker and Paul, 1980), in each joint's own frame:
//! velocities and accelerations outward from the base, forces and moments inward from the tool.
//! Gravity enters as an upward acceleration of the base, so one pass gives the whole torque. The
//! mass matrix is built a column at a time from the same pass (Walker and Orin's first method:
//! no velocity, no gravity, a unit acceleration of one joint), O(N²) for the chains here.

use nalgebra::{SMatrix, SVector, Vector3};

use super::inertia::{Inertia, InertiaError};
use crate::{Chain, JointKind, Pose, Real};

/// Standard gravity (m/s²), as ISO 80000-3 defines it.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// A chain's mass properties: each joint's link (in that joint's moving frame, as URDF's child
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
    /// down, or none.
    pub fn with_gravity(mut self, g: Vector3<T>) -> Self {
        self.gravity = g;
        self
    }

    /// The same carrying `payload` (in the tool frame) rigidly with the last link.
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

    /// The joint torques (N m; N for a prismatic joint) that give the chain at `q` moving at `qd`
    /// the accelerations `qdd`, gravity included.
    pub fn inverse(
        &self,
        chain: &Chain<T, N>,
        q: &SVector<T, N>,
        qd: &SVector<T, N>,
        qdd: &SVector<T, N>,
    ) -> SVector<T, N> {
        self.newton_euler(chain, q, qd, qdd, &self.gravity)
    }

    /// The torques that hold the chain still at `q` against gravity.
    pub fn gravity_torques(&self, chain: &Chain<T, N>, q: &SVector<T, N>) -> SVector<T, N> {
        let zero = SVector::zeros();
        self.newton_euler(chain, q, &zero, &zero, &self.gravity)
    }

    /// The joint-space mass matrix at `q` (symmetric, positive definite for a chain whose every
    /// moving joint carries mass): torque = M q̈ + velocity terms + gravity.
    pub fn mass_matrix(&self, chain: &Chain<T, N>, q: &SVector<T, N>) -> SMatrix<T, N, N> {
        let zero = SVector::zeros();
        let mut m = SMatrix::<T, N, N>::zeros();
        for j in 0..N {
            let unit = SVector::<T, N>::from_fn(|i, _| if i == j { T::one() } else { T::zero() });
            m.set_column(j, &self.newton_euler(chain, q, &zero, &unit, &Vector3::zeros()));
        }
        m
    }

    fn newton_euler(
        &self,
        chain: &Chain<T, N>,
        q: &SVector<T, N>,
        qd: &SVector<T, N>,
        qdd: &SVector<T, N>,
        gravity: &Vector3<T>,
    ) -> SVector<T, N> {
        // Indexed through `get` (within N, which the compiler cannot always see): a firmware links
        // no panic path.
        let at = |v: &SVector<T, N>, k: usize| v.get(k).copied().unwrap_or_else(T::zero);
        let local: [Pose<T>; N] = core::array::from_fn(|k| chain.local_pose(k, at(q, k)));
        // Outward: each frame's angular velocity and acceleration and its origin's linear
        // acceleration, in its own axes; then the force and moment its link needs.
        let (mut w, mut dw, mut a) = (Vector3::zeros(), Vector3::zeros(), -gravity);
        let mut force = [Vector3::<T>::zeros(); N];
        let mut moment = [Vector3::<T>::zeros(); N];
        let outward = chain.joints().iter().zip(&local).zip(&self.links).zip(force.iter_mut().zip(moment.iter_mut()));
        for (k, (((joint, pose), link), (force, moment))) in outward.enumerate() {
            let back = pose.rotation.transpose();
            let p = pose.translation;
            // The parent's origin acceleration carried to this joint's origin, in this frame.
            let a_here = back * (a + dw.cross(&p) + w.cross(&w.cross(&p)));
            let (w_parent, dw_parent) = (back * w, back * dw);
            let z = joint.axis;
            (w, dw, a) = match joint.kind {
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
            *force = a_com * link.mass;
            *moment = link.tensor * dw + w.cross(&(link.tensor * w));
        }
        // Inward: what each link passes to its parent, and the joint's share of it.
        let mut tau = SVector::<T, N>::zeros();
        let (mut f_child, mut n_child) = (Vector3::<T>::zeros(), Vector3::<T>::zeros());
        for k in (0..N).rev() {
            let (Some(link), Some(joint), Some(&force), Some(&moment)) =
                (self.links.get(k), chain.joints().get(k), force.get(k), moment.get(k))
            else {
                continue;
            };
            // The child's force and moment in this frame, and where the child's origin is.
            let (to_child, at_child) = match local.get(k + 1) {
                Some(child) => (child.rotation, child.translation),
                None => (nalgebra::Matrix3::identity(), Vector3::zeros()),
            };
            let f_in = to_child * f_child;
            let f = force + f_in;
            let n = moment + to_child * n_child + link.com.cross(&force) + at_child.cross(&f_in);
            if let Some(t) = tau.get_mut(k) {
                *t = match joint.kind {
                    JointKind::Revolute | JointKind::Continuous => joint.axis.dot(&n),
                    JointKind::Prismatic => joint.axis.dot(&f),
                    JointKind::Fixed => T::zero(),
                };
            }
            (f_child, n_child) = (f, n);
        }
        tau
    }
}
