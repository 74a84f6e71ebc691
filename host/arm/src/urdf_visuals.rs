//! The visual meshes of a URDF arm, placed in the frames of the chain [`urdf::parse`] imports, so
//! that the browser view (`armctl view --urdf`) can draw the links over the kinematic chain: a
//! mesh in frame k moves with `DynArm::joint_frames(q)[k - 1]`, one in frame 0 stays on the base.

use crate::urdf::{self, child, UrdfJoint, UrdfKind};
use anyhow::{anyhow, bail, Result};
use kinematics::Pose;
use roxmltree::Document;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A visual mesh of a link of the chain, placed in one of the chain's frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    /// 0 for the base (the root link's frame); k in 1..=dof for the frame of the k-th moving joint
    /// after its motion, which is `DynArm::joint_frames(q)[k - 1]`.
    pub frame: usize,
    /// The mesh's pose in that frame.
    pub origin: Pose<f64>,
    /// The mesh file, resolved; it exists.
    pub file: PathBuf,
    /// Scale along the mesh's axes (`<mesh scale>`, 1 1 1 when absent).
    pub scale: [f64; 3],
}

/// The `<visual><geometry><mesh filename=.. scale=..>` elements of the links on the chain from the
/// root link to `tip` (or the only leaf, as [`urdf::parse`] chooses), placed in chain frames: frame
/// 0 is the root link's frame (the base), frame k (1..=dof) is the frame of the k-th moving joint
/// after its motion, i.e. the frame its child link is in. A link reached through fixed joints after
/// moving joint k (or from the root) is in frame k with the fixed joints' transforms composed into
/// `origin` (the same folding `urdf::parse` does). `file` is resolved: a relative filename against
/// `base_dir` (the URDF's folder); `package://NAME/rest` against base_dir, then base_dir's ancestors
/// (the first where `rest` or `NAME/rest` exists); `file://` absolute. Meshes whose file does not
/// exist are returned in a second list, one line each with the reason, rather than failing, so the
/// view can say which it could not find. Non-mesh geometries (box, cylinder, sphere) are skipped.
pub fn visuals(text: &str, tip: Option<&str>, base_dir: &Path) -> Result<(Vec<Visual>, Vec<String>)> {
    // `parse` checks the tree, the joints and the tip, with its errors; the walk below relies on it.
    let spec = urdf::parse(text, tip)?;
    let doc = Document::parse(text)?;
    let (links, parent_joint) = urdf::links_and_joints(&doc)?;
    let parents: BTreeSet<&str> = parent_joint.values().map(|j| j.parent).collect();
    let tip = match tip {
        Some(tip) => tip,
        None => *links.keys().find(|l| !parents.contains(*l)).ok_or_else(|| anyhow!("the robot has no leaf link"))?,
    };
    let mut path: Vec<&UrdfJoint> = Vec::new();
    let mut root = tip;
    while let Some(joint) = parent_joint.get(root) {
        path.push(joint);
        root = joint.parent;
    }
    path.reverse();

    let mut found = Vec::new();
    let mut missing = Vec::new();
    let (mut frame, mut pending) = (0, Pose::identity());
    let mut add = |link: &str, frame: usize, pending: &Pose<f64>| -> Result<()> {
        let owner = format!("link {link} <visual>");
        for visual in links[link].children().filter(|n| n.has_tag_name("visual")) {
            let Some(mesh) = child(visual, "geometry").and_then(|g| child(g, "mesh")) else { continue };
            let line = urdf::line_of(mesh);
            let Some(filename) = mesh.attribute("filename") else {
                bail!("line {line}: {owner}: <mesh> has no filename attribute")
            };
            let scale = urdf::vector(mesh, "scale", &owner, line)?.unwrap_or([1.0; 3]);
            let origin = pending.compose(&urdf::origin(child(visual, "origin"), &owner)?);
            match resolve(filename, base_dir) {
                Ok(file) => found.push(Visual { frame, origin, file, scale }),
                Err(reason) => missing.push(format!("link {link}: mesh {filename}: {reason}")),
            }
        }
        Ok(())
    };
    add(root, frame, &pending)?;
    for joint in path {
        // As in `urdf::parse`: a fixed joint's transform waits for the next moving joint, which
        // starts a new frame.
        if joint.kind == UrdfKind::Fixed {
            pending = pending.compose(&joint.origin);
        } else {
            frame += 1;
            pending = Pose::identity();
        }
        add(joint.child, frame, &pending)?;
    }
    debug_assert_eq!(frame, spec.dof());
    Ok((found, missing))
}

