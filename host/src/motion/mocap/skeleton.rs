//! Forward kinematics of a BVH skeleton: every joint's position and orientation in a frame.
//!
//! A joint's local rotation is the product of its rotation channels in the order the file gives
//! them (for `Zrotation Xrotation Yrotation`, Rz * Rx * Ry: intrinsic, as SciPy's
//! `from_euler('ZXY', ...)` with upper-case letters), in degrees; then Q_i = Q_parent * R_i and
//! p_i = p_parent + Q_parent * t_i, where t_i is the joint's OFFSET, or its position channels
//! where it has them (a non-root joint with 6 channels: exporters that write them put the whole
//! local translation there, as three.js's BVHLoader reads them). The root is the exception, a
//! setting ([`RootOffset`]): some exporters add the root's OFFSET to its translation channels,
//! others copy the first frame's translation into OFFSET, which must then not be added again.

use super::bvh::{Bvh, Channel};
use kinematics::nalgebra::{Unit, UnitQuaternion, Vector3};

/// What the root's OFFSET means when the root also has position channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RootOffset {
    /// Root position = OFFSET + the translation channels.
    Add,
    /// Root position = the translation channels alone (OFFSET repeats the first frame's).
    Ignore,
}

impl RootOffset {
    /// Every setting with its name (as typed and as reports write it) and what it does, for the
    /// command line's `--root-offset` and its help.
    pub const NAMES: [(&'static str, RootOffset, &'static str); 2] = [
        ("add", RootOffset::Add, "Root position = OFFSET + the translation channels"),
        (
            "ignore",
            RootOffset::Ignore,
            "Root position = the translation channels alone (OFFSET repeats the first frame's)",
        ),
    ];

    /// The setting of that name, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _, _)| *n == name).map(|&(_, r, _)| r)
    }

    /// What `bvh` seems to use: [`RootOffset::Ignore`] when the root's non-zero OFFSET equals its
    /// first frame's translation (adding it would count it twice), else [`RootOffset::Add`]
    /// (which, for the usual zero OFFSET, changes nothing).
    pub fn detect(bvh: &Bvh) -> Self {
        let root = &bvh.joints[0];
        let translation = local_translation(bvh, 0, 0);
        let has_position = root.channels.iter().any(|c| matches!(c, Channel::Position(_)));
        let copied = root.offset.norm() > 1e-9 && (translation - root.offset).norm() <= 1e-6 * root.offset.norm();
        if has_position && copied {
            RootOffset::Ignore
        } else {
            RootOffset::Add
        }
    }
}

/// A joint's world pose in one frame (file units, file axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointPose {
    /// Position of the joint.
    pub position: Vector3<f64>,
    /// Orientation of the joint's frame (after its own rotation).
    pub orientation: UnitQuaternion<f64>,
}

fn axis(i: usize) -> Unit<Vector3<f64>> {
    match i {
        0 => Vector3::x_axis(),
        1 => Vector3::y_axis(),
        _ => Vector3::z_axis(),
    }
}

/// The local rotation of `joint` in `frame`: one quaternion product per rotation channel, left to
/// right in file order (intrinsic rotations).
pub fn local_rotation(bvh: &Bvh, frame: usize, joint: usize) -> UnitQuaternion<f64> {
    let values = bvh.values(frame, joint);
    bvh.joints[joint].channels.iter().zip(values).fold(UnitQuaternion::identity(), |q, (c, v)| match c {
        Channel::Rotation(i) => q * UnitQuaternion::from_axis_angle(&axis(*i), v.to_radians()),
        Channel::Position(_) => q,
    })
}

/// The position channels of `joint` in `frame` (zero for axes it lacks).
fn local_translation(bvh: &Bvh, frame: usize, joint: usize) -> Vector3<f64> {
    let mut t = Vector3::zeros();
    for (c, v) in bvh.joints[joint].channels.iter().zip(bvh.values(frame, joint)) {
        if let Channel::Position(i) = c {
            t[*i] = *v;
        }
    }
    t
}

