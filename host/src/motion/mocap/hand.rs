//! The human hand's motion: where the wrist is relative to the shoulder, and how the hand is
//! turned, frame by frame, then smoothed and sampled at keyframe times.
//!
//! Both are taken in the torso's frame (the shoulder's parent joint), not the world's: a person
//! walking, turning or leaning carries the arm with them, and the arm on the table does not walk.
//! In the rest pose the torso frame is the file's own axes.

use super::bvh::Bvh;
use super::chain::ArmChain;
use super::skeleton::{frame_poses, RootOffset};
use kinematics::nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// The hand in one frame, in the torso's frame (file units, file axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandSample {
    /// The wrist joint's position less the shoulder joint's.
    pub position: Vector3<f64>,
    /// The wrist joint's orientation in the T-pose rest (Q_A * D_wrist, see [`super::rest`]).
    pub orientation: UnitQuaternion<f64>,
}

/// The hand in every frame of `bvh`; `d_wrist` carries the wrist's frame to the T-pose rest.
pub fn hand_path(bvh: &Bvh, chain: &ArmChain, root: RootOffset, d_wrist: &UnitQuaternion<f64>) -> Vec<HandSample> {
    let [shoulder, _, wrist] = chain.joints;
    let torso = bvh.joints[shoulder].parent;
    (0..bvh.frames.len())
        .map(|f| {
            let p = frame_poses(bvh, f, root);
            let to_torso = torso.map_or_else(UnitQuaternion::identity, |t| p[t].orientation.inverse());
            HandSample {
                position: to_torso * (p[wrist].position - p[shoulder].position),
                orientation: to_torso * p[wrist].orientation * d_wrist,
            }
        })
        .collect()
}

/// The path at time `t` (s), averaged over the frames within `window` s centred on it: a box
/// filter as wide as the keyframe spacing, which takes out the capture's jitter and keeps what
/// the keyframes can carry (no aliasing of faster wobble into slow drift). Orientations are
/// averaged as sign-aligned quaternions, which is close to the mean rotation for the small spread
/// within one window.
pub fn sample(path: &[HandSample], frame_time: f64, t: f64, window: f64) -> HandSample {
    let last = path.len() - 1;
    let at = |s: f64| ((s / frame_time).round().max(0.0) as usize).min(last);
    let (lo, hi) = (at(t - window / 2.0), at(t + window / 2.0));
    let centre = path[at(t)].orientation;
    let mut position = Vector3::zeros();
    let mut q = Quaternion::new(0.0, 0.0, 0.0, 0.0);
    for s in &path[lo..=hi] {
        position += s.position;
        let o = s.orientation.into_inner();
        q += if o.dot(centre.as_ref()) < 0.0 { -o } else { o };
    }
    let n = (hi - lo + 1) as f64;
    HandSample { position: position / n, orientation: UnitQuaternion::try_new(q, 1e-9).unwrap_or(centre) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_averages_positions_around_the_time() {
        let path: Vec<HandSample> = (0..10)
            .map(|i| HandSample { position: Vector3::new(i as f64, 0.0, 0.0), orientation: UnitQuaternion::identity() })
            .collect();
        // Frames 3, 4, 5 around t = 0.4 s at 0.1 s a frame.
        assert!((sample(&path, 0.1, 0.4, 0.2).position.x - 4.0).abs() < 1e-12);
        // At the end the window is cut short: frames 8 and 9.
        assert!((sample(&path, 0.1, 0.9, 0.2).position.x - 8.5).abs() < 1e-12);
    }
}
