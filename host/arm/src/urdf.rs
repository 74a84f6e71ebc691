//! URDF import: the serial chain from the root link to a tip link of a `<robot>` description
//! ([`parse`]), or the tree of every joint on the paths to several tip links ([`parse_tree`]).
//!
//! Only `<link>` and `<joint>` elements directly under `<robot>` are read; visuals, collisions,
//! inertials, transmissions, Gazebo tags and materials are ignored (the view reads the visual
//! meshes with [`crate::urdf_visuals`]), and joints may come in any order.
//! Fixed joints are folded into the next moving joint's origin (or into the tool frame after the
//! last moving joint). Defaults follow the URDF specification: a missing `<origin>` is the identity,
//! missing `xyz`/`rpy` are zero and a missing `<axis>` is (1, 0, 0). Every error is one line that
//! names the line of the file and the joint, link or attribute at fault.

use super::tree::{EffectorSpec, TreeSpec};
use super::{ArmSpec, JointSpec};
use anyhow::{anyhow, bail, Result};
use kinematics::{JointKind, Pose};
use roxmltree::{Document, Node};
use std::collections::{BTreeMap, BTreeSet};

/// How a URDF joint moves, including the kinds that cannot be part of an arm chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum UrdfKind {
    Moving(JointKind),
    Fixed,
    Floating,
    Planar,
}

/// One `<joint>` as read from the file.
pub(crate) struct UrdfJoint<'a> {
    pub(crate) name: &'a str,
    line: u32,
    pub(crate) kind: UrdfKind,
    pub(crate) parent: &'a str,
    pub(crate) child: &'a str,
    pub(crate) origin: Pose<f64>,
    pub(crate) axis: [f64; 3],
    /// `(lower, upper)` from `<limit>` where the element is present (a missing attribute is 0).
    pub(crate) limits: Option<(f64, f64)>,
}

/// A URDF's links and joints, checked: every joint's links exist, every link has at most one
/// parent joint, one root, no cycle.
struct Robot<'a> {
    name: &'a str,
    links: BTreeMap<&'a str, u32>,
    joints: Vec<UrdfJoint<'a>>,
    /// The joint whose child each link is.
    parent_joint: BTreeMap<&'a str, usize>,
}

impl<'a> Robot<'a> {
    fn read(doc: &'a Document<'a>) -> Result<Self> {
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            bail!("the root element is <{}>, not <robot>", robot.tag_name().name());
        }
        let line = |node: Node| doc.text_pos_at(node.range().start).row;
        let name =
            robot.attribute("name").ok_or_else(|| anyhow!("line {}: <robot> has no name attribute", line(robot)))?;

        // Links, by name, with the line that declares them.
        let mut links: BTreeMap<&str, u32> = BTreeMap::new();
        for node in robot.children().filter(|n| n.has_tag_name("link")) {
            let name =
                node.attribute("name").ok_or_else(|| anyhow!("line {}: <link> has no name attribute", line(node)))?;
            if let Some(first) = links.insert(name, line(node)) {
                bail!("line {}: link {name} is declared twice (first on line {first})", line(node));
            }
        }

        // Joints, by child link (every link has at most one parent joint).
        let mut joints: Vec<UrdfJoint> = Vec::new();
        let mut names: BTreeMap<&str, u32> = BTreeMap::new();
        for node in robot.children().filter(|n| n.has_tag_name("joint")) {
            let joint = read_joint(node, line(node))?;
            if let Some(first) = names.insert(joint.name, joint.line) {
                bail!("line {}: joint {} is declared twice (first on line {first})", joint.line, joint.name);
            }
            for (role, link) in [("parent", joint.parent), ("child", joint.child)] {
                if !links.contains_key(link) {
                    bail!("line {}: joint {}: {role} link {link} is not a <link> of the robot", joint.line, joint.name);
                }
            }
            if joint.parent == joint.child {
                bail!("line {}: joint {} connects link {} to itself", joint.line, joint.name, joint.parent);
            }
            joints.push(joint);
        }
        let mut parent_joint: BTreeMap<&str, usize> = BTreeMap::new();
        for (i, j) in joints.iter().enumerate() {
            if let Some(other) = parent_joint.insert(j.child, i) {
                bail!(
                    "line {}: link {} is the child of two joints, {} and {} (a URDF is a tree)",
                    j.line,
                    j.child,
                    joints[other].name,
                    j.name
                );
            }
        }

