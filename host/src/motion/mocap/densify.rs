//! Keyframes added where the arm would move a joint far between two keyframes.
//!
//! The firmware's player interpolates in joint space. Over a short joint step that is close to
//! the straight line between the two tool targets; over a long one (near the base axis a small
//! move of the hand swings the base a long way) the tool bows away from the hand's path. Such a
//! step is cut into pieces no joint moves more than [`MAX_JOINT_STEP`] in, each solved by IK on
//! the straight line between the two targets (and, on arms that follow the hand's turn, on the
//! rotation between the two tool orientations), warm-started. A piece IK cannot reach falls back
//! to the joint-space point. Steps into a changed configuration are left alone: no line joins
//! the two configurations.

use super::solve::request;
use crate::arm::dof::DynArm;
use anyhow::Result;
use kinematics::ik::IkStatus;
use kinematics::nalgebra::{Rotation3, UnitQuaternion, Vector3};

/// The largest joint move (rad) between two keyframes before the step is cut.
pub const MAX_JOINT_STEP: f64 = 0.1;

/// Keyframes with what the retarget knows of each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Track {
    /// Joint values.
    pub q: Vec<Vec<f64>>,
    /// Tool targets (m).
    pub targets: Vec<Vector3<f64>>,
    /// Whether IK reached the target.
    pub reachable: Vec<bool>,
    /// Whether the keyframe starts a new configuration.
    pub reconfigured: Vec<bool>,
    /// Captured duration of each step (s), one fewer than keyframes.
    pub steps: Vec<f64>,
}

fn rotation(arm: &dyn DynArm, q: &[f64]) -> Result<UnitQuaternion<f64>> {
    Ok(UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(arm.tool_pose(q)?.rotation)))
}

/// How many pieces the step into keyframe `k` is cut in (1: left whole).
fn pieces(t: &Track, k: usize) -> usize {
    if t.reconfigured[k] || !(t.reachable[k - 1] && t.reachable[k]) {
        return 1;
    }
    let largest = t.q[k].iter().zip(&t.q[k - 1]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    (largest / MAX_JOINT_STEP).ceil().max(1.0) as usize
}

/// What cutting the long steps did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Added {
    /// This many keyframes (0: no step was long).
    Keyframes(usize),
    /// Nothing: the cut steps would have made this many keyframes, more than allowed.
    TooMany(usize),
}

/// How many pieces each step of `t` would be cut in (1: left whole), step k into keyframe k at
/// index k - 1. Cutting them all ([`cut`]) can make too many keyframes: see [`Added::TooMany`].
pub fn cuts(t: &Track) -> Vec<usize> {
    (1..t.q.len()).map(|k| pieces(t, k)).collect()
}

/// `t` with step k cut in `cuts[k - 1]` pieces: [`cuts`] of this track, or more where the arms of
/// a rig share their keyframe times (another arm's long step cuts this arm's step too). A step
/// this track leaves whole by its own measure because it has no line to follow (into a changed
/// configuration, or from or to a target IK missed) is cut at joint-space points, counted as not
/// reached: they are where the player's interpolation would pass anyway.
pub fn cut(arm: &dyn DynArm, t: Track, oriented: bool, cuts: &[usize]) -> Result<Track> {
    assert_eq!(cuts.len() + 1, t.q.len(), "one cut count per step");
    let mut out = Track::default();
    out.q.push(t.q[0].clone());
    out.targets.push(t.targets[0]);
    out.reachable.push(t.reachable[0]);
    out.reconfigured.push(t.reconfigured[0]);
    for (k, &n) in (1..t.q.len()).zip(cuts) {
        let along_line = !t.reconfigured[k] && t.reachable[k - 1] && t.reachable[k];
        let (r0, r1) = if oriented && n > 1 && along_line {
            (rotation(arm, &t.q[k - 1])?, rotation(arm, &t.q[k])?)
        } else {
            (UnitQuaternion::identity(), UnitQuaternion::identity())
        };
        for i in 1..n {
            let s = i as f64 / n as f64;
            let target = t.targets[k - 1].lerp(&t.targets[k], s);
            let between = || t.q[k - 1].iter().zip(&t.q[k]).map(|(a, b)| a + s * (b - a)).collect();
            let (q, reached) = if along_line {
                let goal = r0.slerp(&r1, s);
                let seed = out.q.last().cloned();
                let solved = arm.solve(&request(target, oriented.then_some(&goal), seed))?;
                if solved.status == IkStatus::Converged {
                    (solved.q, true)
                } else {
                    (between(), false)
                }
            } else {
                (between(), false)
            };
            out.q.push(q);
            out.targets.push(target);
            out.reachable.push(reached);
            out.reconfigured.push(false);
            out.steps.push(t.steps[k - 1] / n as f64);
        }
        out.q.push(t.q[k].clone());
        out.targets.push(t.targets[k]);
        out.reachable.push(t.reachable[k]);
        out.reconfigured.push(t.reconfigured[k]);
        out.steps.push(t.steps[k - 1] / n as f64);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn so101() -> Box<dyn DynArm> {
        crate::arm::dof::build(crate::arm::ArmSpec::load("so101", None).unwrap()).unwrap()
    }

    /// Two keyframes 0.05 rad apart on every joint: short enough to be left whole.
    fn short_step(arm: &dyn DynArm, reconfigured: bool) -> Track {
        let q0 = arm.middle();
        let q1: Vec<f64> = q0.iter().map(|v| v + 0.05).collect();
        let targets = [&q0, &q1].map(|q| arm.tool_pose(q).unwrap().translation).to_vec();
        Track {
            q: vec![q0, q1],
            targets,
            reachable: vec![true, true],
            reconfigured: vec![false, reconfigured],
            steps: vec![0.04],
        }
    }

    #[test]
    fn another_arms_cuts_split_a_short_step_on_the_line_or_in_joint_space() {
        let arm = so101();
        let t = short_step(arm.as_ref(), false);
        assert_eq!(cuts(&t), [1]);
        // Cut in 4 as another arm needs: IK on the line between the targets, each piece reached.
        let c = cut(arm.as_ref(), t.clone(), false, &[4]).unwrap();
        assert_eq!(c.q.len(), 5);
        assert_eq!(c.steps, [0.01; 4]);
        assert_eq!(c.reachable, [true; 5]);
        for (q, target) in c.q.iter().zip(&c.targets) {
            assert!((arm.tool_pose(q).unwrap().translation - target).norm() < 1e-4);
        }
        assert_eq!(c.q[4], t.q[1]);
        // Into a changed configuration there is no line: joint-space points, not reached.
        let t = short_step(arm.as_ref(), true);
        let c = cut(arm.as_ref(), t.clone(), false, &[2]).unwrap();
        let halfway: Vec<f64> = t.q[0].iter().zip(&t.q[1]).map(|(a, b)| a + 0.5 * (b - a)).collect();
        assert_eq!(c.q[1], halfway);
        assert_eq!(c.reachable, [true, false, true]);
        assert_eq!(c.reconfigured, [false, false, true]);
    }
}
