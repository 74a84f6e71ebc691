//! The built-in arms by name.

use super::collision::{allowed, toml, validate, CollisionSpec};
use super::ArmSpec;
use anyhow::{anyhow, bail, Context, Result};
use kinematics::presets;

/// The preset names, for help and error messages.
pub const NAMES: &str = "planar:N (N = 0..=32), ur5e, puma560, iiwa14, so101, open-manipulator-x";

/// The SO-101's collision table, fitted from its STL meshes (the file's header says how).
const SO101_COLLISION: &str = include_str!("../presets/so101-collision.toml");

/// The link radius of each preset whose meshes are not at hand, for capsules measured from its
/// frames ([`CollisionSpec::from_frames`]), and where the figure comes from.
pub const FRAME_RADII: &[(&str, f64, &str)] = &[
    ("open-manipulator-x", 0.025, "its Dynamixel XM430s, 28.5 x 34 mm across (ROBOTIS e-Manual)"),
    ("ur5e", 0.06, "its joint housings, about 0.12 m across (UR5e datasheet drawings)"),
    ("puma560", 0.08, "its upper arm and forearm castings, about 0.15 m across (Corke's model drawings)"),
    ("iiwa14", 0.07, "its links, about 0.13 to 0.15 m across (KUKA LBR iiwa datasheet)"),
];

/// The preset called `name`, with its collision geometry when it is a real arm.
pub fn by_name(name: &str) -> Result<ArmSpec> {
    let mut arm = without_geometry(name)?;
    arm.collision = if arm.name == "so101" {
        Some(toml::parse_section(SO101_COLLISION, &arm).map_err(|e| anyhow!("preset so101's collision table: {e:#}"))?)
    } else if let Some((_, radius, _)) = FRAME_RADII.iter().find(|(n, _, _)| *n == arm.name) {
        Some(measured(&arm, *radius)?)
    } else {
        None
    };
    Ok(arm)
}

/// Capsules of `radius` from the arm's frames, with the pairs that touch at the zero pose allowed
/// too (a first link down to the table, a short link's neighbours).
fn measured(arm: &ArmSpec, radius: f64) -> Result<CollisionSpec> {
    let mut spec = CollisionSpec::from_frames(arm, radius);
    let (bodies, standing) = allowed::touching_at_zero(arm, &spec)?;
    for pair in bodies.into_iter().chain(standing) {
        if !spec.allowed.iter().any(|p| p == &pair || (p[0] == pair[1] && p[1] == pair[0])) {
            spec.allowed.push(pair);
        }
    }
    validate::check(arm, &spec).map_err(|e| anyhow!("preset {}'s collision geometry: {e:#}", arm.name))?;
    Ok(spec)
}

/// The preset called `name`, its joints only.
fn without_geometry(name: &str) -> Result<ArmSpec> {
    let invalid = |e| anyhow!("preset {name} is invalid: {e}");
    if let Some(n) = name.strip_prefix("planar:") {
        let n: usize = n.parse().with_context(|| format!("planar:N needs a joint count, got {name:?}"))?;
        return super::dof::planar_spec(n);
    }
    Ok(match name {
        "ur5e" => ArmSpec::from_chain(name, &presets::ur5e().map_err(invalid)?),
        "puma560" => ArmSpec::from_chain(name, &presets::puma560().map_err(invalid)?),
        "iiwa14" => ArmSpec::from_chain(name, &presets::iiwa14().map_err(invalid)?),
        "so101" => named(
            ArmSpec::from_chain(name, &presets::so101().map_err(invalid)?),
            &["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"],
        ),
        "open-manipulator-x" => named(
            ArmSpec::from_chain(name, &presets::open_manipulator_x().map_err(invalid)?),
            &["joint1", "joint2", "joint3", "joint4"],
        ),
        _ => bail!("unknown arm {name:?}: use a preset ({NAMES}) or a path to a .urdf or .toml file"),
    })
}

