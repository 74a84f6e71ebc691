//! A straight line of the tool, checked by IK before the arm moves along it: points along the
//! line solved in turn, each seeded by the last, as the firmware's tracking follows a moving point,
//! with the firmware's method and scalar (damped least squares in f32). A point that does not
//! solve, or a jump of a joint between two points (another branch of the IK, which tracking would
//! not follow smoothly), blocks the line there; so does a point, or the joint segment to it, in
//! collision when the arm has collision geometry. Used by the demo's planner and by `armctl move`.

use super::collision::Checker;
use crate::arm::dof::{DynArm, IkRequest, Scalar, SolverName};
use kinematics::ik::IkStatus;

/// The largest change of any joint between two neighbouring points of a line (rad or m).
pub const MAX_JOINT_STEP: f64 = 0.5;
/// Spacing of the points `armctl move` checks (m): a joint limit met between two points further
/// apart could be missed.
const SPACING: f64 = 0.005;

/// A straight line of the tool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Where it starts (m).
    pub from: [f64; 3],
    /// Where it ends (m).
    pub to: [f64; 3],
    /// The tool's orientation all along it, w first; `None` leaves it free.
    pub orientation: Option<[f64; 4]>,
}

/// Where a line is blocked.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocked {
    /// How far along the line the last point that solved is (m).
    pub along: f64,
    /// The line's length (m).
    pub length: f64,
    /// The joints at that point: where tracking would stand.
    pub q: Vec<f64>,
    /// The pair in collision beyond it, in words, when that is what blocks it.
    pub contact: Option<String>,
}

impl Line {
    /// Its length (m).
    pub fn length(&self) -> f64 {
        (0..3).map(|i| (self.to[i] - self.from[i]).powi(2)).sum::<f64>().sqrt()
    }

    /// The points `armctl move` checks: one every 5 mm, at least 8, at most 400.
    pub fn points(&self) -> usize {
        ((self.length() / SPACING).ceil() as usize + 1).clamp(8, 400)
    }

    fn at(&self, u: f64) -> [f64; 3] {
        [0, 1, 2].map(|i| self.from[i] + u * (self.to[i] - self.from[i]))
    }

    /// Follows the line from joints `q` (the tool at `from`) through `points` points, ends
    /// included; the joints at its end, or where it is blocked. An error is a request the solver
    /// cannot take at all (an orientation for an arm too short of joints to choose one).
    pub fn follow(&self, arm: &dyn DynArm, q: &[f64], points: usize) -> anyhow::Result<Result<Vec<f64>, Blocked>> {
        self.follow_checked(arm, q, points, None)
    }

