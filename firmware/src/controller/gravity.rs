//! Gravity compensation: the goal each servo gets is offset by the deflection its own position
//! loop will leave under the arm's gravity torque, so that the joint comes to rest where the
//! setpoint (and the IK behind it) put it.
//!
//! A hobby servo is a P loop: at rest it pushes `K (goal - position)` against its load, so under a
//! steady gravity torque `τ` it stands `τ / K` short of its goal (an SO-101's shoulder lift about
//! 40 ticks at LeRobot's P of 16). The host knows each servo's stiffness (its drive model and the
//! P gain the set-up writes) and each link's mass; it sends them per joint
//! ([`crate::link::message::HostMessage::SetGravity`]), the gripper's jaw and a payload in the last
//! joint's. Each tick the controller computes the gravity torques at the setpoint
//! (`kinematics::dynamics`, recursive Newton-Euler with the links as point masses: at rest only
//! their masses and centres matter) and writes `setpoint + compliance x torque`, clamped to the
//! joint's limits and to [`MAX_OFFSET`].
//!
//! The offsets a servo gets move by at most [`MAX_SLEW`] while its torque is on, so compensation
//! taken on (or changed) while the arm holds raises it to its setpoint instead of jumping. With
//! the torque off they follow at once: the torque-on goal is then where the servo will hold the
//! joint, not where it would push it.
//!
//! What it does not do: the loop's velocity terms (the lag while moving), friction's dead band
//! (a joint can rest anywhere within the servo's Coulomb friction over its stiffness), and a load
//! the host was not told of.
//!
//! # RAM
//! Five floats and an `i16` a joint (132 bytes in the 6-joint build), in the running controller
//! only, not in the slot a new arm is built in: the STM32F411 build had 140 bytes left under its
//! 16 KiB goal. The offsets applied are kept in units of [`OFFSET_UNIT`] for it: as `f32`s they
//! took the build 4 bytes over.

use kinematics::dynamics::{Dynamics, Inertia};
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::Chain;

/// The largest offset compensation gives a goal (rad, or m for a prismatic joint): a bound on a
/// wrong mass or compliance, well above what a servo sags before it stalls.
pub const MAX_OFFSET: f32 = 0.25;
/// How fast an offset may change while the torque is on (rad/s): [`MAX_OFFSET`] in a second.
pub const MAX_SLEW: f32 = 0.25;
/// The unit the applied offsets are kept in (rad): 10 µrad, a hundredth of an STS3215's tick;
/// [`MAX_OFFSET`] is 25,000 of them.
pub const OFFSET_UNIT: f32 = 1e-5;

/// One joint's part: the mass its motion carries and how far its servo gives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GravityJoint {
    /// Mass, kg.
    pub mass: f32,
    /// Its centre, in the joint's moving frame (m).
    pub com: [f32; 3],
    /// Deflection per unit of torque (rad per N m).
    pub compliance: f32,
}

/// What compensation knows of the arm, and the offsets the goals carry now.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gravity<const N: usize> {
    joints: [GravityJoint; N],
    /// The offsets the goals carry now, in [`OFFSET_UNIT`]s.
    applied: [i16; N],
}

impl<const N: usize> Gravity<N> {
    /// No compensation: every goal is its setpoint.
    pub fn none() -> Self {
        Self { joints: [GravityJoint::default(); N], applied: [0; N] }
    }

    /// Whether any joint is compensated.
    pub fn active(&self) -> bool {
        self.joints.iter().any(|j| j.compliance > 0.0 && j.mass > 0.0)
    }

    /// Joint `joint`'s part (its numbers checked by the link's validation); `false` for a joint
    /// the build does not have. The offsets move to it at [`Gravity::update`].
    pub fn set(&mut self, joint: usize, part: GravityJoint) -> bool {
        let Some(slot) = self.joints.get_mut(joint) else { return false };
        *slot = part;
        true
    }

    /// The offsets the goals carry now (rad).
    pub fn applied(&self) -> SVector<f32, N> {
        SVector::from_fn(|j, _| f32::from(self.applied[j]) * OFFSET_UNIT)
    }

