//! The mass properties of a URDF arm (its links' `<inertial>`), in the frames of the chain
//! [`urdf::parse`] imports, for [`kinematics::dynamics::Dynamics`]: each moving joint's link with
//! every link fixed to it (the tool frame's, a camera) combined into one body, and what hangs off
//! the chain through other joints (the SO-101's moving jaw) carried rigidly at those joints' zero.
//! Read from the file on demand, not kept in the arm file.

use crate::urdf::{self, child, UrdfJoint, UrdfKind};
use anyhow::{anyhow, bail, Result};
use kinematics::dynamics::Inertia;
use kinematics::nalgebra::{Matrix3, Vector3};
use kinematics::Pose;
use roxmltree::{Document, Node};
use std::collections::BTreeMap;

/// The arm's mass properties.
#[derive(Clone, Debug, PartialEq)]
pub struct Masses {
    /// What the base carries (the root link and every link fixed to it): moved by no joint.
    pub base: Inertia<f64>,
    /// One body per moving joint of the chain, in that joint's moving frame (base first).
    pub links: Vec<Inertia<f64>>,
    /// Links that have no `<inertial>`, taken as massless (URDF's default), by name.
    pub massless: Vec<String>,
    /// Links off the chain carried rigidly at their joints' zero, with the joint that would move
    /// them: "moving_jaw_so101_v1_link (joint gripper)".
    pub carried: Vec<String>,
}

/// The masses of the chain from the root link to `tip` (or the only leaf), as [`urdf::parse`]
/// chooses it. Fails in one line naming the link and the line of the file for an `<inertial>` that
/// cannot be read or is not a body's (a mass not finite or negative, a tensor that breaks the
/// triangle inequality), and when no link of the chain has mass.
pub fn masses(text: &str, tip: Option<&str>) -> Result<Masses> {
    // `parse` checks the tree, the joints and the tip, with its errors; the walk below relies on it.
    let spec = urdf::parse(text, tip)?;
    let doc = Document::parse(text)?;
    let robot = doc.root_element();
    let links: BTreeMap<&str, Node> =
        robot.children().filter(|n| n.has_tag_name("link")).filter_map(|n| Some((n.attribute("name")?, n))).collect();
    let mut parent_joint: BTreeMap<&str, UrdfJoint> = BTreeMap::new();
    for node in robot.children().filter(|n| n.has_tag_name("joint")) {
        let joint = urdf::read_joint(node, urdf::line_of(node))?;
        parent_joint.insert(joint.child, joint);
    }
    // The chain's moving joints, by name, and the frame each moves (1 for the first).
    let frames: BTreeMap<&str, usize> = spec.joints.iter().enumerate().map(|(k, j)| (j.name.as_str(), k + 1)).collect();

    let mut bodies = vec![Inertia::zero(); spec.dof() + 1];
    let (mut massless, mut carried) = (Vec::new(), Vec::new());
    for (&name, &node) in &links {
        // Up from the link to the first joint of the chain that moves it (or the root), composing
        // the fixed joints' origins, and other joints' at their zero, on the way.
        let (mut at, mut current, mut frame, mut off_chain) = (Pose::identity(), name, 0, None);
        while let Some(joint) = parent_joint.get(current) {
            if let Some(&k) = frames.get(joint.name) {
                frame = k;
                break;
            }
            if matches!(joint.kind, UrdfKind::Moving(_)) {
                off_chain.get_or_insert(joint.name);
            }
            at = joint.origin.compose(&at);
            current = joint.parent;
        }
        let Some(inertial) = child(node, "inertial") else {
            massless.push(name.to_string());
            continue;
        };
        let body = read_inertial(inertial, name)?;
        if let Some(joint) = off_chain {
            carried.push(format!("{name} (joint {joint})"));
        }
        bodies[frame] = bodies[frame].combined(&body.moved(&at.rotation, &at.translation));
    }
    let base = bodies.remove(0);
    if bodies.iter().all(|b| b.mass <= 0.0) {
        bail!("{}: no link the joints move has an <inertial> with mass: the URDF gives no dynamics", spec.name);
    }
    Ok(Masses { base, links: bodies, massless, carried })
}

