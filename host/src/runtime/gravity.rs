//! Gravity compensation as the host gives it to the firmware core
//! ([`firmware::controller::gravity`]): per joint, the mass its motion carries (its link, the
//! gripper's jaw where the arm file or URDF puts it, and a payload in the last joint's) and its
//! servo's compliance, the inverse of its position loop's stiffness at rest.
//!
//! The stiffness is the servo model's ([`crate::sim::drive_models`]): `stall torque x duty per
//! radian per unit of P x P`, the P gain being the one the servo holds. That is the set-up's
//! where a set-up writes one (LeRobot's 16 on the STS3215, which the core on this PC writes when
//! it connects and `armctl servo setup` writes to a real arm), else the factory's (the servos
//! of the drive commands' `--sim`, which nothing sets up).

use anyhow::{anyhow, bail, Result};
use firmware::controller::gravity::GravityJoint;
use kinematics::dynamics::Inertia;

use crate::arm::arm_dynamics::{masses_of, point_payload};
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;
use crate::sim::drive_models::{drive_model, DriveRegisters};

/// Which P gain the servos hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gains {
    /// The one the set-up writes ([`crate::runtime::pc::setup::settings`]), else the factory's.
    SetUp,
    /// The factory's.
    Factory,
}

/// Gravity compensation asked for: the servos' gains and a payload at the tool frame's origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compensation {
    /// The P gain the servos hold.
    pub gains: Gains,
    /// kg at the tool.
    pub payload_kg: Option<f64>,
    /// Asked for (`--gravity-compensation on`): an arm without masses is refused. Otherwise (on by
    /// default with physical simulated servos) such an arm goes without.
    pub asked: bool,
}

impl Compensation {
    /// On by default with the servos holding `gains`, carrying `payload_kg`.
    pub fn by_default(gains: Gains, payload_kg: Option<f64>) -> Self {
        Self { gains, payload_kg, asked: false }
    }
}

/// The compliance (rad per N m) of a servo of `arm`'s model holding P gain as `gains` says.
pub fn compliance(arm: &ArmSpec, gains: Gains) -> Result<f64> {
    let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no [servos] table", arm.name))?;
    let model = servos.model;
    let registers = DriveRegisters::of(model);
    let drive = drive_model(model, registers.factory_volts(model))
        .ok_or_else(|| anyhow!("gravity compensation has no drive model of the {} yet", model.name))?;
    let item = registers.p_gain();
    let factory = model.defaults.iter().find(|(i, _)| *i == item).map(|&(_, v)| v);
    let set_up = crate::runtime::pc::setup::settings(model).iter().find(|s| s.item == item).map(|s| s.value);
    let p = match gains {
        Gains::SetUp => set_up.or(factory),
        Gains::Factory => factory,
    }
    .ok_or_else(|| anyhow!("the {}'s P gain is not known", model.name))?;
    let stiffness = drive.stall_torque * drive.kp_scale * p as f64;
    if !stiffness.is_finite() || stiffness <= 0.0 {
        bail!("the {}'s position loop has no stiffness at P = {p}", model.name);
    }
    Ok(1.0 / stiffness)
}

/// What gives the firmware `arm`'s gravity compensation, one part per joint (the session sends
/// each as a `SetGravity`: [`crate::link::session::Session::gravity`]). For an arm
/// without masses (a preset other than the SO-101, an arm file without `mass`): none, or when
/// compensation was asked for, an error in one line; so too for servos without a drive model.
pub fn gravity_parts(arm: &ArmSpec, compensation: &Compensation) -> Result<Vec<GravityJoint>> {
    let Some(masses) = masses_of(arm) else {
        if !compensation.asked {
            return Ok(Vec::new());
        }
        bail!(
            "arm {} has no masses, which gravity compensation needs: give each [[joint]] a mass and com in its arm \
             file (docs/kinematics.md)",
            arm.name
        )
    };
    let mut links: Vec<Inertia<f64>> = masses?;
    if links.len() != arm.dof() {
        bail!("arm {} has {} joints but masses for {}", arm.name, arm.dof(), links.len());
    }
    if let (Some(kg), Some(last)) = (compensation.payload_kg, links.last_mut()) {
        let payload = point_payload(kg, [0.0; 3])?.moved(&arm.tool.rotation, &arm.tool.translation);
        *last = last.combined(&payload);
    }
    let compliance = compliance(arm, compensation.gains)? as f32;
    Ok(links
        .iter()
        .map(|link| GravityJoint {
            mass: link.mass as f32,
            com: [link.com.x as f32, link.com.y as f32, link.com.z as f32],
            compliance,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SO-101's STS3215s at 7.4 V: 0.166 duty per rad per unit of P, 3.35 N m at stall
    /// (docs/servo-model.md: 0.166 x 32 x 3.35 = 17.8 N m/rad at the factory's P of 32), half as
    /// stiff at the set-up's 16.
    #[test]
    fn the_so101s_compliance_follows_its_p_gain() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let factory = compliance(&arm, Gains::Factory).unwrap();
        let set_up = compliance(&arm, Gains::SetUp).unwrap();
        assert!((1.0 / factory - 17.8).abs() < 0.2, "{}", 1.0 / factory);
        assert!((set_up / factory - 2.0).abs() < 1e-9);
    }

    /// One part per joint, the payload in the last joint's mass; an arm without masses refused
    /// when compensation is asked for, left without otherwise.
    #[test]
    fn one_part_per_joint_and_the_payload_in_the_last() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let bare = gravity_parts(&arm, &Compensation::by_default(Gains::SetUp, None)).unwrap();
        let heavy = gravity_parts(&arm, &Compensation::by_default(Gains::SetUp, Some(0.2))).unwrap();
        assert_eq!(bare.len(), arm.dof());
        assert!((heavy[4].mass - bare[4].mass - 0.2).abs() < 1e-6);
        assert_eq!(heavy[0], bare[0]);
        assert!(bare.iter().all(|p| p.mass >= 0.0 && p.compliance > 0.0));
        let omx = ArmSpec::load("open-manipulator-x", None).unwrap();
        assert_eq!(gravity_parts(&omx, &Compensation::by_default(Gains::SetUp, None)).unwrap(), vec![]);
        let asked = Compensation { asked: true, ..Compensation::by_default(Gains::SetUp, None) };
        let err = gravity_parts(&omx, &asked).unwrap_err();
        assert!(err.to_string().contains("has no masses"), "{err}");
    }
}
