//! The same arm in openrr's `k` crate, so `armctl bench ik` can run a second, independent solver on
//! the same targets in the same process, and tests can check our forward kinematics against another
//! library's.
//!
//! `k` uses nalgebra 0.30 (ours is newer), so poses cross over as plain arrays.

use crate::arm::ArmSpec;
use anyhow::{anyhow, Result};
use k::nalgebra as kna;
use k::prelude::*;
use kinematics::{JointKind, Pose};
use std::time::{Duration, Instant};

/// Iteration budget given to k's solver per target (its own default is 10).
pub const K_MAX_TRY: usize = 100;

/// An arm built as a `k::SerialChain`.
pub struct KArm {
    chain: k::SerialChain<f64>,
}

/// What k's solver did with one target.
pub struct KOutcome {
    /// Joint values it left the chain at (the seed again when it reports failure).
    pub q: Vec<f64>,
    /// Whether k itself reported success.
    pub claimed: bool,
    /// Time in k's solver alone.
    pub solve_time: Duration,
}

fn isometry(p: &Pose<f64>) -> kna::Isometry3<f64> {
    let r = &p.rotation;
    let m = kna::Matrix3::new(
        r[(0, 0)],
        r[(0, 1)],
        r[(0, 2)],
        r[(1, 0)],
        r[(1, 1)],
        r[(1, 2)],
        r[(2, 0)],
        r[(2, 1)],
        r[(2, 2)],
    );
    let rotation = kna::UnitQuaternion::from_rotation_matrix(&kna::Rotation3::from_matrix_unchecked(m));
    let t = &p.translation;
    kna::Isometry3::from_parts(kna::Translation3::new(t.x, t.y, t.z), rotation)
}

impl KArm {
    /// Builds the chain of `spec` in `k`: one node per joint, then a fixed node for the tool.
    pub fn new(spec: &ArmSpec) -> Result<Self> {
        let mut nodes: Vec<k::Node<f64>> = Vec::with_capacity(spec.joints.len() + 1);
        for j in &spec.joints {
            let axis = kna::Unit::new_normalize(kna::Vector3::new(j.axis[0], j.axis[1], j.axis[2]));
            let (joint_type, limits) = match j.kind {
                JointKind::Revolute => {
                    (k::JointType::Rotational { axis }, Some(k::joint::Range::new(j.lower, j.upper)))
                }
                JointKind::Continuous => (k::JointType::Rotational { axis }, None),
                JointKind::Prismatic => (k::JointType::Linear { axis }, Some(k::joint::Range::new(j.lower, j.upper))),
                JointKind::Fixed => (k::JointType::Fixed, None),
            };
            let node: k::Node<f64> = k::NodeBuilder::new()
                .name(&j.name)
                .joint_type(joint_type)
                .limits(limits)
                .origin(isometry(&j.origin))
                .into_node();
            if let Some(parent) = nodes.last() {
                node.set_parent(parent);
            }
            nodes.push(node);
        }
        let tool: k::Node<f64> = k::NodeBuilder::new()
            .name("armctl_tool")
            .joint_type(k::JointType::Fixed)
            .origin(isometry(&spec.tool))
            .into_node();
        if let Some(parent) = nodes.last() {
            tool.set_parent(parent);
        }
        nodes.push(tool);
        let chain = k::SerialChain::try_new(k::Chain::from_nodes(nodes))
            .ok_or_else(|| anyhow!("arm {} is not a serial chain for k", spec.name))?;
        Ok(Self { chain })
    }

    /// Tool position and w-first quaternion at `q`, computed by k.
    pub fn tool_pose(&self, q: &[f64]) -> Result<([f64; 3], [f64; 4])> {
        self.chain.set_joint_positions(q).map_err(|e| anyhow!("k: {e}"))?;
        let iso = self.chain.end_transform();
        let t = iso.translation.vector;
        let r = iso.rotation;
        Ok(([t.x, t.y, t.z], [r.w, r.i, r.j, r.k]))
    }

    /// Runs k's `JacobianIkSolver` from `seed` toward `target` with the given tolerances.
    pub fn solve(&self, target: &Pose<f64>, seed: &[f64], tolerance_m: f64, tolerance_rad: f64) -> KOutcome {
        let solver = k::JacobianIkSolver::new(tolerance_m, tolerance_rad, 0.5, K_MAX_TRY);
        self.chain.set_joint_positions_clamped(seed);
        let goal = isometry(target);
        let started = Instant::now();
        let claimed = solver.solve(&self.chain, &goal).is_ok();
        let solve_time = started.elapsed();
        KOutcome { q: self.chain.joint_positions(), claimed, solve_time }
    }
}