        // The root: the one link that is nobody's child.
        let roots: Vec<&str> = links.keys().copied().filter(|l| !parent_joint.contains_key(l)).collect();
        match roots.as_slice() {
            [_] => {}
            [] if links.is_empty() => bail!("the robot has no links"),
            [] => bail!("no root link: every link is the child of a joint, so the joints form a cycle"),
            several => {
                bail!(
                    "several root links: {} (all links must be connected by joints into one tree)",
                    several.join(", ")
                )
            }
        }
        // With one root and one parent per link, any link whose ancestors never reach the root is
        // on a cycle.
        for &link in links.keys() {
            let mut current = link;
            let mut steps = 0;
            while let Some(&j) = parent_joint.get(current) {
                current = joints[j].parent;
                steps += 1;
                if steps > joints.len() {
                    let cycle = cycle_through(link, &joints, &parent_joint);
                    bail!("the joints {} form a cycle", cycle.join(", "));
                }
            }
        }
        Ok(Self { name, links, joints, parent_joint })
    }

    /// `tip` checked to be a link (a joint's name gets a hint).
    fn link(&self, tip: &'a str) -> Result<&'a str> {
        if self.links.contains_key(tip) {
            return Ok(tip);
        }
        if let Some(j) = self.joints.iter().find(|j| j.name == tip) {
            bail!("tip {tip} is a joint, not a link: pass a link name (this joint's child link is {})", j.child);
        }
        bail!("tip link {tip} is not a <link> of the robot (links: {})", join(self.links.keys()))
    }

    /// The links no joint starts from.
    fn leaves(&self) -> Vec<&'a str> {
        let parents: BTreeSet<&str> = self.joints.iter().map(|j| j.parent).collect();
        self.links.keys().copied().filter(|l| !parents.contains(l)).collect()
    }

    /// The joints from the root to `link`, root first.
    fn path(&self, link: &str) -> Vec<&UrdfJoint<'a>> {
        let mut path = Vec::new();
        let mut current = link;
        while let Some(&j) = self.parent_joint.get(current) {
            path.push(&self.joints[j]);
            current = self.joints[j].parent;
        }
        path.reverse();
        path
    }
}

/// The arm's joint for the moving URDF joint `j` at `origin` (its own, with the fixed joints
/// before it folded in); `None` for a fixed joint, an error for a floating or planar one.
fn moving_joint(j: &UrdfJoint, origin: Pose<f64>, what: &str) -> Result<Option<JointSpec>> {
    let kind = match j.kind {
        UrdfKind::Fixed => return Ok(None),
        UrdfKind::Floating | UrdfKind::Planar => {
            let kind = if j.kind == UrdfKind::Floating { "floating" } else { "planar" };
            bail!(
                "line {}: joint {} is {kind}: {what} takes only revolute, continuous, prismatic and fixed joints",
                j.line,
                j.name
            );
        }
        UrdfKind::Moving(kind) => kind,
    };
    let (lower, upper) = match (kind, j.limits) {
        (JointKind::Continuous, _) => (-core::f64::consts::PI, core::f64::consts::PI),
        (_, Some(limits)) => limits,
        // read_joint already demands limits for revolute and prismatic joints.
        (_, None) => bail!("line {}: joint {} has no <limit lower upper>", j.line, j.name),
    };
    Ok(Some(JointSpec { name: j.name.to_string(), kind, origin, axis: j.axis, lower, upper }))
}