/// One `<inertial>`: the centre of mass at its `<origin>`, the tensor in that origin's axes.
fn read_inertial(node: Node, link: &str) -> Result<Inertia<f64>> {
    let owner = format!("link {link} <inertial>");
    let line = urdf::line_of(node);
    let origin = urdf::origin(child(node, "origin"), &owner)?;
    let value = |element: &str, attribute: &str| -> Result<f64> {
        let e = child(node, element).ok_or_else(|| anyhow!("line {line}: {owner} has no <{element}>"))?;
        let text = e
            .attribute(attribute)
            .ok_or_else(|| anyhow!("line {}: {owner}: <{element}> has no {attribute}", urdf::line_of(e)))?;
        urdf::number(text, e, attribute, &owner, urdf::line_of(e))
    };
    let mass = value("mass", "value")?;
    let (xx, xy, xz) = (value("inertia", "ixx")?, value("inertia", "ixy")?, value("inertia", "ixz")?);
    let (yy, yz, zz) = (value("inertia", "iyy")?, value("inertia", "iyz")?, value("inertia", "izz")?);
    let tensor = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let body = Inertia { mass, com: Vector3::zeros(), tensor }
        .validated()
        .map_err(|e| anyhow!("line {line}: {owner}: {e}"))?;
    Ok(body.moved(&origin.rotation, &origin.translation))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SO101: &str = include_str!("../../tests/data/so101_new_calib.urdf");
    /// The preset's tip: the tool frame's link (the jaw is the other leaf).
    const TIP: Option<&str> = Some("gripper_frame_link");

    /// The SO-101's links as its URDF gives them: each joint's link, the tool frame's link fixed
    /// to the wrist roll's, the moving jaw carried at the gripper's zero.
    #[test]
    fn the_so101s_masses_are_its_links_in_the_chains_frames() {
        let m = masses(SO101, TIP).unwrap();
        assert_eq!(m.links.len(), 5);
        assert!((m.base.mass - 0.147).abs() < 1e-12);
        let expected = [0.100006, 0.103, 0.104, 0.079, 0.087 + 1e-9 + 0.012];
        for (link, mass) in m.links.iter().zip(expected) {
            assert!((link.mass - mass).abs() < 1e-12, "{} against {mass}", link.mass);
        }
        assert_eq!(m.carried, vec!["moving_jaw_so101_v1_link (joint gripper)".to_string()]);
        assert!(m.massless.is_empty(), "{:?}", m.massless);
        // The wrist roll's body, by hand from the file's numbers: the gripper link's centre of
        // mass, and the jaw's carried through the gripper joint's origin (xyz, rpy) at zero.
        let gripper = Vector3::new(0.000213627, 0.000245138, -0.025187);
        // The file's roll, 1.5708, as written (not π/2).
        #[allow(clippy::approx_constant)]
        let roll = 1.5708;
        let jaw_origin = Pose::from_xyz_rpy([0.0202, 0.0188, -0.0234], [roll, -5.24284e-08, -1.41553e-15]);
        let jaw = jaw_origin.rotation * Vector3::new(-0.00157495, -0.0300244, 0.0192755) + jaw_origin.translation;
        let com = (gripper * 0.087 + jaw * 0.012) / (0.087 + 0.012 + 1e-9);
        assert!((m.links[4].com - com).norm() < 1e-6, "{} against {com}", m.links[4].com);
    }

    #[test]
    fn bad_inertials_are_refused_in_one_line_naming_the_link() {
        let nan = SO101.replacen(r#"<mass value="0.103"/>"#, r#"<mass value="nan"/>"#, 1);
        let e = masses(&nan, TIP).unwrap_err().to_string();
        assert!(e.contains("link upper_arm_link <inertial>") && e.contains("not a finite number"), "{e}");
        let negative = SO101.replacen(r#"<mass value="0.103"/>"#, r#"<mass value="-0.103"/>"#, 1);
        let e = masses(&negative, TIP).unwrap_err().to_string();
        assert!(e.contains("upper_arm_link") && e.contains("negative"), "{e}");
        let flat = SO101.replacen(r#"izz="0.000142487""#, r#"izz="0.001""#, 1);
        let e = masses(&flat, TIP).unwrap_err().to_string();
        assert!(e.contains("upper_arm_link") && e.contains("triangle"), "{e}");
        let none = without_inertials(SO101);
        let e = masses(&none, TIP).unwrap_err().to_string();
        assert!(e.contains("no dynamics") && !e.contains('\n'), "{e}");
    }

    /// The file without any `<inertial>` element.
    fn without_inertials(text: &str) -> String {
        let mut out = String::new();
        let mut rest = text;
        while let Some(start) = rest.find("<inertial>") {
            out.push_str(&rest[..start]);
            let end = rest[start..].find("</inertial>").unwrap() + start + "</inertial>".len();
            rest = &rest[end..];
        }
        out.push_str(rest);
        out
    }
}
