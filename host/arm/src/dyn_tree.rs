//! From a tree read at run time ([`TreeSpec`]) to the kinematics crate's fixed-size tree, in one
//! instance for every size.
//!
//! `kinematics::tree::Tree<T, N, E>` is fixed in its joint count `N` and end-effector count `E`,
//! as the firmware needs. Dispatching both counts as [`crate::dof`] does for chains would
//! instantiate the tree's solver once per pair; instead every tree is held in one capacity,
//! [`MAX_JOINTS`] joints and [`MAX_EFFECTORS`] end effectors, the unused ones padded: a joint of
//! zero range under no end effector (its Jacobian column is zero, so no step moves it), and an end
//! effector on the root with no target. The padded joints and end effectors never leave this
//! module. A rig whose arms are mounted on one another (`armctl --rig`) and a URDF with branches
//! (`armctl fk`, `jacobian`, `ik`, Python's `Model`) are both a [`DynTree`].

use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use kinematics::ik::IkConfig;
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::tree::{Effector, EffectorOutcome, EffectorTarget, Tree, TreeError, TreeProblem, TreeStatus};
use kinematics::{ChainError, Joint, JointKind, Limits, Pose, SplitMix64};

use crate::dof::check_unit_quaternion;
use crate::tree::TreeSpec;

/// The most joints of a tree.
pub const MAX_JOINTS: usize = 16;
/// The most end effectors of a tree.
pub const MAX_EFFECTORS: usize = 4;

/// The iteration budget over every restart that the front ends give a tree's IK unless told
/// otherwise (a chain's is 1000). Two hands' full poses through a shared joint take more restarts:
/// on the two-arm URDF of the tests, 1000 reach 85 % of random reachable pose pairs, 3000 and more
/// at least 95 %, measured over 40 pairs.
pub const DEFAULT_MAX_ITERATIONS: u32 = 6000;

type Padded = Tree<f64, MAX_JOINTS, MAX_EFFECTORS>;

/// A tree of any size up to [`MAX_JOINTS`] joints and [`MAX_EFFECTORS`] end effectors, in f64.
#[derive(Clone, Debug)]
pub struct DynTree {
    spec: TreeSpec,
    tree: Padded,
}

/// World poses at some joint values: every joint frame (after its motion) and every end effector,
/// in the spec's order.
#[derive(Clone, Debug)]
pub struct TreePoses {
    /// Joint frames.
    pub joints: Vec<Pose<f64>>,
    /// End effector frames.
    pub effectors: Vec<Pose<f64>>,
}

/// What one end effector should reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectorGoal {
    /// Position, m, base frame.
    pub position: [f64; 3],
    /// Orientation, a unit quaternion w first; `None` for a position only.
    pub quaternion_wxyz: Option<[f64; 4]>,
    /// 0 for the first priority; 1 for a target met only in the null space the first ones leave.
    pub priority: u8,
}

/// A target named by its end effector's link, as a person gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedGoal {
    /// The end effector's link.
    pub link: String,
    /// Position, m, base frame.
    pub position: [f64; 3],
    /// Orientation, w first; `None` for a position only.
    pub quaternion_wxyz: Option<[f64; 4]>,
}

/// One IK problem over the whole tree.
#[derive(Clone, Debug)]
pub struct TreeIkRequest {
    /// One per end effector, in the spec's order; `None` where it is free.
    pub goals: Vec<Option<EffectorGoal>>,
    /// Seed joint values; `None` for the middle of the limits.
    pub seed: Option<Vec<f64>>,
    /// Tolerances, the orientation weight and the budgets, as a chain's solve takes them.
    pub config: IkConfig<f64>,
}

/// The answer of [`DynTree::solve`].
#[derive(Clone, Debug)]
pub struct TreeIkOutcome {
    /// Joint values, within the limits.
    pub q: Vec<f64>,
    /// Overall.
    pub status: TreeStatus,
    /// Per end effector, in the spec's order (one without a goal: reached, errors 0).
    pub effectors: Vec<EffectorOutcome<f64>>,
    /// Iterations over every attempt.
    pub iterations: u32,
    /// Restarts drawn.
    pub restarts: u32,
    /// Time in the solver alone.
    pub solve_time: Duration,
}

