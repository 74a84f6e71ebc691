//! Collision bodies from a URDF's `<collision>` elements, one capsule (or sphere) each, on the
//! chain [`crate::urdf::parse`] imports: a `<sphere>` is a sphere; a `<cylinder>` the capsule on
//! its axis with its ends at the faces and its radius; a `<box>` the capsule along its longest
//! axis that holds it; a `<mesh>` (an STL file, scaled) the capsule fitted to its vertices
//! ([`super::fit`]). Every shape is turned into points and a radius about them, and the capsule
//! fitted to the points is grown by that radius, so one fit serves all four.
//!
//! A body goes on the joint whose moving frame carries its link: a link after fixed joints has
//! their origins composed into its pose (as [`crate::urdf_visuals`] places visuals). A link off
//! the chain hangs from it by a fixed joint (carried the same way) or by a moving one not in the
//! chain, such as a gripper's jaw: its body is fitted around its shape at [`SWEEP`] positions
//! through that joint's range, so it holds the jaw however far it is open.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinematics::collision::Capsule;
use kinematics::nalgebra::Vector3;
use kinematics::{JointKind, Pose};
use roxmltree::{Document, Node};

use super::fit::{self, capsule_around};
use super::{stl, BodySpec};
use crate::urdf::{self, child, line_of, UrdfJoint, UrdfKind};
use crate::urdf_visuals::resolve;
use crate::ArmSpec;

/// Positions of a moving joint off the chain (a jaw) its link's bodies are fitted over.
pub const SWEEP: usize = 17;

/// A fitted body and where it came from, for the comment beside it in an arm file.
#[derive(Clone, Debug, PartialEq)]
pub struct Fitted {
    /// The body.
    pub body: BodySpec,
    /// "link gripper_link: mesh assets/x.stl, 24012 vertices".
    pub source: String,
}

/// The arm to `tip` (as [`urdf::parse`] reads it) and a body for every `<collision>` of the links
/// it carries; mesh files resolved against `base_dir` (the URDF's folder) as visuals are. Fails in
/// one line naming the link and the file when a mesh cannot be read.
pub fn bodies(text: &str, tip: Option<&str>, base_dir: &Path) -> Result<(ArmSpec, Vec<Fitted>)> {
    let arm = urdf::parse(text, tip)?;
    let doc = Document::parse(text)?;
    let robot = doc.root_element();
    let links: BTreeMap<&str, Node> =
        robot.children().filter(|n| n.has_tag_name("link")).filter_map(|n| Some((n.attribute("name")?, n))).collect();
    let mut joints: Vec<UrdfJoint> = Vec::new();
    for node in robot.children().filter(|n| n.has_tag_name("joint")) {
        joints.push(urdf::read_joint(node, line_of(node))?);
    }
    // The chain's joints from the root, found by their names in `arm`, and the links on it.
    let by_child: BTreeMap<&str, &UrdfJoint> = joints.iter().map(|j| (j.child, j)).collect();
    let tip = match tip {
        Some(tip) => tip,
        None => {
            let parents: Vec<&str> = joints.iter().map(|j| j.parent).collect();
            links.keys().copied().find(|l| !parents.contains(l)).ok_or_else(|| anyhow!("the robot has no leaf link"))?
        }
    };
    let mut path: Vec<&UrdfJoint> = Vec::new();
    let mut root = tip;
    while let Some(joint) = by_child.get(root) {
        path.push(joint);
        root = joint.parent;
    }
    path.reverse();
    let on_chain: Vec<&str> = std::iter::once(root).chain(path.iter().map(|j| j.child)).collect();

    let mut out = Vec::new();
    let mut reader = Reader { links: &links, base_dir, out: &mut out };
    // Each link of the chain, in the frame it moves with, and what hangs off it.
    let (mut frame, mut pending) = (None::<usize>, Pose::identity());
    let visit = |link: &str, frame: Option<usize>, pending: &Pose<f64>, reader: &mut Reader| -> Result<()> {
        reader.link(link, frame, &[*pending])?;
        reader.hanging(link, frame, vec![*pending], &joints, &on_chain)
    };
    visit(root, frame, &pending, &mut reader)?;
    for joint in &path {
        if joint.kind == UrdfKind::Fixed {
            pending = pending.compose(&joint.origin);
        } else {
            frame = Some(frame.map_or(0, |f| f + 1));
            pending = Pose::identity();
        }
        visit(joint.child, frame, &pending, &mut reader)?;
    }
    Ok((arm, out))
}

