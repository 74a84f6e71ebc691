//! Several arms retargeted from one file on one time base: each arm of a rig follows a human arm
//! of its own, and their keyframes share their times, so one keyframe file holds them all, row by
//! row.
//!
//! Each arm goes through the steps of [`super`] with its own chain, rest, workspace and
//! placement (its own base frame). Four things are shared:
//! - The scale: one for every arm. With `--scale auto` it is the smallest of the arms' own (each
//!   arm's reach over its human arm's length), so every hand fits its arm and the two hands keep
//!   their motions in proportion: hands that move alike (meeting in front of the chest) move both
//!   tools alike, where per-arm scales would differ by the capture's left-right asymmetry (3 % on
//!   CMU's 01_01).
//! - The samples: every arm sampled at the same times from the same frames.
//! - The cuts: where one arm's joint would move far between two keyframes, [`densify`] cuts the
//!   step; every arm's step is cut into as many pieces as the arm that needs the most
//!   ([`densify::cut`]).
//! - The time warp: [`time_joints`] times all the arms' joints as one vector, each joint with its
//!   own arm's limits. With [`Timing::Fit`] a step takes as long as the slowest arm needs, so where
//!   one arm slows down the other slows down with it (it moves the same way, more slowly) and the
//!   rows line up; with [`Timing::Captured`] the times are the capture's, and each arm's joint steps
//!   are cut to its own limits. The lead-in (the way to the first pose) is the longest any arm
//!   needs.
//!
//! Arms that share a joint (a turning torso under both, [`SharedJoints`]): each arm is first
//! retargeted alone with the carrier at rest, which gives each keyframe its tool targets; then
//! every keyframe is solved again as one tree problem over every joint, the carrier's included,
//! seeded from the keyframe before, so the shared joint serves every hand. The carrier follows no
//! human arm: its joints are where the tree puts them, and they are timed with the others, each
//! with its own arm's limits.

use super::{
    check_rate, follow, Followed, Options, Retargeted, Scale, DEFAULT_MAX_ACCELERATION, DEFAULT_MAX_VELOCITY,
    MAX_KEYFRAMES, VELOCITY_MARGIN,
};
use crate::arm::dof::DynArm;
use crate::motion::mocap::bvh::Bvh;
use crate::motion::mocap::chain::ArmChain;
use crate::motion::mocap::densify::{self, Added, Track, MAX_JOINT_STEP};
use crate::motion::mocap::hand::{self, HandSample};
use crate::motion::mocap::rest::{self, RestReading};
use crate::motion::mocap::skeleton::RootOffset;
use crate::motion::mocap::timing::{time_joints, time_keyframes, Limits, Timing};
use crate::motion::mocap::workspace::{self, Workspace};
use anyhow::{bail, Result};

/// The fraction of the way back to rest each keyframe's seed moves a carrier's joints (a torso).
/// Measured on 01_01's first 8 s: the torso over -87.2 to +34.6 degrees, against -90 (its limit)
/// to +34.6 without it.
const TOWARD_REST: f64 = 0.3;

/// One arm to retarget onto.
pub struct Job<'a> {
    /// Its name, for messages (the rig's arm name).
    pub name: String,
    /// The arm.
    pub arm: &'a dyn DynArm,
    /// The human arm it follows.
    pub chain: ArmChain,
}

/// Arms that carry the retargeted ones (a turning torso): one tree IK problem per keyframe over
/// every joint. The followers are the jobs, in their order; the carriers are arms without a human
/// arm of their own. "At rest" is each carrier at the middle of its limits: the followers' frames
/// (their targets, tools and placement) are their base frames with the carriers there.
pub trait SharedJoints {
    /// The carriers, in order.
    fn carriers(&self) -> Vec<&dyn DynArm>;
    /// Solves one keyframe: `targets` are the followers' tool targets (each in its frame at rest),
    /// `seed` the joints to start from (every carrier's, then every follower's). Returns the
    /// joints (in the same order) and, per follower, whether its target was reached.
    fn solve(&self, seed: &[Vec<f64>], targets: &[[f64; 3]]) -> (Vec<Vec<f64>>, Vec<bool>);
    /// The followers' tools at joints `q` (as [`Self::solve`] orders them), each in its frame at rest.
    fn tools(&self, q: &[Vec<f64>]) -> Vec<[f64; 3]>;
}