    /// Moves the offsets toward those of the setpoint `q` on `chain`: by at most [`MAX_SLEW`]
    /// over `dt` seconds when `slew`, else at once.
    pub fn update(&mut self, chain: &Chain<f32, N>, q: &SVector<f32, N>, dt: f32, slew: bool) {
        let target = self.offsets(chain, q);
        let step = if slew { MAX_SLEW * dt.max(0.0) } else { f32::INFINITY };
        let applied = self.applied();
        for j in 0..N {
            let offset = applied[j] + (target[j] - applied[j]).clamp(-step, step);
            // Within MAX_OFFSET, so within i16 (the cast saturates anyway).
            self.applied[j] = libm::roundf(offset / OFFSET_UNIT) as i16;
        }
    }

    /// Each joint's full offset at `q` on `chain` (rad), within [`MAX_OFFSET`]; zeros without
    /// compensation. Never inlined: its frame (the dynamics' temporaries) exists only while it
    /// runs, not under the rest of the tick.
    #[inline(never)]
    pub fn offsets(&self, chain: &Chain<f32, N>, q: &SVector<f32, N>) -> SVector<f32, N> {
        if !self.active() {
            return SVector::zeros();
        }
        let links = self.joints.map(|j| Inertia::point(j.mass, Vector3::from(j.com)));
        let Ok(dynamics) = Dynamics::new(links) else { return SVector::zeros() };
        let torques = dynamics.gravity_torques(chain, q);
        SVector::from_fn(|j, _| {
            let offset = self.joints[j].compliance * torques[j];
            if offset.is_finite() {
                offset.clamp(-MAX_OFFSET, MAX_OFFSET)
            } else {
                0.0
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::{Joint, Pose};

    /// A horizontal one-link arm: a revolute joint about y, its 0.5 kg link's centre 0.2 m out
    /// along x. Gravity pulls the link down (-z): holding it takes m g l about -y's sense.
    fn lever() -> Chain<f32, 1> {
        Chain::new([Joint::continuous(Pose::identity(), [0.0, 1.0, 0.0])], Pose::identity()).unwrap()
    }

    fn part(compliance: f32) -> GravityJoint {
        GravityJoint { mass: 0.5, com: [0.2, 0.0, 0.0], compliance }
    }

    /// The offset is the torque m g l (0.5 x 9.80665 x 0.2 = 0.9807 N m) times the compliance, in
    /// the direction that lifts the link: the torque that holds it, as the servo must give it.
    #[test]
    fn the_offset_is_the_sag_the_torque_leaves() {
        let mut g = Gravity::<1>::none();
        assert!(g.set(0, part(0.1)));
        let offset = g.offsets(&lever(), &SVector::zeros())[0];
        // A rotation about +y lowers +x toward -z: holding the link up is a negative torque.
        assert!((offset - -0.098_066_5).abs() < 1e-5, "{offset}");
        // Pointing straight down (q = pi/2 turns +x to -z), the link needs no torque.
        let down = g.offsets(&lever(), &SVector::from([core::f32::consts::FRAC_PI_2]))[0];
        assert!(down.abs() < 1e-5, "{down}");
        // A compliance far too soft is bounded.
        assert!(g.set(0, part(1.5)));
        assert_eq!(g.offsets(&lever(), &SVector::zeros())[0], -MAX_OFFSET);
        assert!(!g.set(1, part(0.1)));
        assert!(!Gravity::<1>::none().active());
        assert_eq!(Gravity::<1>::none().offsets(&lever(), &SVector::zeros())[0], 0.0);
    }

    /// With the torque on the offsets move at MAX_SLEW at most; off, at once.
    #[test]
    fn the_offsets_slew_while_the_torque_is_on() {
        let mut g = Gravity::<1>::none();
        assert!(g.set(0, part(0.1)));
        let q = SVector::zeros();
        g.update(&lever(), &q, 0.1, true);
        assert!((g.applied()[0] - -0.025).abs() < 1e-6, "{}", g.applied()[0]);
        for _ in 0..10 {
            g.update(&lever(), &q, 0.1, true);
        }
        assert!((g.applied()[0] - -0.098_066_5).abs() < 1e-5);
        // Taken off with the torque on: back at the same pace.
        assert!(g.set(0, GravityJoint::default()));
        g.update(&lever(), &q, 0.1, true);
        assert!((g.applied()[0] - (-0.098_066_5 + 0.025)).abs() < 1e-5);
        g.update(&lever(), &q, 0.1, false);
        assert_eq!(g.applied()[0], 0.0);
        assert!(g.set(0, part(0.1)));
        g.update(&lever(), &q, 0.0, false);
        assert!((g.applied()[0] - -0.098_066_5).abs() < 1e-5);
    }
}
