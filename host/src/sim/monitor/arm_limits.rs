//! The goal limits of an arm's servos, mapped exactly as its firmware maps them: the host sends the
//! joint limits and speed limit as `f32` with each servo's id, zero and direction
//! (`crate::link::arm_config`), the firmware builds a [`JointMapping`] per joint with the servo's
//! whole single-turn range (`firmware::app::arm`) and narrows each joint's range to what the
//! servo's ticks reach, half a tick inside ([`firmware::controller::joint_limits`]). Its limiter
//! keeps every goal inside those limits, mapped to ticks.

use anyhow::{anyhow, bail, Result};

use super::GoalLimit;
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;

/// The goal limits of `arm`'s servos, base joint first: its `[servos]` table, or its preset's.
pub fn limits_of(arm: &ArmSpec) -> Result<Vec<GoalLimit>> {
    let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no [servos] table", arm.name))?;
    let n = arm.joints.len();
    if servos.ids.len() != n {
        bail!("arm {} has {n} joints but {} servo ids", arm.name, servos.ids.len());
    }
    if servos.zero.as_ref().is_some_and(|z| z.len() != n) || servos.reversed.as_ref().is_some_and(|r| r.len() != n) {
        bail!("arm {}: the servo zero and reversed lists need one entry per joint ({n})", arm.name);
    }
    let mut limits = Vec::with_capacity(n);
    for (j, (joint, &id)) in arm.joints.iter().zip(&servos.ids).enumerate() {
        let mapping = servos.mapping(j).ok_or_else(|| anyhow::anyhow!("servo {id}: no mapping"))?;
        let tpr = mapping.ticks_per_revolution;
        // The speed limit as the firmware holds it (f32), in ticks.
        let max_ticks_per_s = f64::from(servos.max_velocity as f32) * f64::from(tpr) / std::f64::consts::TAU;
        let Some((lower, upper)) = servos.commanded_range(arm, j) else {
            bail!("arm {}: joint {}'s limits leave it no range within servo {id}'s ticks", arm.name, joint.name);
        };
        let a = i64::from(mapping.to_ticks(lower).unwrap_or(mapping.min_ticks));
        let b = i64::from(mapping.to_ticks(upper).unwrap_or(mapping.max_ticks));
        limits.push(GoalLimit { id, goal_range: (a.min(b), a.max(b)), max_ticks_per_s });
    }
    // The gripper: between its closed and open ticks, its goal moving at its speed (as f32 on the
    // firmware) across the stroke.
    if let Some(g) = servos.gripper {
        let stroke = f64::from((g.open - g.closed).abs());
        let max_ticks_per_s = f64::from(g.speed as f32) / 100.0 * stroke;
        limits.push(GoalLimit {
            id: g.id,
            goal_range: (g.closed.min(g.open).into(), g.closed.max(g.open).into()),
            max_ticks_per_s,
        });
    }
    Ok(limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn so101_maps_to_its_servos_ticks() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let limits = limits_of(&arm).unwrap();
        assert_eq!(limits.iter().map(|l| l.id).collect::<Vec<_>>(), [1, 2, 3, 4, 5, 6]);
        assert_eq!(limits[5].goal_range, (1934, 3186));
        assert!((limits[5].max_ticks_per_s - 1252.0).abs() < 1e-3);
        // 2 rad/s on 4096 ticks a turn.
        assert!((limits[0].max_ticks_per_s - 2.0 * 4096.0 / std::f64::consts::TAU).abs() < 1e-3);
        for (l, joint) in limits.iter().take(5).zip(&arm.joints) {
            let ticks = |rad: f64| 2048.0 + rad * 4096.0 / std::f64::consts::TAU;
            let (lo, hi) = (ticks(joint.lower).max(0.0), ticks(joint.upper).min(4095.0));
            assert!((l.goal_range.0 as f64 - lo).abs() <= 1.0, "{}: {:?} vs {lo}", joint.name, l.goal_range);
            assert!((l.goal_range.1 as f64 - hi).abs() <= 1.0, "{}: {:?} vs {hi}", joint.name, l.goal_range);
        }
    }

    #[test]
    fn a_reversed_servo_with_its_own_zero_maps_the_other_way() {
        let mut arm = ArmSpec::load("so101", None).unwrap();
        let mut servos = servos_of(&arm).unwrap();
        servos.zero = Some(vec![1000, 2048, 2048, 2048, 2048]);
        servos.reversed = Some(vec![true, false, false, false, false]);
        arm.servos = Some(servos);
        let limits = limits_of(&arm).unwrap();
        let (lower, upper) = (arm.joints[0].lower, arm.joints[0].upper);
        let ticks = |rad: f64| (1000.0 - rad * 4096.0 / std::f64::consts::TAU).round() as i64;
        assert_eq!(limits[0].goal_range, (ticks(upper).max(0), ticks(lower).min(4095)));
    }

    #[test]
    fn an_arm_without_servos_is_refused() {
        let arm = ArmSpec::load("ur5e", None).unwrap();
        let err = limits_of(&arm).unwrap_err().to_string();
        assert_eq!(err, "arm ur5e has no [servos] table");
    }
}
