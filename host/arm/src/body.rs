//! What `--arm` names for the kinematics (`armctl fk`, `jacobian`, `ik`, Python's `Model`): one
//! chain, or a tree with several end effectors.
//!
//! A URDF with more than one leaf link and no tip named is a tree over every joint on the paths to
//! its leaves; with a tip it is the chain to that tip, as it always was. Everything else (a preset,
//! an arm file, a URDF with one leaf) is a chain, read by [`ArmSpec::load`].

use anyhow::{Context, Result};

use crate::tree::TreeSpec;
use crate::{read_urdf, urdf, ArmSpec};

/// An arm description: a chain to one tool, or a tree.
// An arm's servo setup makes the chain the larger variant; a body is read once per command, so
// boxing it would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    /// One chain from the base to the tool.
    Chain(ArmSpec),
    /// Several end effectors on shared joints (a URDF with branches).
    Tree(TreeSpec),
}

impl Body {
    /// Loads `arm` as [`ArmSpec::load`] does, except that a `.urdf` file with several leaves and
    /// no `tip` is the tree of all of them (where `ArmSpec::load` asks for a tip).
    pub fn load(arm: &str, tip: Option<&str>) -> Result<Self> {
        let is_urdf = std::path::Path::new(arm).extension().is_some_and(|e| e.eq_ignore_ascii_case("urdf"));
        if !is_urdf || tip.is_some() {
            return ArmSpec::load(arm, tip).map(Body::Chain);
        }
        let text = read_urdf(arm)?;
        // Both readers start as `leaves` does, so a file neither can read fails with one message.
        let leaves = urdf::leaves(&text).with_context(|| format!("URDF {arm}"))?;
        if leaves.len() > 1 {
            urdf::parse_tree(&text, &[]).with_context(|| format!("URDF {arm}")).map(Body::Tree)
        } else {
            urdf::parse(&text, None).with_context(|| format!("URDF {arm}")).map(Body::Chain)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(file: &str) -> String {
        format!("{}/../tests/data/{file}", env!("CARGO_MANIFEST_DIR"))
    }

    #[test]
    fn a_urdf_with_several_leaves_is_a_tree_unless_a_tip_is_named() {
        let Body::Tree(tree) = Body::load(&data("bimanual_torso.urdf"), None).unwrap() else {
            panic!("the bimanual URDF is a tree")
        };
        let links: Vec<&str> = tree.effectors.iter().map(|e| e.link.as_str()).collect();
        assert_eq!(links, ["camera_link", "left_tip", "right_tip"]);
        let Body::Chain(chain) = Body::load(&data("bimanual_torso.urdf"), Some("left_tip")).unwrap() else {
            panic!("with a tip it is the chain to it")
        };
        assert_eq!(chain, ArmSpec::load(&data("bimanual_torso.urdf"), Some("left_tip")).unwrap());
        assert_eq!(Body::load("so101", None).unwrap(), Body::Chain(ArmSpec::load("so101", None).unwrap()));
    }

    #[test]
    fn a_urdf_that_cannot_be_read_fails_as_for_a_chain() {
        let missing = format!("{:#}", Body::load("/no/such/arm.urdf", None).unwrap_err());
        assert_eq!(missing, format!("{:#}", ArmSpec::load("/no/such/arm.urdf", None).unwrap_err()));
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.urdf");
        std::fs::write(&bad, "<robot name='r'><link name='a'/><joint name='j' type='revolute'/></robot>").unwrap();
        let bad = bad.display().to_string();
        let (tree, chain) = (Body::load(&bad, None).unwrap_err(), ArmSpec::load(&bad, None).unwrap_err());
        assert_eq!(format!("{tree:#}"), format!("{chain:#}"));
        assert!(!format!("{tree:#}").contains('\n'));
    }
}
