//! `armctl --rig FILE status|stop|torque|move|play`: the drive commands over every arm of a rig.
//! As for one arm, everything typed and the whole keyframe file are checked before anything is
//! sent; then each arm gets the request its own `armctl` command would send it.

use std::io::Write;

use anyhow::{bail, Context, Result};
use firmware::link::message::{CartesianTarget, MovePath, Timing};
use kinematics::Pose;

use super::clearance::Clearance;
use super::columns::{self, ArmPart};
use super::play::stop_all;
use super::report::{ArmMoved, ArmStatus, ArmStopped, ByArm, RigMove, RigReport, RigStatus, RigStop, RigTorque};
use super::{Rig, RigSpec};
use crate::commands::drive::avoid;
use crate::commands::drive::move_to::{check_position, check_quaternion, positive, tool_timing};
use crate::commands::drive::path::{self, host_solution};
use crate::commands::drive::state;
use crate::runtime::driver::{check_joints, fmt3};
use crate::support::interrupt;
use crate::support::numbers as parse;

/// One arm's tool target of a rig move (world frame).
struct ArmTarget {
    arm: usize,
    position: [f32; 3],
    orientation: Option<[f32; 4]>,
}

/// A drive command for every arm of a rig, as typed: its arm names (`ARM=VALUES`) and values are
/// checked against the rig file by [`run`] before anything is sent.
#[derive(Clone, Debug, PartialEq)]
pub enum RigCommand {
    /// `status`: every arm's.
    Status,
    /// `stop`: every arm.
    Stop,
    /// `torque on|off`: every arm.
    Torque(bool),
    /// `move`: each arm named in `to` to its tool target.
    Move {
        /// `ARM=x,y,z` (m, the rig's world frame), once per arm to move.
        to: Vec<String>,
        /// `ARM=w,x,y,z`, for the arms whose tool orientation is given.
        quat: Vec<String>,
        /// Tool speed along the line (m/s).
        speed: Option<f64>,
        /// Arrive after this many seconds.
        duration: Option<f64>,
        /// Which way each tool goes.
        path: MovePath,
        /// Give up waiting (and stop the arms) after this many seconds of controller time.
        timeout: f64,
    },
    /// `play`: a keyframe file with each arm's columns (`ARM.q1`, ...).
    Play {
        /// The keyframe CSV file.
        file: std::path::PathBuf,
        /// Seconds of controller time after the last keyframe before giving up.
        timeout: f64,
    },
}

/// A rig command with its input checked.
enum RigRequest {
    Status,
    Stop,
    Torque(bool),
    Move { targets: Vec<ArmTarget>, timing: Timing, path: MovePath, timeout: f64 },
    Play(Vec<ArmPart>),
}

/// Runs a drive command on the rig `file` (a rig file or a built-in rig's name) and prints its
/// report (`json`: one line of JSON); returns the exit code.
pub fn run(file: &str, command: &RigCommand, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let spec = RigSpec::load(file)?;
    let request = parse(&spec, command)?;
    let mut rig = Rig::open(&spec, err)?;
    let code = execute(&mut rig, request, json, out, err)?;
    rig.close(err)?;
    Ok(code)
}

/// `ARM=VALUES`: the arm's index and the values' text.
fn named<'a>(spec: &RigSpec, text: &'a str, what: &str) -> Result<(usize, &'a str)> {
    let Some((name, values)) = text.split_once('=') else {
        bail!("{what} {text:?}: with --rig, name the arm: ARM=VALUES (e.g. {}=0.2,0,0.1)", spec.arms[0].name);
    };
    Ok((spec.arm(name.trim()).with_context(|| what.to_string())?, values))
}

