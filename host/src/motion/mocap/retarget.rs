//! A BVH arm's motion onto a robot arm: joint keyframes whose tool follows the human hand.
//!
//! 1. The hand relative to the shoulder, in the torso's frame ([`super::hand`]), smoothed over
//!    one keyframe spacing and sampled at the keyframe rate.
//! 2. Axes: the file's Y is up and the human faces its +Z (as in CMU's files and most others);
//!    on the arm, up is +Z and the human faces +X, the arm's front, so the file's +X (the human's
//!    left) is the arm's +Y. The human stands where the arm's base is, looking the way it reaches.
//! 3. Scale: the arm's reach over the human arm's length (shoulder to wrist at rest), or a given
//!    factor (metres per file unit).
//! 4. Placement: the scaled path is shifted to where most of it lies in the arm's sampled
//!    workspace above its base ([`Workspace::place`]), the same for every run.
//! 5. IK per keyframe (damped least squares, f64), warm-started from the previous keyframe's
//!    answer: a position target, and on arms of six joints or more the hand's turn too (see
//!    [`orientation_target`]). A target the solver cannot reach counts as outside the workspace;
//!    the arm then goes as far as it can along the straight line from its last tool position
//!    toward it ([`toward`]): a best-effort answer of the solver can lie anywhere (a joint swung
//!    to its limit), and would be cut by the velocity limit into a lurch.
//! 6. Limits: IK answers lie within the joint limits; the keyframes ask no joint for more than
//!    90 % of its velocity and acceleration limits (the servos' `max_velocity` and
//!    `max_acceleration`, which the firmware enforces too), so the player need not cut corners:
//!    see [`super::timing`].
//!
//! Several arms from one file (a rig's, each following its own human arm) go through the same
//! steps with one scale and one time base: [`timebase`], of which one arm is the case [`retarget`]
//! runs.

use super::bvh::Bvh;
use super::chain::{self, ArmChain};
use super::densify::Track;
use super::hand::{self, HandSample};
use super::rest::{Rest, RestReading};
use super::skeleton::RootOffset;
use super::solve::{branch_changed, nearest, request, toward};
use super::timing::Timing;
use super::workspace::Workspace;
use crate::arm::dof::DynArm;
use anyhow::{bail, Result};
use kinematics::ik::IkStatus;
use kinematics::nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

pub mod timebase;

use timebase::{retarget_arms, Job};

/// Keyframes per second by default: the firmware's player interpolates between them (cubic
/// Hermite at its 100 Hz control rate), and 25 Hz carries a human arm's motion (a few hertz).
pub const DEFAULT_RATE: f64 = 25.0;
/// The velocity limit of an arm without servos (rad/s): half a turn a second, a UR5e's.
pub const DEFAULT_MAX_VELOCITY: f64 = std::f64::consts::PI;
/// The acceleration limit of an arm without servos (rad/s²): the presets' servos'.
pub const DEFAULT_MAX_ACCELERATION: f64 = 8.0;
/// The share of the velocity and acceleration limits the keyframes may use, leaving the player's
/// interpolation room within them.
pub const VELOCITY_MARGIN: f64 = 0.9;
/// The most keyframes one retarget writes. `armctl play` streams a file of any length through the
/// firmware's queue; this bounds the file (about 2 MB) and the IK work (a few seconds).
pub const MAX_KEYFRAMES: usize = 20_000;

/// How the human is scaled onto the arm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    /// The arm's reach over the human arm's length.
    Auto,
    /// Metres per file unit.
    Factor(f64),
}

/// The settings of a retarget.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// `SHOULDER,ELBOW,WRIST`; `None` for the right arm by its usual names.
    pub chain: Option<String>,
    /// The file's rest; `None` reads it from the skeleton.
    pub reference: Option<Rest>,
    /// The scale.
    pub scale: Scale,
    /// The root's OFFSET; `None` guesses from the file ([`RootOffset::detect`]).
    pub root_offset: Option<RootOffset>,
    /// Keyframes per second (lowered to fit the keyframe limit).
    pub rate: f64,
    /// Only the first this many seconds of the file.
    pub seconds: Option<f64>,
    /// What gives way where the human is faster than the arm.
    pub timing: Timing,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            chain: None,
            reference: None,
            scale: Scale::Auto,
            root_offset: None,
            rate: DEFAULT_RATE,
            seconds: None,
            timing: Timing::Fit,
        }
    }
}