/// Where the mesh `filename` is, or why it is not there.
pub(crate) fn resolve(filename: &str, base_dir: &Path) -> Result<PathBuf, String> {
    if let Some(package_path) = filename.strip_prefix("package://") {
        let Some((package, rest)) = package_path.split_once('/') else {
            return Err("a package:// filename needs a package name and a path".into());
        };
        // Without ROS to look packages up, the package is taken to be the URDF's folder or one above
        // it, or a folder of that name in one of them. Absolute, so that the search climbs past the
        // working directory when base_dir is relative.
        let dir = std::path::absolute(base_dir).unwrap_or_else(|_| base_dir.to_path_buf());
        return dir
            .ancestors()
            .flat_map(|d| [d.join(rest), d.join(package).join(rest)])
            .find(|p| p.is_file())
            .ok_or_else(|| format!("no {rest} or {package}/{rest} in {} or a folder above it", dir.display()));
    }
    let file = match filename.strip_prefix("file://") {
        Some(absolute) => PathBuf::from(absolute),
        None if filename.contains("://") => return Err("only relative, package:// and file:// names are read".into()),
        None => base_dir.join(filename),
    };
    if file.is_file() {
        Ok(file)
    } else {
        Err(format!("no file {}", file.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dof;
    use kinematics::nalgebra::Matrix3;

    /// A folder of its own (`tempfile`'s), removed when dropped (also when a test fails).
    struct TempDir(tempfile::TempDir);

    impl TempDir {
        fn new(label: &str) -> Self {
            Self(tempfile::Builder::new().prefix(&format!("armctl-{label}-")).tempdir().unwrap())
        }

        fn path(&self) -> &std::path::Path {
            self.0.path()
        }

        /// Creates an empty file at `relative`, and its folders.
        fn touch(&self, relative: &str) -> PathBuf {
            let file = self.path().join(relative);
            std::fs::create_dir_all(file.parent().unwrap()).unwrap();
            std::fs::write(&file, b"").unwrap();
            file
        }
    }

    fn assert_close(actual: &Pose<f64>, expected: &Pose<f64>, tolerance: f64) {
        let error =
            (actual.rotation - expected.rotation).amax().max((actual.translation - expected.translation).amax());
        assert!(error <= tolerance, "{actual:?} is not {expected:?}");
    }

    fn pose(rotation: Matrix3<f64>, translation: [f64; 3]) -> Pose<f64> {
        Pose { rotation, translation: translation.into() }
    }

    const ROBOT: &str = r#"<robot name="t">
  <link name="base">
    <visual><origin xyz="0 0 0.1"/><geometry><mesh filename="base.stl"/></geometry></visual>
    <visual><geometry><box size="1 1 1"/></geometry></visual>
  </link>
  <link name="plate">
    <visual><geometry><mesh filename="package://tools/meshes/plate.stl"/></geometry></visual>
  </link>
  <link name="upper">
    <visual><origin xyz="0 0 0.2" rpy="1.5707963267948966 0 0"/>
      <geometry><mesh filename="package://robot/meshes/upper.stl" scale="0.001 0.002 0.003"/></geometry></visual>
    <visual><geometry><cylinder radius="0.1" length="1"/></geometry></visual>
  </link>
  <link name="hand">
    <visual><origin xyz="0 1 0" rpy="0 0 1.5707963267948966"/>
      <geometry><mesh filename="file://TEMP/abs/hand.stl"/></geometry></visual>
    <visual><geometry><mesh filename="meshes/missing.stl"/></geometry></visual>
    <visual><geometry><sphere radius="0.1"/></geometry></visual>
  </link>
  <link name="side"><visual><geometry><mesh filename="side.stl"/></geometry></visual></link>
  <joint name="plate_mount" type="fixed"><parent link="base"/><child link="plate"/><origin xyz="0 0 0.5"/></joint>
  <joint name="j1" type="revolute"><parent link="plate"/><child link="upper"/><origin xyz="0 0 1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
  <joint name="hand_mount" type="fixed"><parent link="upper"/><child link="hand"/>
    <origin xyz="2 0 0" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="side_mount" type="fixed"><parent link="base"/><child link="side"/></joint>
</robot>"#;

    #[test]
    fn inline_urdf_visuals_in_chain_frames() {
        let temp = TempDir::new("urdf-visuals-inline");
        let base_dir = temp.path().join("robot/urdf");
        let base = temp.touch("robot/urdf/base.stl");
        let plate = temp.touch("tools/meshes/plate.stl"); // package://tools as a folder above the URDF's
        let upper = temp.touch("robot/meshes/upper.stl"); // package://robot as the URDF's parent folder
        let hand = temp.touch("abs/hand.stl");
        temp.touch("robot/urdf/side.stl"); // off the chain to the tip: not listed
        let text = ROBOT.replace("TEMP", temp.path().to_str().unwrap());

        let (found, missing) = visuals(&text, Some("hand"), &base_dir).unwrap();
        let files: Vec<&Path> = found.iter().map(|v| v.file.as_path()).collect();
        assert_eq!(files, [&base, &plate, &upper, &hand]);
        assert_eq!(found.iter().map(|v| v.frame).collect::<Vec<_>>(), [0, 0, 1, 1]);
        assert_eq!(found[2].scale, [0.001, 0.002, 0.003]);
        assert!(found.iter().enumerate().all(|(i, v)| i == 2 || v.scale == [1.0; 3]));
        let identity = Matrix3::identity();
        assert_close(&found[0].origin, &pose(identity, [0.0, 0.0, 0.1]), 0.0);
        // Reached from the root through plate_mount: in the base frame, lifted by it.
        assert_close(&found[1].origin, &pose(identity, [0.0, 0.0, 0.5]), 0.0);
        // Rx(90 degrees).
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        assert_close(&found[2].origin, &pose(rx, [0.0, 0.0, 0.2]), 1e-15);
        // hand_mount then the visual: (2, 0, 0) + Rz(90) (0, 1, 0) = (1, 0, 0), rotated Rz(180).
        let rz180 = Matrix3::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
        assert_close(&found[3].origin, &pose(rz180, [1.0, 0.0, 0.0]), 1e-15);

        assert_eq!(missing.len(), 1, "{missing:?}");
        let expected =
            format!("link hand: mesh meshes/missing.stl: no file {}", base_dir.join("meshes/missing.stl").display());
        assert_eq!(missing[0], expected);

        // Without a tip, side is a second leaf: the same error as urdf::parse.
        let e = format!("{:#}", visuals(&text, None, &base_dir).unwrap_err());
        assert!(e.contains("several tip links"), "{e}");
        let e =
            format!("{:#}", visuals(&text.replace("0.001 0.002 0.003", "1 1"), Some("hand"), &base_dir).unwrap_err());
        assert!(e.contains("line 11: link upper <visual>: <mesh scale=\"1 1\"> needs 3 numbers"), "{e}");
    }

    #[test]
    // The joint origins below are the URDF's own digits (3.14159, 1.5708), not approximations of pi.
    #[allow(clippy::approx_constant)]
    fn so101_meshes_missing_and_frames_match_joint_frames() {
        let path = Path::new("/work/shared/reference/urdf/so101_new_calib.urdf");
        let Ok(text) = std::fs::read_to_string(path) else { return };
        let tip = Some("gripper_frame_link");
        let (found, missing) = visuals(&text, tip, path.parent().unwrap()).unwrap();
        // The STLs are not shipped: every visual of the 6 links to the gripper frame is missing.
        assert!(found.is_empty());
        assert_eq!(missing.len(), 16, "{missing:#?}");
        assert!(missing.iter().all(|m| m.contains(": mesh assets/") && m.contains("no file")), "{missing:#?}");

        // With every mesh present, all are listed, in the frames of their links.
        let temp = TempDir::new("urdf-visuals-so101");
        let doc = Document::parse(&text).unwrap();
        for mesh in doc.descendants().filter(|n| n.has_tag_name("mesh")) {
            temp.touch(mesh.attribute("filename").unwrap());
        }
        let (found, missing) = visuals(&text, tip, temp.path()).unwrap();
        assert!(missing.is_empty(), "{missing:#?}");
        let spec = urdf::parse(&text, tip).unwrap();
        let mut per_frame = vec![0; spec.dof() + 1];
        for v in &found {
            per_frame[v.frame] += 1;
        }
        // base, shoulder, upper arm, lower arm, wrist, gripper.
        assert_eq!(per_frame, [4, 3, 2, 3, 2, 2]);

        // The wrist roll follower on gripper_link, at q = 0, by hand from the URDF's joint origins.
        let follower = found.iter().find(|v| v.file.ends_with("wrist_roll_follower_so101_v1.stl")).unwrap();
        assert_eq!(follower.frame, 5);
        let arm = dof::build(spec).unwrap();
        let world = arm.joint_frames(&[0.0; 5]).unwrap()[follower.frame - 1].compose(&follower.origin);
        let by_hand = [
            ([0.0388353, -8.97657e-09, 0.0624], [3.14159, 4.18253e-17, -3.14159]), // shoulder_pan
            ([-0.0303992, -0.0182778, -0.0542], [-1.5708, -1.5708, 0.0]),          // shoulder_lift
            ([-0.11257, -0.028, 1.73763e-16], [-3.63608e-16, 8.74301e-16, 1.5708]), // elbow_flex
            ([-0.1349, 0.0052, 3.62355e-17], [4.02456e-15, 8.67362e-16, -1.5708]), // wrist_flex
            ([5.55112e-17, -0.0611, 0.0181], [1.5708, 0.0486795, 3.14159]),        // wrist_roll
            ([8.32667e-17, -0.000218214, 0.000949706], [-3.14159, -5.55112e-17, 0.0]), // the visual
        ]
        .iter()
        .fold(Pose::identity(), |pose, (xyz, rpy)| pose.compose(&Pose::from_xyz_rpy(*xyz, *rpy)));
        assert_close(&world, &by_hand, 1e-12);
    }
}
