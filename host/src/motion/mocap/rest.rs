//! Reference (rest) poses: which rest a skeleton has, and its arm's rotations carried over to the
//! T-pose rest.
//!
//! The rest is the pose with every rotation zero: a T-pose (arms horizontal), an A-pose (arms about
//! 45 degrees down) or arms hanging down. The same motion written for two rests has different
//! joint rotations. Retargeting joint i between rests A and B (course lecture 4): with D_i the
//! rotation between joint i's rest bone directions (D_i applied to B's direction gives A's), the
//! local rotation in B is R_B,i = D_parent^-1 * R_A,i * D_i. Along a chain this telescopes to
//! Q_B,i = Q_A,i * D_i for the world orientations: the bones point the same way in both, and a
//! frame attached to a joint differs by the constant D_i. Every joint outside the arm keeps its
//! rest (D = identity), so the shoulder's parent (the clavicle or spine) is unchanged.

use super::bvh::Bvh;
use super::chain::ArmChain;
use anyhow::{bail, Result};
use kinematics::nalgebra::{UnitQuaternion, Vector3};

/// A rest pose of the arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Rest {
    /// Arms horizontal, out to the side.
    TPose,
    /// Arms about 45 degrees below horizontal.
    APose,
    /// Arms hanging straight down.
    ArmsDown,
}

impl Rest {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Rest::TPose => "t-pose",
            Rest::APose => "a-pose",
            Rest::ArmsDown => "arms-down",
        }
    }

    /// The rest of that [`Rest::name`], if any.
    pub fn from_name(name: &str) -> Option<Self> {
        [Rest::TPose, Rest::APose, Rest::ArmsDown].into_iter().find(|r| r.name() == name)
    }

    /// Degrees below horizontal of this rest's arm bones.
    fn droop_deg(self) -> f64 {
        match self {
            Rest::TPose => 0.0,
            Rest::APose => 45.0,
            Rest::ArmsDown => 90.0,
        }
    }
}

/// BVH's usual up axis. Files with another up axis are rare; their rest then reads as unknown.
pub const UP: Vector3<f64> = Vector3::new(0.0, 1.0, 0.0);

/// Where joint `j` is in the rest pose (offsets summed; every rotation zero).
pub fn rest_position(bvh: &Bvh, mut j: usize) -> Vector3<f64> {
    let mut p = bvh.joints[j].offset;
    while let Some(parent) = bvh.joints[j].parent {
        p += bvh.joints[parent].offset;
        j = parent;
    }
    p
}

/// The rest direction of the bone leaving joint `j`: toward `next` when given, else toward its
/// first descendant (or End Site) away from it. Zero-length offsets (CMU's finger bases) are
/// passed through. `None` for a joint with nothing beyond it.
fn bone_direction(bvh: &Bvh, j: usize, next: Option<usize>) -> Option<Vector3<f64>> {
    let from = rest_position(bvh, j);
    let to = match next {
        Some(n) => rest_position(bvh, n),
        None => {
            let mut k = j;
            loop {
                if let Some(end) = bvh.joints[k].end_site.filter(|e| e.norm() > 1e-9) {
                    break rest_position(bvh, k) + end;
                }
                let child = bvh.joints.iter().position(|c| c.parent == Some(k))?;
                if bvh.joints[child].offset.norm() > 1e-9 {
                    break rest_position(bvh, child);
                }
                k = child;
            }
        }
    };
    (to - from).try_normalize(1e-12)
}

/// The arm's rest as read from its skeleton, with the reasons.
#[derive(Clone, Debug, PartialEq)]
pub struct RestReading {
    /// The rest the upper arm's angle falls in.
    pub rest: Rest,
    /// Degrees the upper arm's rest bone points below horizontal.
    pub upper_arm_droop_deg: f64,
    /// Horizontal unit vector out to the arm's side: where a T-pose arm points.
    pub lateral: Vector3<f64>,
}

/// Reads the rest of `chain` in `bvh`: upper arm within 22.5 degrees of horizontal is a T-pose,
/// 22.5 to 67.5 degrees down an A-pose, further down arms down; pointing up is refused.
pub fn detect(bvh: &Bvh, chain: &ArmChain) -> Result<RestReading> {
    let [shoulder, elbow, _] = chain.joints;
    let Some(upper) = bone_direction(bvh, shoulder, Some(elbow)) else {
        bail!("the upper arm ({} to {}) has zero length in the rest pose", chain.names[0], chain.names[1]);
    };
    let droop = (-upper.dot(&UP)).clamp(-1.0, 1.0).asin().to_degrees();
    let rest = match droop {
        d if d < -22.5 => bail!(
            "the upper arm points {:.0} degrees above horizontal at rest: not a T-pose, A-pose or arms-down \
             (give --reference)",
            -d
        ),
        d if d < 22.5 => Rest::TPose,
        d if d < 67.5 => Rest::APose,
        _ => Rest::ArmsDown,
    };
    // Out to the side: where the shoulder sits from the root, else where the upper arm leans.
    let horizontal = |v: Vector3<f64>| (v - UP * v.dot(&UP)).try_normalize(0.05 * v.norm().max(1e-12));
    let lateral =
        horizontal(rest_position(bvh, shoulder) - rest_position(bvh, 0)).or_else(|| horizontal(upper)).ok_or_else(
            || anyhow::anyhow!("cannot tell which side {} is on: it sits above the root at rest", chain.names[0]),
        )?;
    Ok(RestReading { rest, upper_arm_droop_deg: droop, lateral })
}