/// The result of a retarget.
#[derive(Clone, Debug)]
pub struct Retargeted {
    /// The arm chain used.
    pub chain: ArmChain,
    /// The rest as read from the skeleton.
    pub reading: RestReading,
    /// The rest used: `--reference`, or the one read.
    pub rest: Rest,
    /// How the root's OFFSET was taken.
    pub root_offset: RootOffset,
    /// Metres per file unit.
    pub scale: f64,
    /// The human arm's length, shoulder to wrist at rest (file units).
    pub human_arm_length: f64,
    /// The arm's sampled workspace.
    pub workspace: Workspace,
    /// Where the middle of the scaled path's bounding box was put (m, arm base frame).
    pub placed_at: [f64; 3],
    /// The share of the path that placement found inside the sampled workspace (a voxel map:
    /// IK has the last word).
    pub placed_inside: f64,
    /// Keyframes per second.
    pub rate: f64,
    /// Seconds before the first keyframe (the arm's way to its first pose).
    /// Keyframe times follow from the rate and [`Timing`].
    pub lead_in: f64,
    /// File frames used.
    pub frames_used: usize,
    /// Keyframes sampled from the capture, before [`super::densify`] added any.
    pub keyframes_sampled: usize,
    /// Keyframe times (s, from the start of play).
    pub times: Vec<f64>,
    /// Joint values per keyframe.
    pub q: Vec<Vec<f64>>,
    /// The scaled, placed hand per keyframe (m, arm base frame).
    pub targets: Vec<[f64; 3]>,
    /// The tool per keyframe (forward kinematics of `q`).
    pub tool: Vec<[f64; 3]>,
    /// Whether IK reached each keyframe's target (position).
    pub reachable: Vec<bool>,
    /// Keyframes whose IK answer came from a fresh solve (the warm-started one failed): the arm
    /// may change its configuration (elbow or wrist flipped, the base swung round) on the way
    /// there, and its tool leaves the straight line between the two targets meanwhile.
    pub reconfigured: Vec<bool>,
    /// Steps between two sampled keyframes (before [`super::densify`]) in which some joint moves more
    /// than [`super::solve::BRANCH_CHANGE`]: the arm changing its configuration, whichever solve gave it.
    pub jumps: usize,
    /// The share of the sampled keyframes (before [`super::densify`] added any) whose target IK reached.
    pub inside_workspace: f64,
    /// The share of the sampled keyframes whose pose (position and the hand's turn) IK reached;
    /// `None` on arms of fewer than six joints, which follow the position only.
    pub oriented: Option<f64>,
    /// Keyframe steps that the velocity limit slowed down ([`Timing::Fit`]) or cut short
    /// ([`Timing::Captured`]).
    pub velocity_limited: usize,
    /// Things the caller should print as notes.
    pub notes: Vec<String>,
}

/// Mean, 95th percentile and maximum of a set of values.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Maximum.
    pub max: f64,
}

impl Spread {
    /// The spread of `values`; `None` when there are none.
    pub fn of(mut values: Vec<f64>) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        values.sort_by(f64::total_cmp);
        let n = values.len();
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Some(Self { mean: values.iter().sum::<f64>() / n as f64, p95: values[rank], max: values[n - 1] })
    }
}

impl Retargeted {
    /// The share of the sampled keyframes whose target IK reached.
    pub fn reachable_fraction(&self) -> f64 {
        self.inside_workspace
    }

    /// Tool against target (mm) over the keyframes IK reached.
    pub fn tracking_mm(&self) -> Option<Spread> {
        let errors = self
            .targets
            .iter()
            .zip(&self.tool)
            .zip(&self.reachable)
            .filter(|(_, r)| **r)
            .map(|((t, p), _)| 1e3 * (Vector3::from(*t) - Vector3::from(*p)).norm())
            .collect();
        Spread::of(errors)
    }