/// Reads the arm from URDF `text`: the chain from the root link to the link `tip`, or to the only
/// leaf link when `tip` is `None`.
pub fn parse(text: &str, tip: Option<&str>) -> Result<ArmSpec> {
    let doc = Document::parse(text).map_err(|e| anyhow!("not well-formed XML: {e}"))?;
    let robot = Robot::read(&doc)?;
    let tip = match tip {
        Some(tip) => robot.link(tip)?,
        None => match robot.leaves().as_slice() {
            [leaf] => *leaf,
            leaves => bail!("several tip links: name the tip (--tip, or tip= in Python), one of {}", leaves.join(", ")),
        },
    };

    // Fold fixed joints into the next moving joint's origin, or into the tool frame.
    let mut pending = Pose::identity();
    let mut specs = Vec::new();
    for j in robot.path(tip) {
        match moving_joint(j, pending.compose(&j.origin), "an arm chain")? {
            Some(spec) => {
                specs.push(spec);
                pending = Pose::identity();
            }
            None => pending = pending.compose(&j.origin),
        }
    }
    Ok(ArmSpec {
        name: robot.name.to_string(),
        joints: specs,
        tool: pending,
        servos: None,
        collision: None,
        masses: None,
    })
}

/// The leaf links of URDF `text` (no joint starts from them), by name: one for an arm, several
/// for a tree. Fails as [`parse`] does on a file it cannot read as a robot.
pub fn leaves(text: &str) -> Result<Vec<String>> {
    let doc = Document::parse(text).map_err(|e| anyhow!("not well-formed XML: {e}"))?;
    let robot = Robot::read(&doc)?;
    Ok(robot.leaves().into_iter().map(str::to_string).collect())
}

/// Reads a tree from URDF `text`: every joint on the paths from the root to the links `tips` (by
/// default every leaf), each an end effector named by its link. Fixed joints are folded into the
/// next moving joint's origin, or into the end effector's offset; the joints come parents first.
pub fn parse_tree(text: &str, tips: &[&str]) -> Result<TreeSpec> {
    let doc = Document::parse(text).map_err(|e| anyhow!("not well-formed XML: {e}"))?;
    let robot = Robot::read(&doc)?;
    let tips: Vec<&str> =
        if tips.is_empty() { robot.leaves() } else { tips.iter().map(|t| robot.link(t)).collect::<Result<_>>()? };
    for (i, tip) in tips.iter().enumerate() {
        if tips[..i].contains(tip) {
            bail!("tip link {tip} is named twice");
        }
    }
    let mut tree =
        TreeSpec { name: robot.name.to_string(), joints: Vec::new(), parents: Vec::new(), effectors: Vec::new() };
    // Per URDF joint already placed: the tree joint it became (None: folded), and per link the
    // last tree joint above it and the fixed offset since.
    let mut placed: BTreeMap<&str, (Option<usize>, Pose<f64>)> = BTreeMap::new();
    for tip in &tips {
        let (mut above, mut pending) = (None, Pose::identity());
        for j in robot.path(tip) {
            if let Some(&(index, offset)) = placed.get(j.child) {
                (above, pending) = (index, offset);
                continue;
            }
            match moving_joint(j, pending.compose(&j.origin), "a tree")? {
                Some(spec) => {
                    tree.joints.push(spec);
                    tree.parents.push(above);
                    above = Some(tree.joints.len() - 1);
                    pending = Pose::identity();
                }
                None => pending = pending.compose(&j.origin),
            }
            placed.insert(j.child, (above, pending));
        }
        tree.effectors.push(EffectorSpec { link: tip.to_string(), joint: above, offset: pending });
    }
    Ok(tree)
}