impl TreeIkOutcome {
    /// The status by the names a chain's IK prints (`converged`, `best_effort`,
    /// `iteration_limit`, `invalid_input`): a stalled tree is a chain's best effort.
    pub fn status_name(&self) -> &'static str {
        match self.status {
            TreeStatus::Converged => "converged",
            TreeStatus::Stalled => "best_effort",
            TreeStatus::IterationLimit => "iteration_limit",
            TreeStatus::InvalidInput => "invalid_input",
        }
    }
}

/// The kinematics crate's joint for `spec` (the chain's construction, [`crate::ArmSpec::chain`]).
fn joint(spec: &crate::JointSpec) -> Joint<f64> {
    Joint {
        origin: spec.origin,
        axis: spec.axis.into(),
        kind: spec.kind,
        limits: Limits::from_f64(spec.lower, spec.upper),
    }
}

impl DynTree {
    /// The tree of `spec`; fails, naming the joint or end effector, for a spec the kinematics
    /// refuses (a zero axis, lower limit above upper, a parent after its child) or one too big.
    pub fn build(spec: TreeSpec) -> Result<Self> {
        let (n, e) = (spec.joints.len(), spec.effectors.len());
        if n > MAX_JOINTS || e > MAX_EFFECTORS {
            bail!(
                "tree {} has {n} joints and {e} end effectors; a tree holds at most {MAX_JOINTS} joints and \
                 {MAX_EFFECTORS} end effectors",
                spec.name
            );
        }
        if spec.parents.len() != n {
            bail!("tree {}: {} parents for {n} joints", spec.name, spec.parents.len());
        }
        let padding = Joint {
            origin: Pose::identity(),
            axis: Vector3::z(),
            kind: JointKind::Revolute,
            limits: Limits::from_f64(0.0, 0.0),
        };
        let joints = core::array::from_fn(|k| spec.joints.get(k).map_or(padding, joint));
        let parents = core::array::from_fn(|k| spec.parents.get(k).copied().flatten());
        let effectors = core::array::from_fn(|i| match spec.effectors.get(i) {
            Some(x) => Effector { joint: x.joint, offset: x.offset },
            None => Effector { joint: None, offset: Pose::identity() },
        });
        let tree = Tree::new(joints, parents, effectors).map_err(|error| {
            let named = match error {
                TreeError::Joint(
                    ChainError::ZeroAxis { joint }
                    | ChainError::BadLimits { joint }
                    | ChainError::BadFrame { joint: Some(joint) },
                )
                | TreeError::Parent { joint } => format!(" ({})", spec.joints[joint].name),
                TreeError::Effector { effector } => format!(" ({})", spec.effectors[effector].link),
                TreeError::Joint(ChainError::BadFrame { joint: None }) => String::new(),
            };
            anyhow!("tree {}: {error}{named}", spec.name)
        })?;
        Ok(Self { spec, tree })
    }

    /// The description it was built from.
    pub fn spec(&self) -> &TreeSpec {
        &self.spec
    }

    /// Number of moving joints.
    pub fn dof(&self) -> usize {
        self.spec.joints.len()
    }

    /// The end effectors' links, in order.
    pub fn effector_names(&self) -> Vec<&str> {
        self.spec.effectors.iter().map(|e| e.link.as_str()).collect()
    }

    /// The index of the end effector that is link `link`.
    pub fn effector(&self, link: &str) -> Result<usize> {
        self.spec.effectors.iter().position(|e| e.link == link).ok_or_else(|| {
            anyhow!(
                "tree {} has no end effector {link:?} (its end effectors: {})",
                self.spec.name,
                self.effector_names().join(", ")
            )
        })
    }

    /// `q` padded to the capacity, or the error for a wrong count.
    fn padded(&self, q: &[f64]) -> Result<SVector<f64, MAX_JOINTS>> {
        if q.len() != self.dof() {
            bail!(
                "tree {} has {} joints (every joint on the paths to {}) but {} joint values were given; a tip \
                 (--tip LINK, or tip= in Python) reads the chain to one of them",
                self.spec.name,
                self.dof(),
                self.effector_names().join(", "),
                q.len()
            );
        }
        Ok(SVector::from_fn(|k, _| q.get(k).copied().unwrap_or(0.0)))
    }