fn parse(spec: &RigSpec, command: &RigCommand) -> Result<RigRequest> {
    Ok(match command {
        RigCommand::Status => RigRequest::Status,
        RigCommand::Stop => RigRequest::Stop,
        RigCommand::Torque(on) => RigRequest::Torque(*on),
        RigCommand::Move { to, quat, speed, duration, path, timeout } => {
            parse_move(spec, to, quat, *speed, *duration, *path, *timeout)?
        }
        RigCommand::Play { file, timeout } => {
            if !(timeout.is_finite() && *timeout > 0.0) {
                bail!("--timeout: {timeout} s must be a positive number");
            }
            let names: Vec<&str> = spec.arms.iter().map(|a| a.name.as_str()).collect();
            let bases: Vec<Pose<f64>> = spec.arms.iter().map(|a| a.base).collect();
            let parts = columns::read(file, &names, &bases, *timeout)?;
            if let Some(part) = parts.iter().find(|p| spec.arms[p.arm].mount.is_some() && p.plan.is_cartesian()) {
                bail!(
                    "{}: arm {} is mounted on another arm, which moves its base: give it joint columns (its Cartesian \
                     columns would be in a moving frame)",
                    file.display(),
                    spec.arms[part.arm].name
                );
            }
            RigRequest::Play(parts)
        }
    })
}

fn parse_move(
    spec: &RigSpec,
    to: &[String],
    quat: &[String],
    speed: Option<f64>,
    duration: Option<f64>,
    path: MovePath,
    timeout: f64,
) -> Result<RigRequest> {
    let mut targets: Vec<ArmTarget> = Vec::new();
    for text in to {
        let (arm, values) = named(spec, text, "--to")?;
        if targets.iter().any(|t| t.arm == arm) {
            bail!("--to: arm {} is given twice", spec.arms[arm].name);
        }
        targets.push(ArmTarget {
            arm,
            position: check_position(parse::fixed::<3>(values, "--to")?, "--to")?,
            orientation: None,
        });
    }
    for text in quat {
        let (arm, values) = named(spec, text, "--quat")?;
        let Some(target) = targets.iter_mut().find(|t| t.arm == arm) else {
            bail!("--quat: arm {} has no --to", spec.arms[arm].name);
        };
        if target.orientation.is_some() {
            bail!("--quat: arm {} is given twice", spec.arms[arm].name);
        }
        target.orientation = Some(check_quaternion(parse::fixed::<4>(values, "--quat")?, "--quat")?);
    }
    let timing = tool_timing(speed, duration)?;
    positive(timeout, f64::from(firmware::link::message::MAX_TIME), "--timeout", "s")?;
    if spec.arms.iter().any(|a| a.mount.is_some()) {
        // One tree: solved on the host, each arm's share sent as a joint move.
        if targets.iter().any(|t| t.orientation.is_some()) {
            bail!("--quat: a rig with an arm mounted on another (a shared joint) solves tool positions only so far");
        }
        if path == MovePath::Line {
            bail!("--path line: a rig with an arm mounted on another (a shared joint) moves by joints (auto or joint)");
        }
    }
    Ok(RigRequest::Move { targets, timing, path, timeout })
}

/// A world-frame target in the base frame of the arm at `base`.
fn in_base(base: &Pose<f64>, target: &ArmTarget) -> CartesianTarget {
    let rotation = target
        .orientation
        .and_then(|q| Pose::rotation_from_quaternion_wxyz(q.map(f64::from)))
        .unwrap_or_else(kinematics::nalgebra::Matrix3::identity);
    let world = Pose { rotation, translation: target.position.map(f64::from).into() };
    let local = base.inverse().compose(&world);
    CartesianTarget {
        position: local.translation.map(|x| x as f32).into(),
        orientation: target.orientation.map(|_| local.quaternion_wxyz().map(|x| x as f32)),
    }
}

/// Carries out `request` on every arm and prints its report (`json`: one line of JSON); returns
/// the exit code (130 after Ctrl-C stopped every arm).
fn execute(rig: &mut Rig, request: RigRequest, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let report = match request {
        RigRequest::Status => RigReport::Status(status(rig)?),
        RigRequest::Stop => RigReport::Stop(stop(rig)?),
        RigRequest::Torque(on) => RigReport::Torque(torque(rig, on)?),
        RigRequest::Move { targets, timing, path, timeout } => {
            let moved = match rig.tree()? {
                Some(tree) => move_tree(rig, &tree, &targets, timing, timeout, err)?,
                None => move_arms(rig, &targets, timing, path, timeout, err)?,
            };
            match moved {
                Some(report) => RigReport::Move(report),
                None => return Ok(interrupt::EXIT_CODE),
            }
        }
        RigRequest::Play(parts) => match super::play::report(rig, parts, err)? {
            Some(report) => RigReport::Play(report),
            None => return Ok(interrupt::EXIT_CODE),
        },
    };
    report.print(json, out)?;
    Ok(0)
}