/// Reads links' `<collision>` elements into bodies.
struct Reader<'a, 'b> {
    links: &'a BTreeMap<&'a str, Node<'a, 'a>>,
    base_dir: &'b Path,
    out: &'b mut Vec<Fitted>,
}

impl Reader<'_, '_> {
    /// The bodies of `link`, whose pose in joint frame `frame` is each of `poses` (one, or the
    /// positions of a swept joint).
    fn link(&mut self, link: &str, frame: Option<usize>, poses: &[Pose<f64>]) -> Result<()> {
        let Some(node) = self.links.get(link) else { return Ok(()) };
        let elements: Vec<Node> = node.children().filter(|n| n.has_tag_name("collision")).collect();
        let base = link.strip_suffix("_link").unwrap_or(link);
        for (k, element) in elements.iter().enumerate() {
            let owner = format!("link {link} <collision>");
            let line = line_of(*element);
            let origin = urdf::origin(child(*element, "origin"), &owner)?;
            let geometry = child(*element, "geometry")
                .and_then(|g| g.children().find(|n| n.is_element()))
                .ok_or_else(|| anyhow!("line {line}: {owner} has no <geometry> shape"))?;
            let (points, extra, what) = self.shape(geometry, &owner)?;
            let placed: Vec<Vector3<f64>> = poses
                .iter()
                .flat_map(|pose| {
                    let at = pose.compose(&origin);
                    points.iter().map(move |p| at.rotation * p + at.translation)
                })
                .collect();
            let capsule =
                capsule_around(&placed).ok_or_else(|| anyhow!("line {line}: {owner}: {what} has no points"))?;
            let name = if k == 0 { base.to_string() } else { format!("{base}.{}", k + 1) };
            let swept =
                if poses.len() > 1 { format!(", over {} positions of its joint", poses.len()) } else { String::new() };
            self.out.push(Fitted {
                body: BodySpec { name, link: frame, capsule: grown(&capsule, extra) },
                source: format!("link {link}: {what}{swept}"),
            });
        }
        Ok(())
    }

    /// Points in the shape's frame, the radius about them, and a few words on it.
    fn shape(&self, geometry: Node, owner: &str) -> Result<(Vec<Vector3<f64>>, f64, String)> {
        let line = line_of(geometry);
        let positive = |attribute: &str| -> Result<f64> {
            match urdf::scalar(geometry, attribute, owner, line)? {
                Some(v) if v >= 0.0 => Ok(v),
                Some(v) => {
                    bail!("line {line}: {owner}: <{} {attribute}> is {v}, not a size", geometry.tag_name().name())
                }
                None => bail!("line {line}: {owner}: <{}> has no {attribute}", geometry.tag_name().name()),
            }
        };
        Ok(match geometry.tag_name().name() {
            "sphere" => {
                let r = positive("radius")?;
                (vec![Vector3::zeros()], r, format!("sphere of radius {r}"))
            }
            "cylinder" => {
                let (r, length) = (positive("radius")?, positive("length")?);
                let half = Vector3::new(0.0, 0.0, length / 2.0);
                (vec![-half, half], r, format!("cylinder {r} x {length}"))
            }
            "box" => {
                let size = urdf::vector(geometry, "size", owner, line)?
                    .ok_or_else(|| anyhow!("line {line}: {owner}: <box> has no size"))?;
                if size.iter().any(|s| *s < 0.0) {
                    bail!("line {line}: {owner}: <box size> {size:?} has a negative size");
                }
                let corners = (0..8)
                    .map(|k| {
                        let sign = |bit: u32| if k & (1 << bit) == 0 { -0.5 } else { 0.5 };
                        Vector3::new(size[0] * sign(0), size[1] * sign(1), size[2] * sign(2))
                    })
                    .collect();
                (corners, 0.0, format!("box {} x {} x {}", size[0], size[1], size[2]))
            }
            "mesh" => {
                let filename = geometry
                    .attribute("filename")
                    .ok_or_else(|| anyhow!("line {line}: {owner}: <mesh> has no filename attribute"))?;
                let scale = urdf::vector(geometry, "scale", owner, line)?.unwrap_or([1.0; 3]);
                let file = resolve(filename, self.base_dir)
                    .map_err(|reason| anyhow!("line {line}: {owner}: mesh {filename}: {reason}"))?;
                let vertices = stl::read(&file).map_err(|e| anyhow!("line {line}: {owner}: mesh {filename}: {e:#}"))?;
                let count = vertices.len();
                let scaled = vertices.into_iter().map(|v| v.component_mul(&Vector3::from(scale))).collect();
                (scaled, 0.0, format!("mesh {filename}, {count} vertices"))
            }
            other => bail!("line {line}: {owner}: <{other}> is not a URDF geometry (box, cylinder, sphere or mesh)"),
        })
    }