/// How the tree solves of [`SharedJoints`] came out.
#[derive(Clone, Debug, Default)]
pub struct TreeFigures {
    /// Keyframes solved again from the arms' own joints with the carriers at rest, because the
    /// solve from the keyframe before missed a target the arm's own solve reached.
    pub reseeded: usize,
    /// Keyframes where even that missed such a target (the tracking figures include them).
    pub missed: usize,
}

/// Several arms retargeted on one time base.
#[derive(Clone, Debug)]
pub struct Retargets {
    /// Each arm's result, in the order of the jobs. Their `times`, `lead_in`, `rate`, `scale`,
    /// `frames_used` and `keyframes_sampled` are the shared ones below; `velocity_limited` counts
    /// the steps that arm's own limits would have slowed down (or cut) had it been alone; `notes`
    /// are empty (the notes are the rig's, below).
    pub arms: Vec<Retargeted>,
    /// Keyframe times (s, from the start of play), every arm's.
    pub times: Vec<f64>,
    /// Seconds before the first keyframe: the longest any arm needs to reach its first pose.
    pub lead_in: f64,
    /// Keyframes per second.
    pub rate: f64,
    /// Metres per file unit, every arm's.
    pub scale: f64,
    /// File frames used.
    pub frames_used: usize,
    /// Keyframes sampled from the capture, before [`densify`] added any.
    pub keyframes_sampled: usize,
    /// Keyframe steps the common time warp slowed down ([`Timing::Fit`]), or in which some arm's
    /// joint step was cut ([`Timing::Captured`]).
    pub velocity_limited: usize,
    /// Things the caller should print as notes.
    pub notes: Vec<String>,
    /// With [`SharedJoints`]: each carrier's joints at every keyframe (else empty).
    pub carriers: Vec<Vec<Vec<f64>>>,
    /// With [`SharedJoints`]: how the tree solves came out.
    pub tree: Option<TreeFigures>,
}

impl Retargets {
    /// The one arm's result, with the notes: what [`super::retarget`] returns.
    pub fn into_one(mut self) -> Retargeted {
        let mut r = self.arms.swap_remove(0);
        r.velocity_limited = self.velocity_limited;
        r.notes = self.notes;
        r
    }

    /// The rig keyframe file: `t,NAME.q1,...,NAME.qN` for each arm (`names`, in the arms' order),
    /// one row per shared keyframe time, as `armctl --rig RIG play` reads it
    /// ([`crate::rig::columns`]).
    pub fn write_csv(&self, names: &[&str], out: &mut dyn std::io::Write) -> Result<()> {
        assert_eq!(names.len(), self.arms.len(), "one name per arm");
        let columns: Vec<(&str, &[Vec<f64>])> = names.iter().zip(&self.arms).map(|(n, r)| (*n, &r.q[..])).collect();
        self.write_columns(&columns, out)
    }

    /// The rig keyframe file with `columns` in the order given: each an arm's name and its joints
    /// at every keyframe (a follower's `q` or a carrier's from [`Self::carriers`]).
    pub fn write_columns(&self, columns: &[(&str, &[Vec<f64>])], out: &mut dyn std::io::Write) -> Result<()> {
        use std::fmt::Write;
        let mut text = String::from("t");
        for (name, q) in columns {
            for j in 1..=q.first().map_or(0, Vec::len) {
                write!(text, ",{name}.q{j}")?;
            }
        }
        text.push('\n');
        for (k, t) in self.times.iter().enumerate() {
            // In full, as the one-arm file (see [`Retargeted::write_csv`]).
            let values = columns.iter().flat_map(|(_, q)| q[k].iter().copied());
            crate::motion::trajectory::push_keyframe_row(&mut text, *t, values);
        }
        out.write_all(text.as_bytes())?;
        Ok(())
    }
}

