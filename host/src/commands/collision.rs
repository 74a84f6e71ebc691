//! `armctl collision`: an arm's collision geometry made from its URDF ([`fit`]: a capsule per
//! `<collision>` element, the allowed pairs found by sampling, written as the arm file's
//! `[collision]` section) and a configuration checked against it ([`check`]: the closest pair
//! and whether it keeps the margin).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use serde::Serialize;

use crate::arm::collision::allowed::{self, SAMPLES, SEED, SHARE};
use crate::arm::collision::obstacle::Surroundings;
use crate::arm::collision::toml::{self as collision_toml, AllowedGroup, Notes};
use crate::arm::collision::{self, CollisionSpec, ObstacleSpec, MAX_BODIES, MAX_OBSTACLES, TABLE};
use crate::arm::ArmSpec;

/// What `collision fit` is asked.
#[derive(Clone, Debug, PartialEq)]
pub struct FitRequest {
    /// The URDF whose `<collision>` elements are fitted.
    pub urdf: PathBuf,
    /// Its tip link (default: its only leaf).
    pub tip: Option<String>,
    /// The margin every checked pair keeps (m).
    pub margin: f64,
    /// The command as typed, written in the section's header.
    pub command: String,
}

/// A fitted body, as reported.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BodyReport {
    /// Its name.
    pub name: String,
    /// The joint that carries it, or `base`.
    pub link: String,
    /// One end of its core segment (m, in that joint's moving frame).
    pub a: [f64; 3],
    /// The other end.
    pub b: [f64; 3],
    /// Its radius (m).
    pub radius: f64,
    /// What it was fitted to.
    pub source: String,
}

/// An allowed pair and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PairReport {
    /// The two names.
    pub pair: [String; 2],
    /// Why it is never checked.
    pub reason: String,
}

/// What `collision fit` found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// The arm's name.
    pub arm: String,
    /// The margin (m).
    pub margin: f64,
    /// The bodies.
    pub bodies: Vec<BodyReport>,
    /// The pairs never checked.
    pub allowed: Vec<PairReport>,
    /// The arm file's `[collision]` section.
    pub toml: String,
}

/// Fits the geometry of `request.urdf`'s collision elements and finds its allowed pairs.
pub fn fit(request: &FitRequest) -> Result<FitReport> {
    if !(request.margin.is_finite() && request.margin >= 0.0) {
        bail!("--margin {}: a distance of zero or more (m)", request.margin);
    }
    if !request.urdf.extension().is_some_and(|e| e.eq_ignore_ascii_case("urdf")) {
        bail!(
            "collision fit reads a URDF's <collision> elements, and {} is not a .urdf file (a preset's or an arm \
             file's geometry is shown by `armctl collision check`)",
            request.urdf.display()
        );
    }
    let (arm, spec, notes) = fitted(request)?;
    let mut toml = String::new();
    collision_toml::write(&mut toml, &spec, &arm, &notes);
    let link = |l: Option<usize>| l.and_then(|l| arm.joints.get(l)).map_or("base".to_string(), |j| j.name.clone());
    let bodies = spec
        .bodies
        .iter()
        .zip(&notes.sources)
        .map(|(b, source)| BodyReport {
            name: b.name.clone(),
            link: link(b.link),
            a: b.capsule.a.into(),
            b: b.capsule.b.into(),
            radius: b.capsule.radius,
            source: source.clone(),
        })
        .collect();
    let allowed = notes
        .allowed
        .iter()
        .flat_map(|g| {
            g.pairs.iter().enumerate().map(|(k, p)| {
                let comment = g.comments.get(k).map_or(String::new(), |c| format!(" ({c})"));
                PairReport { pair: p.clone(), reason: format!("{}{comment}", g.reason) }
            })
        })
        .collect();
    Ok(FitReport { arm: arm.name.clone(), margin: spec.margin, bodies, allowed, toml })
}

