//! A rig whose arms are mounted on one another (`mount` in the rig file: two arms on a turning
//! torso) is one kinematic tree: the torso's joint moves both hands. A move of several tools is
//! then one IK problem over every joint of the tree ([`kinematics::tree`]), solved here on the host,
//! and each arm's core gets its share as a joint move, all timed to arrive together.
//!
//! The tree is the one every tree of the host is: [`DynTree`], of fixed capacity (its
//! [`MAX_JOINTS`] joints and [`MAX_EFFECTORS`] end effectors, the unused ones padded), so one
//! instance of the solver serves every rig and every URDF with branches.

use anyhow::{bail, Context, Result};
use kinematics::ik::IkConfig;
use kinematics::Pose;

use crate::arm::dyn_tree::{DynTree, EffectorGoal, TreeIkRequest};
pub use crate::arm::dyn_tree::{MAX_EFFECTORS, MAX_JOINTS};
use crate::arm::tree::{EffectorSpec, TreeSpec};
use crate::arm::ArmSpec;

/// One arm as the tree sees it.
pub struct TreeArm<'a> {
    /// Its description.
    pub arm: &'a ArmSpec,
    /// Its base: in the world, or on the tool frame of the arm `mount`.
    pub base: Pose<f64>,
    /// The earlier arm it is mounted on.
    pub mount: Option<usize>,
}

/// The rig's arms as one tree: arm `a`'s joints are tree joints `first[a]..first[a] + count[a]`,
/// and its tool is end effector `a`.
pub struct RigTree {
    tree: DynTree,
    first: Vec<usize>,
    count: Vec<usize>,
}

/// How a tree move came out: each arm's joints, and each target's distance after the solve (m).
pub struct TreeMove {
    /// Each arm's joint values.
    pub q: Vec<Vec<f64>>,
    /// Each arm's tool distance from its target (0 for an arm without one).
    pub errors: Vec<f64>,
}

impl RigTree {
    /// The tree of `arms`, in rig order (a mount is always an earlier arm).
    pub fn new(arms: &[TreeArm<'_>]) -> Result<Self> {
        let total: usize = arms.iter().map(|a| a.arm.dof()).sum();
        if total > MAX_JOINTS || arms.len() > MAX_EFFECTORS {
            bail!(
                "a rig with mounted arms is one tree of at most {MAX_JOINTS} joints and {MAX_EFFECTORS} arms; this one has \
                 {total} joints and {} arms",
                arms.len()
            );
        }
        let mut spec = TreeSpec { name: "rig".into(), joints: Vec::new(), parents: Vec::new(), effectors: Vec::new() };
        let (mut first, mut count) = (Vec::new(), Vec::new());
        for (a, arm) in arms.iter().enumerate() {
            first.push(spec.joints.len());
            count.push(arm.arm.dof());
            // The arm's first joint hangs where its mount's tool is (that arm's end effector),
            // through the mount offset; or from the root, through its base.
            let (parent, to_first) = match arm.mount {
                Some(m) if m < a => {
                    let tool: &EffectorSpec = &spec.effectors[m];
                    (tool.joint, tool.offset.compose(&arm.base))
                }
                Some(_) => bail!("arm {} is mounted on an arm that is not before it", arm.arm.name),
                None => (None, arm.base),
            };
            for (j, joint) in arm.arm.joints.iter().enumerate() {
                let (origin, up) = if j == 0 {
                    (to_first.compose(&joint.origin), parent)
                } else {
                    (joint.origin, Some(spec.joints.len() - 1))
                };
                spec.joints.push(crate::arm::JointSpec { origin, ..joint.clone() });
                spec.parents.push(up);
            }
            // The tool on the arm's last joint; an arm without joints is its tool, fixed where its
            // first joint would be.
            let (joint, offset) = match arm.arm.joints.is_empty() {
                false => (Some(spec.joints.len() - 1), arm.arm.tool),
                true => (parent, to_first.compose(&arm.arm.tool)),
            };
            spec.effectors.push(EffectorSpec { link: arm.arm.name.clone(), joint, offset });
        }
        let tree = DynTree::build(spec).context("the rig's tree")?;
        Ok(Self { tree, first, count })
    }

    /// Every arm's joint values as one vector over the tree's joints.
    fn pack(&self, q: &[Vec<f64>]) -> Vec<f64> {
        let mut v = vec![0.0; self.tree.dof()];
        for (a, values) in q.iter().enumerate() {
            for (j, x) in values.iter().take(self.count[a]).enumerate() {
                v[self.first[a] + j] = *x;
            }
        }
        v
    }

    fn unpack(&self, v: &[f64]) -> Vec<Vec<f64>> {
        (0..self.first.len()).map(|a| v[self.first[a]..self.first[a] + self.count[a]].to_vec()).collect()
    }

    /// Every arm's tool in the world frame at joint values `q` (one vector per arm).
    pub fn tools(&self, q: &[Vec<f64>]) -> Vec<[f64; 3]> {
        // `pack` gives one value per joint of the tree, so forward kinematics cannot refuse it.
        let poses = self.tree.forward(&self.pack(q)).expect("one value per joint of the tree");
        poses.effectors.iter().map(|p| p.translation.into()).collect()
    }

    /// Solves for `targets` (world-frame tool positions, one per arm or `None`) from `q`, at the
    /// firmware's tolerance (0.1 mm): every joint of the tree used at once, the shared ones by
    /// every arm below them. An arm without a target keeps its tool where it is. Fails, saying by
    /// how far, if a target is out of reach within the joint limits.
    pub fn solve(&self, q: &[Vec<f64>], targets: &[Option<[f64; 3]>], names: &[&str]) -> Result<TreeMove> {
        let now = self.tools(q);
        let held: Vec<Option<[f64; 3]>> = targets.iter().zip(&now).map(|(t, p)| Some(t.unwrap_or(*p))).collect();
        let (solved, reached) = self.solve_free(q, &held);
        let missed: Vec<String> = (0..targets.len())
            .filter(|&a| !reached[a])
            .map(|a| format!("{} {:.1} mm short", names[a], solved.errors[a] * 1e3))
            .collect();
        if !missed.is_empty() {
            bail!("the tree's IK finds no joints within the limits that reach every target ({})", missed.join(", "));
        }
        Ok(solved)
    }

    /// Solves for `targets` from `q` as [`Self::solve`] does, except that an arm without a target
    /// is free (its tool goes where the others need it: a carrier such as a torso), and that a
    /// target out of reach is no error: the answer is the closest the solver came, with whether
    /// each arm reached its target (an arm without one always has).
    pub fn solve_free(&self, q: &[Vec<f64>], targets: &[Option<[f64; 3]>]) -> (TreeMove, Vec<bool>) {
        let mut goals = vec![None; self.first.len()];
        for (goal, target) in goals.iter_mut().zip(targets) {
            *goal = target.map(|position| EffectorGoal { position, quaternion_wxyz: None, priority: 0 });
        }
        let request = TreeIkRequest {
            goals,
            seed: Some(self.pack(q)),
            config: IkConfig { position_tolerance: 1e-4, orientation_tolerance: 1e-3, ..IkConfig::default() },
        };
        // One goal per arm, a seed of one value per joint, no quaternion: nothing the solve refuses.
        let solution = self.tree.solve(&request).expect("a rig's request is always posed");
        let errors: Vec<f64> = (0..targets.len()).map(|a| solution.effectors[a].position_error).collect();
        let reached = (0..targets.len()).map(|a| targets[a].is_none() || solution.effectors[a].reached).collect();
        (TreeMove { q: self.unpack(&solution.q), errors }, reached)
    }
}
