//! Which joints of a skeleton are the arm to retarget: shoulder, elbow and wrist.
//!
//! By default the right arm, found by the names the common exporters use; `--chain` names any
//! three joints, each a descendant of the one before.

use super::bvh::Bvh;
use anyhow::{bail, Result};

/// Right-arm names, tried in order: CMU / MotionBuilder, Poser / DAZ, and plain names. CMU's
/// files also have a `RightShoulder` (the clavicle), so the MotionBuilder names come first.
pub const RIGHT_ARM_NAMES: [[&str; 3]; 3] = [
    ["RightArm", "RightForeArm", "RightHand"],
    ["rShldr", "rForeArm", "rHand"],
    ["RightShoulder", "RightElbow", "RightWrist"],
];

/// The arm chain: joint indices into [`Bvh::joints`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ArmChain {
    /// Shoulder (the upper arm's joint), elbow, wrist.
    pub joints: [usize; 3],
    /// Their names.
    pub names: [String; 3],
    /// How they were chosen, for the report: `--chain` or the naming convention found.
    pub found_by: String,
}

fn is_ancestor(bvh: &Bvh, ancestor: usize, mut joint: usize) -> bool {
    while let Some(p) = bvh.joints[joint].parent {
        if p == ancestor {
            return true;
        }
        joint = p;
    }
    false
}

fn chain_of(bvh: &Bvh, names: [&str; 3]) -> Option<[usize; 3]> {
    let [s, e, w] = names.map(|n| bvh.joint(n));
    let joints = [s?, e?, w?];
    (is_ancestor(bvh, joints[0], joints[1]) && is_ancestor(bvh, joints[1], joints[2])).then_some(joints)
}

/// The chain named by `given` (`SHOULDER,ELBOW,WRIST`), or the right arm by its usual names.
pub fn find(bvh: &Bvh, given: Option<&str>) -> Result<ArmChain> {
    let all = || bvh.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>().join(", ");
    if let Some(text) = given {
        let names: Vec<&str> = text.split(',').map(str::trim).collect();
        let [s, e, w] = names[..] else {
            bail!("--chain {text}: give three joint names, SHOULDER,ELBOW,WRIST");
        };
        for n in [s, e, w] {
            if bvh.joint(n).is_none() {
                bail!("--chain: no joint named {n}; the file's joints are {}", all());
            }
        }
        let joints = chain_of(bvh, [s, e, w])
            .ok_or_else(|| anyhow::anyhow!("--chain {text}: each joint must be a descendant of the one before"))?;
        return Ok(ArmChain { joints, names: [s, e, w].map(str::to_string), found_by: "--chain".into() });
    }
    for names in RIGHT_ARM_NAMES {
        if let Some(joints) = chain_of(bvh, names) {
            return Ok(ArmChain {
                joints,
                names: names.map(str::to_string),
                found_by: format!("the right arm by its names {}", names.join("/")),
            });
        }
    }
    let tried: Vec<String> = RIGHT_ARM_NAMES.iter().map(|n| n.join("/")).collect();
    bail!(
        "no right arm found (tried {}); give --chain SHOULDER,ELBOW,WRIST from the file's joints: {}",
        tried.join(", "),
        all()
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mocap::bvh::parse;

    fn skeleton(names: [&str; 4]) -> Bvh {
        let [a, b, c, d] = names;
        parse(&format!(
            "HIERARCHY\nROOT {a}\n{{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\nJOINT {b}\n{{\nOFFSET -1 0 0\n\
             CHANNELS 3 Zrotation Xrotation Yrotation\nJOINT {c}\n{{\nOFFSET -2 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n\
             JOINT {d}\n{{\nOFFSET -2 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{{\nOFFSET -1 0 0\n}}\n}}\n}}\n}}\n}}\n\
             MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0 0 0 0 0 0 0 0 0 0\n"
        ))
        .unwrap()
    }

    #[test]
    fn finds_each_naming_convention() {
        let b = skeleton(["Hips", "rShldr", "rForeArm", "rHand"]);
        let c = find(&b, None).unwrap();
        assert_eq!(c.joints, [1, 2, 3]);
        assert_eq!(c.found_by, "the right arm by its names rShldr/rForeArm/rHand");
        let b = skeleton(["RightShoulder", "RightArm", "RightForeArm", "RightHand"]);
        assert_eq!(find(&b, None).unwrap().joints, [1, 2, 3]);
    }

    #[test]
    fn no_arm_lists_the_joints_and_a_given_chain_is_checked() {
        let b = skeleton(["Hips", "A", "B", "C"]);
        assert_eq!(
            find(&b, None).unwrap_err().to_string(),
            "no right arm found (tried RightArm/RightForeArm/RightHand, rShldr/rForeArm/rHand, \
             RightShoulder/RightElbow/RightWrist); give --chain SHOULDER,ELBOW,WRIST from the file's joints: Hips, A, B, C"
        );
        assert_eq!(find(&b, Some("A,B,C")).unwrap().joints, [1, 2, 3]);
        assert_eq!(
            find(&b, Some("C,B,A")).unwrap_err().to_string(),
            "--chain C,B,A: each joint must be a descendant of the one before"
        );
        assert!(find(&b, Some("A,B")).is_err());
        assert!(find(&b, Some("A,B,X")).unwrap_err().to_string().starts_with("--chain: no joint named X"));
    }
}
