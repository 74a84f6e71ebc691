//! The rig file: several arms, each with its own firmware core and place, and where each base sits
//! in one world frame. TOML, one `[[arm]]` table per arm:
//!
//! ```toml
//! name = "bimanual-so101"
//! [[arm]]
//! name = "left"                 # the arm's name in commands and keyframe columns
//! arm = "so101"                 # a preset or an arm file (.toml, .urdf), relative to this file
//! sim = true                    # or port = "/dev/ttyACM0", or bus = "/dev/ttyUSB0" + protocol = "sts"
//! calibration = "left.json"     # with bus: LeRobot's calibration file, relative to this file
//! xyz = [0.0, 0.15, 0.0]        # the base in the world frame (m)
//! rpy_deg = [0.0, 0.0, 0.0]     # and its roll, pitch, yaw (degrees, fixed axes x, y, z)
//! mount = "torso"               # optional: the base sits on this earlier arm's tool frame
//!                               # instead (xyz and rpy_deg then relative to it): a shared joint
//! [arm.leader]                  # optional: the leader arm that drives it in `armctl teleop --rig`
//! port = "/dev/ttyUSB2"         # its USB adapter; or sim = true with script = "left.csv"
//! arm = "so101"                 # and calibration, protocol, baud as `armctl teleop --leader-*`
//! ```
//!
//! Each arm becomes the place of one arm ([`Place`]), checked as the drive options are, so a rig
//! arm is driven exactly as `armctl --sim`, `--port` or `--bus` drives one. Built in:
//! `bimanual-so101`, two simulated SO-101 arms 0.3 m apart.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use kinematics::Pose;
use serde::Deserialize;

pub use crate::motion::teleop::leader::LeaderSpec;
use crate::runtime::connection::{calibrated, protocol_named, Place};

/// The rigs built in, by name.
const PRESETS: [(&str, &str); 1] = [("bimanual-so101", include_str!("../../examples/rigs/bimanual-so101.toml"))];

/// The most arms a rig takes (a bound for a hand-written file gone wrong, not a design limit).
pub const MAX_ARMS: usize = 8;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigFile {
    name: String,
    #[serde(rename = "arm")]
    arms: Vec<ArmEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ArmEntry {
    name: String,
    arm: String,
    #[serde(default)]
    sim: bool,
    port: Option<String>,
    bus: Option<String>,
    protocol: Option<String>,
    baud: Option<u32>,
    calibration: Option<String>,
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
    mount: Option<String>,
    leader: Option<LeaderEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LeaderEntry {
    port: Option<String>,
    #[serde(default)]
    sim: bool,
    script: Option<String>,
    arm: Option<String>,
    calibration: Option<String>,
    protocol: Option<String>,
    baud: Option<u32>,
}

/// One arm of a rig.
#[derive(Clone, Debug)]
pub struct RigArmSpec {
    /// Its name (letters, digits, `_` and `-`), unique in the rig.
    pub name: String,
    /// Where its core runs and which arm it drives (always named), as the drive options say it
    /// for one arm.
    pub place: Place,
    /// Its base in the world frame, or on the tool frame of the arm it is mounted on.
    pub base: Pose<f64>,
    /// The earlier arm whose tool frame carries its base (`None`: the world): that arm's joints
    /// move it too, and the rig is then a kinematic tree ([`super::tree`]).
    pub mount: Option<usize>,
    /// The leader arm that drives it in `armctl teleop --rig`, if the file names one.
    pub leader: Option<LeaderSpec>,
}

/// A rig: its arms, in the file's order.
#[derive(Clone, Debug)]
pub struct RigSpec {
    /// The rig's name.
    pub name: String,
    /// The arms.
    pub arms: Vec<RigArmSpec>,
}

impl RigSpec {
    /// Reads the rig file at `path`, or the built-in rig of that name.
    pub fn load(path: &str) -> Result<Self> {
        if let Some((_, text)) = PRESETS.iter().find(|(name, _)| *name == path) {
            return Self::parse(text, Path::new("."));
        }
        if !Path::new(path).exists() {
            let names: Vec<&str> = PRESETS.iter().map(|(name, _)| *name).collect();
            bail!("rig {path}: no such file, and not a built-in rig ({})", names.join(", "));
        }
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read rig file {path}"))?;
        let dir = Path::new(path).parent().unwrap_or(Path::new("."));
        Self::parse(&text, dir).with_context(|| format!("rig file {path}"))
    }

    /// Parses a rig file's text; relative paths in it are relative to `dir`.
    pub fn parse(text: &str, dir: &Path) -> Result<Self> {
        let file: RigFile = toml::from_str(text).map_err(|e| anyhow::anyhow!("{}", one_line(&e.to_string())))?;
        if file.arms.is_empty() {
            bail!("no [[arm]]: a rig has at least one arm");
        }
        if file.arms.len() > MAX_ARMS {
            bail!("{} arms: a rig takes at most {MAX_ARMS}", file.arms.len());
        }
        let mut arms: Vec<RigArmSpec> = Vec::new();
        for entry in file.arms {
            let mut arm = entry.check(dir).with_context(|| format!("arm {:?}", entry.name))?;
            if arms.iter().any(|a| a.name == arm.name) {
                bail!("two arms are named {:?}: each needs a name of its own", arm.name);
            }
            if let Some(mount) = &entry.mount {
                let Some(on) = arms.iter().position(|a| &a.name == mount) else {
                    bail!("arm {:?}: mount {mount:?} is not an arm named before it", arm.name);
                };
                arm.mount = Some(on);
            }
            arms.push(arm);
        }
        Ok(Self { name: file.name, arms })
    }

    /// Refuses a rig with an arm mounted on another (a shared joint) for `what`, which places
    /// every arm's base in the world once and for all.
    pub fn refuse_mounts(&self, what: &str) -> Result<()> {
        if let Some(arm) = self.arms.iter().find(|a| a.mount.is_some()) {
            bail!(
                "rig {}: arm {} is mounted on another arm (a shared joint), which {what} does not handle yet; \
                 status, stop, torque, move and play with joint columns do",
                self.name,
                arm.name
            );
        }
        Ok(())
    }

    /// The arm named `name`.
    pub fn arm(&self, name: &str) -> Result<usize> {
        self.arms.iter().position(|a| a.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.arms.iter().map(|a| a.name.as_str()).collect();
            anyhow::anyhow!("the rig {} has no arm {name:?} (its arms: {})", self.name, names.join(", "))
        })
    }
}

/// toml's messages span lines (the source line with a caret): one line here.
fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `path` relative to `dir` unless absolute.
fn relative(dir: &Path, path: &str) -> PathBuf {
    let p = Path::new(path);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        dir.join(p)
    }
}