/// Reads the `<joint>` element `node`, declared on `line`.
pub(crate) fn read_joint<'a>(node: Node<'a, 'a>, line: u32) -> Result<UrdfJoint<'a>> {
    let name = node.attribute("name").ok_or_else(|| anyhow!("line {line}: <joint> has no name attribute"))?;
    let owner = &format!("joint {name}");
    let type_name = node.attribute("type").ok_or_else(|| anyhow!("line {line}: joint {name} has no type attribute"))?;
    let kind = match type_name {
        "revolute" => UrdfKind::Moving(JointKind::Revolute),
        "continuous" => UrdfKind::Moving(JointKind::Continuous),
        "prismatic" => UrdfKind::Moving(JointKind::Prismatic),
        "fixed" => UrdfKind::Fixed,
        "floating" => UrdfKind::Floating,
        "planar" => UrdfKind::Planar,
        other => bail!(
            "line {line}: joint {name} has unknown type {other:?} (expected revolute, continuous, prismatic, fixed, \
             floating or planar)"
        ),
    };
    let link_of = |tag: &str| -> Result<&'a str> {
        let element = child(node, tag).ok_or_else(|| anyhow!("line {line}: joint {name} has no <{tag} link=...>"))?;
        element
            .attribute("link")
            .ok_or_else(|| anyhow!("line {}: joint {name}: <{tag}> has no link attribute", line_of(element)))
    };
    let parent = link_of("parent")?;
    let child_link = link_of("child")?;

    let origin = origin(child(node, "origin"), owner)?;
    let axis = match child(node, "axis") {
        None => [1.0, 0.0, 0.0],
        Some(a) => vector(a, "xyz", owner, line_of(a))?
            .ok_or_else(|| anyhow!("line {}: joint {name}: <axis> has no xyz attribute", line_of(a)))?,
    };
    let limits = match child(node, "limit") {
        None => None,
        Some(l) => {
            // URDF specification: a missing lower or upper attribute of <limit> defaults to 0.
            let lower = scalar(l, "lower", owner, line_of(l))?.unwrap_or(0.0);
            let upper = scalar(l, "upper", owner, line_of(l))?.unwrap_or(0.0);
            if lower > upper {
                bail!("line {}: joint {name}: <limit> lower {lower} is above upper {upper}", line_of(l));
            }
            Some((lower, upper))
        }
    };
    if matches!(kind, UrdfKind::Moving(JointKind::Revolute | JointKind::Prismatic)) && limits.is_none() {
        bail!("line {line}: joint {name} is {type_name} and needs <limit lower=... upper=...>");
    }
    Ok(UrdfJoint { name, line, kind, parent, child: child_link, origin, axis, limits })
}

/// The pose an `<origin xyz rpy>` element gives (the identity when there is none); `owner` names
/// the joint or link it belongs to in errors.
pub(crate) fn origin(element: Option<Node>, owner: &str) -> Result<Pose<f64>> {
    let Some(o) = element else { return Ok(Pose::identity()) };
    let xyz = vector(o, "xyz", owner, line_of(o))?.unwrap_or([0.0; 3]);
    let rpy = vector(o, "rpy", owner, line_of(o))?.unwrap_or([0.0; 3]);
    Ok(Pose::from_xyz_rpy(xyz, rpy))
}

/// A URDF's `<link>` elements by name and each link's parent joint, read as [`read_joint`] reads
/// them: what the readers that walk the chain after [`parse`] (visuals, masses) start from.
pub(crate) type LinksAndJoints<'a, 'input> = (BTreeMap<&'a str, Node<'a, 'input>>, BTreeMap<&'a str, UrdfJoint<'a>>);

/// The links and parent joints of the `<robot>` in `doc`.
pub(crate) fn links_and_joints<'a>(doc: &'a Document<'a>) -> Result<LinksAndJoints<'a, 'a>> {
    let robot = doc.root_element();
    let links =
        robot.children().filter(|n| n.has_tag_name("link")).filter_map(|n| Some((n.attribute("name")?, n))).collect();
    let mut parent_joint = BTreeMap::new();
    for node in robot.children().filter(|n| n.has_tag_name("joint")) {
        let joint = read_joint(node, line_of(node))?;
        parent_joint.insert(joint.child, joint);
    }
    Ok((links, parent_joint))
}

/// The line of the file where `node` starts.
pub(crate) fn line_of(node: Node) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

/// The first child element called `tag`.
pub(crate) fn child<'a, 'input>(node: Node<'a, 'input>, tag: &str) -> Option<Node<'a, 'input>> {
    node.children().find(|n| n.has_tag_name(tag))
}

/// `owner` names the element's joint or link (`joint j1`) in errors.
pub(crate) fn number(text: &str, element: Node, attribute: &str, owner: &str, line: u32) -> Result<f64> {
    let tag = element.tag_name().name();
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => bail!("line {line}: {owner}: <{tag} {attribute}>: {text:?} is not a finite number"),
    }
}

/// An optional attribute holding one number.
pub(crate) fn scalar(element: Node, attribute: &str, owner: &str, line: u32) -> Result<Option<f64>> {
    element.attribute(attribute).map(|text| number(text.trim(), element, attribute, owner, line)).transpose()
}

