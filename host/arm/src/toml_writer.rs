//! An arm written as the project's TOML arm file ([`super::toml_file`]), so that an arm made here
//! (by `armctl calibrate`, from a preset or a URDF) is one file a person can read, edit and load
//! with `--arm FILE`.
//!
//! The joints are written in the URDF convention (`xyz`, `rpy`, `axis`), angles in radians, every
//! number as Rust prints an `f64` (the shortest text that reads back as the same value), so that
//! the file loads back as the arm it was written from: the same limits, servos and gripper, and
//! joint frames equal to within 1e-15 (the roll-pitch-yaw round trip).

use std::fmt::Write as _;

use kinematics::{JointKind, Pose};

use super::servos::ServoSetup;
use super::ArmSpec;

/// The arm file of `arm`; `header` lines are written first as comments.
pub fn to_text(arm: &ArmSpec, header: &[String]) -> String {
    let mut out = String::new();
    for line in header {
        let _ = writeln!(out, "# {line}");
    }
    let _ = writeln!(out, "name = {}", quoted(&arm.name));
    for (k, joint) in arm.joints.iter().enumerate() {
        let _ = writeln!(out, "\n[[joint]]");
        let _ = writeln!(out, "name = {}", quoted(&joint.name));
        let kind = match joint.kind {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        };
        let _ = writeln!(out, "type = \"{kind}\"");
        let (xyz, rpy) = xyz_rpy(&joint.origin);
        let _ = writeln!(out, "xyz = {}", list(&xyz));
        let _ = writeln!(out, "rpy = {}", list(&rpy));
        let _ = writeln!(out, "axis = {}", list(&joint.axis));
        match joint.kind {
            JointKind::Continuous | JointKind::Fixed => {}
            JointKind::Prismatic => {
                let _ = writeln!(out, "limits = {}  # metres", list(&[joint.lower, joint.upper]));
            }
            JointKind::Revolute => {
                let _ = writeln!(
                    out,
                    "limits = {}  # {:.2} to {:.2} degrees",
                    list(&[joint.lower, joint.upper]),
                    joint.lower.to_degrees(),
                    joint.upper.to_degrees()
                );
            }
        }
        if let Some(body) = arm.masses.as_ref().and_then(|m| m.get(k)) {
            let t = &body.tensor;
            let _ = writeln!(out, "mass = {:?}  # kg", body.mass);
            let _ = writeln!(out, "com = {}", list(&[body.com.x, body.com.y, body.com.z]));
            let _ = writeln!(
                out,
                "inertia = {}  # kg m², ixx ixy ixz iyy iyz izz",
                list(&[t.m11, t.m12, t.m13, t.m22, t.m23, t.m33])
            );
        }
    }
    let (xyz, rpy) = xyz_rpy(&arm.tool);
    let _ = writeln!(out, "\n[tool]\nxyz = {}\nrpy = {}", list(&xyz), list(&rpy));
    if let Some(servos) = &arm.servos {
        servos_table(&mut out, servos);
    }
    if let Some(collision) = &arm.collision {
        out.push('\n');
        super::collision::toml::write(&mut out, collision, arm, &Default::default());
    }
    out
}

fn servos_table(out: &mut String, servos: &ServoSetup) {
    let _ = writeln!(out, "\n[servos]\nmodel = {}", quoted(servos.model.name));
    let _ = writeln!(out, "ids = {}", list(&servos.ids));
    if let Some(zero) = &servos.zero {
        let _ = writeln!(out, "zero = {}", list(zero));
    }
    // With a calibration, `reversed` is read as LeRobot's drive_mode: a drive mode 1 is written there.
    let drive_modes = servos.calibration.as_ref().map(|c| c.iter().map(|m| m.drive_mode == 1).collect::<Vec<_>>());
    let reversed = match drive_modes {
        Some(modes) if modes.iter().any(|&r| r) => Some(modes),
        _ => servos.reversed.clone(),
    };
    if let Some(reversed) = reversed {
        let _ = writeln!(out, "reversed = {}", list(&reversed));
    }
    let _ = writeln!(out, "max_velocity = {:?}  # rad/s", servos.max_velocity);
    let _ = writeln!(out, "max_acceleration = {:?}  # rad/s²", servos.max_acceleration);
    if servos.baud != super::servos::DEFAULT_BAUD {
        let _ = writeln!(out, "baud = {}", servos.baud);
    }
    if let Some(c) = &servos.calibration {
        let field = |f: fn(&super::calibration::MotorCalibration) -> i32| list(&c.iter().map(f).collect::<Vec<_>>());
        let _ = writeln!(out, "homing_offset = {}", field(|m| m.homing_offset));
        let _ = writeln!(out, "range_min = {}", field(|m| m.range_min));
        let _ = writeln!(out, "range_max = {}", field(|m| m.range_max));
    }
    if let Some(g) = &servos.gripper {
        let _ = writeln!(out, "\n[gripper]\nid = {}\nclosed = {}\nopen = {}", g.id, g.closed, g.open);
        let _ = writeln!(out, "effort = {:?}\nopening_mm = {:?}", g.effort, g.opening_mm);
    }
}

