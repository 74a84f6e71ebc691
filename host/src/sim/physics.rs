//! The arm's physics on the bus: every servo's drive ([`super::drive`]) stepped on one clock
//! against what its joint carries: the torques the links ask of it (gravity, a payload, the
//! velocity terms) and the inertia it moves, from the arm's rigid-body dynamics
//! ([`crate::arm::arm_dynamics`]) at the horns' present angles and speeds.
//!
//! Each joint moves the diagonal of the mass matrix (its own inertia with the others held): the
//! off-diagonal coupling (one joint's acceleration pushing on another) is left out, so a fast move
//! of the shoulder does not jolt the wrist here. A servo that drives no joint of the arm (a
//! gripper's) turns its armature alone. An arm without masses (a preset other than the SO-101, an
//! arm file without them) gets the drives without gravity.

use std::sync::Arc;

use anyhow::{anyhow, Result};
use firmware::bus::mapping::JointMapping;
use kinematics::dynamics::Inertia;

use super::drive::{radians_per_tick, STEP_NS};
use super::servo::SimServo;
use super::world::angle_of;
use crate::arm::arm_dynamics::{dynamics, masses_of, ArmDynamics};
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;

/// A load the simulated arm carries at its tool: `kg` at `at` (m, in the tool frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Payload {
    /// Mass, kg.
    pub kg: f64,
    /// Where, m, in the tool frame.
    pub at: [f64; 3],
}

/// The servos a simulation has (`--servos`).
///
/// Ideal by default until the firmware compensates gravity: physical servos leave the SO-101's
/// tool 9 mm below where the IK put it, 21 mm with 200 g at the tool (docs/servo-model.md), and
/// every accuracy figure of the manual is measured on ideal ones.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum ServoKind {
    /// Each with its drive, carrying the arm's links (and a payload) under gravity: they sag, lag,
    /// draw current, warm up and stall ([`super::drive`]).
    Physical(Option<Payload>),
    /// Each reaching its profile exactly: no load, no lag, no heat.
    #[default]
    Ideal,
}

/// The servos named `name` (`ideal` or `physical`; `None`: the default) carrying `payload_kg` at
/// the tool frame's origin; a payload needs physical servos.
pub fn servo_kind(name: Option<&str>, payload_kg: Option<f64>) -> Result<ServoKind> {
    let payload = payload_kg.map(|kg| Payload { kg, at: [0.0; 3] });
    match (name, payload) {
        (Some("physical"), payload) => Ok(ServoKind::Physical(payload)),
        (Some("ideal") | None, None) => Ok(ServoKind::Ideal),
        (Some("ideal") | None, Some(_)) => {
            anyhow::bail!(
                "a payload is carried by physical servos only: add --servos physical (servos=\"physical\" in Python)"
            )
        }
        (Some(other), _) => anyhow::bail!("--servos {other:?}: give ideal or physical"),
    }
}

/// Poses sampled to find the most a payload asks of each joint.
const PAYLOAD_POSES: usize = 256;

impl ServoKind {
    /// The physics for the servos of `arm` (`None`: no arm, the servos' drives alone), or none
    /// for ideal servos. Fails for a payload the servos cannot hold: one whose gravity torque, at
    /// some of [`PAYLOAD_POSES`] poses across the joints' ranges, exceeds a joint servo's stall
    /// torque.
    pub fn physics(&self, arm: Option<&ArmSpec>) -> Result<Option<Physics>> {
        let Self::Physical(payload) = self else { return Ok(None) };
        let Some(arm) = arm else {
            if payload.is_some() {
                anyhow::bail!("a payload needs an arm (--arm) to carry it");
            }
            return Ok(Some(Physics::servos_only()));
        };
        let payload = payload.map(|p| crate::arm::arm_dynamics::point_payload(p.kg, p.at)).transpose()?;
        let physics = Physics::new(arm, payload.as_ref())?;
        if let (Some(p), Some(model)) = (payload, &physics.dynamics) {
            check_payload(arm, model.as_ref(), p.mass)?;
        }
        Ok(Some(physics))
    }
}

