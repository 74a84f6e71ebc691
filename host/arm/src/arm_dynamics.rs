//! An arm's rigid-body dynamics at its run-time joint count: [`kinematics::dynamics::Dynamics`]
//! behind the object-safe [`ArmDynamics`], as [`crate::dof`] hides the chain, for the simulator's
//! servos and anything else on the host that needs the torques the links ask of their joints.
//!
//! Only the joint counts a firmware carries are dispatched (0 to [`crate::dof::F32_MAX_JOINTS`]):
//! these are the arms whose servos the simulator drives, and each count instantiates the
//! recursive Newton-Euler pass once more.

use crate::dof::{dispatch, dispatch_f32, F32_MAX_JOINTS, MAX_JOINTS};
use crate::urdf_inertials::{self, Masses};
use crate::ArmSpec;
use anyhow::{anyhow, bail, Result};
use kinematics::dynamics::{Dynamics, Inertia};
use kinematics::nalgebra::SVector;
use kinematics::Chain;

/// The SO-101's URDF: the preset's masses are its `<inertial>` tags (the preset's frames are the
/// URDF's, a test of `presets` checks it).
const SO101_URDF: &str = include_str!("../../tests/data/so101_new_calib.urdf");

/// Torques an arm's links ask of its joints (N m, base first).
pub trait ArmDynamics: Send + Sync {
    /// The joint count.
    fn dof(&self) -> usize;

    /// The torques that keep the arm at `q` moving at `qd` without accelerating it: gravity and
    /// the velocity terms (Coriolis and centrifugal).
    fn bias(&self, q: &[f64], qd: &[f64]) -> Vec<f64>;

    /// The torques that hold the arm still at `q` against gravity.
    fn gravity(&self, q: &[f64]) -> Vec<f64>;

    /// The diagonal of the joint-space mass matrix at `q`: the inertia each joint moves with the
    /// others held (kg m²).
    fn inertia_diagonal(&self, q: &[f64]) -> Vec<f64>;
}

/// What each joint of `arm` moves (base first): the arm file's masses when it gives them, the
/// SO-101 preset's from its URDF, `None` for any other arm.
pub fn masses_of(arm: &ArmSpec) -> Option<Result<Vec<Inertia<f64>>>> {
    if let Some(links) = &arm.masses {
        return Some(Ok(links.clone()));
    }
    (arm.name == "so101")
        .then(|| urdf_inertials::masses(SO101_URDF, Some("gripper_frame_link")).map(|m: Masses| m.links))
}

/// The dynamics of `arm` with `masses` (one body per joint, base first) and `payload` in the tool
/// frame, if any. Fails when the counts differ, a body or the payload is not a body's, or the arm
/// has more joints than a firmware drives.
pub fn dynamics(
    arm: &ArmSpec,
    masses: &[Inertia<f64>],
    payload: Option<&Inertia<f64>>,
) -> Result<Box<dyn ArmDynamics>> {
    if masses.len() != arm.dof() {
        bail!("arm {} has {} joints but masses for {}", arm.name, arm.dof(), masses.len());
    }
    struct Build<'a>(&'a ArmSpec, &'a [Inertia<f64>], Option<&'a Inertia<f64>>);
    fn build<const N: usize>(b: Build<'_>) -> Result<Box<dyn ArmDynamics>> {
        let Build(arm, masses, payload) = b;
        let chain: Chain<f64, N> = arm.chain()?;
        let links: [Inertia<f64>; N] = core::array::from_fn(|i| masses[i]);
        let mut model = Dynamics::new(links).map_err(|e| anyhow!("arm {}'s masses: {e}", arm.name))?;
        if let Some(payload) = payload {
            model = model.with_payload(&chain, payload).map_err(|e| anyhow!("payload: {e}"))?;
        }
        Ok(Box::new(Fixed { chain, model }))
    }
    let b = Build(arm, masses, payload);
    match arm.dof() {
        n @ 0..=F32_MAX_JOINTS => dispatch_f32!(n, build(b)),
        n => bail!("arm {} has {n} joints: the simulator's servos drive at most {F32_MAX_JOINTS}", arm.name),
    }
}

/// A payload of `mass` kg at `at` (m, in the tool frame), as a point; refused when the mass is not
/// finite and non-negative.
pub fn point_payload(mass: f64, at: [f64; 3]) -> Result<Inertia<f64>> {
    Inertia::point(mass, at.into()).validated().map_err(|e| anyhow!("payload {mass} kg at {at:?}: {e}"))
}

struct Fixed<const N: usize> {
    chain: Chain<f64, N>,
    model: Dynamics<f64, N>,
}

impl<const N: usize> Fixed<N> {
    fn vector(v: &[f64]) -> SVector<f64, N> {
        SVector::from_fn(|i, _| v.get(i).copied().unwrap_or(0.0))
    }
}

impl<const N: usize> ArmDynamics for Fixed<N> {
    fn dof(&self) -> usize {
        N
    }

    fn bias(&self, q: &[f64], qd: &[f64]) -> Vec<f64> {
        let zero = SVector::zeros();
        self.model.inverse(&self.chain, &Self::vector(q), &Self::vector(qd), &zero).iter().copied().collect()
    }

    fn gravity(&self, q: &[f64]) -> Vec<f64> {
        self.model.gravity_torques(&self.chain, &Self::vector(q)).iter().copied().collect()
    }

    fn inertia_diagonal(&self, q: &[f64]) -> Vec<f64> {
        self.model.mass_matrix(&self.chain, &Self::vector(q)).diagonal().iter().copied().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets;

    /// The SO-101 preset's gravity torques are its URDF's (the masses are read in the URDF's
    /// frames, which the preset shares): the shoulder lift holds the most at the zero pose, the
    /// base's vertical pan axis none.
    #[test]
    fn the_so101_preset_has_its_urdfs_masses() {
        let arm = presets::by_name("so101").unwrap();
        let masses = masses_of(&arm).unwrap().unwrap();
        let d = dynamics(&arm, &masses, None).unwrap();
        let g = d.gravity(&[0.0; 5]);
        // The file rounds its angles (1.5708 for π/2): the pan axis is vertical to 1e-5.
        assert!(g[0].abs() < 1e-5, "{g:?}");
        assert!(g[1].abs() > g[2].abs() && g[2].abs() > g[3].abs(), "{g:?}");
        // A 0.2 kg payload adds to every lifting joint's load, more nearer the base.
        let payload = point_payload(0.2, [0.0; 3]).unwrap();
        let heavy = dynamics(&arm, &masses, Some(&payload)).unwrap().gravity(&[0.0; 5]);
        assert!((heavy[1] - g[1]).abs() > (heavy[3] - g[3]).abs() && (heavy[3] - g[3]).abs() > 0.0);
        // Moving adds velocity terms; the diagonal is the inertia each joint moves.
        let m = d.inertia_diagonal(&[0.0; 5]);
        assert!(m.iter().all(|&x| x > 0.0), "{m:?}");
        assert!(presets::by_name("ur5e").map(|a| masses_of(&a).is_none()).unwrap());
        assert!(point_payload(f64::NAN, [0.0; 3]).is_err());
        assert!(dynamics(&presets::by_name("open-manipulator-x").unwrap(), &masses, None).is_err());
    }
}
