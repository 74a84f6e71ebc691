//! The project's own arm file (TOML), for people who build arms.
//!
//! ```toml
//! name = "my-arm"
//! convention = "urdf"      # or "dh" (standard, distal) or "modified-dh" (Craig, proximal); default "urdf"
//! angles = "degrees"       # or "radians" (the default); lengths are always metres
//!
//! [[joint]]
//! name = "base_yaw"        # optional, default joint1, joint2, ...
//! type = "revolute"        # "revolute", "continuous" or "prismatic"
//! xyz = [0, 0, 0.05]       # origin from the previous joint frame, optional (default zero)
//! rpy = [0, 0, 0]          # fixed-axis roll, pitch, yaw as in URDF, optional (default zero)
//! axis = [0, 0, 1]         # motion axis in the joint frame
//! limits = [-170, 170]     # [lower, upper]; required except for continuous joints
//! mass = 0.147             # optional, every joint or none: kg of what the joint moves (its link
//! com = [0, 0.02, 0.03]    #   and all fixed to it), its centre of mass in the joint's frame (m),
//! inertia = [2e-4, 0, 0, 1e-4, 0, 1e-4] # and, optional, its inertia about the centre of mass
//!                          #   (kg m², URDF's order ixx ixy ixz iyy iyz izz; default a point mass)
//!
//! [tool]                   # optional: tool frame after the last joint
//! xyz = [0.1, 0, 0]
//! rpy = [0, 0, 0]
//!
//! [servos]                 # optional: the servos, to drive the arm through the firmware
//! model = "STS3215"        # STS3215, XL430-W250, XM430-W350 or XL330-M288
//! ids = [1, 2, 3]          # one per joint, base first
//! zero = [2048, 2048, 1024] # optional: ticks at joint value 0 (default half a turn)
//! reversed = [false, true, false] # optional: servos turning against the joint axis
//! max_velocity = 2.0       # rad/s, every joint
//! max_acceleration = 8.0   # rad/s², every joint
//! baud = 1000000           # optional: the bus's baud rate (default 1 Mbps), one the model offers
//! # optional, all three or none: a LeRobot calibration of each joint's servo (`armctl calibrate`
//! # writes them), raw ticks; `reversed` is then LeRobot's drive_mode 1, and `zero` does not apply
//! homing_offset = [953, -1200, 0]  # written to the servo's Homing_Offset, |offset| <= 2047
//! range_min = [1000, 812, 900]     # the range it was seen to move through (offset-corrected)
//! range_max = [3100, 3313, 3200]
//!
//! [gripper]                # optional, needs [servos]: a gripper servo of the same model
//! id = 6                   # bus id, not one of the joints'
//! closed = 1934            # ticks with the jaws closed (0 %)
//! open = 3186              # ticks with the jaws open (100 %)
//! effort = 50              # optional: percent of the servo's maximum torque or current (default 50)
//! opening_mm = 90          # distance between the jaws when open
//! speed = 100              # optional: percent of the stroke per second (default 100)
//!
//! [collision]              # optional: the arm's collision geometry, see `collision::toml`
//! margin = 0.01
//! table = 0.0
//! ```
//!
//! With `convention = "dh"` or `"modified-dh"` each `[[joint]]` holds a DH row instead of
//! `xyz`/`rpy`/`axis`: `a`, `alpha`, `d` and `theta` (the joint-angle offset, default 0), plus
//! `type` and `limits`. A standard-DH `[tool]` follows the last DH frame; a modified-DH one follows
//! the last joint frame (as in [`kinematics::Chain::from_dh_standard`] and
//! [`kinematics::Chain::from_dh_modified`], which do the conversion). Unknown keys are errors, and
//! every error is one line that names the line of the file and the joint or key at fault.
//!
//! With the calibration arrays, [`ServoSetup::calibration`](super::servos::ServoSetup) holds a
//! [`MotorCalibration`] per joint, so the joints map to ticks as LeRobot's degree mode maps them and
//! connecting checks that the servos hold the offsets and limits; each joint's limits are then the
//! file's tightened to its calibrated range less
//! [`STOP_MARGIN_DEG`](super::calibration::record::STOP_MARGIN_DEG) a side
//! ([`joint_limits`](super::calibration::record::joint_limits)). [`super::toml_writer`] writes such
//! a file, and [`super::toml_update`] writes a calibration into an existing one.
//!
//! The masses (`mass`, `com`, `inertia`, every joint's or none, convention `urdf` only) are in the
//! joint's own frame, as a URDF's `<inertial>` is in its child link's; they are what the
//! simulator's physical servos carry ([`super::arm_dynamics::masses_of`]).