/// The constant rotations D of the three chain joints from the file's rest (A) to the T-pose (B):
/// D_i applied to the T-pose bone direction (`lateral`) gives the file's. With `declared`, the
/// file's directions are that rest's ideal ones (for files whose offsets are not trusted);
/// otherwise they are read from the offsets.
pub fn rest_to_t_pose(
    bvh: &Bvh,
    chain: &ArmChain,
    reading: &RestReading,
    declared: Option<Rest>,
) -> [UnitQuaternion<f64>; 3] {
    let [s, e, w] = chain.joints;
    let ideal = |rest: Rest| {
        let d = rest.droop_deg().to_radians();
        reading.lateral * d.cos() - UP * d.sin()
    };
    let nexts = [Some(e), Some(w), None];
    core::array::from_fn(|k| {
        let file = match declared {
            Some(rest) => Some(ideal(rest)),
            None => bone_direction(bvh, [s, e, w][k], nexts[k]),
        };
        file.and_then(|a| UnitQuaternion::rotation_between(&reading.lateral, &a))
            // Opposite directions (a bone pointing inward): half a turn about the up axis.
            .unwrap_or_else(|| {
                if file.is_some() {
                    UnitQuaternion::from_axis_angle(
                        &kinematics::nalgebra::Unit::new_normalize(UP),
                        core::f64::consts::PI,
                    )
                } else {
                    UnitQuaternion::identity()
                }
            })
    })
}

/// R_B,i = D_parent^-1 * R_A,i * D_i: joint i's local rotation carried from rest A to rest B.
pub fn retarget_local(
    d_parent: &UnitQuaternion<f64>,
    r_a: &UnitQuaternion<f64>,
    d_i: &UnitQuaternion<f64>,
) -> UnitQuaternion<f64> {
    d_parent.inverse() * r_a * d_i
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::mocap::bvh::parse;
    use crate::motion::mocap::chain::find;
    use crate::motion::mocap::skeleton::{frame_poses, local_rotation, RootOffset};

    fn arm(dx: f64, dy: f64, frame: &str) -> Bvh {
        parse(&format!(
            "HIERARCHY\nROOT Hips\n{{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
             JOINT RightArm\n{{\nOFFSET -1 5 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nJOINT RightForeArm\n{{\n\
             OFFSET {dx} {dy} 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nJOINT RightHand\n{{\nOFFSET {dx} {dy} 0\n\
             CHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{{\nOFFSET {dx} {dy} 0\n}}\n}}\n}}\n}}\n}}\n\
             MOTION\nFrames: 1\nFrame Time: 0.1\n{frame}\n"
        ))
        .unwrap()
    }

    #[test]
    fn rests_are_read_from_the_upper_arm() {
        let zero = "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
        for (dx, dy, rest) in [(-2.0, 0.0, Rest::TPose), (-1.4, -1.4, Rest::APose), (0.0, -2.0, Rest::ArmsDown)] {
            let b = arm(dx, dy, zero);
            let r = detect(&b, &find(&b, None).unwrap()).unwrap();
            assert_eq!(r.rest, rest);
            assert!((r.lateral - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        }
        let b = arm(0.0, 2.0, zero);
        assert!(detect(&b, &find(&b, None).unwrap()).unwrap_err().to_string().contains("90 degrees above"));
    }

    /// The A-pose arm raised to horizontal by its shoulder (Rz -45) with the elbow bent 90 degrees
    /// (Rz 90): in the T-pose rest the shoulder's rotation is the identity and the elbow's Rz(90),
    /// worked out by hand (module doc), and the bones point the same way.
    #[test]
    fn a_pose_to_t_pose_on_a_two_joint_arm() {
        let b = arm(-1.0, -1.0, "0 0 0 0 0 0 -45 0 0 90 0 0 0 0 0");
        let chain = find(&b, None).unwrap();
        let reading = detect(&b, &chain).unwrap();
        assert_eq!(reading.rest, Rest::APose);
        let d = rest_to_t_pose(&b, &chain, &reading, None);
        let z45 = UnitQuaternion::from_euler_angles(0.0, 0.0, 45f64.to_radians());
        for di in &d {
            assert!(di.angle_to(&z45) < 1e-12, "{di:?}");
        }
        let [s, e, _] = chain.joints;
        let r_s = retarget_local(&UnitQuaternion::identity(), &local_rotation(&b, 0, s), &d[0]);
        let r_e = retarget_local(&d[0], &local_rotation(&b, 0, e), &d[1]);
        assert!(r_s.angle() < 1e-12, "{r_s:?}");
        let z90 = UnitQuaternion::from_euler_angles(0.0, 0.0, 90f64.to_radians());
        assert!(r_e.angle_to(&z90) < 1e-12, "{r_e:?}");
        // The T-pose forearm (along -x at rest) under Q_B = R_B,s * R_B,e points where the A-pose
        // forearm points: straight down.
        let forearm_b = r_s * r_e * Vector3::new(-1.0, 0.0, 0.0);
        let p = frame_poses(&b, 0, RootOffset::Add);
        let forearm_a = (p[3].position - p[2].position).normalize();
        assert!((forearm_b - forearm_a).norm() < 1e-12 && (forearm_a - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn a_declared_rest_uses_its_ideal_directions() {
        let b = arm(-2.0, 0.0, "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0");
        let chain = find(&b, None).unwrap();
        let reading = detect(&b, &chain).unwrap();
        let d = rest_to_t_pose(&b, &chain, &reading, Some(Rest::ArmsDown));
        // Down is the lateral direction (-x) turned 90 degrees about +z.
        assert!((d[0] * Vector3::new(-1.0, 0.0, 0.0) - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        let same = rest_to_t_pose(&b, &chain, &reading, None);
        assert!(same.iter().all(|q| q.angle() < 1e-12));
    }
}
