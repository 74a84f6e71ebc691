//! Which joints of a skeleton are the arm to retarget: shoulder, elbow and wrist.
//!
//! By default the right arm, found by the names the common exporters use; `--chain` names any
//! three joints, each a descendant of the one before. A rig's arms named left and right get the
//! human's left and right arms by the same names ([`Side`]).

use super::bvh::Bvh;
use anyhow::{bail, Result};

/// Right-arm names, tried in order: CMU / MotionBuilder, Poser / DAZ, and plain names. CMU's
/// files also have a `RightShoulder` (the clavicle), so the MotionBuilder names come first.
pub const RIGHT_ARM_NAMES: [[&str; 3]; 3] = [
    ["RightArm", "RightForeArm", "RightHand"],
    ["rShldr", "rForeArm", "rHand"],
    ["RightShoulder", "RightElbow", "RightWrist"],
];

/// Left-arm names, the mirror of [`RIGHT_ARM_NAMES`].
pub const LEFT_ARM_NAMES: [[&str; 3]; 3] = [
    ["LeftArm", "LeftForeArm", "LeftHand"],
    ["lShldr", "lForeArm", "lHand"],
    ["LeftShoulder", "LeftElbow", "LeftWrist"],
];

/// Which of the human's arms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The left arm.
    Left,
    /// The right arm.
    Right,
}

impl Side {
    /// `left` or `right`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// The names tried for this arm, in order.
    pub fn names(self) -> &'static [[&'static str; 3]; 3] {
        match self {
            Side::Left => &LEFT_ARM_NAMES,
            Side::Right => &RIGHT_ARM_NAMES,
        }
    }

    /// The side a rig arm's name calls for: `left` or `right` (any case) as the whole name or one
    /// of its words between `_` and `-` (`left`, `Left`, `left_follower`, `arm-right`); `None` for
    /// a name with neither, or with both.
    pub fn of_arm_name(name: &str) -> Option<Side> {
        let words: Vec<String> = name.split(['_', '-']).map(str::to_ascii_lowercase).collect();
        let has = |w: &str| words.iter().any(|x| x == w);
        match (has("left"), has("right")) {
            (true, false) => Some(Side::Left),
            (false, true) => Some(Side::Right),
            _ => None,
        }
    }
}

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

/// The file's joints, for messages.
pub fn joint_list(bvh: &Bvh) -> String {
    bvh.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>().join(", ")
}

/// The chain `text` names (`SHOULDER,ELBOW,WRIST`). Messages start with `label` (the option as
/// given, `--chain TEXT`), or `option` (`--chain`) where a joint is missing.
pub fn named(bvh: &Bvh, text: &str, label: &str, option: &str) -> Result<ArmChain> {
    let names: Vec<&str> = text.split(',').map(str::trim).collect();
    let [s, e, w] = names[..] else {
        bail!("{label}: give three joint names, SHOULDER,ELBOW,WRIST");
    };
    for n in [s, e, w] {
        if bvh.joint(n).is_none() {
            bail!("{option}: no joint named {n}; the file's joints are {}", joint_list(bvh));
        }
    }
    let joints = chain_of(bvh, [s, e, w])
        .ok_or_else(|| anyhow::anyhow!("{label}: each joint must be a descendant of the one before"))?;
    Ok(ArmChain { joints, names: [s, e, w].map(str::to_string), found_by: option.to_string() })
}

/// The arm of `side` by its usual names ([`Side::names`]), where the file has one.
pub fn by_names(bvh: &Bvh, side: Side) -> Option<ArmChain> {
    side.names().iter().find_map(|names| {
        chain_of(bvh, *names).map(|joints| ArmChain {
            joints,
            names: names.map(str::to_string),
            found_by: format!("the {} arm by its names {}", side.name(), names.join("/")),
        })
    })
}

/// The names tried for `side`, for messages: `A/B/C, D/E/F, ...`.
pub fn tried(side: Side) -> String {
    side.names().iter().map(|n| n.join("/")).collect::<Vec<_>>().join(", ")
}

/// The chain named by `given` (`SHOULDER,ELBOW,WRIST`), or the right arm by its usual names.
pub fn find(bvh: &Bvh, given: Option<&str>) -> Result<ArmChain> {
    if let Some(text) = given {
        return named(bvh, text, &format!("--chain {text}"), "--chain");
    }
    by_names(bvh, Side::Right).ok_or_else(|| {
        anyhow::anyhow!(
            "no right arm found (tried {}); give --chain SHOULDER,ELBOW,WRIST from the file's joints: {}",
            tried(Side::Right),
            joint_list(bvh)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::mocap::bvh::parse;

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
    fn the_left_arm_by_its_names_and_sides_by_arm_names() {
        let b = skeleton(["Hips", "LeftArm", "LeftForeArm", "LeftHand"]);
        let c = by_names(&b, Side::Left).unwrap();
        assert_eq!(c.joints, [1, 2, 3]);
        assert_eq!(c.found_by, "the left arm by its names LeftArm/LeftForeArm/LeftHand");
        assert!(by_names(&b, Side::Right).is_none());
        for (name, side) in [
            ("left", Some(Side::Left)),
            ("Right", Some(Side::Right)),
            ("left_follower", Some(Side::Left)),
            ("arm-right", Some(Side::Right)),
            ("leftover", None),
            ("left-right", None),
            ("a", None),
        ] {
            assert_eq!(Side::of_arm_name(name), side, "{name}");
        }
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