/// Refuses a payload of `kg` that asks a joint for more than its servo's stall torque somewhere
/// in its range.
fn check_payload(arm: &ArmSpec, model: &dyn ArmDynamics, kg: f64) -> Result<()> {
    let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no [servos] table", arm.name))?;
    let volts = super::drive_models::DriveRegisters::of(servos.model).factory_volts(servos.model);
    let Some(drive) = super::drive_models::drive_model(servos.model, volts) else { return Ok(()) };
    let stall = drive.stall_torque * drive.max_duty;
    let built = crate::arm::dof::build(arm.clone())?;
    let mut rng = kinematics::SplitMix64::new(39);
    for _ in 0..PAYLOAD_POSES {
        let q = built.random_configuration(&mut rng);
        for (j, torque) in model.gravity(&q).iter().enumerate() {
            if torque.abs() > stall {
                anyhow::bail!(
                    "a payload of {kg} kg needs {:.2} N m at {} (at {q:.2?} rad), beyond its {} servo's stall torque of {stall:.2} N m",
                    torque.abs(),
                    arm.joints[j].name,
                    drive.name
                );
            }
        }
    }
    Ok(())
}

/// The arm's joints on the bus, and what they carry.
#[derive(Clone)]
pub struct Physics {
    /// Per joint, base first: its servo's mapping from ticks to the joint's angle.
    mappings: Vec<JointMapping>,
    /// Per joint: its angle's direction against its horn's ([`direction`]).
    directions: Vec<f64>,
    /// The links' torques and inertia; `None`: the drives turn their armatures alone.
    dynamics: Option<Arc<dyn ArmDynamics>>,
    /// The joints' inertias and the steps they stay in use: they change with the pose, slowly,
    /// and cost a pass of the dynamics per joint.
    inertia: (Vec<f64>, u32),
    /// What it was made from (the arm and its payload), which tells two apart.
    made_from: Option<(ArmSpec, Option<Inertia<f64>>)>,
}

impl PartialEq for Physics {
    fn eq(&self, other: &Self) -> bool {
        self.made_from == other.made_from
    }
}

/// A joint angle's direction against its horn's: 1, or -1 where the mapping is reversed.
fn direction(mapping: &JointMapping) -> f64 {
    (angle_of(mapping, 1.0) - angle_of(mapping, 0.0)).signum()
}

/// Steps an inertia is used for before it is computed again (10 ms: a joint at full speed turns
/// 0.05 rad in that time).
const INERTIA_STEPS: u32 = 10;

impl std::fmt::Debug for Physics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Physics").field("joints", &self.mappings.len()).field("gravity", &self.has_gravity()).finish()
    }
}

impl Physics {
    /// Drives with no arm: each servo turns its own armature.
    pub fn servos_only() -> Self {
        Self { mappings: Vec::new(), directions: Vec::new(), dynamics: None, inertia: (Vec::new(), 0), made_from: None }
    }

    /// `arm`'s servos carrying its links (the masses of [`masses_of`]), and `payload` at the tool.
    /// Fails for an arm without servos, or a payload that is not a body's.
    pub fn new(arm: &ArmSpec, payload: Option<&Inertia<f64>>) -> Result<Self> {
        let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no [servos] table", arm.name))?;
        let mappings: Vec<JointMapping> = (0..arm.dof()).filter_map(|j| servos.mapping(j)).collect();
        let dynamics = match masses_of(arm) {
            Some(masses) => Some(Arc::from(dynamics(arm, &masses?, payload)?)),
            None if payload.is_some() => {
                anyhow::bail!(
                    "arm {} has no masses: a payload needs the links' too (give each [[joint]] of its arm file a mass and com)",
                    arm.name
                )
            }
            None => None,
        };
        let made_from = Some((arm.clone(), payload.copied()));
        let directions = mappings.iter().map(direction).collect();
        Ok(Self { mappings, directions, dynamics, inertia: (Vec::new(), 0), made_from })
    }

    /// Whether the links have mass (gravity loads the servos).
    pub fn has_gravity(&self) -> bool {
        self.dynamics.is_some()
    }