/// An optional attribute holding three whitespace-separated numbers.
pub(crate) fn vector(element: Node, attribute: &str, owner: &str, line: u32) -> Result<Option<[f64; 3]>> {
    let Some(text) = element.attribute(attribute) else { return Ok(None) };
    let parts: Vec<&str> = text.split_whitespace().collect();
    if parts.len() != 3 {
        let tag = element.tag_name().name();
        bail!("line {line}: {owner}: <{tag} {attribute}=\"{text}\"> needs 3 numbers, found {}", parts.len());
    }
    let mut v = [0.0; 3];
    for (slot, part) in v.iter_mut().zip(parts) {
        *slot = number(part, element, attribute, owner, line)?;
    }
    Ok(Some(v))
}

/// The joints on the cycle that `start`'s ancestors run into, parent to child, starting with the one
/// declared first.
fn cycle_through<'a>(start: &str, joints: &[UrdfJoint<'a>], parent_joint: &BTreeMap<&str, usize>) -> Vec<&'a str> {
    // Walk far enough to be on the cycle, then collect it once around.
    let mut link = start;
    for _ in 0..=joints.len() {
        link = joints[parent_joint[link]].parent;
    }
    let mut cycle = Vec::new();
    let first = link;
    loop {
        let j = parent_joint[link];
        cycle.push(j);
        link = joints[j].parent;
        if link == first {
            break;
        }
    }
    cycle.reverse();
    let earliest = cycle.iter().enumerate().min_by_key(|(_, j)| **j).map_or(0, |(k, _)| k);
    cycle.rotate_left(earliest);
    cycle.into_iter().map(|j| joints[j].name).collect()
}