use super::calibration::MotorCalibration;
use super::{ArmSpec, JointSpec};
use anyhow::{anyhow, bail, Result};
use kinematics::dynamics::Inertia;
use kinematics::nalgebra::{Matrix3, Vector3};
use kinematics::{Chain, DhRow, JointKind, Limits, Pose};
use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ArmFile {
    name: String,
    #[serde(default)]
    convention: Convention,
    #[serde(default)]
    angles: AngleUnit,
    #[serde(rename = "joint", default)]
    joints: Vec<Spanned<JointEntry>>,
    tool: Option<Spanned<ToolEntry>>,
    servos: Option<Spanned<ServosEntry>>,
    gripper: Option<Spanned<GripperEntry>>,
    collision: Option<Spanned<super::collision::toml::CollisionEntry>>,
    #[serde(default)]
    obstacles: Vec<Spanned<super::collision::toml::ObstacleEntry>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GripperEntry {
    id: u8,
    closed: i32,
    open: i32,
    effort: Option<f64>,
    opening_mm: f64,
    speed: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ServosEntry {
    model: String,
    ids: Vec<u8>,
    zero: Option<Spanned<Vec<i32>>>,
    reversed: Option<Vec<bool>>,
    max_velocity: f64,
    max_acceleration: f64,
    baud: Option<u32>,
    homing_offset: Option<Spanned<Vec<i64>>>,
    range_min: Option<Spanned<Vec<i64>>>,
    range_max: Option<Spanned<Vec<i64>>>,
}

use super::calibration::record::{joint_limits, MAX_HOMING_OFFSET};

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
enum Convention {
    #[default]
    Urdf,
    Dh,
    ModifiedDh,
}

impl Convention {
    fn name(self) -> &'static str {
        match self {
            Convention::Urdf => "urdf",
            Convention::Dh => "dh",
            Convention::ModifiedDh => "modified-dh",
        }
    }
}

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
enum AngleUnit {
    #[default]
    Radians,
    Degrees,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
enum Kind {
    Revolute,
    Continuous,
    Prismatic,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JointEntry {
    name: Option<String>,
    #[serde(rename = "type")]
    kind: Kind,
    limits: Option<[f64; 2]>,
    // convention = "urdf"
    xyz: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
    axis: Option<[f64; 3]>,
    // convention = "dh" | "modified-dh"
    a: Option<f64>,
    alpha: Option<f64>,
    d: Option<f64>,
    theta: Option<f64>,
    // What the joint moves (all joints or none): kg, m, kg m² as a URDF's <inertia> lists them.
    mass: Option<f64>,
    com: Option<[f64; 3]>,
    inertia: Option<[f64; 6]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ToolEntry {
    xyz: Option<[f64; 3]>,
    rpy: Option<[f64; 3]>,
}

/// Reads an arm file.
pub fn parse(text: &str) -> Result<ArmSpec> {
    let file: ArmFile = toml::from_str(text).map_err(|e| {
        let message = e.message().trim().replace('\n', "; ");
        match e.span() {
            Some(span) => anyhow!("{}: {message}", position(text, span.start)),
            None => anyhow!("{message}"),
        }
    })?;
    let angle = match file.angles {
        AngleUnit::Radians => 1.0,
        AngleUnit::Degrees => core::f64::consts::PI / 180.0,
    };
    let convention = file.convention;

    let mut joints = Vec::with_capacity(file.joints.len());
    let mut masses = Vec::with_capacity(file.joints.len());
    // Standard DH: the constant part of row i is the origin of joint i + 1 (and of the tool).
    let mut previous_link = Pose::identity();
    for (i, entry) in file.joints.iter().enumerate() {
        let j = entry.get_ref();
        let name = j.name.clone().unwrap_or_else(|| format!("joint{}", i + 1));
        let at = format!("{}: joint {name}", position(text, entry.span().start));
        let kind = match j.kind {
            Kind::Revolute => JointKind::Revolute,
            Kind::Continuous => JointKind::Continuous,
            Kind::Prismatic => JointKind::Prismatic,
        };
        // Limits: radians (or degrees) for rotations, metres for prismatic joints.
        let (lower, upper) = match (kind, j.limits) {
            (JointKind::Continuous, Some(_)) => {
                bail!("{at} is continuous and has no limits: remove `limits` or make it revolute")
            }
            (JointKind::Continuous, None) => (-core::f64::consts::PI, core::f64::consts::PI),
            (_, None) => bail!("{at}: `limits = [lower, upper]` is required for a {} joint", kind_name(kind)),
            (JointKind::Prismatic, Some([l, u])) => (l, u),
            (_, Some([l, u])) => (l * angle, u * angle),
        };
        finite(&at, "limits", &[lower, upper])?;
        if lower > upper {
            bail!("{at}: `limits` lower {lower} is above upper {upper}");
        }

        let dh_keys = [("a", j.a), ("alpha", j.alpha), ("d", j.d), ("theta", j.theta)];
        let urdf_keys = [("xyz", j.xyz.is_some()), ("rpy", j.rpy.is_some()), ("axis", j.axis.is_some())];
        let spec = match convention {
            Convention::Urdf => {
                if let Some((key, _)) = dh_keys.iter().find(|(_, v)| v.is_some()) {
                    bail!("{at}: `{key}` is a DH parameter: set convention = \"dh\" or \"modified-dh\", or use xyz/rpy/axis");
                }
                let xyz = j.xyz.unwrap_or([0.0; 3]);
                let rpy = j.rpy.unwrap_or([0.0; 3]).map(|v| v * angle);
                let axis = j.axis.ok_or_else(|| anyhow!("{at}: `axis = [x, y, z]` is required"))?;
                finite(&at, "xyz", &xyz)?;
                finite(&at, "rpy", &rpy)?;
                finite(&at, "axis", &axis)?;
                JointSpec { name, kind, origin: Pose::from_xyz_rpy(xyz, rpy), axis, lower, upper }
            }
            Convention::Dh | Convention::ModifiedDh => {
                if let Some((key, _)) = urdf_keys.iter().find(|(_, present)| *present) {
                    bail!(
                        "{at}: `{key}` does not belong in a {} table: give a, alpha, d and theta, or set convention = \
                         \"urdf\"",
                        convention.name()
                    );
                }
                let required =
                    |key: &str, v: Option<f64>| v.ok_or_else(|| anyhow!("{at}: DH parameter `{key}` is missing"));
                let row = DhRow {
                    a: required("a", j.a)?,
                    alpha: required("alpha", j.alpha)? * angle,
                    d: required("d", j.d)?,
                    theta: j.theta.unwrap_or(0.0) * angle,
                    kind,
                    limits: Limits::new(lower, upper),
                };
                finite(&at, "a, alpha, d and theta", &[row.a, row.alpha, row.d, row.theta])?;
                let origin = if convention == Convention::Dh {
                    core::mem::replace(&mut previous_link, standard_link(&row))
                } else {
                    modified_link(&row)
                };
                JointSpec { name, kind, origin, axis: [0.0, 0.0, 1.0], lower, upper }
            }
        };
        masses.push(body(&at, j, convention)?);
        joints.push(spec);
    }
    let masses = all_or_none(text, &file.joints, masses)?;

    let tool = match &file.tool {
        None => Pose::identity(),
        Some(tool) => {
            let at = format!("{}: [tool]", position(text, tool.span().start));
            let xyz = tool.get_ref().xyz.unwrap_or([0.0; 3]);
            let rpy = tool.get_ref().rpy.unwrap_or([0.0; 3]).map(|v| v * angle);
            finite(&at, "xyz", &xyz)?;
            finite(&at, "rpy", &rpy)?;
            Pose::from_xyz_rpy(xyz, rpy)
        }
    };
    let tool = if convention == Convention::Dh { previous_link.compose(&tool) } else { tool };
    let servos = match &file.servos {
        None => None,
        Some(entry) => {
            let at = format!("{}: [servos]", position(text, entry.span().start));
            let servos = servos(&at, text, entry.get_ref(), &joints)?;
            // A calibrated joint keeps clear of the stops it was moved to: the file's limits are
            // the arm's, the calibration tightens them here (`armctl calibrate` writing into an
            // existing file changes the servos' keys only, never a joint's limits).
            if let Some(calibration) = &servos.calibration {
                for (joint, m) in joints.iter_mut().zip(calibration) {
                    (joint.lower, joint.upper) =
                        joint_limits(joint, m, servos.model.ticks_per_revolution).map_err(|e| anyhow!("{at}: {e}"))?;
                }
            }
            Some(servos)
        }
    };
    let servos = match (&file.gripper, servos) {
        (None, servos) => servos,
        (Some(entry), None) => bail!("{}: [gripper] needs a [servos] table", position(text, entry.span().start)),
        (Some(entry), Some(mut servos)) => {
            let at = format!("{}: [gripper]", position(text, entry.span().start));
            servos.gripper = Some(gripper(&at, entry.get_ref(), &servos)?);
            Some(servos)
        }
    };
    let mut arm = ArmSpec { name: file.name, joints, tool, servos, collision: None, masses };
    arm.collision = super::collision::toml::read(text, file.collision.as_ref(), &file.obstacles, angle, &arm)?;
    Ok(arm)
}

/// What joint `j` moves, from its `mass`, `com` and `inertia` keys, if it has them.
fn body(at: &str, j: &JointEntry, convention: Convention) -> Result<Option<Inertia<f64>>> {
    let Some(mass) = j.mass else {
        if let Some(key) = [("com", j.com.is_some()), ("inertia", j.inertia.is_some())].iter().find(|k| k.1) {
            bail!("{at}: `{}` needs `mass`", key.0);
        }
        return Ok(None);
    };
    if convention != Convention::Urdf {
        bail!(
            "{at}: `mass` needs convention = \"urdf\": the centre of mass is given in the joint's own frame, which \
             a {} row does not place",
            convention.name()
        );
    }
    let com =
        j.com.ok_or_else(|| anyhow!("{at}: `com = [x, y, z]` (m, in the joint's frame) is required with `mass`"))?;
    // URDF's order: ixx, ixy, ixz, iyy, iyz, izz; none is a point mass.
    let [xx, xy, xz, yy, yz, zz] = j.inertia.unwrap_or([0.0; 6]);
    let tensor = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    Inertia { mass, com: Vector3::from(com), tensor }
        .validated()
        .map_err(|e| {
            anyhow!("{at}: mass {mass} kg, com {com:?}, inertia {:?} is not a body's: {e}", [xx, xy, xz, yy, yz, zz])
        })
        .map(Some)
}

/// Every joint's body, or none: an arm with some masses missing would be simulated as if those
/// links weighed nothing.
fn all_or_none(
    text: &str,
    entries: &[Spanned<JointEntry>],
    masses: Vec<Option<Inertia<f64>>>,
) -> Result<Option<Vec<Inertia<f64>>>> {
    if masses.iter().all(Option::is_none) {
        return Ok(None);
    }
    if let Some(k) = masses.iter().position(Option::is_none) {
        let name = entries[k].get_ref().name.clone().unwrap_or_else(|| format!("joint{}", k + 1));
        bail!(
            "{}: joint {name} has no `mass`, where others have: give every joint's mass and com, or none",
            position(text, entries[k].span().start)
        );
    }
    Ok(Some(masses.into_iter().flatten().collect()))
}

/// The `[gripper]` table, checked against the servos.
fn gripper(at: &str, entry: &GripperEntry, servos: &super::servos::ServoSetup) -> Result<super::servos::GripperSpec> {
    if entry.id > 252 || servos.ids.contains(&entry.id) {
        bail!("{at}: gripper id {} is above 252 or a joint's servo", entry.id);
    }
    let top = i64::from(servos.model.ticks_per_revolution) - 1;
    for (key, v) in [("closed", entry.closed), ("open", entry.open)] {
        if !(0..=top).contains(&i64::from(v)) {
            bail!("{at}: {key} = {v} is outside the servo's 0..={top} ticks");
        }
    }
    if entry.closed == entry.open {
        bail!("{at}: closed and open are both {} ticks: the range has zero width", entry.open);
    }
    let effort = entry.effort.unwrap_or(50.0);
    if !(effort.is_finite() && effort > 0.0 && effort <= 100.0) {
        bail!("{at}: effort must be a percent in (0, 100], not {effort}");
    }
    if !(entry.opening_mm.is_finite() && entry.opening_mm > 0.0) {
        bail!("{at}: opening_mm must be a positive number, not {}", entry.opening_mm);
    }
    let speed = entry.speed.unwrap_or(super::servos::GRIPPER_SPEED);
    if !(speed.is_finite() && speed > 0.0 && speed <= 1000.0) {
        bail!("{at}: speed must be a percent of the stroke per second in (0, 1000], not {speed}");
    }
    Ok(super::servos::GripperSpec {
        id: entry.id,
        closed: entry.closed,
        open: entry.open,
        effort,
        opening_mm: entry.opening_mm,
        speed,
    })
}

/// The `[servos]` table, checked against the joints.
fn servos(at: &str, text: &str, entry: &ServosEntry, joints: &[JointSpec]) -> Result<super::servos::ServoSetup> {
    let model =
        firmware::bus::table::MODELS.into_iter().find(|m| m.name.eq_ignore_ascii_case(&entry.model)).ok_or_else(
            || anyhow!("{at}: unknown servo model {:?} (STS3215, XL430-W250, XM430-W350, XL330-M288)", entry.model),
        )?;
    let n = joints.len();
    let count = |key: &str, len: usize| -> Result<()> {
        if len != n {
            bail!("{at}: {key} has {len} entries for {n} joints");
        }
        Ok(())
    };
    count("ids", entry.ids.len())?;
    if let Some(z) = &entry.zero {
        count("zero", z.get_ref().len())?;
    }
    if let Some(r) = &entry.reversed {
        count("reversed", r.len())?;
    }
    let mut seen = std::collections::BTreeSet::new();
    if let Some(id) = entry.ids.iter().find(|id| !seen.insert(**id) || **id > 252) {
        bail!("{at}: servo id {id} is repeated or above 252");
    }
    for (key, v) in [("max_velocity", entry.max_velocity), ("max_acceleration", entry.max_acceleration)] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{at}: {key} must be a positive number, not {v}");
        }
    }
    let baud = entry.baud.unwrap_or(super::servos::DEFAULT_BAUD);
    if model.baud_index(baud).is_none() {
        let offered: Vec<String> = model.bauds.iter().map(|(_, b)| b.to_string()).collect();
        bail!("{at}: the {} has no baud rate {baud} (it offers {})", model.name, offered.join(", "));
    }
    let calibration = calibration(text, entry, joints, model.ticks_per_revolution)?;
    Ok(super::servos::ServoSetup {
        model,
        ids: entry.ids.clone(),
        zero: entry.zero.as_ref().map(|z| z.get_ref().clone()),
        reversed: entry.reversed.clone(),
        max_velocity: entry.max_velocity,
        max_acceleration: entry.max_acceleration,
        calibration,
        gripper: None,
        gripper_calibration: None,
        baud,
    })
}

/// The `[servos]` calibration arrays (all three, or none), one [`MotorCalibration`] per joint.
/// Errors name the line of the key at fault and the joint.
fn calibration(
    text: &str,
    entry: &ServosEntry,
    joints: &[JointSpec],
    ticks_per_revolution: u32,
) -> Result<Option<Vec<MotorCalibration>>> {
    let keys =
        [("homing_offset", &entry.homing_offset), ("range_min", &entry.range_min), ("range_max", &entry.range_max)];
    let given: Vec<&str> = keys.iter().filter(|(_, v)| v.is_some()).map(|(k, _)| *k).collect();
    let (Some(offsets), Some(mins), Some(maxes)) = (&entry.homing_offset, &entry.range_min, &entry.range_max) else {
        if let Some((key, Some(value))) = keys.iter().find(|(_, v)| v.is_some()) {
            bail!(
                "{}: [servos] {key}: a calibration needs homing_offset, range_min and range_max together (given: {})",
                position(text, value.span().start),
                given.join(", ")
            );
        }
        return Ok(None);
    };
    let at = |value: &Spanned<Vec<i64>>, key: &str| format!("{}: [servos] {key}", position(text, value.span().start));
    let n = joints.len();
    for (key, value) in [("homing_offset", offsets), ("range_min", mins), ("range_max", maxes)] {
        if value.get_ref().len() != n {
            bail!("{} has {} entries for {n} joints", at(value, key), value.get_ref().len());
        }
    }
    if let Some(zero) = &entry.zero {
        bail!(
            "{}: [servos] zero does not apply with a calibration (the zero is the calibrated range's middle): remove it",
            position(text, zero.span().start)
        );
    }
    let top = i64::from(ticks_per_revolution) - 1;
    let ids = &entry.ids;
    let mut calibration = Vec::with_capacity(n);
    for (j, joint) in joints.iter().enumerate() {
        let name = format!("joint {} ({})", j + 1, joint.name);
        let (offset, lo, hi) = (offsets.get_ref()[j], mins.get_ref()[j], maxes.get_ref()[j]);
        if offset.abs() > MAX_HOMING_OFFSET {
            bail!("{}: {name}: {offset} is beyond +-{MAX_HOMING_OFFSET}", at(offsets, "homing_offset"));
        }
        for (key, value, v) in [("range_min", mins, lo), ("range_max", maxes, hi)] {
            if !(0..=top).contains(&v) {
                bail!("{}: {name}: {v} is outside the servo's 0..={top} ticks", at(value, key));
            }
        }
        if lo == hi {
            bail!("{}: {name}: range_min and range_max are both {lo}: a range of zero width", at(maxes, "range_max"));
        }
        if lo > hi {
            bail!("{}: {name}: range_min {lo} is above range_max {hi}", at(mins, "range_min"));
        }
        let reversed = entry.reversed.as_ref().is_some_and(|r| r[j]);
        // The values are checked to fit above.
        calibration.push(MotorCalibration {
            id: ids[j],
            drive_mode: u8::from(reversed),
            homing_offset: offset as i32,
            range_min: lo as i32,
            range_max: hi as i32,
        });
    }
    Ok(Some(calibration))
}

/// Standard DH `Rz(theta) Tz(d) Tx(a) Rx(alpha)`, computed by the kinematics crate: a one-row
/// chain's tool frame is its row's link transform.
fn standard_link(row: &DhRow<f64>) -> Pose<f64> {
    match Chain::<f64, 1>::from_dh_standard([link_only(row)], Pose::identity()) {
        Ok(chain) => *chain.tool(),
        // Unreachable: the parameters are finite and the limits valid.
        Err(_) => Pose::identity(),
    }
}

/// Modified DH `Rx(alpha) Tx(a) Rz(theta) Tz(d)`, computed by the kinematics crate: a one-row
/// chain's joint origin is its row's link transform.
fn modified_link(row: &DhRow<f64>) -> Pose<f64> {
    match Chain::<f64, 1>::from_dh_modified([link_only(row)], Pose::identity()) {
        Ok(chain) => chain.joints()[0].origin,
        // Unreachable: the parameters are finite and the limits valid.
        Err(_) => Pose::identity(),
    }
}

/// The row with limits that always validate (the link transform does not depend on them).
fn link_only(row: &DhRow<f64>) -> DhRow<f64> {
    DhRow { kind: JointKind::Revolute, limits: Limits::new(0.0, 0.0), ..*row }
}

fn kind_name(kind: JointKind) -> &'static str {
    match kind {
        JointKind::Revolute => "revolute",
        JointKind::Continuous => "continuous",
        JointKind::Prismatic => "prismatic",
        JointKind::Fixed => "fixed",
    }
}

pub(crate) fn finite(at: &str, key: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        bail!("{at}: `{key}` must be finite numbers (no nan or inf)")
    }
}