    /// Steps every drive on `servos` up to `to_ns`, all on one grid.
    pub fn advance(&mut self, servos: &mut [SimServo], to_ns: u64) {
        let index: Vec<Option<usize>> =
            self.mappings.iter().map(|m| servos.iter().position(|s| s.id() == m.id)).collect();
        // The joints can be placed only with every joint's servo on the bus.
        let joints: Option<Vec<usize>> = index.iter().copied().collect();
        let mut loads = vec![(0.0, 0.0); servos.len()];
        while servos.iter().filter_map(SimServo::drive).any(|d| d.stepped_ns() + STEP_NS <= to_ns) {
            loads.iter_mut().for_each(|l| *l = (0.0, 0.0));
            if let (Some(model), Some(joints)) = (self.dynamics.clone(), &joints) {
                self.joint_loads(model.as_ref(), servos, joints, &mut loads);
            }
            for (servo, &(load, inertia)) in servos.iter_mut().zip(&loads) {
                if servo.drive().is_some_and(|d| d.stepped_ns() + STEP_NS <= to_ns) {
                    servo.drive_step(load, inertia);
                }
            }
        }
    }

    /// Each joint's load (N m) and inertia (kg m²) in its horn's direction, at the horns' present
    /// angles and speeds.
    fn joint_loads(&mut self, model: &dyn ArmDynamics, servos: &[SimServo], joints: &[usize], out: &mut [(f64, f64)]) {
        let mut q = Vec::with_capacity(joints.len());
        let mut qd = Vec::with_capacity(joints.len());
        for ((m, &s), &i) in self.mappings.iter().zip(&self.directions).zip(joints) {
            let servo = &servos[i];
            let Some(drive) = servo.drive() else { return };
            let per_tick = radians_per_tick(servo.model().ticks_per_revolution);
            let ticks = servo.reported(drive.angle() / per_tick);
            q.push(angle_of(m, ticks));
            qd.push(s * drive.speed());
        }
        let bias = model.bias(&q, &qd);
        let (inertia, age) = &mut self.inertia;
        if *age == 0 || inertia.len() != joints.len() {
            *inertia = model.inertia_diagonal(&q);
            *age = INERTIA_STEPS;
        }
        *age -= 1;
        for (k, &i) in joints.iter().enumerate() {
            out[i] = (self.directions[k] * bias[k], inertia[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::presets;
    use crate::sim::drive_table::STS3215_7V4;
    use crate::sim::SimBus;
    use firmware::bus::table::STS3215;

    /// The SO-101's bus with physics, torque on at `ticks` per servo, run for `seconds`: each
    /// servo's present position less its goal.
    fn settled(arm: &ArmSpec, payload: Option<&Inertia<f64>>, ticks: &[i64], seconds: f64) -> Vec<i64> {
        let servos = servos_of(arm).unwrap();
        let mut bus = SimBus::new(STS3215.protocol, &STS3215, &servos.bus_ids(), 1_000_000)
            .with_physics(Some(Physics::new(arm, payload).unwrap()));
        for (servo, &t) in bus.servos_mut().iter_mut().zip(ticks) {
            servo.set_position(t, 0);
            servo.set_register(STS3215.items.torque_enable, 1, 0).unwrap();
        }
        bus.advance_to((seconds * 1e9) as u64);
        let items = STS3215.items;
        bus.servos().iter().map(|s| s.get(items.present_position) - s.get(items.goal_position)).collect()
    }

    /// An arm file's masses load its servos as the preset's do: the SO-101 under another name
    /// (its servos in its file) has none until its file gives them, then sags as the preset does.
    #[test]
    fn an_arm_files_masses_load_its_servos() {
        let so101 = presets::by_name("so101").unwrap();
        let mut mine = ArmSpec { name: "my-arm".into(), servos: servos_of(&so101), ..so101.clone() };
        assert!(!Physics::new(&mine, None).unwrap().has_gravity());
        assert!(Physics::new(&mine, Some(&Inertia::point(0.1, [0.0; 3].into()))).is_err());
        mine.masses = Some(masses_of(&so101).unwrap().unwrap());
        let text = crate::arm::toml_writer::to_text(&mine, &[]);
        let mine = crate::arm::toml_file::parse(&text).unwrap();
        assert!(Physics::new(&mine, None).unwrap().has_gravity());
        let ticks = [2048, 1600, 2500, 2048, 2048, 2048];
        let (theirs, ours) = (settled(&so101, None, &ticks, 2.0), settled(&mine, None, &ticks, 2.0));
        assert_eq!(theirs, ours);
        assert!(ours[1].abs() >= 3, "{ours:?}");
    }

    /// Each joint sags by its gravity torque over its loop's stiffness, within friction's band,
    /// in the direction gravity pulls it: the rigid-body dynamics reaches the drives through the
    /// mappings (a reversed joint included). The pan's axis is vertical: no sag.
    #[test]
    fn the_so101_sags_by_its_gravity_torques() {
        let arm = presets::by_name("so101").unwrap();
        let servos = servos_of(&arm).unwrap();
        let physics = Physics::new(&arm, None).unwrap();
        assert!(physics.has_gravity());
        // A pose with the upper arm and forearm out to the side: shoulder lift and elbow loaded.
        let q = [0.3, -0.8, 0.9, 0.4, 0.0];
        let mut ticks: Vec<i64> =
            (0..5).map(|j| i64::from(servos.mapping(j).unwrap().to_ticks(q[j]).unwrap())).collect();
        ticks.push(2048);
        let sag = settled(&arm, None, &ticks, 3.0);
        let masses = masses_of(&arm).unwrap().unwrap();
        let g = dynamics(&arm, &masses, None).unwrap().gravity(&q);
        let m = STS3215_7V4;
        let stiffness = 32.0 * m.kp_scale * m.stall_torque * radians_per_tick(4096);
        for j in 0..5 {
            let mapping = servos.mapping(j).unwrap();
            let s = direction(&mapping);
            // Holding the arm takes +g; gravity pulls the horn the other way.
            let (lo, hi) = ((g[j].abs() - m.coulomb).max(0.0) / stiffness, (g[j].abs() + m.coulomb) / stiffness);
            let toward = -s * g[j].signum();
            let along = sag[j] as f64 * toward;
            assert!(
                along >= lo.floor() - 1.0 && along <= hi.ceil() + 1.0,
                "joint {j}: {} ticks, {lo:.1} to {hi:.1}, g {g:?}",
                sag[j]
            );
        }
        assert!(sag[1].abs() >= 3 && sag[0] == 0, "{sag:?}");
        // A 200 g payload at the tool sags the shoulder lift further.
        let payload = crate::arm::arm_dynamics::point_payload(0.2, [0.0; 3]).unwrap();
        let heavy = settled(&arm, Some(&payload), &ticks, 3.0);
        assert!(heavy[1].abs() > sag[1].abs() + 2, "{heavy:?} against {sag:?}");
    }

    /// Without a drive, a servo follows its profile exactly (the ideal servo): the same bus
    /// without physics reports its goals.
    #[test]
    fn without_physics_the_servos_are_ideal() {
        let arm = presets::by_name("so101").unwrap();
        let servos = servos_of(&arm).unwrap();
        let mut bus = SimBus::new(STS3215.protocol, &STS3215, &servos.bus_ids(), 1_000_000);
        for servo in bus.servos_mut() {
            servo.set_position(1500, 0);
            servo.set_register(STS3215.items.torque_enable, 1, 0).unwrap();
        }
        bus.advance_to(1_000_000_000);
        assert!(bus.servos().iter().all(|s| s.get(STS3215.items.present_position) == 1500 && s.drive().is_none()));
    }

    /// A servo whose winding reaches its temperature limit under torque sets its overheat bit
    /// and lets go, on both families (the STS3215's 70 °C, an XM430's `Temperature_Limit`).
    #[test]
    fn an_overheated_servo_sets_its_bit_and_lets_go() {
        for model in [&STS3215, &firmware::bus::table::XM430_W350] {
            let mut bus = SimBus::new(model.protocol, model, &[1], 1_000_000);
            let registers = crate::sim::drive_models::DriveRegisters::of(model);
            // The winding starts where its reading says: 5 °C over the limit.
            let limit = registers.temperature_limit(|item| bus.servo(1).unwrap().get(item));
            bus.servo_mut(1).unwrap().set_register(registers.temperature(), limit as i64 + 5, 0).unwrap();
            bus.set_physics(Some(Physics::servos_only()));
            bus.servo_mut(1).unwrap().set_register(model.items.torque_enable, 1, 0).unwrap();
            bus.advance_to(10_000_000);
            let servo = bus.servo(1).unwrap();
            assert!(!servo.torque(), "{}: torque off", model.name);
            let bits = match model.items.hardware_error {
                Some(item) => servo.get(item) as u8,
                None => servo.status_error(0),
            };
            assert_eq!(bits & 0x04, 0x04, "{}: overheat bit in {bits:#x}", model.name);
        }
    }
}