fn join<'a>(names: impl Iterator<Item = &'a &'a str>) -> String {
    names.copied().collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::nalgebra::{SVector, Vector3};
    use kinematics::SplitMix64;

    const SO101: &str = include_str!("../../tests/data/so101_new_calib.urdf");
    const SO100: &str = include_str!("../../tests/data/so100.urdf");

    fn names(spec: &ArmSpec) -> Vec<&str> {
        spec.joints.iter().map(|j| j.name.as_str()).collect()
    }

    fn error(text: &str, tip: Option<&str>) -> String {
        let e = parse(text, tip).expect_err("the URDF should be rejected");
        let message = format!("{e:#}");
        assert!(!message.contains('\n'), "error is not one line: {message}");
        message
    }

    /// A robot from joint snippets, with links `a` and `b` declared.
    fn robot(joints: &str) -> String {
        robot_links(&["a", "b"], joints)
    }

    fn robot_links(links: &[&str], joints: &str) -> String {
        let links: String = links.iter().map(|l| format!("<link name=\"{l}\"/>")).collect();
        format!("<robot name=\"test\">\n{links}\n{joints}\n</robot>")
    }

    #[test]
    fn so101_chain_to_gripper_frame() {
        let spec = parse(SO101, Some("gripper_frame_link")).unwrap();
        assert_eq!(spec.name, "so101_new_calib");
        assert_eq!(names(&spec), ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]);
        assert!(spec.joints.iter().all(|j| j.kind == JointKind::Revolute && j.axis == [0.0, 0.0, 1.0]));
        assert_eq!((spec.joints[4].lower, spec.joints[4].upper), (-2.74385, 2.84121));
        assert_eq!(spec.tool.translation, Vector3::new(-0.0079, -0.000218121, -0.0981274));
    }

    #[test]
    fn so101_matches_the_preset() {
        let imported = parse(SO101, Some("gripper_frame_link")).unwrap().chain::<f64, 5>().unwrap();
        let preset = ArmSpec::load("so101", None).unwrap().chain::<f64, 5>().unwrap();
        let mut rng = SplitMix64::new(101);
        for _ in 0..20 {
            let q = SVector::<f64, 5>::from_fn(|i, _| {
                let l = imported.joints()[i].limits;
                rng.uniform(l.lower, l.upper)
            });
            let (a, b) = (imported.tool_pose(&q), preset.tool_pose(&q));
            assert!((a.translation - b.translation).amax() <= 1e-9, "q = {q:?}");
            assert!((a.rotation - b.rotation).amax() <= 1e-9, "q = {q:?}");
        }
    }

    #[test]
    fn so101_without_tip_lists_the_leaves() {
        let message = error(SO101, None);
        assert!(
            message.contains("several tip links: name the tip (--tip, or tip= in Python), one of gripper_frame_link, moving_jaw_so101_v1_link"),
            "{message}"
        );
    }

    #[test]
    fn so100_chain_to_gripper() {
        let spec = parse(SO100, Some("gripper")).unwrap();
        assert_eq!(spec.name, "so_arm100");
        assert_eq!(names(&spec), ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]);
        assert_eq!(spec.tool, Pose::identity());
        assert_eq!(spec.joints[0].axis, [0.0, 1.0, 0.0]);
        assert_eq!((spec.joints[1].lower, spec.joints[1].upper), (0.0, 3.5));
        spec.chain::<f64, 5>().unwrap();
        // Its only leaf is the jaw, so without a tip the gripper joint is part of the chain.
        let whole = parse(SO100, None).unwrap();
        assert_eq!(whole.dof(), 6);
        assert_eq!(whole.joints[5].name, "gripper");
    }

    #[test]
    fn fixed_joints_fold_into_the_next_origin_and_the_tool() {
        let text = robot_links(
            &["a", "b", "c", "d", "e"],
            r#"
  <joint name="j2" type="revolute"><parent link="c"/><child link="d"/><origin xyz="0 0 1"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1"/></joint>
  <joint name="mount" type="fixed"><parent link="a"/><child link="b"/><origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="tool" type="fixed"><parent link="d"/><child link="e"/><origin xyz="0 0 0.5"/></joint>
  <joint name="j1" type="continuous"><parent link="b"/><child link="c"/><origin xyz="0 2 0"/><axis xyz="0 0 1"/></joint>
"#,
        );
        let spec = parse(&text, None).unwrap();
        assert_eq!(names(&spec), ["j1", "j2"]);
        // mount then j1's origin: (1, 0, 0) + Rz(90) (0, 2, 0) = (-1, 0, 0).
        let o = spec.joints[0].origin;
        assert!((o.translation - Vector3::new(-1.0, 0.0, 0.0)).amax() < 1e-12);
        assert!((o.rotation[(1, 0)] - 1.0).abs() < 1e-12);
        assert_eq!(spec.joints[0].kind, JointKind::Continuous);
        assert_eq!(spec.joints[1].origin, Pose::from_translation(Vector3::new(0.0, 0.0, 1.0)));
        assert_eq!(spec.tool, Pose::from_translation(Vector3::new(0.0, 0.0, 0.5)));
    }

    #[test]
    fn urdf_defaults() {
        let text = r#"<robot name="r"><link name="a"/><link name="b"/>
            <joint name="j" type="prismatic"><parent link="a"/><child link="b"/><limit lower="0" upper="0.1"/></joint>
            </robot>"#;
        let spec = parse(text, None).unwrap();
        assert_eq!(spec.joints[0].origin, Pose::identity());
        assert_eq!(spec.joints[0].axis, [1.0, 0.0, 0.0]);
        assert_eq!(spec.joints[0].kind, JointKind::Prismatic);
        let text = text.replace("<limit", r#"<origin rpy="0 0 0.5"/><limit"#);
        let spec = parse(&text, None).unwrap();
        assert_eq!(spec.joints[0].origin, Pose::from_xyz_rpy([0.0; 3], [0.0, 0.0, 0.5]));
    }

    #[test]
    fn errors_name_what_is_wrong() {
        let revolute = |attrs: &str, body: &str| {
            robot(&format!(r#"<joint name="j1" {attrs}><parent link="a"/><child link="b"/>{body}</joint>"#))
        };
        let cases: Vec<(String, Option<&str>, &str)> = vec![
            ("<robot name='r'><link name='a'>".into(), None, "not well-formed XML"),
            ("<root/>".into(), None, "not <robot>"),
            (revolute(r#"type="revolute""#, ""), None, "joint j1 is revolute and needs <limit"),
            (revolute(r#"type="prismatic""#, r#"<limit lower="1"/>"#), None, "lower 1 is above upper 0"),
            (revolute(r#"type="hinge""#, ""), None, "joint j1 has unknown type \"hinge\""),
            (revolute("", ""), None, "joint j1 has no type attribute"),
            (revolute(r#"type="floating""#, ""), Some("b"), "joint j1 is floating"),
            (revolute(r#"type="planar""#, ""), Some("b"), "joint j1 is planar"),
            (
                revolute(r#"type="continuous""#, r#"<origin xyz="0 0.1O 0"/>"#),
                None,
                "line 3: joint j1: <origin xyz>: \"0.1O\" is not a finite number",
            ),
            (revolute(r#"type="continuous""#, r#"<origin rpy="0 0"/>"#), None, "needs 3 numbers, found 2"),
            (revolute(r#"type="continuous""#, r#"<axis xyz="0 0 nan"/>"#), None, "\"nan\" is not a finite number"),
            (
                revolute(r#"type="revolute""#, r#"<limit lower="-1" upper="x"/>"#),
                None,
                "joint j1: <limit upper>: \"x\" is not a finite number",
            ),
            (
                robot(r#"<joint name="j1" type="fixed"><parent link="a"/><child link="z"/></joint>"#),
                None,
                "joint j1: child link z is not a <link> of the robot",
            ),
            (
                robot(r#"<joint name="j1" type="fixed"><child link="b"/></joint>"#),
                None,
                "joint j1 has no <parent link=...>",
            ),
            (robot_links(&["a", "b", "c"], ""), None, "several root links: a, b, c"),
            (
                robot_links(
                    &["a", "b", "c"],
                    r#"<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
                    <joint name="j2" type="fixed"><parent link="c"/><child link="b"/></joint>"#,
                ),
                None,
                "link b is the child of two joints, j1 and j2",
            ),
            (
                robot_links(
                    &["a", "b", "c", "d", "e"],
                    r#"<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
                    <joint name="j2" type="fixed"><parent link="a"/><child link="c"/></joint>
                    <joint name="j3" type="fixed"><parent link="a"/><child link="d"/></joint>
                    <joint name="j4" type="fixed"><parent link="e"/><child link="d"/></joint>"#,
                ),
                None,
                "link d is the child of two joints",
            ),
            (
                r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
                <joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>
                <joint name="y" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#
                    .into(),
                None,
                "the joints x, y form a cycle",
            ),
            (
                r#"<robot name="r"><link name="a"/><link name="b"/>
                <joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>
                <joint name="y" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#
                    .into(),
                None,
                "no root link",
            ),
            (
                r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
                <joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>
                <joint name="y" type="fixed"><parent link="c"/><child link="d"/></joint>
                <joint name="z" type="fixed"><parent link="d"/><child link="c"/></joint></robot>"#
                    .into(),
                None,
                "the joints y, z form a cycle",
            ),
            (
                robot(r#"<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>"#),
                Some("q"),
                "tip link q is not a <link> of the robot (links: a, b)",
            ),
            (
                robot(r#"<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>"#),
                Some("j1"),
                "tip j1 is a joint, not a link",
            ),
            (
                revolute(r#"type="revolute""#, r#"<limit lower="1" upper="-1"/>"#),
                None,
                "joint j1: <limit> lower 1 is above upper -1",
            ),
            ("<robot><link name='a'/></robot>".into(), None, "<robot> has no name attribute"),
            ("<robot name='r'><link name='a'/><link name='a'/></robot>".into(), None, "link a is declared twice"),
        ];
        for (text, tip, expected) in cases {
            let message = error(&text, tip);
            assert!(message.contains(expected), "expected {expected:?} in {message:?}");
        }
    }

    #[test]
    fn zero_axis_is_reported_by_chain() {
        let text = robot(
            r#"<joint name="lift" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 0"/>
            <limit lower="-1" upper="1"/></joint>"#,
        );
        let spec = parse(&text, Some("b")).unwrap();
        let e = spec.chain::<f64, 1>().unwrap_err().to_string();
        assert!(e.contains("zero") && e.contains("lift"), "{e}");
    }
}