    /// The links hanging from `link` off the chain, carried by it through fixed joints, or swept
    /// through the range of a moving joint; `poses` is `link`'s.
    fn hanging(
        &mut self,
        link: &str,
        frame: Option<usize>,
        poses: Vec<Pose<f64>>,
        joints: &[UrdfJoint],
        on_chain: &[&str],
    ) -> Result<()> {
        for joint in joints.iter().filter(|j| j.parent == link && !on_chain.contains(&j.child)) {
            let motions: Vec<Pose<f64>> = match joint.kind {
                UrdfKind::Fixed => vec![Pose::identity()],
                UrdfKind::Moving(kind) => sweep(kind, joint.axis, joint.limits),
                // Floating and planar joints cannot be part of an arm; what hangs there is not.
                UrdfKind::Floating | UrdfKind::Planar => continue,
            };
            let placed: Vec<Pose<f64>> =
                poses.iter().flat_map(|p| motions.iter().map(move |m| p.compose(&joint.origin).compose(m))).collect();
            self.link(joint.child, frame, &placed)?;
            self.hanging(joint.child, frame, placed, joints, on_chain)?;
        }
        Ok(())
    }
}

/// The motions of a joint at [`SWEEP`] positions through its range.
fn sweep(kind: JointKind, axis: [f64; 3], limits: Option<(f64, f64)>) -> Vec<Pose<f64>> {
    let (lower, upper) = match (kind, limits) {
        (JointKind::Continuous, _) | (_, None) => (-core::f64::consts::PI, core::f64::consts::PI),
        (_, Some(range)) => range,
    };
    let axis = Vector3::from(axis);
    (0..SWEEP)
        .map(|k| {
            let q = lower + (upper - lower) * k as f64 / (SWEEP - 1) as f64;
            match kind {
                JointKind::Prismatic => Pose::from_translation(axis.normalize() * q),
                _ => Pose::from_axis_angle(&axis, q),
            }
        })
        .collect()
}

