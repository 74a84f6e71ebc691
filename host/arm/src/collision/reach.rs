//! How far a joint's turn can move the arm's bodies: the bound that lets a collision check skip
//! a stretch of motion instead of sampling it (the host's segment check,
//! `armctl::motion::collision`, and the simulator's contact model, `armctl::sim::contact`).

use kinematics::JointKind;

use super::CollisionSpec;
use crate::ArmSpec;

/// Each joint's reach over `spec`'s bodies on `arm`: for joint `i`, the largest distance from its
/// origin to a point of a body it carries, by the triangle inequality along the frames between
/// (each joint origin's offset, and a prismatic joint's longest travel), so that it holds in every
/// configuration. A revolute joint turned by `dq` moves a point at distance `r` by at most
/// `r |dq|`; a prismatic joint moves everything it carries by its own travel (reach 1).
pub fn reach(arm: &ArmSpec, spec: &CollisionSpec) -> Vec<f64> {
    let travel = |j: usize| {
        let joint = &arm.joints[j];
        match joint.kind {
            JointKind::Prismatic => joint.lower.abs().max(joint.upper.abs()),
            _ => 0.0,
        }
    };
    (0..arm.joints.len())
        .map(|i| {
            if arm.joints[i].kind == JointKind::Prismatic {
                return 1.0;
            }
            spec.bodies
                .iter()
                .filter_map(|body| {
                    let k = body.link?;
                    if k < i {
                        return None;
                    }
                    let between: f64 =
                        ((i + 1)..=k).map(|m| arm.joints[m].origin.translation.norm() + travel(m)).sum::<f64>();
                    let c = &body.capsule;
                    Some(between + c.a.norm().max(c.b.norm()) + c.radius)
                })
                .fold(0.0, f64::max)
        })
        .collect()
}