    /// The keyframe CSV `armctl play` reads: `t,q1,...,qN`.
    pub fn write_csv(&self, out: &mut dyn std::io::Write) -> Result<()> {
        let n = self.q.first().map_or(0, Vec::len);
        let header: Vec<String> = std::iter::once("t".to_string()).chain((1..=n).map(|j| format!("q{j}"))).collect();
        let mut text = header.join(",");
        text.push('\n');
        for (t, q) in self.times.iter().zip(&self.q) {
            // Joint values in full: rounded, a value IK left at a joint limit could land beyond it.
            crate::motion::trajectory::push_keyframe_row(&mut text, *t, q.iter().copied());
        }
        out.write_all(text.as_bytes())?;
        Ok(())
    }
}

/// The file's axes to the arm's: arm x = file z (the way the human faces), arm y = file x (their
/// left), arm z = file y (up). A proper rotation (a cyclic permutation).
pub fn file_to_arm() -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0))
}

/// The tool's target orientation for a hand turned `hand` when the first keyframe's was `first`:
/// the tool starts as IK left it at the first keyframe (`tool_first`) and turns with the hand,
/// the turn carried into the arm's axes. A human hand and a tool share no natural "zero", so only
/// the turn is copied, not an absolute orientation.
pub fn orientation_target(
    hand: &UnitQuaternion<f64>,
    first: &UnitQuaternion<f64>,
    tool_first: &UnitQuaternion<f64>,
) -> UnitQuaternion<f64> {
    let c = UnitQuaternion::from_rotation_matrix(&file_to_arm());
    c * (hand * first.inverse()) * c.inverse() * tool_first
}

fn rotation_of(pose: &kinematics::Pose<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(pose.rotation))
}

/// Fails unless `rate` is a positive number of keyframes per second.
fn check_rate(rate: f64) -> Result<()> {
    if !(rate.is_finite() && rate > 0.0) {
        bail!("--rate {rate}: keyframes per second must be a positive number");
    }
    Ok(())
}

/// Retargets `bvh` onto `arm`: the one-arm case of [`timebase::retarget_arms`].
pub fn retarget(bvh: &Bvh, arm: &dyn DynArm, options: &Options) -> Result<Retargeted> {
    check_rate(options.rate)?;
    let chain = chain::find(bvh, options.chain.as_deref())?;
    let job = Job { name: arm.spec().name.clone(), arm, chain };
    Ok(retarget_arms(bvh, vec![job], options)?.into_one())
}

/// One arm's keyframes as IK found them, before [`super::densify`] and timing.
struct Followed {
    /// Where the middle of the scaled path's bounding box was put (m, arm base frame).
    pub placed_at: [f64; 3],
    /// The share of the path placement found inside the sampled workspace.
    pub placed_inside: f64,
    /// The keyframes, one per sample.
    pub track: Track,
    /// Whether IK follows the hand's turn too (arms of six joints or more).
    pub with_orientation: bool,
    /// The share of the samples whose pose IK reached (with orientation only).
    pub oriented: Option<f64>,
    /// The share of the samples whose target IK reached.
    pub inside_workspace: f64,
    /// Steps in which some joint moves more than [`super::solve::BRANCH_CHANGE`].
    pub jumps: usize,
}