/// `c` with `extra` more radius, rounded up to the fit's grid.
fn grown(c: &Capsule<f64>, extra: f64) -> Capsule<f64> {
    let steps = ((c.radius + extra) / fit::ROUNDING - 1e-9).ceil();
    let radius: f64 = format!("{:.4}", steps * fit::ROUNDING).parse().unwrap_or(c.radius + extra);
    Capsule { radius, ..*c }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::fit::depth;
    use crate::collision::stl::tests::binary_stl;

    const ROBOT: &str = r#"<robot name="t">
  <link name="base_link">
    <collision><origin xyz="0 0 0.02"/><geometry><cylinder radius="0.05" length="0.04"/></geometry></collision>
  </link>
  <link name="upper_link">
    <collision><origin xyz="0.1 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><box size="0.04 0.02 0.2"/></geometry></collision>
    <collision><geometry><sphere radius="0.03"/></geometry></collision>
  </link>
  <link name="mount_link"/>
  <link name="hand_link">
    <collision><origin xyz="0 0 0.01"/><geometry><mesh filename="hand.stl" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <link name="jaw_link">
    <collision><geometry><box size="0.05 0.01 0.01"/></geometry></collision>
  </link>
  <joint name="pan" type="revolute"><parent link="base_link"/><child link="upper_link"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
  <joint name="mount" type="fixed"><parent link="upper_link"/><child link="mount_link"/><origin xyz="0.2 0 0"/></joint>
  <joint name="wrist" type="revolute"><parent link="mount_link"/><child link="hand_link"/><origin xyz="0 0 0.03"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1"/></joint>
  <joint name="jaw" type="revolute"><parent link="hand_link"/><child link="jaw_link"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="1.5707963267948966"/></joint>
</robot>"#;

    fn write_hand(dir: &Path) {
        // A 40 x 20 x 10 mm slab in millimetres, two triangles per face are not needed: its
        // corners are what the fit sees.
        let c = |x: f32, y: f32, z: f32| [x, y, z];
        let corners = [
            [c(-20.0, -10.0, -5.0), c(20.0, -10.0, -5.0), c(20.0, 10.0, -5.0)],
            [c(-20.0, 10.0, 5.0), c(20.0, 10.0, 5.0), c(-20.0, -10.0, 5.0)],
            [c(20.0, -10.0, 5.0), c(-20.0, 10.0, -5.0), c(20.0, 10.0, 5.0)],
        ];
        std::fs::write(dir.join("hand.stl"), binary_stl(&corners)).unwrap();
    }

    fn body<'a>(fitted: &'a [Fitted], name: &str) -> &'a Fitted {
        fitted.iter().find(|f| f.body.name == name).unwrap_or_else(|| panic!("no body {name}: {fitted:#?}"))
    }

    #[test]
    fn shapes_become_capsules_on_the_frames_that_carry_them() {
        let dir = tempfile::tempdir().unwrap();
        write_hand(dir.path());
        let (arm, fitted) = bodies(ROBOT, Some("jaw_link"), dir.path()).unwrap();
        assert_eq!(arm.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>(), ["pan", "wrist", "jaw"]);
        let names: Vec<&str> = fitted.iter().map(|f| f.body.name.as_str()).collect();
        assert_eq!(names, ["base", "upper", "upper.2", "hand", "jaw"]);
        let close = |a: &Vector3<f64>, b: [f64; 3]| (a - Vector3::from(b)).amax() < 1e-12;
        let ends = |c: &Capsule<f64>, p: [f64; 3], q: [f64; 3]| {
            (close(&c.a, p) && close(&c.b, q)) || (close(&c.a, q) && close(&c.b, p))
        };

        // The cylinder: its axis from face to face, its radius.
        let base = body(&fitted, "base");
        assert_eq!(base.body.link, None);
        assert!(ends(&base.body.capsule, [0.0, 0.0, 0.0], [0.0, 0.0, 0.04]), "{base:?}");
        assert_eq!(base.body.capsule.radius, 0.0501);
        // The box stands along z in its own frame and is turned onto x: the capsule from x = 0 to
        // 0.2 through its end faces, radius its cross-section's half diagonal hypot(0.02, 0.01).
        let upper = body(&fitted, "upper");
        assert_eq!(upper.body.link, Some(0));
        assert!(ends(&upper.body.capsule, [0.0, 0.0, 0.0], [0.2, 0.0, 0.0]), "{upper:?}");
        assert_eq!(upper.body.capsule.radius, 0.0225);
        let sphere = &body(&fitted, "upper.2").body.capsule;
        assert!(close(&sphere.a, [0.0; 3]) && close(&sphere.b, [0.0; 3]) && sphere.radius == 0.0301, "{sphere:?}");
        // The mesh, in mm scaled to m, lifted by its origin: on the wrist's frame.
        let hand = body(&fitted, "hand");
        assert_eq!(hand.body.link, Some(1));
        assert!(hand.source.contains("mesh hand.stl, 9 vertices"), "{}", hand.source);
        for corner in [[-0.02, -0.01, 0.005], [0.02, 0.01, 0.015], [0.02, -0.01, 0.015]] {
            assert!(depth(&hand.body.capsule, &Vector3::from(corner)) >= 0.0, "{corner:?} outside {hand:?}");
        }
    }

    #[test]
    fn a_jaw_off_the_chain_is_fitted_over_its_range() {
        let dir = tempfile::tempdir().unwrap();
        write_hand(dir.path());
        let (arm, fitted) = bodies(ROBOT, Some("hand_link"), dir.path()).unwrap();
        assert_eq!(arm.dof(), 2);
        let jaw = body(&fitted, "jaw");
        assert_eq!(jaw.body.link, Some(1));
        assert!(jaw.source.ends_with(&format!("over {SWEEP} positions of its joint")), "{}", jaw.source);
        // The jaw's box at 0 and at 90 degrees about z, 5 cm above the wrist: both held.
        for (x, y) in [(0.025, 0.005), (-0.025, -0.005), (0.005, 0.025), (-0.005, -0.025)] {
            for z in [0.045, 0.055] {
                assert!(depth(&jaw.body.capsule, &Vector3::new(x, y, z)) >= 0.0, "({x}, {y}, {z}) outside {jaw:?}");
            }
        }
    }

    #[test]
    fn a_mesh_that_cannot_be_read_is_one_line_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = format!("{:#}", bodies(ROBOT, Some("jaw_link"), dir.path()).unwrap_err());
        assert!(e.starts_with("line 12: link hand_link <collision>: mesh hand.stl: no file"), "{e}");
        std::fs::write(dir.path().join("hand.stl"), b"not a mesh").unwrap();
        let e = format!("{:#}", bodies(ROBOT, Some("jaw_link"), dir.path()).unwrap_err());
        assert!(e.contains("mesh hand.stl: mesh ") && e.contains("hand.stl: not an STL file: 10 bytes"), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }
}
