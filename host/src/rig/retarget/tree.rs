//! `armctl retarget FILE.bvh --rig RIG` on a rig with a shared joint (an arm mounted on another's
//! tool frame, as two arms on a turning torso): the rig's tree ([`RigTree`]) as the
//! [`SharedJoints`] of the retarget. The arms that follow human arms are the followers; the arms
//! that carry them and follow none are the carriers, at rest in the middle of their limits while
//! each follower is retargeted alone, then free in the tree solve of every keyframe.

use anyhow::{bail, Result};
use kinematics::Pose;

use crate::arm::dof::DynArm;
use crate::motion::mocap::retarget::timebase::SharedJoints;
use crate::rig::tree::{RigTree, TreeArm};
use crate::rig::RigSpec;

/// The rig's tree, its arms split into carriers and followers (rig indices, in rig order).
pub struct RigShared<'a> {
    tree: RigTree,
    arms: &'a [Box<dyn DynArm>],
    carriers: Vec<usize>,
    followers: Vec<usize>,
    /// Each rig arm's base in the world with the carriers at rest.
    rest: Vec<Pose<f64>>,
}

impl<'a> RigShared<'a> {
    /// The tree of `spec`'s arms (`arms`, in rig order); `carriers[i]` says whether rig arm `i`
    /// follows no human arm (it carries another). A follower must carry no arm: a carrier's
    /// joints are free in the tree solve, a follower's serve its own hand.
    pub fn new(spec: &RigSpec, arms: &'a [Box<dyn DynArm>], carriers: &[bool]) -> Result<Self> {
        for (i, a) in spec.arms.iter().enumerate() {
            let carries: Vec<&str> = spec.arms.iter().filter(|b| b.mount == Some(i)).map(|b| b.name.as_str()).collect();
            if !carriers[i] && !carries.is_empty() {
                bail!(
                    "rig arm {} carries {} and follows a human arm: a carrier that follows a hand is not handled yet",
                    a.name,
                    carries.join(", ")
                );
            }
        }
        let tree_arms: Vec<TreeArm<'_>> = spec
            .arms
            .iter()
            .zip(arms)
            .map(|(a, arm)| TreeArm { arm: arm.spec(), base: a.base, mount: a.mount })
            .collect();
        let tree = RigTree::new(&tree_arms)?;
        let mut rest: Vec<Pose<f64>> = Vec::with_capacity(arms.len());
        for a in &spec.arms {
            let base = match a.mount {
                Some(m) => rest[m].compose(&arms[m].tool_pose(&arms[m].middle())?).compose(&a.base),
                None => a.base,
            };
            rest.push(base);
        }
        Ok(Self {
            tree,
            arms,
            carriers: (0..arms.len()).filter(|&i| carriers[i]).collect(),
            followers: (0..arms.len()).filter(|&i| !carriers[i]).collect(),
            rest,
        })
    }

    /// Each rig arm's base in the world with the carriers at rest, in rig order.
    pub fn rest_bases(&self) -> &[Pose<f64>] {
        &self.rest
    }

    /// Joints given carriers first, then followers, in rig order.
    fn to_rig(&self, q: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mut rig = vec![Vec::new(); self.arms.len()];
        for (i, values) in self.carriers.iter().chain(&self.followers).zip(q) {
            rig[*i] = values.clone();
        }
        rig
    }
}

fn apply(pose: &Pose<f64>, p: [f64; 3]) -> [f64; 3] {
    pose.compose(&Pose::from_translation(p.into())).translation.into()
}

impl SharedJoints for RigShared<'_> {
    fn carriers(&self) -> Vec<&dyn DynArm> {
        self.carriers.iter().map(|&i| self.arms[i].as_ref()).collect()
    }

    fn solve(&self, seed: &[Vec<f64>], targets: &[[f64; 3]]) -> (Vec<Vec<f64>>, Vec<bool>) {
        let mut world: Vec<Option<[f64; 3]>> = vec![None; self.arms.len()];
        for (&i, t) in self.followers.iter().zip(targets) {
            world[i] = Some(apply(&self.rest[i], *t));
        }
        let (solved, reached) = self.tree.solve_free(&self.to_rig(seed), &world);
        let q = self.carriers.iter().chain(&self.followers).map(|&i| solved.q[i].clone()).collect();
        (q, self.followers.iter().map(|&i| reached[i]).collect())
    }

    fn tools(&self, q: &[Vec<f64>]) -> Vec<[f64; 3]> {
        let world = self.tree.tools(&self.to_rig(q));
        self.followers.iter().map(|&i| apply(&self.rest[i].inverse(), world[i])).collect()
    }
}