fn named(mut spec: ArmSpec, names: &[&str]) -> ArmSpec {
    for (j, n) in spec.joints.iter_mut().zip(names) {
        j.name = (*n).to_string();
    }
    spec
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::{MAX_BODIES, MAX_OBSTACLES, TABLE};
    use kinematics::nalgebra::Vector3;

    /// Every real arm stands on a table at its base plane and is free of contacts at its zero
    /// pose and in the middle of its joint ranges.
    #[test]
    fn every_real_preset_carries_geometry_free_at_zero_and_in_the_middle() {
        for name in ["so101", "open-manipulator-x", "ur5e", "puma560", "iiwa14"] {
            let arm = by_name(name).unwrap();
            let spec = arm.collision.clone().unwrap_or_else(|| panic!("{name} has no collision geometry"));
            let table = spec.obstacles.iter().find(|o| o.name == TABLE).unwrap();
            assert_eq!(table.shape, kinematics::collision::Shape::table(0.0), "{name}");
            let model = crate::dof::build(arm.clone()).unwrap();
            let mut scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(arm.dof()).unwrap();
            for q in [allowed::zero_pose(&arm), model.middle()] {
                let frames = model.joint_frames(&q).unwrap();
                let contact = scene.first_contact(&frames);
                assert!(contact.is_none(), "{name} at {q:?}: {}", spec.describe(&contact.unwrap()));
            }
        }
        assert!(by_name("planar:3").unwrap().collision.is_none());
    }

    /// The bodies were fitted on the URDF's frames: the preset's joint frames are the URDF's at
    /// random poses, so each body lands where the URDF's mesh does.
    #[test]
    fn the_so101_meshes_frames_are_the_presets() {
        let text = include_str!("../../tests/data/so101_new_calib.urdf");
        let urdf = crate::dof::build(crate::urdf::parse(text, Some("gripper_frame_link")).unwrap()).unwrap();
        let preset = crate::dof::build(by_name("so101").unwrap()).unwrap();
        let mut rng = kinematics::SplitMix64::new(11);
        for _ in 0..50 {
            let q = preset.random_configuration(&mut rng);
            for (a, b) in urdf.joint_frames(&q).unwrap().iter().zip(preset.joint_frames(&q).unwrap()) {
                assert!((a.translation - b.translation).amax() < 1e-12 && (a.rotation - b.rotation).amax() < 1e-12);
            }
        }
    }

    /// The first case: the tool 8 cm below the base plane puts the gripper through the
    /// table, and the check names it; the zero pose passes.
    #[test]
    fn the_so101_refuses_the_tool_below_the_table_naming_the_gripper() {
        let arm = by_name("so101").unwrap();
        let spec = arm.collision.clone().unwrap();
        let model = crate::dof::build(arm.clone()).unwrap();
        let target = Vector3::new(0.20, 0.0, -0.08);
        let request = crate::dof::IkRequest {
            position: target.into(),
            quaternion_wxyz: None,
            seed: None,
            solver: crate::dof::SolverName::Dls,
            config: Default::default(),
            scalar: crate::dof::Scalar::F64,
            tilt_only: true,
        };
        let outcome = model.solve(&request).unwrap();
        let q = outcome.q.clone();
        let reached = model.tool_pose(&q).unwrap().translation;
        assert!((reached - target).norm() < 1e-4, "IK reached {reached}");
        let mut scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(arm.dof()).unwrap();
        let frames = model.joint_frames(&q).unwrap();
        assert!(scene.first_contact(&frames).is_some(), "the tool under the table passed");
        let deepest = scene.closest(&frames).unwrap();
        let (body, other) = (spec.name(kinematics::collision::Part::Body(deepest.body)), spec.name(deepest.other));
        assert_eq!(other, TABLE, "{}", spec.describe(&deepest));
        assert!(["gripper", "moving_jaw", "wrist"].iter().any(|b| body.starts_with(b)), "{}", spec.describe(&deepest));
        // The tool tip is 8 cm down; the gripper's body reaches deeper than that.
        assert!(deepest.distance < -0.08, "{}", spec.describe(&deepest));
        let zero = model.joint_frames(&allowed::zero_pose(&arm)).unwrap();
        assert_eq!(scene.first_contact(&zero), None);
    }
}