/// A TOML basic string.
pub(crate) fn quoted(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// `[a, b, c]`, each as its `Debug` text (floats keep a point or an exponent, which TOML reads
/// as the same `f64`).
pub(crate) fn list<T: std::fmt::Debug>(values: &[T]) -> String {
    let items: Vec<String> = values.iter().map(|v| format!("{v:?}")).collect();
    format!("[{}]", items.join(", "))
}

/// The URDF origin of `pose`: its translation and the fixed-axis roll, pitch, yaw of its rotation
/// (`R = Rz(yaw) Ry(pitch) Rx(roll)`, as [`Pose::from_xyz_rpy`] builds it).
pub(crate) fn xyz_rpy(pose: &Pose<f64>) -> ([f64; 3], [f64; 3]) {
    let r = &pose.rotation;
    // atan2 rather than asin: asin loses digits near +-90 degrees, where the SO-101 has frames.
    let cos_pitch = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cos_pitch);
    let (roll, yaw) = if cos_pitch > 1e-12 {
        (r[(2, 1)].atan2(r[(2, 2)]), r[(1, 0)].atan2(r[(0, 0)]))
    } else {
        // Pitch at +-90 degrees: roll and yaw turn about one axis; all of it is put in yaw.
        (0.0, (-r[(0, 1)]).atan2(r[(1, 1)]))
    };
    (pose.translation.into(), [clean(roll), clean(pitch), clean(yaw)])
}

/// `-0.0` as `0.0` (the file reads the same, and looks it).
fn clean(x: f64) -> f64 {
    if x == 0.0 {
        0.0
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::MotorCalibration;
    use crate::toml_file;
    use kinematics::nalgebra::SVector;
    use kinematics::SplitMix64;

    fn assert_same_arm<const N: usize>(a: &ArmSpec, b: &ArmSpec) {
        assert_eq!(a.name, b.name);
        for (x, y) in a.joints.iter().zip(&b.joints) {
            assert_eq!((&x.name, x.kind, x.axis, x.lower, x.upper), (&y.name, y.kind, y.axis, y.lower, y.upper));
            assert!((x.origin.rotation - y.origin.rotation).amax() < 1e-15, "{}", x.name);
            assert!((x.origin.translation - y.origin.translation).amax() == 0.0, "{}", x.name);
        }
        assert_eq!(a.servos, b.servos);
        // The collision geometry too (the presets carry theirs), number for number.
        assert_eq!(a.collision, b.collision);
        // The masses: numbers as written, the tensor's upper triangle read back symmetric.
        assert_eq!(a.masses.is_some(), b.masses.is_some());
        for (x, y) in a.masses.iter().flatten().zip(b.masses.iter().flatten()) {
            assert_eq!((x.mass, x.com), (y.mass, y.com));
            assert!((x.tensor - y.tensor).amax() < 1e-18, "{:?} {:?}", x.tensor, y.tensor);
        }
        let (ca, cb) = (a.chain::<f64, N>().unwrap(), b.chain::<f64, N>().unwrap());
        let mut rng = SplitMix64::new(3);
        for _ in 0..50 {
            let q = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-2.0, 2.0));
            let (p, r) = (ca.tool_pose(&q), cb.tool_pose(&q));
            assert!((p.translation - r.translation).amax() < 1e-14 && (p.rotation - r.rotation).amax() < 1e-14);
        }
    }

    #[test]
    fn a_preset_with_its_servos_and_a_calibration_reads_back_as_written() {
        let mut arm = crate::presets::by_name("so101").unwrap();
        let mut servos = crate::servos::ServoSetup::for_arm("so101").unwrap();
        servos.calibration = Some(
            (0..5)
                .map(|j| MotorCalibration {
                    id: servos.ids[j],
                    drive_mode: u8::from(j == 2),
                    homing_offset: 953 - 400 * j as i32,
                    range_min: 800 + j as i32,
                    range_max: 3300 - j as i32,
                })
                .collect(),
        );
        servos.reversed = Some(vec![false, false, true, false, false]);
        arm.servos = Some(servos);
        // Its URDF's masses written out: the file carries them for an arm of another name.
        arm.masses = Some(crate::arm_dynamics::masses_of(&arm).unwrap().unwrap());
        arm.joints[1].lower = -1.2345678901234567;
        // Loading tightens a calibrated arm's limits to its ranges: written tightened, they read
        // back as written.
        let calibration = arm.servos.as_ref().and_then(|s| s.calibration.clone()).unwrap();
        for (joint, m) in arm.joints.iter_mut().zip(&calibration) {
            (joint.lower, joint.upper) = crate::calibration::record::joint_limits(joint, m, 4096).unwrap();
        }
        let text = to_text(&arm, &["made by a test".to_string()]);
        assert!(text.starts_with("# made by a test\nname = \"so101\"\n"), "{text}");
        let back = toml_file::parse(&text).unwrap_or_else(|e| panic!("{e:#}\n{text}"));
        assert_same_arm::<5>(&arm, &back);
    }

    #[test]
    fn urdf_like_frames_and_odd_names_survive() {
        let arm = crate::presets::by_name("open-manipulator-x").unwrap();
        let mut arm = ArmSpec { name: "my \"OMX\" \\ arm".into(), ..arm };
        arm.joints[0].origin = Pose::from_xyz_rpy([0.1, -0.2, 0.3], [0.4, -1.2, 2.9]);
        // Pitch of exactly 90 degrees: roll and yaw are one turn, written as yaw.
        arm.joints[1].origin = Pose::from_xyz_rpy([0.0, 0.0, 0.05], [0.0, core::f64::consts::FRAC_PI_2, 0.7]);
        arm.servos = crate::servos::ServoSetup::for_arm("open-manipulator-x");
        let text = to_text(&arm, &[]);
        let back = toml_file::parse(&text).unwrap_or_else(|e| panic!("{e:#}\n{text}"));
        assert_same_arm::<4>(&arm, &back);
    }
}