/// Every arm's status, with its tool in the world frame.
fn status(rig: &mut Rig) -> Result<RigStatus> {
    let mut arms = Vec::new();
    for i in 0..rig.arms.len() {
        let status = rig.arms[i].driver.status()?;
        let tool_world = rig.tool_in_world(i, &status.measured)?;
        let arm = &rig.arms[i];
        arms.push((arm.name.clone(), ArmStatus { status: state::report(&arm.driver, status)?, tool_world }));
    }
    Ok(RigStatus { rig: rig.name.clone(), arms: ByArm(arms) })
}

/// Stops every arm: each told first, then each waited for, so no arm waits on another's stop.
fn stop(rig: &mut Rig) -> Result<RigStop> {
    let sent = stop_all(rig);
    let mut arms = Vec::new();
    for i in 0..rig.arms.len() {
        let name = rig.arms[i].name.clone();
        let status = rig.arms[i].driver.stop().with_context(|| format!("arm {name}"))?;
        let tool_world = rig.tool_in_world(i, &status.measured)?;
        arms.push((name, ArmStopped { state: status.state, tool_world, joints: status.measured.to_vec() }));
    }
    Ok(RigStop { command: "stop", rig: rig.name.clone(), arms: ByArm(arms), sent })
}

/// Every arm's torque on or off.
fn torque(rig: &mut Rig, on: bool) -> Result<RigTorque> {
    let mut arms = Vec::new();
    for arm in &mut rig.arms {
        let result = if on { arm.driver.torque_on() } else { arm.driver.session().torque_off() };
        result.map_err(|e| anyhow::anyhow!("arm {}: torque {}: {e}", arm.name, if on { "on" } else { "off" }))?;
        arms.push((arm.name.clone(), arm.driver.status()?.state));
    }
    Ok(RigTorque { command: "torque", on, rig: rig.name.clone(), arms: ByArm(arms) })
}

/// Seeds tried after the arms' own joints when a tree's solution collides: a free solution of a
/// random target on the torso rig took up to 31 (its nearest solutions fold an arm into its base).
const TREE_SEEDS: usize = 200;
/// The seeds' generator, fixed: the same move finds the same solution.
const TREE_SEEDS_RNG: u64 = 0x5eed;

