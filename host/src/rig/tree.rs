//! A rig whose arms are mounted on one another (`mount` in the rig file: two arms on a turning
//! torso) is one kinematic tree: the torso's joint moves both hands. A move of several tools is
//! then one IK problem over every joint of the tree ([`kinematics::tree`]), solved here on the host,
//! and each arm's core gets its share as a joint move, all timed to arrive together.
//!
//! The tree is built in fixed capacity: [`MAX_JOINTS`] joints and [`MAX_EFFECTORS`] end effectors,
//! the unused ones padded (a joint of zero range under no end effector, an end effector on the
//! root without a target), so one instance of the solver serves every rig.

use anyhow::{bail, Result};
use kinematics::ik::IkConfig;
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::tree::{Effector, EffectorTarget, Tree, TreeProblem};
use kinematics::{Joint, JointKind, Limits, Pose};

use crate::arm::ArmSpec;

/// The most joints of a rig's tree.
pub const MAX_JOINTS: usize = 16;
/// The most arms of a rig's tree.
pub const MAX_EFFECTORS: usize = 4;

type RigTreeOf = Tree<f64, MAX_JOINTS, MAX_EFFECTORS>;

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
    tree: RigTreeOf,
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

fn joint(spec: &crate::arm::JointSpec, origin: Pose<f64>) -> Joint<f64> {
    Joint { origin, axis: spec.axis.into(), kind: spec.kind, limits: Limits::from_f64(spec.lower, spec.upper) }
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
        let padding = Joint {
            origin: Pose::identity(),
            axis: Vector3::z(),
            kind: JointKind::Revolute,
            limits: Limits::from_f64(0.0, 0.0),
        };
        let mut joints = [padding; MAX_JOINTS];
        let mut parents = [None; MAX_JOINTS];
        let mut effectors = [Effector { joint: None, offset: Pose::identity() }; MAX_EFFECTORS];
        let (mut first, mut count) = (Vec::new(), Vec::new());
        let mut k = 0;
        for (a, arm) in arms.iter().enumerate() {
            first.push(k);
            count.push(arm.arm.dof());
            // The arm's first joint hangs from its mount's last joint, through that arm's tool
            // frame and the mount offset; or from the root, through its base.
            let (parent, to_first) = match arm.mount {
                Some(m) if m < a => {
                    let last = first[m] + count[m] - 1;
                    (Some(last), arms[m].arm.tool.compose(&arm.base))
                }
                Some(_) => bail!("arm {} is mounted on an arm that is not before it", arm.arm.name),
                None => (None, arm.base),
            };
            for (j, spec) in arm.arm.joints.iter().enumerate() {
                let (origin, up) =
                    if j == 0 { (to_first.compose(&spec.origin), parent) } else { (spec.origin, Some(k - 1)) };
                joints[k] = joint(spec, origin);
                parents[k] = up;
                k += 1;
            }
            effectors[a] = Effector { joint: Some(k - 1), offset: arm.arm.tool };
        }
        let tree = Tree::new(joints, parents, effectors).map_err(|e| anyhow::anyhow!("the rig's tree: {e}"))?;
        Ok(Self { tree, first, count })
    }

    fn pack(&self, q: &[Vec<f64>]) -> SVector<f64, MAX_JOINTS> {
        let mut v = SVector::zeros();
        for (a, values) in q.iter().enumerate() {
            for (j, x) in values.iter().take(self.count[a]).enumerate() {
                v[self.first[a] + j] = *x;
            }
        }
        v
    }

    fn unpack(&self, v: &SVector<f64, MAX_JOINTS>) -> Vec<Vec<f64>> {
        (0..self.first.len()).map(|a| (0..self.count[a]).map(|j| v[self.first[a] + j]).collect()).collect()
    }

    /// Every arm's tool in the world frame at joint values `q` (one vector per arm).
    pub fn tools(&self, q: &[Vec<f64>]) -> Vec<[f64; 3]> {
        let frames = self.tree.forward(&self.pack(q));
        (0..self.first.len()).map(|a| frames.effectors[a].translation.into()).collect()
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
        let mut problem = TreeProblem {
            targets: [None; MAX_EFFECTORS],
            seed: self.pack(q),
            config: IkConfig { position_tolerance: 1e-4, orientation_tolerance: 1e-3, ..IkConfig::default() },
        };
        for (a, target) in targets.iter().enumerate() {
            problem.targets[a] =
                target.map(|p| EffectorTarget { position: p.into(), rotation: None, weight: 1.0, priority: 0 });
        }
        let solution = self.tree.solve(&problem);
        let errors: Vec<f64> = (0..targets.len()).map(|a| solution.effectors[a].position_error).collect();
        let reached = (0..targets.len()).map(|a| targets[a].is_none() || solution.effectors[a].reached).collect();
        (TreeMove { q: self.unpack(&solution.q), errors }, reached)
    }
}
