//! Arms as the host knows them: a run-time joint list ([`ArmSpec`]) read from a preset name, a URDF
//! file or the project's TOML arm file, turned into the kinematics crate's fixed-size chain for the
//! joint count it has (see [`dof`]).

#![warn(missing_docs)]

pub mod arm_dynamics;
pub mod body;
pub mod calibration;
pub mod collision;
pub mod dof;
pub mod dyn_tree;
pub mod presets;
pub mod servos;
pub mod toml_file;
pub mod toml_update;
pub mod toml_writer;
pub mod tree;
pub mod urdf;
pub mod urdf_inertials;
pub mod urdf_visuals;

use anyhow::{bail, Context, Result};
use kinematics::{Chain, Joint, JointKind, Limits, Pose, Real};
use std::path::Path;

/// One joint of an arm, in the form every source converts to.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSpec {
    /// Name (URDF joint name, or `joint1`.. for presets).
    pub name: String,
    /// Revolute, continuous or prismatic.
    pub kind: JointKind,
    /// Transform from the previous joint's frame (or the base) at zero joint value.
    pub origin: Pose<f64>,
    /// Motion axis in the joint frame.
    pub axis: [f64; 3],
    /// Position limits (ignored for continuous joints).
    pub lower: f64,
    /// Upper position limit.
    pub upper: f64,
}

/// An arm: its joints from the base and the fixed tool frame after the last joint.
#[derive(Clone, Debug, PartialEq)]
pub struct ArmSpec {
    /// Name shown in output.
    pub name: String,
    /// Moving joints, base first.
    pub joints: Vec<JointSpec>,
    /// Tool frame relative to the last joint's frame.
    pub tool: Pose<f64>,
    /// The servos driving the joints, when the description names them (the arm file's
    /// `[servos]`); the presets' are in [`servos::ServoSetup::for_arm`].
    pub servos: Option<servos::ServoSetup>,
    /// Its collision geometry, when the description has some (the arm file's `[collision]`, or
    /// a preset's); see [`collision::collision_of`].
    pub collision: Option<collision::CollisionSpec>,
    /// The mass properties of what each joint moves, base first, in the frame it moves, when the
    /// description gives them (the arm file's `mass`, `com` and `inertia` per joint); the
    /// presets' are in [`arm_dynamics::masses_of`].
    pub masses: Option<Vec<kinematics::dynamics::Inertia<f64>>>,
}

impl ArmSpec {
    /// Number of moving joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The baud rate its servos' bus runs at (the arm file's, or the default), if it has servos.
    pub fn bus_baud(&self) -> Option<u32> {
        servos::servos_of(self).map(|s| s.baud)
    }

    /// The same arm with its servos' bus at `baud` (a preset's servos taken as shipped): what is
    /// sent to a firmware core driving a port opened at that rate.
    pub fn at_baud(mut self, baud: u32) -> Self {
        if let Some(mut s) = servos::servos_of(&self) {
            s.baud = baud;
            self.servos = Some(s);
        }
        self
    }

    /// The fixed-size chain in scalar `T`; fails if `N` is not the joint count or the description is
    /// invalid (zero axis, bad limits).
    pub fn chain<T: Real, const N: usize>(&self) -> Result<Chain<T, N>> {
        if self.joints.len() != N {
            bail!("arm {} has {} joints, not {N}", self.name, self.joints.len());
        }
        let joints: [Joint<T>; N] = core::array::from_fn(|i| {
            let j = &self.joints[i];
            Joint {
                origin: cast_pose(&j.origin),
                axis: j.axis.map(T::of).into(),
                kind: j.kind,
                limits: Limits::from_f64(j.lower, j.upper),
            }
        });
        Chain::new(joints, cast_pose(&self.tool)).map_err(|e| {
            let named = match e {
                kinematics::ChainError::ZeroAxis { joint }
                | kinematics::ChainError::BadLimits { joint }
                | kinematics::ChainError::BadFrame { joint: Some(joint) } => {
                    format!(" ({})", self.joints[joint].name)
                }
                kinematics::ChainError::BadFrame { joint: None } => String::new(),
            };
            anyhow::anyhow!("arm {}: {e}{named}", self.name)
        })
    }

    /// The spec of an already built chain (used for the presets).
    pub fn from_chain<const N: usize>(name: &str, chain: &Chain<f64, N>) -> Self {
        let joints = chain
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| JointSpec {
                name: format!("joint{}", i + 1),
                kind: j.kind,
                origin: j.origin,
                axis: [j.axis.x, j.axis.y, j.axis.z],
                lower: j.limits.lower,
                upper: j.limits.upper,
            })
            .collect();
        Self { name: name.to_string(), joints, tool: *chain.tool(), servos: None, collision: None, masses: None }
    }

    /// Loads `arm`: a preset name (`ur5e`, `planar:4`, ...), a `.urdf` file (needs `tip`), or a
    /// `.toml` arm file.
    pub fn load(arm: &str, tip: Option<&str>) -> Result<Self> {
        let path = Path::new(arm);
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match extension.as_deref() {
            _ if tip.is_some() && extension.as_deref() != Some("urdf") => {
                bail!("a tip (--tip, or tip= in Python) applies only to .urdf arms, not to {arm}")
            }
            Some("urdf") => {
                let text = read_urdf(arm)?;
                urdf::parse(&text, tip).with_context(|| format!("URDF {arm}"))
            }
            Some("toml") => {
                let text = std::fs::read_to_string(path).with_context(|| format!("cannot read arm file {arm}"))?;
                toml_file::parse(&text).with_context(|| format!("arm file {arm}"))
            }
            _ => presets::by_name(arm),
        }
    }
}

/// The text of the URDF file `arm`.
fn read_urdf(arm: &str) -> Result<String> {
    std::fs::read_to_string(arm).with_context(|| format!("cannot read URDF {arm}"))
}

fn cast_pose<T: Real>(p: &Pose<f64>) -> Pose<T> {
    Pose { rotation: p.rotation.map(T::of), translation: p.translation.map(T::of) }
}