/// The tree's solution for `wanted` from `seed`, if it is free: every arm's goal clear of itself
/// and its surroundings, and the arms clear of each other. Else why not.
fn free_tree_solution(
    rig: &Rig,
    tree: &super::tree::RigTree,
    clearance: &Clearance,
    seed: &[Vec<f64>],
    wanted: &[Option<[f64; 3]>],
    names: &[&str],
) -> Result<super::tree::TreeMove> {
    let solved = tree.solve(seed, wanted, names)?;
    for (a, arm) in rig.arms.iter().enumerate() {
        avoid::check_goal(&arm.driver, &solved.q[a], &format!("arm {}'s goal", arm.name))
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let ends: Vec<Option<Vec<f64>>> = solved.q.iter().cloned().map(Some).collect();
    if let Some(near) = clearance.closest(&clearance.placed(&ends)?).filter(|n| n.too_close()) {
        bail!("the arms would end too close: {}", near.describe());
    }
    Ok(solved)
}

/// The move of a rig that is one tree (an arm mounted on another): every target solved at once
/// on the host over every joint of the tree (an arm without a target keeps its tool where it is),
/// then each arm's share sent as a joint move, all with one duration so they arrive together.
/// `None` after Ctrl-C (every arm stopped).
fn move_tree(
    rig: &mut Rig,
    tree: &super::tree::RigTree,
    targets: &[ArmTarget],
    timing: Timing,
    timeout: f64,
    err: &mut dyn Write,
) -> Result<Option<RigMove>> {
    let mut q = Vec::new();
    for arm in &mut rig.arms {
        q.push(arm.driver.status()?.measured.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>());
    }
    let mut wanted: Vec<Option<[f64; 3]>> = vec![None; rig.arms.len()];
    for t in targets {
        wanted[t.arm] = Some(t.position.map(f64::from));
    }
    let names: Vec<&str> = rig.arms.iter().map(|a| a.name.as_str()).collect();
    let shown: Vec<String> =
        targets.iter().map(|t| format!("{} to {} m", names[t.arm], fmt3(&t.position.map(f64::from)))).collect();
    // An arm without a target keeps its tool where it is now, whatever the seed.
    let now = tree.tools(&q);
    let wanted: Vec<Option<[f64; 3]>> = wanted.iter().zip(&now).map(|(w, p)| Some(w.unwrap_or(*p))).collect();
    let clearance = Clearance::of(rig)?;
    // The solve from where the arms stand first; if its solution collides (an arm in itself or
    // the table, two arms too close), from other seeds across the joint limits: a target has
    // several solutions, and the nearest one is not always free. The first refusal is the one
    // reported when none is.
    let mut rng = kinematics::SplitMix64::new(TREE_SEEDS_RNG);
    let mut first_error = None;
    let mut solved = None;
    for attempt in 0..=TREE_SEEDS {
        let seed: Vec<Vec<f64>> = if attempt == 0 {
            q.clone()
        } else {
            rig.arms.iter().map(|a| a.driver.model().random_configuration(&mut rng)).collect()
        };
        match free_tree_solution(rig, tree, &clearance, &seed, &wanted, &names) {
            Ok(found) => {
                solved = Some(found);
                break;
            }
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    let Some(solved) = solved else {
        let e = first_error.map(|e| format!("{e:#}")).unwrap_or_default();
        bail!("move {} (world): {e}; no arm moved", shown.join(", "));
    };
    // One duration for all: the tool speed over the longest tool travel, or --duration; each
    // firmware lengthens it where its joint limits need longer, so the speed limit still holds.
    let before = tree.tools(&q);
    let after = tree.tools(&solved.q);
    let travel = before
        .iter()
        .zip(&after)
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    let seconds = match timing {
        Timing::Duration(d) => d,
        Timing::MaxSpeed(speed) => ((travel / f64::from(speed)) as f32).max(0.5),
    };
    let mut switched = Vec::new();
    for (a, arm) in rig.arms.iter_mut().enumerate() {
        let (_, on) = arm.driver.ready_to_move().with_context(|| format!("arm {}", arm.name))?;
        switched.push(on);
        check_joints(&arm.driver, &solved.q[a], &format!("arm {}", arm.name))?;
        // Each arm's move checked as `armctl joints` checks it: in collision refused, a blocked
        // straight path planned around (stretched to the same duration where it can be).
        let from: Vec<f64> = arm.driver.status()?.measured.iter().map(|&x| f64::from(x)).collect();
        if let Err(e) = avoid::send(&mut arm.driver, &from, &solved.q[a], Timing::Duration(seconds)) {
            let name = arm.name.clone();
            let stopped = stop_all(rig);
            bail!("move: arm {name} refused its joints: {e}; {stopped}");
        }
    }
    interrupt::catch();
    let all: Vec<usize> = (0..rig.arms.len()).collect();
    let Some(ends) = rig.wait_all(&all, timeout)? else {
        let stopped = stop_all(rig);
        writeln!(err, "stopped by Ctrl-C: {stopped}")?;
        return Ok(None);
    };
    let measured: Vec<Vec<f64>> = ends.iter().map(|s| s.measured.iter().map(|&x| f64::from(x)).collect()).collect();
    let reached = tree.tools(&measured);
    let mut arms = Vec::new();
    for (a, arm) in rig.arms.iter().enumerate() {
        if switched[a] {
            writeln!(err, "{}: torque was off: switched it on", arm.name)?;
        }
        let goal = wanted[a];
        let error_mm = goal.map(|g| 1e3 * (0..3).map(|i| (reached[a][i] - g[i]).powi(2)).sum::<f64>().sqrt());
        let joints = ends[a].measured.to_vec();
        arms.push((arm.name.clone(), ArmMoved { target: goal, reached: reached[a], error_mm, time_s: None, joints }));
    }
    Ok(Some(RigMove {
        command: "move",
        rig: rig.name.clone(),
        solved_as: Some("one tree"),
        tree_seconds: f64::from(seconds),
        arms: ByArm(arms),
    }))
}

/// Sends every arm its move (each decided as `armctl move` decides one), then waits for all.
/// `None` after Ctrl-C (every arm stopped).
fn move_arms(
    rig: &mut Rig,
    targets: &[ArmTarget],
    timing: Timing,
    path: MovePath,
    timeout: f64,
    err: &mut dyn Write,
) -> Result<Option<RigMove>> {
    // Every target solved on the host first: one out of reach moves no arm.
    let mut ends = Vec::new();
    for arm in &mut rig.arms {
        ends.push(arm.driver.status()?.measured.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>());
    }
    for target in targets {
        let arm = &mut rig.arms[target.arm];
        let status = arm.driver.status()?;
        match host_solution(&arm.driver, &status, &in_base(&arm.base, target))? {
            Some(q) => ends[target.arm] = q,
            None => bail!(
                "move {} to {} m (world): out of reach within the joint limits; no arm moved",
                arm.name,
                fmt3(&target.position.map(f64::from))
            ),
        }
    }
    // Each arm an obstacle for the others: where they would end too close, none moves.
    let clearance = Clearance::of(rig)?;
    let ends: Vec<Option<Vec<f64>>> = ends.into_iter().map(Some).collect();
    if let Some(near) = clearance.closest(&clearance.placed(&ends)?).filter(|n| n.too_close()) {
        bail!("move: the arms would end too close: {}; no arm moved", near.describe());
    }
    let mut starts = Vec::new();
    for (k, target) in targets.iter().enumerate() {
        let arm = &mut rig.arms[target.arm];
        let local = in_base(&arm.base, target);
        let shown = format!("{} to {} m (world)", arm.name, fmt3(&target.position.map(f64::from)));
        let sent = (|| -> Result<(firmware::link::message::Status, bool)> {
            let (start, switched) = arm.driver.ready_to_move()?;
            // As `armctl move` goes: the one rule of drive::path.
            match path::take(&mut arm.driver, &start, local, timing, path) {
                Ok(_) => Ok((start, switched)),
                Err(refused) => {
                    let undone = arm.driver.undo_torque(switched);
                    bail!("{}{undone}{}", refused.reason, refused.hint)
                }
            }
        })();
        match sent {
            Ok(start) => starts.push(start),
            Err(e) => {
                let others = if k > 0 { format!("; {}", stop_all(rig)) } else { String::new() };
                bail!("move {shown}: {e:#}; that arm did not move{others}");
            }
        }
    }
    interrupt::catch();
    let indices: Vec<usize> = targets.iter().map(|t| t.arm).collect();
    let Some(ends) = rig.wait_all(&indices, timeout)? else {
        let stopped = stop_all(rig);
        writeln!(err, "stopped by Ctrl-C: {stopped}")?;
        return Ok(None);
    };
    let mut arms = Vec::new();
    for ((target, (start, switched)), status) in targets.iter().zip(starts).zip(ends) {
        let reached = rig.tool_in_world(target.arm, &status.measured)?;
        let arm = &rig.arms[target.arm];
        if switched {
            writeln!(err, "{}: torque was off: switched it on", arm.name)?;
        }
        let goal = target.position.map(f64::from);
        let error_mm = 1e3 * (0..3).map(|i| (reached[i] - goal[i]).powi(2)).sum::<f64>().sqrt();
        let took = f64::from(status.time - start.time);
        let joints = status.measured.to_vec();
        arms.push((
            arm.name.clone(),
            ArmMoved { target: Some(goal), reached, error_mm: Some(error_mm), time_s: Some(took), joints },
        ));
    }
    Ok(Some(RigMove { command: "move", rig: rig.name.clone(), solved_as: None, tree_seconds: 0.0, arms: ByArm(arms) }))
}