    /// Every joint frame and end effector at `q`.
    pub fn forward(&self, q: &[f64]) -> Result<TreePoses> {
        let frames = self.tree.forward(&self.padded(q)?);
        Ok(TreePoses {
            joints: frames.joints[..self.dof()].to_vec(),
            effectors: frames.effectors[..self.spec.effectors.len()].to_vec(),
        })
    }

    /// Each end effector's 6 x N geometric Jacobian at `q` (rows linear x, y, z then angular x,
    /// y, z; one column per joint of the tree, zero for the joints that do not move it).
    pub fn jacobians(&self, q: &[f64]) -> Result<Vec<Vec<Vec<f64>>>> {
        let all = self.tree.jacobians(&self.padded(q)?);
        Ok(all[..self.spec.effectors.len()]
            .iter()
            .map(|j| (0..6).map(|r| (0..self.dof()).map(|c| j[(r, c)]).collect()).collect())
            .collect())
    }

    /// The middle of every joint range.
    pub fn middle(&self) -> Vec<f64> {
        self.tree.middle().iter().take(self.dof()).copied().collect()
    }

    /// A joint vector drawn uniformly within the limits.
    pub fn random_configuration(&self, rng: &mut SplitMix64) -> Vec<f64> {
        self.spec.joints.iter().map(|j| rng.uniform(j.lower, j.upper)).collect()
    }

    /// True if `q` has one value per joint, each within its joint's limits.
    pub fn admits(&self, q: &[f64]) -> bool {
        self.padded(q).is_ok_and(|v| self.tree.admits(&v))
    }

    /// One goal per end effector from targets named by link: each end effector at most once;
    /// `first`, if given, names the targets of the first priority, the rest then met only in the
    /// null space those leave (it must name some targets, not all, each once).
    pub fn goals(&self, targets: &[NamedGoal], first: Option<&[String]>) -> Result<Vec<Option<EffectorGoal>>> {
        let mut goals: Vec<Option<EffectorGoal>> = vec![None; self.spec.effectors.len()];
        for t in targets {
            let e = self.effector(&t.link)?;
            if goals[e].is_some() {
                bail!("end effector {} has two targets", t.link);
            }
            if let Some(quat) = t.quaternion_wxyz {
                check_unit_quaternion(quat).map_err(|error| anyhow!("end effector {}: {error}", t.link))?;
            }
            goals[e] = Some(EffectorGoal { position: t.position, quaternion_wxyz: t.quaternion_wxyz, priority: 0 });
        }
        if targets.is_empty() {
            bail!("no target: name one end effector at least ({})", self.effector_names().join(", "));
        }
        let Some(first) = first else { return Ok(goals) };
        let mut ranked = vec![false; goals.len()];
        for link in first {
            let e = self.effector(link).map_err(|error| anyhow!("priority: {error}"))?;
            if goals[e].is_none() {
                bail!("priority: end effector {link} has no target");
            }
            if ranked[e] {
                bail!("priority: end effector {link} is named twice");
            }
            ranked[e] = true;
        }
        if first.is_empty() || goals.iter().zip(&ranked).all(|(g, r)| g.is_none() || *r) {
            bail!(
                "priority: it names the targets met first, and must leave some for the second priority (it names {} of \
                 {} targets)",
                first.len(),
                targets.len()
            );
        }
        for (goal, ranked) in goals.iter_mut().zip(&ranked) {
            if let Some(goal) = goal {
                goal.priority = if *ranked { 0 } else { 1 };
            }
        }
        Ok(goals)
    }

