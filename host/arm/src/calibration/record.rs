//! What LeRobot's calibration procedure measures, and what it makes of an arm (`armctl
//! calibrate` runs the procedure on the servos; this is the arithmetic, apart from any bus).
//!
//! - [`half_turn_offset`]: the homing offset that makes the present position read half a turn
//!   (LeRobot's `_get_half_turn_homings`).
//! - [`check_sweep`]: a joint's recorded range, refused when it was not moved.
//! - [`joint_limits`]: the limits the firmware enforces, from the arm's and the measured range.
//! - [`calibrated_arm`] and [`lerobot_file`]: the arm file's content and LeRobot's file.

use anyhow::{bail, Result};
use firmware::bus::Protocol;
use kinematics::JointKind;

use super::{normalise, Calibration, MotorCalibration};
use crate::servos::ServoSetup;
use crate::{ArmSpec, JointSpec};

/// The margin kept between each joint limit and the end of the range the joint was moved through
/// by hand, in degrees. Those ends are the joint's mechanical stops, or as far as the person
/// pushed it: a goal right at a stop has the servo press against it, stalled, drawing its stall
/// current and heating, and a position 20 ms sampling missed can lie a little beyond. 2 degrees is
/// 23 ticks of a 4096-tick servo: clear of both, and little of any joint's range.
pub const STOP_MARGIN_DEG: f64 = 2.0;

/// The narrowest range a joint that was moved through its range can have, ticks (8.8 degrees on a
/// 4096-tick servo): narrower, and the joint was not moved (a hand's tremor or the sampling's
/// noise spans a few ticks), which would leave it a useless range.
pub const MIN_SWEEP_TICKS: i32 = 100;

/// The largest homing offset a half-turn homing gives on a 4096-tick servo (`present - 2047` or
/// `2047 - present`, the present position read with no offset), and the most the STS3215's
/// Homing_Offset holds (11 bits of magnitude; LeRobot's "Magnitude 2114 exceeds 2047").
pub const MAX_HOMING_OFFSET: i64 = 2047;

/// The largest homing offset a Dynamixel X applies in position control mode (operating mode 3):
/// the e-manual's Homing Offset(20) says "any invalid Homing Offset values will be ignored (valid
/// range: -1,024 ~ 1,024)".
pub const DXL_POSITION_MODE_MAX_OFFSET: i64 = 1024;

/// Whether LeRobot takes `joint` as full-turn: its SO arms' `wrist_roll` (recorded as `0..=4095`,
/// not swept), and any continuous joint.
pub fn full_turn(joint: &JointSpec) -> bool {
    joint.name == "wrist_roll" || joint.kind == JointKind::Continuous
}

/// The homing offset that puts the present position `present` (read with the offset at 0) at half
/// a turn of a servo of `resolution` ticks: LeRobot's `_get_half_turn_homings`, with `max_res =
/// resolution - 1` and `int(max_res / 2)` (2047): Feetech reports `present = actual - offset`, so
/// `present - 2047`; Dynamixel reports `present = actual + offset`, so `2047 - present`.
pub fn half_turn_offset(protocol: Protocol, present: i64, resolution: u32) -> i64 {
    let half = (i64::from(resolution) - 1) / 2;
    match protocol {
        Protocol::Feetech => present - half,
        Protocol::Dxl2 => half - present,
    }
}

/// A joint's recorded range `(min, max)`, checked: at least [`MIN_SWEEP_TICKS`] wide and within
/// the servo's ticks. `what` names the joint and its servo in the error.
pub fn check_sweep(what: &str, min: i64, max: i64, resolution: u32) -> Result<(i32, i32)> {
    let top = i64::from(resolution) - 1;
    if max - min < i64::from(MIN_SWEEP_TICKS) {
        bail!(
            "{what} moved only {} ticks ({min}..{max}): it was not moved through its range (at least \
             {MIN_SWEEP_TICKS} ticks)",
            max - min
        );
    }
    if min < 0 || max > top {
        bail!(
            "{what} was seen at {min}..{max}, beyond the servo's 0..={top} ticks: its homing pose was not the middle \
             of its range; run the calibration again"
        );
    }
    // Both lie in 0..=top.
    Ok((min as i32, max as i32))
}