/// Steps 1, 2, 4 and 5 of the module's list for one arm: the hand `path` (file frames
/// `frame_time` s apart) sampled `count` times at `rate`, scaled by `scale`, placed in `ws` and
/// followed by IK keyframe by keyframe.
fn follow(
    arm: &dyn DynArm,
    path: &[HandSample],
    frame_time: f64,
    (rate, count): (f64, usize),
    scale: f64,
    ws: &Workspace,
) -> Result<Followed> {
    let c = file_to_arm();
    let samples: Vec<HandSample> =
        (0..count).map(|k| hand::sample(path, frame_time, k as f64 / rate, 1.0 / rate)).collect();
    let scaled: Vec<Vector3<f64>> = samples.iter().map(|h| c * h.position * scale).collect();
    let (shift, placed_inside) = ws.place(&scaled);
    let lo = scaled.iter().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = scaled.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
    let targets: Vec<Vector3<f64>> = scaled.iter().map(|p| p + shift).collect();

    let with_orientation = arm.spec().dof() >= 6;
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(count);
    let mut reachable = Vec::with_capacity(count);
    let mut reconfigured = Vec::with_capacity(count);
    let mut oriented = 0usize;
    let mut tool_first = UnitQuaternion::identity();
    for (k, target) in targets.iter().enumerate() {
        let previous = q.last().cloned();
        let mut fresh_start = false;
        let mut solved = arm.solve(&request(*target, None, previous.clone()))?;
        if let (false, Some(prev)) = (solved.status == IkStatus::Converged, &previous) {
            // Stuck (often at the stretched-out singularity the last unreachable target left the
            // arm in): the closed form nearest the last keyframe, else afresh with restarts, else
            // as far as the line allows.
            if let Some(q) = nearest(arm, *target, None, prev)? {
                fresh_start = branch_changed(prev, &q);
                (solved.q, solved.status) = (q, IkStatus::Converged);
            } else {
                let fresh = arm.solve(&request(*target, None, None))?;
                if fresh.status == IkStatus::Converged {
                    solved = fresh;
                    fresh_start = true;
                } else {
                    solved.q = toward(arm, prev, target)?;
                }
            }
        }
        if k == 0 {
            tool_first = rotation_of(&arm.tool_pose(&solved.q)?);
        }
        let mut reached = solved.status == IkStatus::Converged;
        if with_orientation {
            let goal = orientation_target(&samples[k].orientation, &samples[0].orientation, &tool_first);
            let seed = previous.clone().unwrap_or_else(|| solved.q.clone());
            let mut posed = arm.solve(&request(*target, Some(&goal), Some(seed.clone())))?;
            let mut posed_fresh = false;
            if posed.status != IkStatus::Converged && k > 0 {
                // As for the position: the closed form nearest, else afresh with restarts, before
                // settling for position only.
                if let Some(q) = nearest(arm, *target, Some(&goal), &seed)? {
                    posed_fresh = branch_changed(&seed, &q);
                    (posed.q, posed.status) = (q, IkStatus::Converged);
                } else {
                    posed = arm.solve(&request(*target, Some(&goal), None))?;
                    posed_fresh = true;
                }
            }
            if posed.status == IkStatus::Converged {
                oriented += 1;
                reached = true;
                solved = posed;
                fresh_start = posed_fresh;
            }
        }
        reachable.push(reached);
        reconfigured.push(fresh_start);
        q.push(solved.q);
    }

    let inside_workspace = reachable.iter().filter(|r| **r).count() as f64 / count as f64;
    let jumps = q.windows(2).filter(|w| branch_changed(&w[0], &w[1])).count();
    Ok(Followed {
        placed_at: (shift + (lo + hi) / 2.0).into(),
        placed_inside,
        track: Track { q, targets, reachable, reconfigured, steps: vec![1.0 / rate; count - 1] },
        with_orientation,
        oriented: with_orientation.then_some(oriented as f64 / count as f64),
        inside_workspace,
        jumps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_axes_map_onto_the_arm_as_documented() {
        let c = file_to_arm();
        assert_eq!(c * Vector3::new(0.0, 0.0, 1.0), Vector3::new(1.0, 0.0, 0.0)); // faces +x
        assert_eq!(c * Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, 0.0)); // left is +y
        assert_eq!(c * Vector3::new(0.0, 1.0, 0.0), Vector3::new(0.0, 0.0, 1.0)); // up is +z
        assert!((c.matrix().determinant() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn the_tool_turns_as_the_hand_turns() {
        let first = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.1);
        let tool_first = UnitQuaternion::from_euler_angles(0.0, 1.0, 0.0);
        assert!(orientation_target(&first, &first, &tool_first).angle_to(&tool_first) < 1e-12);
        // A quarter turn of the hand about the file's up axis is a quarter turn of the tool about
        // the arm's z, applied in the base frame.
        let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.5);
        let target = orientation_target(&(turn * first), &first, &tool_first);
        let expected = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.5) * tool_first;
        assert!(target.angle_to(&expected) < 1e-12);
    }

    #[test]
    fn spreads_use_the_nearest_rank() {
        let s = Spread::of((1..=100).map(f64::from).collect()).unwrap();
        assert_eq!((s.mean, s.p95, s.max), (50.5, 95.0, 100.0));
        assert!(Spread::of(Vec::new()).is_none());
    }
}