/// Every joint's world pose in `frame`, in joint order.
pub fn frame_poses(bvh: &Bvh, frame: usize, root_offset: RootOffset) -> Vec<JointPose> {
    let mut out: Vec<JointPose> = Vec::with_capacity(bvh.joints.len());
    for (i, j) in bvh.joints.iter().enumerate() {
        let has_position = j.channels.iter().any(|c| matches!(c, Channel::Position(_)));
        let translation = match (j.parent, has_position) {
            (_, false) => j.offset,
            (None, true) if root_offset == RootOffset::Add => j.offset + local_translation(bvh, frame, i),
            (_, true) => local_translation(bvh, frame, i),
        };
        let rotation = local_rotation(bvh, frame, i);
        out.push(match j.parent {
            None => JointPose { position: translation, orientation: rotation },
            Some(p) => {
                let parent = out[p];
                JointPose {
                    position: parent.position + parent.orientation * translation,
                    orientation: parent.orientation * rotation,
                }
            }
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::mocap::bvh::parse;

    fn close(a: Vector3<f64>, b: [f64; 3]) -> bool {
        (a - Vector3::from(b)).norm() < 1e-12
    }

    /// Root at (1,2,3) + channels; one arm joint 2 units along x, its End Site 1 unit along x.
    fn file(root: &str, arm: &str, frame: &str) -> String {
        format!(
            "HIERARCHY\nROOT R\n{{\nOFFSET 1 2 3\nCHANNELS 6 Xposition Yposition Zposition {root}\nJOINT A\n{{\nOFFSET 2 0 0\n\
             CHANNELS 3 {arm}\nJOINT H\n{{\nOFFSET 1 0 0\nCHANNELS 3 {arm}\nEnd Site\n{{\nOFFSET 1 0 0\n}}\n}}\n}}\n}}\n\
             MOTION\nFrames: 1\nFrame Time: 0.1\n{frame}\n"
        )
    }

    #[test]
    fn rotations_compose_in_file_order() {
        // Z 90 then X 90 (intrinsic): Rz * Rx maps x -> y, and y -> z... hand-computed:
        // Rz(90) = [[0,-1,0],[1,0,0],[0,0,1]], Rx(90) = [[1,0,0],[0,0,-1],[0,1,0]];
        // Rz*Rx = [[0,0,1],[1,0,0],[0,1,0]]: x -> (0,1,0), y -> (0,0,1), z -> (1,0,0).
        let b =
            parse(&file("Zrotation Xrotation Yrotation", "Zrotation Xrotation Yrotation", "0 0 0 0 0 0 90 90 0 0 0 0"))
                .unwrap();
        let r = local_rotation(&b, 0, 1);
        assert!(close(r * Vector3::x(), [0.0, 1.0, 0.0]));
        assert!(close(r * Vector3::y(), [0.0, 0.0, 1.0]));
        // The other order, X then Z: Rx * Rz maps x -> (0,0,1)... Rx*Rz = [[0,-1,0],[0,0,-1],[1,0,0]].
        let b =
            parse(&file("Zrotation Xrotation Yrotation", "Xrotation Zrotation Yrotation", "0 0 0 0 0 0 90 90 0 0 0 0"))
                .unwrap();
        let r = local_rotation(&b, 0, 1);
        assert!(close(r * Vector3::x(), [0.0, 0.0, 1.0]));
        assert!(close(r * Vector3::y(), [-1.0, 0.0, 0.0]));
    }

    #[test]
    fn positions_follow_parent_orientations() {
        // Root translated by (10,0,0) and turned 90 degrees about Y; arm bent 90 degrees about Z.
        let b = parse(&file(
            "Zrotation Xrotation Yrotation",
            "Zrotation Xrotation Yrotation",
            "10 0 0 0 0 90 90 0 0 0 0 0",
        ))
        .unwrap();
        let p = frame_poses(&b, 0, RootOffset::Add);
        assert!(close(p[0].position, [11.0, 2.0, 3.0]));
        // Ry(90) maps x to -z: the arm joint sits 2 units along -z from the root.
        assert!(close(p[1].position, [11.0, 2.0, 1.0]));
        // Q_arm = Ry(90) * Rz(90): the hand's offset x -> Rz: y -> Ry: y.
        assert!(close(p[2].position, [11.0, 3.0, 1.0]));
        let ignored = frame_poses(&b, 0, RootOffset::Ignore);
        assert!(close(ignored[0].position, [10.0, 0.0, 0.0]));
    }

    #[test]
    fn a_root_offset_copied_from_the_first_frame_is_detected() {
        let copied =
            parse(&file("Zrotation Xrotation Yrotation", "Zrotation Xrotation Yrotation", "1 2 3 0 0 0 0 0 0 0 0 0"))
                .unwrap();
        assert_eq!(RootOffset::detect(&copied), RootOffset::Ignore);
        let added =
            parse(&file("Zrotation Xrotation Yrotation", "Zrotation Xrotation Yrotation", "0 0 0 0 0 0 0 0 0 0 0 0"))
                .unwrap();
        assert_eq!(RootOffset::detect(&added), RootOffset::Add);
    }
}