/// An arm's velocity and acceleration limits (rad/s, rad/s²): its servos', else the defaults.
pub fn limits_of(arm: &dyn DynArm) -> (f64, f64) {
    let servos = crate::arm::servos::servos_of(arm.spec());
    (
        servos.as_ref().map_or(DEFAULT_MAX_VELOCITY, |s| s.max_velocity),
        servos.as_ref().map_or(DEFAULT_MAX_ACCELERATION, |s| s.max_acceleration),
    )
}

/// Retargets `bvh` onto every job's arm, each following its chain, on one time base (see the
/// module's documentation). With several jobs, errors name the arm.
pub fn retarget_arms(bvh: &Bvh, jobs: Vec<Job<'_>>, options: &Options) -> Result<Retargets> {
    retarget_sharing(bvh, jobs, None, options)
}

/// [`retarget_arms`], with the arms on carriers that `shared` solves with them as one tree at
/// every keyframe (see the module's documentation).
pub fn retarget_sharing(
    bvh: &Bvh,
    jobs: Vec<Job<'_>>,
    shared: Option<&dyn SharedJoints>,
    options: &Options,
) -> Result<Retargets> {
    check_rate(options.rate)?;
    if jobs.is_empty() {
        bail!("no arm to retarget onto");
    }
    let several = jobs.len() > 1;
    let in_arm = |e: anyhow::Error, name: &str| if several { e.context(format!("arm {name}")) } else { e };
    let root_offset = options.root_offset.unwrap_or_else(|| RootOffset::detect(bvh));
    let mut notes = Vec::new();

    // Each arm's rest and hand path.
    let mut readings: Vec<RestReading> = Vec::with_capacity(jobs.len());
    let mut paths: Vec<Vec<HandSample>> = Vec::with_capacity(jobs.len());
    for job in &jobs {
        let reading = rest::detect(bvh, &job.chain).map_err(|e| in_arm(e, &job.name))?;
        let d = rest::rest_to_t_pose(bvh, &job.chain, &reading, options.reference);
        paths.push(hand::hand_path(bvh, &job.chain, root_offset, &d[2]));
        readings.push(reading);
    }
    let mut frames_used = bvh.frames.len();
    if let Some(seconds) = options.seconds {
        if !(seconds.is_finite() && seconds > 0.0) {
            bail!("--seconds {seconds}: must be a positive number");
        }
        frames_used = ((seconds / bvh.frame_time).floor() as usize + 1).min(frames_used);
    }
    for path in &mut paths {
        path.truncate(frames_used);
    }
    if frames_used < 2 {
        bail!("one frame of motion: a path needs at least two");
    }
    let duration = (frames_used - 1) as f64 * bvh.frame_time;
    let mut rate = options.rate;
    if (duration * rate).floor() as usize + 1 > MAX_KEYFRAMES {
        rate = (MAX_KEYFRAMES - 1) as f64 / duration;
        notes.push(format!(
            "{duration:.1} s of motion at {} keyframes a second would be more than {MAX_KEYFRAMES} keyframes: \
             {rate:.2} a second instead",
            options.rate
        ));
    }
    let count = (duration * rate + 1e-9).floor() as usize + 1;

    // Each human arm's length (shoulder to wrist at rest) and each arm's workspace.
    let mut lengths: Vec<f64> = Vec::with_capacity(jobs.len());
    let mut workspaces: Vec<Workspace> = Vec::with_capacity(jobs.len());
    for job in &jobs {
        let [s, e, w] = job.chain.joints;
        let length = (rest::rest_position(bvh, e) - rest::rest_position(bvh, s)).norm()
            + (rest::rest_position(bvh, w) - rest::rest_position(bvh, e)).norm();
        if length <= 0.0 {
            let e = anyhow::anyhow!("the arm {}..{} has zero length at rest", job.chain.names[0], job.chain.names[2]);
            return Err(in_arm(e, &job.name));
        }
        lengths.push(length);
        workspaces.push(workspace::sample(job.arm).map_err(|e| in_arm(e, &job.name))?);
    }
    let scale = match options.scale {
        // The smallest of the arms' own: each hand then fits its arm (see the module's documentation).
        Scale::Auto => workspaces.iter().zip(&lengths).map(|(w, l)| w.reach / l).fold(f64::INFINITY, f64::min),
        Scale::Factor(f) if f.is_finite() && f > 0.0 => f,
        Scale::Factor(f) => bail!("--scale {f}: must be a positive number (metres per file unit) or auto"),
    };

    let mut followed: Vec<Followed> = Vec::with_capacity(jobs.len());
    for ((job, path), ws) in jobs.iter().zip(&paths).zip(&workspaces) {
        let f = follow(job.arm, path, bvh.frame_time, (rate, count), scale, ws).map_err(|e| in_arm(e, &job.name))?;
        followed.push(f);
    }

    // One set of cuts: each step into as many pieces as the arm needing the most.
    let own: Vec<Vec<usize>> = followed.iter().map(|f| densify::cuts(&f.track)).collect();
    let cuts: Vec<usize> = (0..count - 1).map(|k| own.iter().map(|c| c[k]).max().unwrap_or(1)).collect();
    let total = 1 + cuts.iter().sum::<usize>();
    let added = if total > MAX_KEYFRAMES {
        Added::TooMany(total)
    } else if total == count {
        Added::Keyframes(0)
    } else {
        for (job, f) in jobs.iter().zip(&mut followed) {
            let track = std::mem::take(&mut f.track);
            f.track = densify::cut(job.arm, track, f.with_orientation, &cuts)?;
        }
        Added::Keyframes(total - count)
    };
    match added {
        Added::Keyframes(0) => {}
        Added::Keyframes(n) => notes.push(format!(
            "{n} keyframes added where a joint would move more than {MAX_JOINT_STEP} rad between two (the tool \
             would bow off the hand's path)"
        )),
        Added::TooMany(n) => notes.push(format!(
            "no keyframes added between those where a joint moves more than {MAX_JOINT_STEP} rad: that would make \
             {n}, more than {MAX_KEYFRAMES}; the tool bows off the hand's path there (a lower --rate or --seconds \
             leaves room)"
        )),
    }
    let keyframes = followed[0].track.q.len();
    let steps = followed[0].track.steps.clone();

    // Arms that share a joint: every keyframe one tree problem, seeded from the keyframe before.
    let carrier_arms: Vec<&dyn DynArm> = shared.map_or_else(Vec::new, |s| s.carriers());
    let mut carried: Vec<Vec<Vec<f64>>> = Vec::new();
    let mut tree = None;
    if let Some(shared) = shared {
        let mut figures = TreeFigures::default();
        let at_rest: Vec<Vec<f64>> = carrier_arms.iter().map(|a| a.middle()).collect();
        let mut previous: Option<Vec<Vec<f64>>> = None;
        for k in 0..keyframes {
            let own: Vec<Vec<f64>> = followed.iter().map(|f| f.track.q[k].clone()).collect();
            // Where an arm's own solve fell short, its own tool is the target: reachable, and the
            // closest to the hand it found.
            let mut targets = Vec::with_capacity(jobs.len());
            for (job, f) in jobs.iter().zip(&followed) {
                targets.push(if f.track.reachable[k] {
                    f.track.targets[k].into()
                } else {
                    job.arm.tool_pose(&f.track.q[k])?.translation.into()
                });
            }
            let from_rest: Vec<Vec<f64>> = at_rest.iter().chain(&own).cloned().collect();
            let missed = |reached: &[bool]| followed.iter().zip(reached).any(|(f, r)| f.track.reachable[k] && !r);
            // The seed: the keyframe before, with the carriers' joints drawn back toward rest by
            // TOWARD_REST, so the smallest step from there uses the shared joint but leans it
            // back to its middle. (Seeded from each arm's own solution instead, the torso never
            // moves: those reach every target with it at rest. Seeded from the keyframe before
            // alone, it went to its limit on 01_01; with the lean it stops 2.7 degrees short.)
            let seed: Vec<Vec<f64>> = match &previous {
                None => from_rest.clone(),
                Some(previous) => at_rest
                    .iter()
                    .zip(previous)
                    .map(|(rest, q)| q.iter().zip(rest).map(|(x, r)| x + TOWARD_REST * (r - x)).collect())
                    .chain(previous[at_rest.len()..].iter().cloned())
                    .collect(),
            };
            let (mut q, reached) = shared.solve(&seed, &targets);
            if previous.is_some() && missed(&reached) {
                figures.reseeded += 1;
                let (again, reached) = shared.solve(&from_rest, &targets);
                q = again;
                if missed(&reached) {
                    figures.missed += 1;
                }
            } else if missed(&reached) {
                figures.missed += 1;
            }
            for (i, f) in followed.iter_mut().enumerate() {
                f.track.q[k] = q[carrier_arms.len() + i].clone();
            }
            carried.push(q[..carrier_arms.len()].to_vec());
            previous = Some(q);
        }
        tree = Some(figures);
    }

    // Time for every arm to come to its first pose: from the middle of its limits at half its
    // velocity limit, plus a second to settle; the longest of them.
    let mut lead_in = 0.0f64;
    let mut limits: Vec<Limits> = Vec::new();
    let mut alone = Vec::with_capacity(jobs.len());
    for (c, arm) in carrier_arms.iter().enumerate() {
        let (v_max, a_max) = limits_of(*arm);
        let middle = arm.middle();
        let far = carried[0][c].iter().zip(&middle).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        lead_in = lead_in.max(1.0 + far / (0.5 * v_max));
        let arm_limits = Limits { velocity: VELOCITY_MARGIN * v_max, acceleration: VELOCITY_MARGIN * a_max };
        limits.extend(std::iter::repeat_n(arm_limits, arm.spec().dof()));
    }
    for (job, f) in jobs.iter().zip(&followed) {
        let (v_max, a_max) = limits_of(job.arm);
        let middle = job.arm.middle();
        let far = f.track.q[0].iter().zip(&middle).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        lead_in = lead_in.max(1.0 + far / (0.5 * v_max));
        let arm_limits = Limits { velocity: VELOCITY_MARGIN * v_max, acceleration: VELOCITY_MARGIN * a_max };
        limits.extend(std::iter::repeat_n(arm_limits, job.arm.spec().dof()));
        // The steps this arm would have slowed down (or cut) alone.
        alone.push(time_keyframes(&mut f.track.q.clone(), &steps, &arm_limits, options.timing).limited);
    }
    // All the arms' joints as one vector: one time warp.
    // Every carrier's joints first, then every follower's.
    let mut all: Vec<Vec<f64>> = (0..keyframes)
        .map(|k| {
            let carriers = carried.get(k).into_iter().flatten().flat_map(|q| q.iter().copied());
            carriers.chain(followed.iter().flat_map(|f| f.track.q[k].iter().copied())).collect()
        })
        .collect();
    let timed = time_joints(&mut all, &steps, &limits, options.timing);
    let times: Vec<f64> = timed.offsets.iter().map(|t| lead_in + t).collect();
    if timed.limited > 0 {
        // Each arm's limits once (the same arms' once in all): velocity and acceleration for
        // fit, velocity for captured, which cuts joint steps to it.
        let mut limits_texts: Vec<String> = Vec::new();
        for arm in carrier_arms.iter().copied().chain(jobs.iter().map(|j| j.arm)) {
            let (v, a) = limits_of(arm);
            let text = match options.timing {
                Timing::Fit => format!("{v} rad/s, {a} rad/s²"),
                Timing::Captured => format!("{v} rad/s"),
            };
            if !limits_texts.contains(&text) {
                limits_texts.push(text);
            }
        }
        let limits_text = limits_texts.join("; ");
        notes.push(match options.timing {
            Timing::Fit => format!(
                "{} of {} keyframe steps would move or speed up a joint faster than {:.0} % of its limits ({limits_text}): \
                 they take longer{}, and the motion plays in {:.2} s instead of the captured {:.2} s",
                timed.limited,
                keyframes - 1,
                VELOCITY_MARGIN * 100.0,
                if several { " for every arm (one time warp)" } else { "" },
                timed.offsets[keyframes - 1],
                (count - 1) as f64 / rate
            ),
            Timing::Captured => format!(
                "{} of {} keyframe steps had a joint step cut to {:.0} % of the velocity limit ({limits_text}): the \
                 tool lags the hand there",
                timed.limited,
                keyframes - 1,
                VELOCITY_MARGIN * 100.0
            ),
        });
    }

    // The carriers' joints, and every keyframe's joints split per arm, as timed.
    let mut column = 0;
    let mut carriers = Vec::with_capacity(carrier_arms.len());
    for arm in &carrier_arms {
        let dof = arm.spec().dof();
        carriers.push(all.iter().map(|row| row[column..column + dof].to_vec()).collect::<Vec<_>>());
        column += dof;
    }
    let split = |row: &[f64]| -> Vec<Vec<f64>> {
        let mut at = 0;
        let mut parts = Vec::new();
        for arm in carrier_arms.iter().copied().chain(jobs.iter().map(|j| j.arm)) {
            let dof = arm.spec().dof();
            parts.push(row[at..at + dof].to_vec());
            at += dof;
        }
        parts
    };
    // With a tree, each follower's tool in its frame at rest, from the tree's forward kinematics.
    let tree_tools: Option<Vec<Vec<[f64; 3]>>> = shared.map(|s| all.iter().map(|row| s.tools(&split(row))).collect());
    let mut arms = Vec::with_capacity(jobs.len());
    let arms_data = jobs.into_iter().zip(readings).zip(lengths).zip(workspaces).zip(followed).zip(alone);
    for (i, (((((job, reading), length), workspace), f), alone)) in arms_data.enumerate() {
        let dof = job.arm.spec().dof();
        let q: Vec<Vec<f64>> = all.iter().map(|row| row[column..column + dof].to_vec()).collect();
        column += dof;
        let tool = match &tree_tools {
            Some(tools) => tools.iter().map(|t| t[i]).collect(),
            None => q
                .iter()
                .map(|qk| job.arm.tool_pose(qk).map(|p| p.translation.into()))
                .collect::<Result<Vec<[f64; 3]>>>()?,
        };
        let Track { targets, reachable, reconfigured, .. } = f.track;
        arms.push(Retargeted {
            rest: options.reference.unwrap_or(reading.rest),
            chain: job.chain,
            reading,
            root_offset,
            scale,
            human_arm_length: length,
            workspace,
            placed_at: f.placed_at,
            placed_inside: f.placed_inside,
            rate,
            lead_in,
            frames_used,
            keyframes_sampled: count,
            times: times.clone(),
            q,
            targets: targets.iter().map(|t| (*t).into()).collect(),
            tool,
            reachable,
            reconfigured,
            jumps: f.jumps,
            inside_workspace: f.inside_workspace,
            oriented: f.oriented,
            velocity_limited: alone,
            notes: Vec::new(),
        });
    }
    Ok(Retargets {
        arms,
        times,
        lead_in,
        rate,
        scale,
        frames_used,
        keyframes_sampled: count,
        velocity_limited: timed.limited,
        notes,
        carriers,
        tree,
    })
}