impl ArmEntry {
    fn check(&self, dir: &Path) -> Result<RigArmSpec> {
        let name_ok =
            !self.name.is_empty() && self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        if !name_ok {
            bail!("the name must be letters, digits, _ and - (it names the arm's keyframe columns)");
        }
        if self.xyz.iter().chain(&self.rpy_deg).any(|x| !x.is_finite()) {
            bail!("xyz and rpy_deg must be finite numbers");
        }
        let places = usize::from(self.sim) + usize::from(self.port.is_some()) + usize::from(self.bus.is_some());
        if places != 1 {
            bail!("give exactly one of sim = true, port = \"PORT\" or bus = \"PORT\" (with protocol)");
        }
        let protocol = self.protocol.as_deref().map(protocol_named).transpose()?;
        let arm = arm_path(dir, &self.arm);
        let place = Place {
            port: self.port.clone(),
            bus: self.bus.clone(),
            protocol,
            baud: self.baud,
            sim: self.sim,
            arm: Some(arm),
            calibration: self.calibration.as_deref().map(|c| relative(dir, c)),
            object_mm: None,
            servos: None,
            surroundings: Default::default(),
            hidden_obstacles: Vec::new(),
            no_collision_check: false,
            gravity: None,
        };
        // The same checks as the drive options of one arm, and the arm loaded once to prove it.
        place.target()?;
        let rpy = self.rpy_deg.map(f64::to_radians);
        let leader = self.leader.as_ref().map(|l| l.check(dir)).transpose().context("leader")?;
        Ok(RigArmSpec { name: self.name.clone(), place, base: Pose::from_xyz_rpy(self.xyz, rpy), mount: None, leader })
    }
}

/// An arm's name as typed: a preset's name stays a name, anything with an extension is a file
/// next to the rig file.
fn arm_path(dir: &Path, arm: &str) -> String {
    if Path::new(arm).extension().is_some() {
        relative(dir, arm).display().to_string()
    } else {
        arm.to_string()
    }
}

impl LeaderEntry {
    fn check(&self, dir: &Path) -> Result<LeaderSpec> {
        let port = match (&self.port, self.sim, &self.script) {
            (Some(port), false, None) => port.clone(),
            (None, true, Some(_)) => "sim".to_string(),
            (None, true, None) => {
                bail!("sim = true needs script = \"FILE\": the path the simulated hand moves it along")
            }
            (_, false, Some(_)) => bail!("script moves a simulated leader: it needs sim = true (and no port)"),
            _ => bail!("give one of port = \"PORT\" or sim = true (with script)"),
        };
        let arm = arm_path(dir, self.arm.as_deref().unwrap_or("so101"));
        // Loaded once here, so a bad arm or calibration is said before anything opens.
        let spec = calibrated(
            crate::arm::ArmSpec::load(&arm, None)?,
            self.calibration.as_deref().map(|c| relative(dir, c)).as_deref(),
        )?;
        drop(spec);
        Ok(LeaderSpec {
            port,
            script: self.script.as_deref().map(|s| relative(dir, s)),
            arm,
            calibration: self.calibration.as_deref().map(|c| relative(dir, c)),
            protocol: self.protocol.as_deref().map(protocol_named).transpose()?,
            baud: self.baud,
        })
    }
}