    /// Solves every goal at once ([`Tree::solve`]: damped least squares over the whole tree, shared
    /// joints serving every end effector below them). Errors only for a request that cannot be
    /// posed (a seed of the wrong length, a goal list not one per end effector, a quaternion that
    /// is not a rotation); everything else is in the outcome.
    pub fn solve(&self, request: &TreeIkRequest) -> Result<TreeIkOutcome> {
        let count = self.spec.effectors.len();
        if request.goals.len() != count {
            bail!("tree {}: {} goals for {count} end effectors", self.spec.name, request.goals.len());
        }
        let seed = match &request.seed {
            Some(s) => self.padded(s)?,
            None => self.tree.middle(),
        };
        let mut targets = [None; MAX_EFFECTORS];
        for (e, goal) in request.goals.iter().enumerate() {
            let Some(goal) = goal else { continue };
            let rotation = match goal.quaternion_wxyz {
                None => None,
                Some(quat) => {
                    let link = &self.spec.effectors[e].link;
                    check_unit_quaternion(quat).map_err(|error| anyhow!("end effector {link}: {error}"))?;
                    Some(Pose::rotation_from_quaternion_wxyz(quat).ok_or_else(|| {
                        anyhow!("end effector {link}: the target quaternion must be finite and non-zero")
                    })?)
                }
            };
            targets[e] =
                Some(EffectorTarget { position: goal.position.into(), rotation, weight: 1.0, priority: goal.priority });
        }
        let problem = TreeProblem { targets, seed, config: request.config };
        let started = Instant::now();
        let solution = self.tree.solve(&problem);
        let solve_time = started.elapsed();
        Ok(TreeIkOutcome {
            q: solution.q.iter().take(self.dof()).copied().collect(),
            status: solution.status,
            effectors: solution.effectors[..count].to_vec(),
            iterations: solution.iterations,
            restarts: solution.restarts,
            solve_time,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::urdf::{parse, parse_tree};
    use crate::JointSpec;

    const BIMANUAL: &str = include_str!("../../tests/data/bimanual_torso.urdf");

    fn bimanual() -> DynTree {
        DynTree::build(parse_tree(BIMANUAL, &[]).unwrap()).unwrap()
    }

    /// The padded tree's poses and Jacobians are those of the chain to each leaf, at random
    /// joint values; the padding shows nowhere.
    #[test]
    fn each_end_effector_is_the_chain_to_its_leaf() {
        let tree = bimanual();
        assert_eq!(tree.dof(), 11);
        assert_eq!(tree.effector_names(), ["camera_link", "left_tip", "right_tip"]);
        let mut rng = SplitMix64::new(31);
        for (e, link) in ["camera_link", "left_tip", "right_tip"].iter().enumerate() {
            let chain = parse(BIMANUAL, Some(link)).unwrap();
            let path = tree.spec().path(e);
            let arm = crate::dof::build(chain).unwrap();
            for _ in 0..50 {
                let q = tree.random_configuration(&mut rng);
                let on_path: Vec<f64> = path.iter().map(|&k| q[k]).collect();
                let poses = tree.forward(&q).unwrap();
                assert_eq!(poses.joints.len(), 11);
                assert_eq!(poses.effectors.len(), 3);
                let tool = arm.tool_pose(&on_path).unwrap();
                assert!((tool.translation - poses.effectors[e].translation).amax() < 1e-12);
                assert!((tool.rotation - poses.effectors[e].rotation).amax() < 1e-12);
                let (tree_j, chain_j) = (&tree.jacobians(&q).unwrap()[e], arm.jacobian(&on_path).unwrap());
                assert_eq!(tree_j.len(), 6);
                for (r, row) in tree_j.iter().enumerate() {
                    assert_eq!(row.len(), 11);
                    for (k, value) in row.iter().enumerate() {
                        let want = path.iter().position(|&p| p == k).map_or(0.0, |c| chain_j[r][c]);
                        assert!((value - want).abs() < 1e-12, "row {r} column {k}");
                    }
                }
            }
        }
    }

    /// Both hands' full poses from the FK of random joint values over the whole range, seeded at
    /// the middle, with the front ends' budget; each answer checked by FK here.
    #[test]
    fn both_hands_reach_random_reachable_poses_at_once() {
        let tree = bimanual();
        let mut rng = SplitMix64::new(32);
        let mut converged = 0;
        for _ in 0..20 {
            let q = tree.random_configuration(&mut rng);
            let poses = tree.forward(&q).unwrap();
            let targets: Vec<NamedGoal> = [1, 2]
                .iter()
                .map(|&e| NamedGoal {
                    link: tree.effector_names()[e].to_string(),
                    position: poses.effectors[e].translation.into(),
                    quaternion_wxyz: Some(poses.effectors[e].quaternion_wxyz()),
                })
                .collect();
            let goals = tree.goals(&targets, None).unwrap();
            let config = IkConfig { max_iterations: DEFAULT_MAX_ITERATIONS, ..IkConfig::default() };
            let outcome = tree.solve(&TreeIkRequest { goals, seed: None, config }).unwrap();
            assert_eq!(outcome.q.len(), 11);
            if outcome.status == TreeStatus::Converged {
                converged += 1;
                // Checked here too, by the padded tree's own forward kinematics.
                let reached = tree.forward(&outcome.q).unwrap();
                for t in &targets {
                    let e = tree.effector(&t.link).unwrap();
                    let p: [f64; 3] = reached.effectors[e].translation.into();
                    assert!((0..3).all(|i| (p[i] - t.position[i]).abs() < 1e-5));
                }
                assert!(tree.admits(&outcome.q));
            }
        }
        assert!(converged >= 19, "{converged} of 20");
    }

    #[test]
    fn bad_goals_and_trees_are_one_line_errors() {
        let tree = bimanual();
        let at = |link: &str| NamedGoal { link: link.into(), position: [0.3, 0.2, 0.4], quaternion_wxyz: None };
        let first = |links: &[&str]| links.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        for (targets, priority, words) in [
            (vec![at("nowhere")], None, "has no end effector \"nowhere\" (its end effectors: camera_link, left_tip"),
            (vec![at("left_tip"), at("left_tip")], None, "left_tip has two targets"),
            (vec![], None, "no target"),
            (vec![at("left_tip"), at("right_tip")], Some(first(&["camera_link"])), "camera_link has no target"),
            (vec![at("left_tip"), at("right_tip")], Some(first(&["left_tip", "right_tip"])), "must leave some"),
            (vec![at("left_tip"), at("right_tip")], Some(first(&["left_tip", "left_tip"])), "named twice"),
            (
                vec![NamedGoal { quaternion_wxyz: Some([1.0, 1.0, 0.0, 0.0]), ..at("left_tip") }],
                None,
                "left_tip: the target quaternion w,x,y,z is not a unit quaternion",
            ),
        ] {
            let e = format!("{:#}", tree.goals(&targets, priority.as_deref()).unwrap_err());
            assert!(e.contains(words) && !e.contains('\n'), "{e}");
        }
        let ranked = tree.goals(&[at("left_tip"), at("right_tip")], Some(&first(&["right_tip"]))).unwrap();
        assert_eq!(ranked.iter().map(|g| g.map(|g| g.priority)).collect::<Vec<_>>(), [None, Some(1), Some(0)]);
        let seed = Some(vec![0.0; 5]);
        let request = TreeIkRequest { goals: vec![None; 3], seed, config: IkConfig::default() };
        let e = format!("{:#}", tree.solve(&request).unwrap_err());
        assert!(e.contains("has 11 joints") && e.contains("but 5 joint values"), "{e}");
        let mut spec = parse_tree(BIMANUAL, &[]).unwrap();
        spec.joints[3].axis = [0.0; 3];
        let e = format!("{:#}", DynTree::build(spec).unwrap_err());
        assert!(e.contains("joint 3 has a zero or non-finite axis (left_elbow_flex)"), "{e}");
        let too_big = TreeSpec {
            name: "big".into(),
            joints: vec![
                JointSpec {
                    name: "j".into(),
                    kind: JointKind::Revolute,
                    origin: Pose::identity(),
                    axis: [0.0, 0.0, 1.0],
                    lower: -1.0,
                    upper: 1.0,
                };
                17
            ],
            parents: (0..17usize).map(|k| k.checked_sub(1)).collect(),
            effectors: Vec::new(),
        };
        let e = format!("{:#}", DynTree::build(too_big).unwrap_err());
        assert!(e.contains("17 joints") && e.contains("at most 16"), "{e}");
    }
}
