//! The IK requests of a retarget: warm-started from the previous keyframe, or afresh, and the
//! way toward a target out of reach.

use crate::arm::dof::{DynArm, IkRequest, Scalar, SolverName};
use anyhow::Result;
use kinematics::ik::{IkConfig, IkStatus};
use kinematics::nalgebra::{UnitQuaternion, Vector3};

/// An f64 request for `position` (and `orientation`): the closed form's solution nearest `seed`
/// where the arm's geometry has one (the SO-101 by position and pitch, a six-joint arm by pose),
/// else damped least squares, warm-started from `seed` without restarts, or from the middle of
/// the limits with restarts when `seed` is `None`.
pub fn request(position: Vector3<f64>, orientation: Option<&UnitQuaternion<f64>>, seed: Option<Vec<f64>>) -> IkRequest {
    let warm = seed.is_some();
    let config = IkConfig {
        // 0.1 mm: far below what the servos resolve, and quick to reach.
        position_tolerance: 1e-4,
        orientation_tolerance: 1e-3,
        // Warm-started from the last keyframe, a restart would jump to another branch of the
        // solution (the arm flipping its elbow between two keyframes): none.
        max_restarts: if warm { 0 } else { 40 },
        max_iterations: if warm { 200 } else { 2000 },
        attempt_iterations: if warm { 200 } else { 150 },
        ..IkConfig::default()
    };
    IkRequest {
        position: position.into(),
        quaternion_wxyz: orientation.map(|q| [q.w, q.i, q.j, q.k]),
        seed,
        solver: SolverName::Auto,
        config,
        scalar: Scalar::F64,
    }
}

/// Halvings of the line toward an unreachable target.
const TOWARD_STEPS: usize = 6;

/// The joints that bring the tool furthest along the straight line from where `from` puts it
/// toward `target`, found by halving (to 1/64 of the line), each solve warm-started; `from`
/// itself when no step along the line converges.
pub fn toward(arm: &dyn DynArm, from: &[f64], target: &Vector3<f64>) -> Result<Vec<f64>> {
    let start = arm.tool_pose(from)?.translation;
    let (mut good, mut bad) = (0.0, 1.0);
    let mut best = from.to_vec();
    for _ in 0..TOWARD_STEPS {
        let s = (good + bad) / 2.0;
        let solved = arm.solve(&request(start + (target - start) * s, None, Some(best.clone())))?;
        if solved.status == IkStatus::Converged {
            good = s;
            best = solved.q;
        } else {
            bad = s;
        }
    }
    Ok(best)
}