/// "line L, column C" of byte offset `offset` (both from 1).
pub(crate) fn position(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("line {line}, column {column}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::nalgebra::{SVector, Vector3};
    use kinematics::SplitMix64;

    const MY_ARM: &str = include_str!("../../examples/arms/my-arm.toml");
    const UR5E: &str = include_str!("../../examples/arms/ur5e-dh.toml");

    fn error(text: &str) -> String {
        let e = parse(text).err().unwrap_or_else(|| panic!("accepted:\n{text}"));
        let message = format!("{e:#}");
        assert!(!message.contains('\n'), "error is not one line: {message}");
        message
    }

    fn assert_close(a: &Pose<f64>, b: &Pose<f64>, tolerance: f64) {
        assert!((a.translation - b.translation).amax() <= tolerance, "{a:?}\n{b:?}");
        assert!((a.rotation - b.rotation).amax() <= tolerance, "{a:?}\n{b:?}");
    }

    #[test]
    fn ur5e_file_matches_the_preset() {
        let spec = parse(UR5E).unwrap();
        assert_eq!(spec.name, "ur5e-dh");
        let file = spec.chain::<f64, 6>().unwrap();
        let preset = kinematics::presets::ur5e::<f64>().unwrap();
        // Same joint origins as Chain::from_dh_standard builds, not only the same FK.
        for (a, b) in file.joints().iter().zip(preset.joints()) {
            assert_close(&a.origin, &b.origin, 1e-12);
            assert_eq!((a.limits, a.axis, a.kind), (b.limits, b.axis, b.kind));
        }
        let mut rng = SplitMix64::new(5);
        for _ in 0..20 {
            let q = SVector::<f64, 6>::from_fn(|_, _| rng.uniform(-3.0, 3.0));
            assert_close(&file.tool_pose(&q), &preset.tool_pose(&q), 1e-12);
        }
    }

    #[test]
    fn my_arm_example_loads() {
        let spec = parse(MY_ARM).unwrap();
        assert_eq!(spec.dof(), 4);
        assert_eq!(spec.joints[0].name, "base_yaw");
        // Degrees in the file, radians in the spec.
        assert!((spec.joints[0].upper - 170f64.to_radians()).abs() < 1e-15);
        let chain = spec.chain::<f64, 4>().unwrap();
        // Straight up at zero: 0.05 + 0.04 + 0.15 + 0.13 + tool 0.07.
        let p = chain.tool_pose(&SVector::zeros()).translation;
        assert!((p - Vector3::new(0.0, 0.0, 0.44)).amax() < 1e-12, "{p}");
        // Shoulder forward 90 degrees: the arm lies along +x at shoulder height.
        let p = chain.tool_pose(&SVector::from([0.0, core::f64::consts::FRAC_PI_2, 0.0, 0.0])).translation;
        assert!((p - Vector3::new(0.35, 0.0, 0.09)).amax() < 1e-12, "{p}");
    }

    #[test]
    fn modified_dh_matches_hand_computation() {
        // Base yaw, a shoulder whose axis is tilted by alpha = 90 degrees, a 0.3 m upper arm and a
        // 0.2 m forearm to the tool.
        let text = r#"
            name = "craig"
            convention = "modified-dh"
            angles = "degrees"
            [[joint]]
            type = "revolute"
            a = 0
            alpha = 0
            d = 0.1
            limits = [-180, 180]
            [[joint]]
            type = "revolute"
            a = 0
            alpha = 90
            d = 0
            limits = [-180, 180]
            [[joint]]
            type = "revolute"
            a = 0.3
            alpha = 0
            d = 0
            limits = [-180, 180]
            [tool]
            xyz = [0.2, 0, 0]
        "#;
        let chain = parse(text).unwrap().chain::<f64, 3>().unwrap();
        let h = core::f64::consts::FRAC_PI_2;
        let cases = [
            // Reach out along x at height d1.
            ([0.0, 0.0, 0.0], [0.5, 0.0, 0.1]),
            // Base yaw turns the reach onto y.
            ([h, 0.0, 0.0], [0.0, 0.5, 0.1]),
            // Rx(90) Rz(90) carries x onto z: the arm points straight up.
            ([0.0, h, 0.0], [0.0, 0.0, 0.6]),
            // Elbow at 90: the upper arm along x, the forearm along y of frame 2 = z of the base.
            ([0.0, 0.0, h], [0.3, 0.0, 0.3]),
        ];
        for (q, p) in cases {
            let got = chain.tool_pose(&SVector::from(q)).translation;
            assert!((got - Vector3::from(p)).amax() < 1e-12, "q = {q:?}: {got} vs {p:?}");
        }
        // Joint frames: modified DH puts joint 2's origin at Rx(alpha1) Tx(a1) Tz(d2).
        let o = chain.joints()[1].origin;
        assert!((o.rotation * Vector3::z() - Vector3::new(0.0, -1.0, 0.0)).amax() < 1e-12);
    }

    #[test]
    fn prismatic_dh_joint_slides_along_z() {
        let text = r#"
            name = "lift"
            convention = "dh"
            [[joint]]
            type = "prismatic"
            a = 0.1
            alpha = 0
            d = 0.2
            limits = [0, 0.5]
        "#;
        let chain = parse(text).unwrap().chain::<f64, 1>().unwrap();
        let p = chain.tool_pose(&SVector::from([0.25])).translation;
        assert!((p - Vector3::new(0.1, 0.0, 0.45)).amax() < 1e-12, "{p}");
    }

    /// Masses per joint, all or none, each a body: one line naming the joint for each mistake,
    /// and the numbers as written (the tensor in URDF's order).
    #[test]
    fn masses_are_every_joints_or_none() {
        let joint = |name: &str, extra: &str| {
            format!("[[joint]]\nname = \"{name}\"\ntype = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\n{extra}\n")
        };
        let body = "mass = 0.2\ncom = [0.01, 0, 0.05]\ninertia = [3e-4, 1e-5, 0, 2e-4, 0, 1e-4]";
        let two = |a: &str, b: &str| format!("name = \"x\"\n{}{}", joint("lift", a), joint("elbow", b));
        let arm = parse(&two(body, "mass = 0.1\ncom = [0, 0, 0.1]")).unwrap();
        let masses = arm.masses.unwrap();
        assert_eq!((masses[0].mass, masses[0].com), (0.2, Vector3::new(0.01, 0.0, 0.05)));
        assert_eq!((masses[0].tensor.m12, masses[0].tensor.m21, masses[0].tensor.m22), (1e-5, 1e-5, 2e-4));
        assert_eq!((masses[1].mass, masses[1].tensor), (0.1, kinematics::nalgebra::Matrix3::zeros()));
        assert_eq!(parse(&two("", "")).unwrap().masses, None);
        for (text, needle) in [
            (two(body, ""), "line 10, column 1: joint elbow has no `mass`, where others have"),
            (two("mass = nan\ncom = [0, 0, 0]", "mass = 0.1\ncom = [0, 0, 0]"), "joint lift: mass NaN kg"),
            (two("mass = -1\ncom = [0, 0, 0]", "mass = 0.1\ncom = [0, 0, 0]"), "is not a body's"),
            (two("mass = 1\ncom = [0, 0, 0]\ninertia = [1, 0, 0, 0.1, 0, 0.1]", ""), "is not a body's"),
            (two("mass = 1", ""), "joint lift: `com = [x, y, z]` (m, in the joint's frame) is required"),
            (two("com = [0, 0, 0]", ""), "joint lift: `com` needs `mass`"),
            (two("mass = 1\ncom = [0, 0]", ""), "invalid length 2"),
        ] {
            let message = error(&text);
            assert!(message.contains(needle), "{message:?} does not say {needle:?}");
        }
        let dh = "name = \"x\"\nconvention = \"dh\"\n[[joint]]\ntype = \"revolute\"\na = 0\nalpha = 0\nd = 0.1\nlimits = [-1, 1]\nmass = 1\ncom = [0, 0, 0]\n";
        assert!(error(dh).contains("`mass` needs convention = \"urdf\""), "{}", error(dh));
    }

    #[test]
    fn errors_say_what_is_wrong() {
        let arm = |joint: &str| format!("name = \"x\"\n[[joint]]\nname = \"elbow\"\n{joint}\n");
        let cases: Vec<(String, &str)> = vec![
            (
                arm("type = \"revolute\"\naxis = [0, 0, 1]"),
                "line 2, column 1: joint elbow: `limits = [lower, upper]` is required for a revolute joint",
            ),
            (arm("type = \"prismatic\"\naxis = [0, 0, 1]"), "required for a prismatic joint"),
            (
                arm("type = \"hinge\"\naxis = [0, 0, 1]"),
                "unknown variant `hinge`, expected one of `revolute`, `continuous`, `prismatic`",
            ),
            (arm("type = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1x]"), "line 6"),
            (arm("type = \"revolute\"\naxis = [0, 0, \"1\"]\nlimits = [-1, 1]"), "line 5"),
            (arm("type = \"revolute\"\naxis = [0, 1]\nlimits = [-1, 1]"), "invalid length 2"),
            (arm("type = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\nlenght = 3"), "unknown field `lenght`"),
            (
                arm("type = \"revolute\"\naxis = [0, 0, 1]\nlimits = [1, -1]"),
                "joint elbow: `limits` lower 1 is above upper -1",
            ),
            (arm("type = \"revolute\"\naxis = [0, 0, nan]\nlimits = [-1, 1]"), "joint elbow: `axis` must be finite"),
            (arm("type = \"revolute\"\nlimits = [-1, 1]"), "joint elbow: `axis = [x, y, z]` is required"),
            (
                arm("type = \"continuous\"\naxis = [0, 0, 1]\nlimits = [-1, 1]"),
                "joint elbow is continuous and has no limits",
            ),
            (arm("type = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\na = 0.1"), "`a` is a DH parameter"),
            (arm("axis = [0, 0, 1]\nlimits = [-1, 1]"), "missing field `type`"),
            (
                format!("convention = \"dh\"\n{}", arm("type = \"revolute\"\na = 0\nd = 0\nlimits = [-1, 1]")),
                "joint elbow: DH parameter `alpha` is missing",
            ),
            (
                format!(
                    "convention = \"modified-dh\"\n{}",
                    arm("type = \"revolute\"\nxyz = [0, 0, 1]\nlimits = [-1, 1]")
                ),
                "`xyz` does not belong in a modified-dh table",
            ),
            (
                "name = \"x\"\nconvention = \"craig\"".into(),
                "unknown variant `craig`, expected one of `urdf`, `dh`, `modified-dh`",
            ),
            ("name = \"x\"\nunits = \"mm\"".into(), "line 2, column 1: unknown field `units`"),
            ("name = \"x\"\n[tool]\nxyz = [0, 0, 1]\nrpy = [0, 0]".into(), "invalid length 2"),
            ("name = \"x\"\n[tool]\nquat = [1, 0, 0, 0]".into(), "unknown field `quat`"),
            ("[[joint]]\ntype = \"continuous\"\naxis = [0, 0, 1]".into(), "missing field `name`"),
        ];
        for (text, expected) in cases {
            let message = error(&text);
            assert!(message.contains(expected), "expected {expected:?} in {message:?}\n{text}");
        }
    }

    #[test]
    fn zero_axis_is_reported_by_chain() {
        let text =
            "name = \"x\"\n[[joint]]\nname = \"wrist\"\ntype = \"revolute\"\naxis = [0, 0, 0]\nlimits = [-1, 1]\n";
        let spec = parse(text).unwrap();
        let e = spec.chain::<f64, 1>().unwrap_err().to_string();
        assert!(e.contains("zero") && e.contains("wrist"), "{e}");
    }

    #[test]
    fn a_gripper_is_read_and_checked() {
        let arm = "name = \"g\"\n[[joint]]\ntype = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\n";
        let servos = "[servos]\nmodel = \"sts3215\"\nids = [1]\nmax_velocity = 2\nmax_acceleration = 8\n";
        let ok = format!("{arm}{servos}[gripper]\nid = 6\nclosed = 2000\nopen = 3000\nopening_mm = 80\n");
        let g = parse(&ok).unwrap().servos.unwrap().gripper.unwrap();
        assert_eq!((g.id, g.closed, g.open, g.effort, g.opening_mm), (6, 2000, 3000, 50.0, 80.0));
        assert_eq!(g.ticks(50.0), 2500);
        let bad = |gripper: &str| error(&format!("{arm}{servos}[gripper]\n{gripper}"));
        assert!(bad("id = 1\nclosed = 2000\nopen = 3000\nopening_mm = 80").contains("a joint's servo"));
        assert!(bad("id = 6\nclosed = 2000\nopen = 2000\nopening_mm = 80").contains("zero width"));
        assert!(bad("id = 6\nclosed = 2000\nopen = 5000\nopening_mm = 80").contains("outside the servo"));
        assert!(bad("id = 6\nclosed = 2000\nopen = 3000\neffort = 150\nopening_mm = 80").contains("effort"));
        assert!(bad("id = 6\nclosed = 2000\nopen = 3000\nopening_mm = nan").contains("opening_mm"));
        assert!(error(&format!("{arm}[gripper]\nid = 6\nclosed = 1\nopen = 2\nopening_mm = 1"))
            .contains("needs a [servos]"));
        assert!(bad("id = 6\nclosed = 2000\nopen = 3000\nopening_mm = 80\nforce = 1").contains("force"));
    }

    #[test]
    fn a_calibration_in_the_servos_table_maps_as_lerobot_does() {
        let arm = "name = \"a\"\n[[joint]]\nname = \"pan\"\ntype = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\n[[joint]]\nname = \"lift\"\ntype = \"revolute\"\naxis = [0, 1, 0]\nlimits = [-1, 1]\n";
        let servos = "[servos]\nmodel = \"sts3215\"\nids = [3, 4]\nmax_velocity = 2\nmax_acceleration = 8\n";
        let ok = format!("{arm}{servos}reversed = [false, true]\nhoming_offset = [953, -1200]\nrange_min = [758, 812]\nrange_max = [3292, 3313]\n");
        let setup = parse(&ok).unwrap().servos.unwrap();
        assert_eq!(
            setup.calibration,
            Some(vec![
                MotorCalibration { id: 3, drive_mode: 0, homing_offset: 953, range_min: 758, range_max: 3292 },
                MotorCalibration { id: 4, drive_mode: 1, homing_offset: -1200, range_min: 812, range_max: 3313 },
            ])
        );
        assert_eq!(setup.mapping(1), Some(firmware::bus::mapping::JointMapping::lerobot(4, 4096, 812, 3313)));
        let bad = |calibration: &str| error(&format!("{arm}{servos}{calibration}"));
        let three = |o: &str, lo: &str, hi: &str| format!("homing_offset = {o}\nrange_min = {lo}\nrange_max = {hi}\n");
        for (text, needle) in [
            (three("[0, 0]", "[100, 2000]", "[3000, 2000]"), "line 19, column 13: [servos] range_max: joint 2 (lift): range_min and range_max are both 2000: a range of zero width"),
            (three("[0, 0]", "[100, 2100]", "[3000, 2000]"), "line 18, column 13: [servos] range_min: joint 2 (lift): range_min 2100 is above range_max 2000"),
            (three("[2048, 0]", "[100, 100]", "[3000, 3000]"), "line 17, column 17: [servos] homing_offset: joint 1 (pan): 2048 is beyond +-2047"),
            (three("[0, -2100]", "[100, 100]", "[3000, 3000]"), "joint 2 (lift): -2100 is beyond +-2047"),
            (three("[0]", "[100, 100]", "[3000, 3000]"), "line 17, column 17: [servos] homing_offset has 1 entries for 2 joints"),
            (three("[0, 0]", "[100, 100]", "[3000, 3000, 1]"), "[servos] range_max has 3 entries for 2 joints"),
            (three("[0, 0]", "[100, -1]", "[3000, 3000]"), "joint 2 (lift): -1 is outside the servo's 0..=4095 ticks"),
            (three("[0, 0]", "[100, 100]", "[3000, 4096]"), "joint 2 (lift): 4096 is outside"),
            ("range_min = [1, 2]\n".into(), "line 17, column 13: [servos] range_min: a calibration needs homing_offset, range_min and range_max together (given: range_min)"),
            (format!("zero = [2048, 2048]\n{}", three("[0, 0]", "[100, 100]", "[3000, 3000]")), "line 17, column 8: [servos] zero does not apply with a calibration"),
        ] {
            let e = bad(&text);
            assert!(e.contains(needle), "expected {needle:?} in {e:?}");
        }
    }

    #[test]
    fn servos_are_read_and_checked() {
        let arm = "name = \"a\"\n[[joint]]\ntype = \"revolute\"\naxis = [0, 0, 1]\nlimits = [-1, 1]\n[[joint]]\ntype = \"revolute\"\naxis = [0, 1, 0]\nlimits = [-1, 1]\n";
        let ok = format!("{arm}[servos]\nmodel = \"sts3215\"\nids = [3, 4]\nreversed = [false, true]\nmax_velocity = 2\nmax_acceleration = 8\n");
        let servos = parse(&ok).unwrap().servos.unwrap();
        assert_eq!(servos.model.name, "STS3215");
        assert_eq!(servos.ids, vec![3, 4]);
        assert_eq!(servos.reversed, Some(vec![false, true]));
        assert_eq!(servos.zero, None);
        assert!(parse(arm).unwrap().servos.is_none());
        let bad = |servos: &str| error(&format!("{arm}[servos]\n{servos}"));
        assert!(bad("model = \"mx-28\"\nids = [1, 2]\nmax_velocity = 2\nmax_acceleration = 8")
            .contains("unknown servo model \"mx-28\""));
        assert!(bad("model = \"STS3215\"\nids = [1]\nmax_velocity = 2\nmax_acceleration = 8")
            .contains("ids has 1 entries for 2 joints"));
        assert!(bad("model = \"STS3215\"\nids = [1, 1]\nmax_velocity = 2\nmax_acceleration = 8")
            .contains("servo id 1 is repeated"));
        assert!(bad("model = \"STS3215\"\nids = [1, 2]\nmax_velocity = 0\nmax_acceleration = 8")
            .contains("max_velocity must be a positive number"));
        assert!(bad("model = \"STS3215\"\nids = [1, 2]\nmax_velocity = 1\nmax_acceleration = 8\nspeed = 3")
            .contains("unknown field"));
    }
}