/// The limits (radians) of `joint` once calibrated to `m` on a servo of `resolution` ticks: the
/// tighter of its own limits and the measured range less [`STOP_MARGIN_DEG`] at each end, the
/// measured range taken in LeRobot's degree mode (its middle is the joint's zero). A continuous
/// joint keeps its limits.
pub fn joint_limits(joint: &JointSpec, m: &MotorCalibration, resolution: u32) -> Result<(f64, f64)> {
    if joint.kind == JointKind::Continuous {
        return Ok((joint.lower, joint.upper));
    }
    let margin = STOP_MARGIN_DEG.to_radians();
    let measured = |ticks: i32| normalise::degrees(i64::from(ticks), m, resolution).to_radians();
    let lower = joint.lower.max(measured(m.range_min) + margin);
    let upper = joint.upper.min(measured(m.range_max) - margin);
    if lower >= upper {
        bail!(
            "joint {}: its limits ({:.1} to {:.1} degrees) and the range it was moved through less {STOP_MARGIN_DEG} \
             degrees a side ({:.1} to {:.1}) leave no range: is the arm description the arm's?",
            joint.name,
            joint.lower.to_degrees(),
            joint.upper.to_degrees(),
            (measured(m.range_min) + margin).to_degrees(),
            (measured(m.range_max) - margin).to_degrees()
        );
    }
    Ok((lower, upper))
}

/// `arm` calibrated: each joint's servo to `joints[j]` (joint order), the joint limits tightened
/// ([`joint_limits`]), and the gripper's range from `gripper` when there is one.
pub fn calibrated_arm(
    arm: &ArmSpec,
    servos: &ServoSetup,
    joints: &[MotorCalibration],
    gripper: Option<&MotorCalibration>,
) -> Result<ArmSpec> {
    if joints.len() != arm.joints.len() {
        bail!("arm {}: {} calibrations for {} joints", arm.name, joints.len(), arm.joints.len());
    }
    let resolution = servos.model.ticks_per_revolution;
    let mut out = arm.clone();
    for (joint, m) in out.joints.iter_mut().zip(joints) {
        (joint.lower, joint.upper) = joint_limits(joint, m, resolution)?;
    }
    let mut servos = servos.clone();
    servos.calibration = Some(joints.to_vec());
    // The calibration's drive modes (0) are what the arm file's `reversed` then says.
    servos.reversed = None;
    servos.zero = None;
    if let (Some(g), Some(m)) = (servos.gripper.as_mut(), gripper) {
        *g = g.calibrated(m);
    }
    out.servos = Some(servos);
    Ok(out)
}

