//! A kinematic tree as the host reads it (a URDF with branches, [`crate::urdf::parse_tree`]):
//! joints with parents and end effectors named by their links, of any count, for
//! [`kinematics::tree::Tree`] once the counts are fixed.

use kinematics::Pose;

use super::JointSpec;

/// An end effector: a link fixed to a joint's moving frame (or to the root), at an offset.
#[derive(Clone, Debug, PartialEq)]
pub struct EffectorSpec {
    /// The link it is.
    pub link: String,
    /// The tree joint it is fixed to (`None`: the root).
    pub joint: Option<usize>,
    /// Its frame relative to that joint's moving frame.
    pub offset: Pose<f64>,
}

/// A tree: moving joints, parents first, and the end effectors.
#[derive(Clone, Debug, PartialEq)]
pub struct TreeSpec {
    /// The robot's name.
    pub name: String,
    /// Moving joints; each joint's origin is relative to its parent's moving frame.
    pub joints: Vec<JointSpec>,
    /// Each joint's parent, an earlier joint (`None`: the root).
    pub parents: Vec<Option<usize>>,
    /// The end effectors, in the order their links were named.
    pub effectors: Vec<EffectorSpec>,
}

impl TreeSpec {
    /// The joints that move end effector `e`, root first.
    pub fn path(&self, e: usize) -> Vec<usize> {
        let mut path = Vec::new();
        let mut at = self.effectors.get(e).and_then(|x| x.joint);
        while let Some(k) = at {
            path.push(k);
            at = self.parents.get(k).copied().flatten();
        }
        path.reverse();
        path
    }
}

#[cfg(test)]
mod tests {
    use kinematics::nalgebra::SVector;
    use kinematics::tree::{Effector, Tree};
    use kinematics::{Joint, Limits, SplitMix64};

    use super::*;
    use crate::urdf::{parse, parse_tree};

    const BIMANUAL: &str = include_str!("../../tests/data/bimanual_torso.urdf");

    fn joint(spec: &JointSpec) -> Joint<f64> {
        let limits = Limits::new(spec.lower, spec.upper);
        match spec.kind {
            kinematics::JointKind::Continuous => Joint::continuous(spec.origin, spec.axis),
            kinematics::JointKind::Prismatic => Joint::prismatic(spec.origin, spec.axis, limits),
            _ => Joint::revolute(spec.origin, spec.axis, limits),
        }
    }

    /// The two-arm URDF with a shared torso joint as a tree: 11 joints, the torso shared, the
    /// camera's leaf left out; each hand's pose by the tree equals the chain `parse` reads from the
    /// root to that hand (an independent path through the file), at random joint values.
    #[test]
    fn a_urdf_with_branches_is_a_tree_whose_paths_are_its_chains() {
        let spec = parse_tree(BIMANUAL, &["left_tip", "right_tip"]).unwrap();
        assert_eq!(spec.joints.len(), 11);
        assert_eq!(spec.joints[0].name, "torso_yaw");
        assert_eq!(spec.parents[0], None);
        let (left, right) = (spec.path(0), spec.path(1));
        assert_eq!(left[0], 0, "the torso moves the left hand");
        assert_eq!(right[0], 0, "and the right");
        assert_eq!((left.len(), right.len()), (6, 6));
        let tree = Tree::<f64, 11, 2>::new(
            core::array::from_fn(|k| joint(&spec.joints[k])),
            core::array::from_fn(|k| spec.parents[k]),
            core::array::from_fn(|e| Effector { joint: spec.effectors[e].joint, offset: spec.effectors[e].offset }),
        )
        .unwrap();
        let chains = [parse(BIMANUAL, Some("left_tip")).unwrap(), parse(BIMANUAL, Some("right_tip")).unwrap()];
        let mut rng = SplitMix64::new(30);
        for _ in 0..100 {
            let q = SVector::<f64, 11>::from_fn(|k, _| {
                let j = &spec.joints[k];
                rng.uniform(j.lower, j.upper)
            });
            let frames = tree.forward(&q);
            for (e, chain) in chains.iter().enumerate() {
                let path = spec.path(e);
                let names: Vec<&str> = path.iter().map(|&k| spec.joints[k].name.as_str()).collect();
                assert_eq!(names, chain.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>());
                // The chain by hand: each joint's origin, motion, then the tool.
                let mut pose = kinematics::Pose::identity();
                for (j, &k) in chain.joints.iter().zip(&path) {
                    pose = pose.compose(&j.origin).compose(&joint(j).motion(q[k]));
                }
                let pose = pose.compose(&chain.tool);
                assert!((pose.translation - frames.effectors[e].translation).amax() < 1e-12);
                assert!((pose.rotation - frames.effectors[e].rotation).amax() < 1e-12);
            }
        }
    }

    #[test]
    fn every_leaf_by_default_and_bad_tips_are_one_line() {
        let all = parse_tree(BIMANUAL, &[]).unwrap();
        let links: Vec<&str> = all.effectors.iter().map(|e| e.link.as_str()).collect();
        assert_eq!(links, ["camera_link", "left_tip", "right_tip"]);
        // The camera is fixed to the torso: it is on the torso joint, at the folded offset.
        assert_eq!(all.effectors[0].joint, Some(0));
        for (tips, words) in [
            (vec!["left_tip", "left_tip"], "named twice"),
            (vec!["left_wrist_roll"], "is a joint, not a link"),
            (vec!["nowhere"], "is not a <link>"),
        ] {
            let e = format!("{:#}", parse_tree(BIMANUAL, &tips).unwrap_err());
            assert!(e.contains(words) && !e.contains('\n'), "{e}");
        }
    }
}