/// The arm of a URDF, its fitted geometry standing on a table at its base plane, and the notes an
/// arm file keeps beside it.
fn fitted(request: &FitRequest) -> Result<(ArmSpec, CollisionSpec, Notes)> {
    let text = std::fs::read_to_string(&request.urdf)
        .with_context(|| format!("cannot read URDF {}", request.urdf.display()))?;
    let base_dir = request.urdf.parent().map(PathBuf::from).unwrap_or_default();
    let (arm, bodies) = collision::urdf::bodies(&text, request.tip.as_deref(), &base_dir)
        .with_context(|| format!("URDF {}", request.urdf.display()))?;
    if bodies.is_empty() {
        bail!("URDF {}: no <collision> element on the chain's links: nothing to fit", request.urdf.display());
    }
    if bodies.len() > MAX_BODIES {
        bail!(
            "URDF {}: {} collision elements on the chain, and a firmware holds {MAX_BODIES} bodies: merge some \
             elements in the URDF, or write the arm file's [[collision.bodies]] by hand",
            request.urdf.display(),
            bodies.len()
        );
    }
    let mut spec = CollisionSpec {
        margin: request.margin,
        bodies: bodies.iter().map(|f| f.body.clone()).collect(),
        obstacles: vec![ObstacleSpec { name: TABLE.into(), shape: kinematics::collision::Shape::table(0.0) }],
        allowed: Vec::new(),
    };
    let found = allowed::find(&arm, &spec)?;
    spec.allowed = found.pairs();
    collision::validate::check(&arm, &spec)?;
    let percent = |share: f64| format!("{:.0} %", share * 100.0);
    let notes = Notes {
        header: vec![
            format!("The collision geometry of {}, made by", arm.name),
            format!("  {}", request.command),
            "from the URDF's <collision> elements: one capsule (a sphere where a and b are one point) per".into(),
            "element, on the joint whose moving frame carries its link; a mesh's holds all its vertices.".into(),
            "The table is the plane the base stands on. Edit freely: the arm file is read as written.".into(),
        ],
        sources: bodies.iter().map(|f| f.source.clone()).collect(),
        allowed: vec![
            AllowedGroup {
                reason: "closer than the margin at the zero pose".into(),
                pairs: found.at_zero.clone(),
                comments: vec![],
            },
            AllowedGroup {
                reason: format!(
                    "closer than the margin in more than {} of {SAMPLES} random poses within the joint limits (seed \
                     {SEED})",
                    percent(SHARE)
                ),
                pairs: found.often.iter().map(|(p, _)| p.clone()).collect(),
                comments: found.often.iter().map(|(_, s)| format!("in {} of them", percent(*s))).collect(),
            },
            AllowedGroup {
                reason: "standing on it at the zero pose".into(),
                pairs: found.standing.clone(),
                comments: vec![],
            },
        ],
    };
    Ok((arm, spec, notes))
}

impl FitReport {
    /// The text `collision fit` prints: the section itself.
    pub fn text(&self) -> String {
        self.toml.clone()
    }
}

/// What `collision check` is asked.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckRequest {
    /// A preset, an arm file, or a URDF (its `<collision>` elements fitted on the way).
    pub arm: String,
    /// A URDF's tip link.
    pub tip: Option<String>,
    /// The joint values (rad, m for prismatic joints).
    pub joints: Vec<f64>,
    /// Obstacles added, the table taken away.
    pub surroundings: Surroundings,
}

/// The closest pair of a configuration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckReport {
    /// The arm's name.
    pub arm: String,
    /// The joint values checked.
    pub joints: Vec<f64>,
    /// The closest checked pair (`None`: no pair is checked).
    pub closest: Option<[String; 2]>,
    /// Their signed distance (m; negative: they overlap).
    pub distance: Option<f64>,
    /// The margin every checked pair keeps (m).
    pub margin: f64,
    /// True when every checked pair keeps the margin: a goal the check lets through.
    pub free: bool,
    /// The closest pair in words.
    pub said: String,
}

impl CheckReport {
    /// One line.
    pub fn text(&self) -> String {
        let verdict = if self.free { "free" } else { "in contact" };
        format!("{verdict}: {}", self.said)
    }
}

/// The closest checked pair of `request.arm` at `request.joints`.
pub fn check(request: &CheckRequest) -> Result<CheckReport> {
    let arm = if request.arm.to_ascii_lowercase().ends_with(".urdf") {
        let fit = FitRequest {
            urdf: PathBuf::from(&request.arm),
            tip: request.tip.clone(),
            margin: collision::DEFAULT_MARGIN,
            command: String::new(),
        };
        let (arm, spec, _) = fitted(&fit)?;
        ArmSpec { collision: Some(spec), ..arm }
    } else {
        ArmSpec::load(&request.arm, request.tip.as_deref())?
    };
    let arm = arm.with_surroundings(&request.surroundings)?;
    let Some(spec) = collision::collision_of(&arm) else {
        bail!(
            "arm {} has no collision geometry: give its arm file a [collision] table (`armctl collision fit` makes \
             one from a URDF)",
            arm.name
        );
    };
    let model = crate::arm::dof::build(arm.clone())?;
    if request.joints.len() != arm.dof() {
        bail!("--joints has {} values for the {} joints of {}", request.joints.len(), arm.dof(), arm.name);
    }
    if !model.admits(&request.joints) {
        bail!("--joints {:?} is outside the joint limits of {}", request.joints, arm.name);
    }
    let frames = model.joint_frames(&request.joints)?;
    let mut scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(arm.dof())?;
    let closest = scene.closest(&frames);
    let free = scene.first_contact(&frames).is_none();
    Ok(CheckReport {
        arm: arm.name.clone(),
        joints: request.joints.clone(),
        closest: closest.map(|c| {
            [spec.name(kinematics::collision::Part::Body(c.body)).to_string(), spec.name(c.other).to_string()]
        }),
        distance: closest.map(|c| c.distance),
        margin: spec.margin,
        free,
        said: closest.map_or_else(|| "no pair is checked".to_string(), |c| spec.describe(&c)),
    })
}
