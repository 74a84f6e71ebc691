//! What the arm can reach, read by forward kinematics of joint vectors drawn with a fixed seed
//! (the same on every run): how far its tool gets from its shoulder, which sets the human-to-arm
//! scale, and a voxel map of the tool positions above the base, in which the hand's path is
//! placed ([`Workspace::place`]).

use crate::arm::dof::DynArm;
use anyhow::{bail, Result};
use kinematics::nalgebra::Vector3;
use kinematics::SplitMix64;

/// Joint vectors drawn: enough to fill the voxels of the presets' workspaces (a few thousand
/// voxels) several times over, in tens of milliseconds.
const SAMPLES: usize = 40_000;
/// The generator's seed, fixed so that a file retargets the same way every time.
const SEED: u64 = 0xB5_4D;
/// Voxels along the reach: the map's resolution (about 2 cm on an SO-101).
const VOXELS_PER_REACH: f64 = 24.0;
/// Path points scored per candidate placement (evenly spaced keyframes).
const SCORED_POINTS: usize = 200;

/// The arm's workspace as sampled.
#[derive(Clone, Debug, PartialEq)]
pub struct Workspace {
    /// The shoulder: joint 2's position (joint 1's on a one-joint arm) at the middle of the
    /// limits.
    pub shoulder: Vector3<f64>,
    /// The largest distance of the tool from the shoulder (m).
    pub reach: f64,
    /// The mean tool position above the base (z > 0).
    pub centre: Vector3<f64>,
    /// Voxel edge (m).
    voxel: f64,
    /// The map's lowest corner.
    origin: Vector3<f64>,
    /// Voxels along x, y, z.
    dims: [usize; 3],
    /// Whether some sample's tool lay in each voxel (x fastest).
    occupied: Vec<bool>,
}

/// Samples the workspace of `arm`. Only tool positions above the base's plane (z > 0) count:
/// the arm stands on a table.
pub fn sample(arm: &dyn DynArm) -> Result<Workspace> {
    if arm.spec().dof() == 0 {
        bail!("arm {} has no joints to move", arm.spec().name);
    }
    let shoulder_joint = 1.min(arm.spec().dof() - 1);
    let shoulder = arm.joint_frames(&arm.middle())?[shoulder_joint].translation;
    let mut rng = SplitMix64::new(SEED);
    let mut tools = Vec::with_capacity(SAMPLES);
    let mut reach = 0.0f64;
    for _ in 0..SAMPLES {
        let tool = arm.tool_pose(&arm.random_configuration(&mut rng))?.translation;
        reach = reach.max((tool - shoulder).norm());
        if tool.z > 0.0 {
            tools.push(tool);
        }
    }
    if reach <= 1e-9 || tools.is_empty() {
        bail!("arm {}: its tool never gets above the base or away from its shoulder", arm.spec().name);
    }
    let centre = tools.iter().sum::<Vector3<f64>>() / tools.len() as f64;
    let voxel = reach / VOXELS_PER_REACH;
    let lo = tools.iter().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = tools.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
    let dims = [0, 1, 2].map(|i| ((hi[i] - lo[i]) / voxel).floor() as usize + 1);
    let mut ws =
        Workspace { shoulder, reach, centre, voxel, origin: lo, dims, occupied: vec![false; dims.iter().product()] };
    for p in &tools {
        if let Some(i) = ws.index(p) {
            ws.occupied[i] = true;
        }
    }
    Ok(ws)
}

impl Workspace {
    fn index(&self, p: &Vector3<f64>) -> Option<usize> {
        let mut at = [0usize; 3];
        for i in 0..3 {
            let v = ((p[i] - self.origin[i]) / self.voxel).floor();
            if !(v >= 0.0 && (v as usize) < self.dims[i]) {
                return None;
            }
            at[i] = v as usize;
        }
        Some(at[0] + self.dims[0] * (at[1] + self.dims[1] * at[2]))
    }

    /// Whether a sampled tool position lay in `p`'s voxel.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        self.index(p).is_some_and(|i| self.occupied[i])
    }

    /// The shift that puts the most of `path` inside the map: the middle of the path's bounding
    /// box tried at every occupied voxel's centre, scored on up to 200 evenly spaced points, ties
    /// going to the shift nearest [`Workspace::centre`]. Deterministic: the same path and arm give
    /// the same shift. Returns the shift and the share of scored points inside.
    pub fn place(&self, path: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
        let lo = path.iter().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
        let hi = path.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
        let middle = (lo + hi) / 2.0;
        let every = path.len().div_ceil(SCORED_POINTS).max(1);
        let scored: Vec<Vector3<f64>> = path.iter().step_by(every).map(|p| p - middle).collect();
        let mut best = (self.centre - middle, 0usize, f64::INFINITY);
        for (i, _) in self.occupied.iter().enumerate().filter(|(_, o)| **o) {
            let at = [i % self.dims[0], (i / self.dims[0]) % self.dims[1], i / (self.dims[0] * self.dims[1])];
            let centre = self.origin + Vector3::from(at.map(|a| (a as f64 + 0.5) * self.voxel));
            let inside = scored.iter().filter(|p| self.contains(&(centre + *p))).count();
            let distance = (centre - self.centre).norm();
            if inside > best.1 || (inside == best.1 && distance < best.2) {
                best = (centre - middle, inside, distance);
            }
        }
        (best.0, best.1 as f64 / scored.len().max(1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_path_is_placed_inside_the_so101_workspace() {
        let arm = crate::arm::dof::build(crate::arm::ArmSpec::load("so101", None).unwrap()).unwrap();
        let ws = sample(arm.as_ref()).unwrap();
        assert!(ws.reach > 0.3 && ws.reach < 0.6, "{}", ws.reach);
        let path: Vec<Vector3<f64>> = (0..50).map(|i| Vector3::new(0.001 * i as f64, 0.0, -1.0)).collect();
        let (shift, inside) = ws.place(&path);
        assert_eq!(inside, 1.0);
        assert!(path.iter().all(|p| ws.contains(&(p + shift))));
    }
}