    /// [`Line::follow`], with every point's joints, and the joint segment from the point before,
    /// checked against the arm's collision geometry when `checker` is given: the line is blocked
    /// where the arm would come closer than the margin to something.
    pub fn follow_checked(
        &self,
        arm: &dyn DynArm,
        q: &[f64],
        points: usize,
        mut checker: Option<&mut Checker<'_>>,
    ) -> anyhow::Result<Result<Vec<f64>, Blocked>> {
        let mut q = q.to_vec();
        let mut last = 0.0;
        for k in 1..points {
            let u = k as f64 / (points - 1) as f64;
            let request = IkRequest {
                position: self.at(u),
                quaternion_wxyz: self.orientation,
                seed: Some(q.clone()),
                solver: SolverName::Dls,
                config: Default::default(),
                scalar: Scalar::F32,
                tilt_only: true,
            };
            let outcome = arm.solve(&request)?;
            let step = outcome.q.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            if outcome.status != IkStatus::Converged || step > MAX_JOINT_STEP {
                return Ok(Err(Blocked { along: last * self.length(), length: self.length(), q, contact: None }));
            }
            if let Some(checker) = checker.as_deref_mut() {
                if let Some(found) = checker.straight(&q, &outcome.q)? {
                    let contact = Some(checker.describe_along(&found));
                    return Ok(Err(Blocked { along: last * self.length(), length: self.length(), q, contact }));
                }
            }
            q = outcome.q;
            last = u;
        }
        Ok(Ok(q))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::dof::build;
    use crate::arm::ArmSpec;

    fn tool(arm: &dyn DynArm, q: &[f64]) -> [f64; 3] {
        arm.tool_pose(q).unwrap().translation.into()
    }

    #[test]
    fn a_clear_line_ends_at_its_end_and_a_blocked_one_says_where() {
        let arm = build(ArmSpec::load("so101", None).unwrap()).unwrap();
        let arm = arm.as_ref();
        // Both ways clear: near the middle of the ranges.
        let (a, b) = ([0.1, -0.2, 0.3, 0.2, 0.0], [0.3, 0.1, 0.1, 0.4, 0.0]);
        let line = Line { from: tool(arm, &a), to: tool(arm, &b), orientation: None };
        let end = line.follow(arm, &a, line.points()).unwrap().unwrap();
        let reached = tool(arm, &end);
        let error = (0..3).map(|i| (reached[i] - line.to[i]).powi(2)).sum::<f64>().sqrt();
        assert!(error < 1e-4, "{error} m from the end");
        // Blocked: a move the firmware's tracking stalled on (controller_sil.rs).
        let (a, b) = ([0.619, 0.712, 0.457, 1.201, -1.828], [-0.576, 1.521, 1.086, -0.089, 1.206]);
        let line = Line { from: tool(arm, &a), to: tool(arm, &b), orientation: None };
        let blocked = line.follow(arm, &a, line.points()).unwrap().unwrap_err();
        assert!(blocked.along < blocked.length && (blocked.length - line.length()).abs() < 1e-12, "{blocked:?}");
        assert_eq!(blocked.q.len(), 5);
    }

    /// Sideways from a bent start with the orientation held (issue 43, item 2): on a five-joint
    /// arm the host holds the tilt as the firmware does, so the line is clear and the Cartesian
    /// file of the same points is reachable; the full pose (`armctl ik`'s) is not, a step on.
    #[test]
    fn a_sideways_line_with_the_orientation_held_is_clear_on_a_five_joint_arm() {
        let arm = build(ArmSpec::load("so101", None).unwrap()).unwrap();
        let arm = arm.as_ref();
        let start = [0.2, -0.4, 0.6, 0.8, 0.3];
        let pose = arm.tool_pose(&start).unwrap();
        let from: [f64; 3] = pose.translation.into();
        // Across the arm's reach: mostly a turn of the pan.
        let side = kinematics::nalgebra::Vector3::new(-from[1], from[0], 0.0).normalize() * 0.03;
        let to: [f64; 3] = (pose.translation + side).into();
        let orientation = Some(pose.quaternion_wxyz());
        let line = Line { from, to, orientation };
        let end = line.follow(arm, &start, line.points()).unwrap().unwrap();
        let reached = arm.tool_pose(&end).unwrap();
        assert!((reached.translation - pose.translation - side).norm() < 1e-4);
        let (up, held) = (reached.rotation.row(2), pose.rotation.row(2));
        assert!((up - held).norm() < 1e-3, "tilt {up} vs {held}");

        let k = crate::motion::CartesianKeyframes {
            times: vec![0.0, 1.0],
            positions: vec![from, to],
            orientations: Some(vec![pose.quaternion_wxyz(); 2]),
            gripper: None,
            lines: vec![2, 3],
        };
        crate::motion::reach::check(arm, &k, &|line| format!("line {line}")).unwrap();
        let full = IkRequest {
            position: to,
            quaternion_wxyz: orientation,
            seed: Some(start.to_vec()),
            solver: SolverName::Dls,
            config: Default::default(),
            scalar: Scalar::F64,
            tilt_only: false,
        };
        assert_ne!(arm.solve(&full).unwrap().status, IkStatus::Converged);
    }
}