/// LeRobot's calibration file of the arm: the joints by name in order, then the gripper as
/// `gripper` (LeRobot's SO-101 names: `shoulder_pan` .. `wrist_roll`, `gripper`).
pub fn lerobot_file(arm: &ArmSpec, joints: &[MotorCalibration], gripper: Option<&MotorCalibration>) -> Calibration {
    let mut motors: Vec<(String, MotorCalibration)> =
        arm.joints.iter().zip(joints).map(|(j, m)| (j.name.clone(), *m)).collect();
    if let Some(g) = gripper {
        motors.push(("gripper".to_string(), *g));
    }
    Calibration { motors }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cal(id: u8, range_min: i32, range_max: i32) -> MotorCalibration {
        MotorCalibration { id, drive_mode: 0, homing_offset: 0, range_min, range_max }
    }

    #[test]
    fn half_turn_offsets_are_lerobots() {
        // Feetech: present = actual - offset, so a horn at 3000 needs 953 to read 2047.
        assert_eq!(half_turn_offset(Protocol::Feetech, 3000, 4096), 953);
        assert_eq!(half_turn_offset(Protocol::Feetech, 0, 4096), -2047);
        // The edge of LeRobot's "Magnitude 2048 exceeds 2047" (lerobot PR #3370): a horn at 4095.
        assert_eq!(half_turn_offset(Protocol::Feetech, 4095, 4096), 2048);
        // Dynamixel: present = actual + offset.
        assert_eq!(half_turn_offset(Protocol::Dxl2, 3000, 4096), -953);
    }

    #[test]
    fn a_joint_not_moved_is_named_and_a_moved_one_kept() {
        assert_eq!(check_sweep("joint 2", 1000, 3000, 4096).unwrap(), (1000, 3000));
        let e = check_sweep("joint 2 (shoulder_lift, servo 2)", 2040, 2060, 4096).unwrap_err().to_string();
        assert!(
            e.starts_with("joint 2 (shoulder_lift, servo 2) moved only 20 ticks (2040..2060): it was not moved"),
            "{e}"
        );
        assert!(check_sweep("j", -5, 3000, 4096).unwrap_err().to_string().contains("beyond the servo's 0..=4095"));
    }

    #[test]
    fn joint_limits_are_the_tighter_of_the_arms_and_the_measured_less_the_margin() {
        let arm = crate::presets::by_name("so101").unwrap();
        let pan = &arm.joints[0]; // +-1.91986 rad, +-110 degrees
        let margin = STOP_MARGIN_DEG.to_radians();
        // Measured 1000..3000: (ticks - 2000) * 360 / 4095 degrees, +-87.9 degrees: tighter.
        let (lo, hi) = joint_limits(pan, &cal(1, 1000, 3000), 4096).unwrap();
        let end = (1000.0f64 * 360.0 / 4095.0).to_radians();
        assert!((lo - (-end + margin)).abs() < 1e-12 && (hi - (end - margin)).abs() < 1e-12, "{lo} {hi}");
        // Degree mode centres the measured range on the joint's zero, so it is symmetric: wider
        // than the URDF's (+-153.8 degrees), the URDF's limits stay.
        assert_eq!(joint_limits(pan, &cal(1, 300, 3800), 4096).unwrap(), (pan.lower, pan.upper));
        // The full-turn wrist roll: its URDF limits are tighter than +-180 less the margin.
        let roll = &arm.joints[4];
        assert!(full_turn(roll) && !full_turn(pan));
        assert_eq!(joint_limits(roll, &cal(5, 0, 4095), 4096).unwrap(), (roll.lower, roll.upper));
        // A joint whose measured range misses its limits altogether.
        let far = ArmSpec { joints: vec![JointSpec { lower: 0.5, upper: 0.6, ..pan.clone() }], ..arm.clone() };
        let e = joint_limits(&far.joints[0], &cal(1, 1900, 2100), 4096).unwrap_err().to_string();
        assert!(e.contains("joint shoulder_pan") && e.contains("leave no range"), "{e}");
    }

    #[test]
    fn the_calibrated_arm_and_lerobots_file_carry_the_measurements() {
        let arm = crate::presets::by_name("so101").unwrap();
        let servos = ServoSetup::for_arm("so101").unwrap();
        let joints: Vec<MotorCalibration> =
            (1..=5).map(|id| MotorCalibration { homing_offset: 100 * i32::from(id), ..cal(id, 900, 3100) }).collect();
        let gripper = MotorCalibration { homing_offset: -7, ..cal(6, 2000, 3300) };
        let out = calibrated_arm(&arm, &servos, &joints, Some(&gripper)).unwrap();
        let s = out.servos.as_ref().unwrap();
        assert_eq!(s.calibration.as_deref(), Some(&joints[..]));
        assert_eq!(s.gripper.map(|g| (g.closed, g.open)), Some((2000, 3300)));
        assert_eq!(s.mapping(0), Some(firmware::bus::mapping::JointMapping::lerobot(1, 4096, 900, 3100)));
        assert!(out.joints[0].upper < arm.joints[0].upper);
        let file = lerobot_file(&arm, &joints, Some(&gripper));
        let names: Vec<&str> = file.motors.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]);
        assert_eq!(file.motor("gripper"), Some(&gripper));
        file.check().unwrap();
    }
}
