//! What the page draws the arm from: `GET /api/arm`'s chain, and the visual meshes of a URDF
//! (`--urdf`) placed in the chain's frames.
//!
//! A URDF of an arm often carries more moving joints than the arm drives: the SO-101's has the
//! gripper's jaw after its five arm joints. Its first joints must be the arm's, one for one; a mesh
//! past the arm's last joint is drawn with the joints between at zero, so the jaw is drawn shut.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use kinematics::{JointKind, Pose};
use serde_json::{json, Value};

use super::telemetry::frame;
use crate::arm::servos::servos_of;
use crate::arm::urdf_visuals::{visuals, Visual};
use crate::arm::ArmSpec;

/// A mesh in a frame of the arm: 0 the base, k the frame of joint k after its motion.
pub struct Mesh {
    /// The frame.
    pub frame: usize,
    /// Its pose in that frame.
    pub origin: Pose<f64>,
    /// The STL file.
    pub file: PathBuf,
    /// Scale per axis.
    pub scale: [f64; 3],
}

/// A URDF read for its meshes, before it is matched to the arm the firmware runs.
pub struct Urdf {
    shown: String,
    chain: ArmSpec,
    visuals: Vec<Visual>,
    missing: Vec<String>,
}

impl Urdf {
    /// Reads `file`: its chain to `tip` (or its only leaf) and its visual meshes, those whose
    /// file is missing set apart.
    pub fn read(file: &Path, tip: Option<&str>) -> Result<Self> {
        let shown = file.display().to_string();
        let text = std::fs::read_to_string(file).with_context(|| format!("--urdf: cannot read {shown}"))?;
        let chain = crate::arm::urdf::parse(&text, tip).with_context(|| format!("--urdf {shown}"))?;
        let base = file.parent().unwrap_or(Path::new("."));
        let (visuals, missing) = visuals(&text, tip, base).with_context(|| format!("--urdf {shown}"))?;
        let missing = missing.into_iter().map(|m| format!("--urdf {shown}: {m}")).collect();
        Ok(Self { shown, chain, visuals, missing })
    }

    /// The meshes over `arm`, whose joints must be the URDF's first ones; and one line for each
    /// mesh whose file was not found.
    pub fn over(self, arm: &ArmSpec) -> Result<(Vec<Mesh>, Vec<String>)> {
        let Self { shown, chain, visuals, missing } = self;
        if chain.dof() < arm.dof() {
            bail!(
                "--urdf {shown}: its chain has {} moving joints, the arm {} has {}",
                chain.dof(),
                arm.name,
                arm.dof()
            );
        }
        for (j, (theirs, ours)) in chain.joints.iter().zip(&arm.joints).enumerate() {
            if theirs.kind != ours.kind || !same_axis(theirs.axis, ours.axis) {
                bail!(
                    "--urdf {shown}: its joint {} ({}) is not the arm {}'s joint {} ({}): another kind or axis",
                    j + 1,
                    theirs.name,
                    arm.name,
                    j + 1,
                    ours.name
                );
            }
        }
        let meshes = visuals
            .into_iter()
            .map(|Visual { frame, origin, file, scale }| {
                // Past the arm's last joint: the joints between at zero, from the arm's last frame.
                let (frame, origin) = if frame > arm.dof() {
                    let between =
                        chain.joints[arm.dof()..frame].iter().fold(Pose::identity(), |p, j| p.compose(&j.origin));
                    (arm.dof(), between.compose(&origin))
                } else {
                    (frame, origin)
                };
                Mesh { frame, origin, file, scale }
            })
            .collect();
        Ok((meshes, missing))
    }
}

fn same_axis(a: [f64; 3], b: [f64; 3]) -> bool {
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    (dot / (norm(a) * norm(b)) - 1.0).abs() < 1e-6
}

/// `GET /api/arm`: the chain, for drawing (see docs/view.md, the API).
pub fn arm_json(arm: &ArmSpec, queue_capacity: usize, meshes: &[Mesh]) -> Result<Value> {
    let joints: Vec<Value> = arm
        .joints
        .iter()
        .map(|j| {
            let kind = match j.kind {
                JointKind::Revolute => "revolute",
                JointKind::Continuous => "continuous",
                JointKind::Prismatic => "prismatic",
                JointKind::Fixed => "fixed",
            };
            json!({"name": j.name, "kind": kind, "lower": j.lower, "upper": j.upper, "axis": j.axis})
        })
        .collect();
    // The longest the chain can stretch: for the grid and the camera.
    let reach = arm.joints.iter().map(|j| j.origin.translation.norm()).sum::<f64>() + arm.tool.translation.norm();
    let gripper = servos_of(arm).and_then(|s| s.gripper).map(|_| json!({"min_percent": 0, "max_percent": 100}));
    let meshes: Vec<Value> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut v = frame(&m.origin);
            v["frame"] = json!(m.frame);
            v["url"] = json!(format!("/api/mesh/{i}"));
            v["scale"] = json!(m.scale);
            v
        })
        .collect();
    Ok(json!({
        "name": arm.name,
        "dof": arm.dof(),
        "joints": joints,
        "orientation": arm.dof() >= 6,
        "gripper": gripper,
        "reach": reach,
        "queue_capacity": queue_capacity,
        "meshes": meshes,
    }))
}
