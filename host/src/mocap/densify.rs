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

/// What [`densify`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Added {
    /// This many keyframes (0: no step was long).
    Keyframes(usize),
    /// Nothing: the cut steps would have made this many keyframes, more than allowed.
    TooMany(usize),
}

/// `t` with the long steps cut; unchanged when that would make more than `max_keyframes`.
pub fn densify(arm: &dyn DynArm, t: Track, oriented: bool, max_keyframes: usize) -> Result<(Track, Added)> {
    let cuts: Vec<usize> = (1..t.q.len()).map(|k| pieces(&t, k)).collect();
    let total = 1 + cuts.iter().sum::<usize>();
    if total > max_keyframes {
        return Ok((t, Added::TooMany(total)));
    }
    if total == t.q.len() {
        return Ok((t, Added::Keyframes(0)));
    }
    let mut out = Track::default();
    out.q.push(t.q[0].clone());
    out.targets.push(t.targets[0]);
    out.reachable.push(t.reachable[0]);
    out.reconfigured.push(t.reconfigured[0]);
    for (k, &n) in (1..t.q.len()).zip(&cuts) {
        let (r0, r1) = if oriented && n > 1 {
            (rotation(arm, &t.q[k - 1])?, rotation(arm, &t.q[k])?)
        } else {
            (UnitQuaternion::identity(), UnitQuaternion::identity())
        };
        for i in 1..n {
            let s = i as f64 / n as f64;
            let target = t.targets[k - 1].lerp(&t.targets[k], s);
            let goal = r0.slerp(&r1, s);
            let seed = out.q.last().cloned();
            let solved = arm.solve(&request(target, oriented.then_some(&goal), seed))?;
            let q = if solved.status == IkStatus::Converged {
                solved.q
            } else {
                t.q[k - 1].iter().zip(&t.q[k]).map(|(a, b)| a + s * (b - a)).collect()
            };
            out.q.push(q);
            out.targets.push(target);
            out.reachable.push(solved.status == IkStatus::Converged);
            out.reconfigured.push(false);
            out.steps.push(t.steps[k - 1] / n as f64);
        }
        out.q.push(t.q[k].clone());
        out.targets.push(t.targets[k]);
        out.reachable.push(t.reachable[k]);
        out.reconfigured.push(t.reconfigured[k]);
        out.steps.push(t.steps[k - 1] / n as f64);
    }
    let added = out.q.len() - t.q.len();
    Ok((out, Added::Keyframes(added)))
}
