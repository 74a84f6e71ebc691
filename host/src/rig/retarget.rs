//! `armctl retarget FILE.bvh --rig RIG`: the human's arms onto every arm of a rig in one pass, as
//! one keyframe file with every arm's columns for `armctl --rig RIG play` (`--out`), a plot per arm
//! (`--plot`), and with `--play` streamed to the rig's arms on one timeline through the same code
//! as `armctl --rig RIG play`.
//!
//! Which human arm each rig arm follows: `--chain ARM=SHOULDER,ELBOW,WRIST`, once per rig arm (as
//! `armctl --rig RIG move` takes `--to ARM=x,y,z` once per arm); by default a rig arm named `left`
//! or `right` (or with that word in its name) follows that human arm, found by the names the
//! one-arm retarget knows ([`crate::motion::mocap::chain::Side`]). The arms share one scale and one time
//! base ([`crate::motion::mocap::retarget::timebase`]); each is placed in its own workspace, in its own base frame.
//!
//! A rig with a shared joint (arms mounted on a turning torso, `mount` in the rig file) is one
//! tree: an arm that carries others and whose name says no side (and has no `--chain`) follows no
//! human arm; each hand is retargeted with it at rest, then every keyframe is solved as one tree
//! problem over every joint ([`tree`]). The carrier gets its own columns in the file, and
//! the report its range of motion (`carriers`) and how the tree solves came out (`tree`).
//!
//! The report is one JSON line on stdout: the shared figures, and per arm those of the one-arm
//! report. With `--play`, the play's report follows as a second line, with each simulated arm's
//! safety monitor figures added; a violation makes the exit code 1.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use kinematics::Pose;
use serde_json::{json, Value};

use crate::arm::dof::DynArm;
use crate::arm::ArmSpec;
use crate::commands::retarget::{chain_note, rest_note, RetargetRequest, AXES_NOTE};
use crate::motion::mocap::bvh::Bvh;
use crate::motion::mocap::chain::{self, ArmChain, Side};
use crate::motion::mocap::retarget::timebase::{retarget_sharing, Job, Retargets, SharedJoints};
use crate::motion::mocap::retarget::{Retargeted, Scale};
use crate::rig::{columns, Rig, RigSpec};
use crate::runtime::connection::calibrated;

pub mod tree;

/// Whether rig arm `i` follows no human arm: it carries another arm (a shared joint), no chain is
/// given for it, and its name says no side.
fn is_carrier(spec: &RigSpec, i: usize, chain: Option<&String>) -> bool {
    chain.is_none() && Side::of_arm_name(&spec.arms[i].name).is_none() && spec.arms.iter().any(|b| b.mount == Some(i))
}

/// The `--chain ARM=...` options: per rig arm (in the rig's order), the chain text given.
fn given_chains(spec: &RigSpec, given: &[String]) -> Result<Vec<Option<String>>> {
    let mut chains = vec![None; spec.arms.len()];
    for text in given {
        let Some((name, joints)) = text.split_once('=') else {
            bail!(
                "--chain {text}: with --rig, name the rig's arm: ARM=SHOULDER,ELBOW,WRIST (e.g. \
                 {}=LeftArm,LeftForeArm,LeftHand)",
                spec.arms[0].name
            );
        };
        let arm = spec.arm(name.trim()).with_context(|| format!("--chain {text}"))?;
        if chains[arm].is_some() {
            bail!("--chain: arm {} is given twice", spec.arms[arm].name);
        }
        chains[arm] = Some(joints.trim().to_string());
    }
    // A rig arm whose name says no side needs its chain named: said before the file is read.
    for (i, (arm, chain)) in spec.arms.iter().zip(&chains).enumerate() {
        if chain.is_none() && Side::of_arm_name(&arm.name).is_none() && !is_carrier(spec, i, None) {
            bail!(
                "rig arm {}: its name says neither left nor right, so it follows no human arm by default: give \
                 --chain {}=SHOULDER,ELBOW,WRIST",
                arm.name,
                arm.name
            );
        }
    }
    Ok(chains)
}

/// The chain rig arm `name` follows: the one given, else its side's arm by the usual names.
fn chain_for(bvh: &Bvh, name: &str, given: Option<&str>) -> Result<ArmChain> {
    if let Some(text) = given {
        let label = format!("--chain {name}={text}");
        return Ok(ArmChain { found_by: "--chain".into(), ..chain::named(bvh, text, &label, &label)? });
    }
    let side = Side::of_arm_name(name).expect("checked by given_chains");
    chain::by_names(bvh, side).ok_or_else(|| {
        anyhow::anyhow!(
            "no {} arm found for rig arm {name} (tried {}); give --chain {name}=SHOULDER,ELBOW,WRIST from the file's \
             joints: {}",
            side.name(),
            chain::tried(side),
            chain::joint_list(bvh)
        )
    })
}

/// A point of the base frame `base` in the world frame.
fn to_world(base: &Pose<f64>, local: [f64; 3]) -> [f64; 3] {
    base.compose(&Pose::from_translation(local.into())).translation.into()
}

/// `path` with `-ARM` before its extension: one plot per arm.
fn plot_path(path: &Path, arm: &str) -> PathBuf {
    let stem = path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{arm}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{arm}"),
    };
    path.with_file_name(name)
}

/// The closest the tools of two arms come (world frame): the two arms, the distance (m) and the
/// keyframe's time (s). Tool points only: the arms' links are not checked against each other.
fn closest_tools(r: &Retargets, names: &[&str], bases: &[Pose<f64>]) -> Option<(String, String, f64, f64)> {
    let world: Vec<Vec<[f64; 3]>> =
        r.arms.iter().zip(bases).map(|(a, b)| a.tool.iter().map(|p| to_world(b, *p)).collect()).collect();
    let mut best: Option<(String, String, f64, f64)> = None;
    for i in 0..world.len() {
        for j in i + 1..world.len() {
            for (k, (p, q)) in world[i].iter().zip(&world[j]).enumerate() {
                let d = (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt();
                if best.as_ref().is_none_or(|b| d < b.2) {
                    best = Some((names[i].to_string(), names[j].to_string(), d, r.times[k]));
                }
            }
        }
    }
    best
}

/// One arm's part of the report: the one-arm report's figures for it.
fn arm_report(r: &Retargeted, arm: &dyn DynArm, base: &Pose<f64>) -> Value {
    json!({
        "arm": arm.spec().name,
        "chain": r.chain.names,
        "chain_found_by": r.chain.found_by,
        "rest_detected": r.reading.rest.name(),
        "rest_used": r.rest.name(),
        // + 0.0 turns the -0.0 of a horizontal bone into 0.
        "upper_arm_droop_deg": r.reading.upper_arm_droop_deg + 0.0,
        "human_arm_length": r.human_arm_length,
        "own_scale_m_per_unit": r.workspace.reach / r.human_arm_length,
        "placed_at": r.placed_at,
        "placed_at_world": to_world(base, r.placed_at),
        "inside_workspace": r.reachable_fraction(),
        "oriented": r.oriented,
        "velocity_limited_steps_alone": r.velocity_limited,
        "reconfigurations": r.reconfigured.iter().filter(|c| **c).count(),
        "jumps": r.jumps,
        "tracking_mm": r.tracking_mm(),
    })
}

/// A carrier's part of the report: the range of each of its joints over the keyframes (rad), and
/// the span used.
fn carrier_report(q: &[Vec<f64>]) -> Value {
    let joints = q.first().map_or(0, Vec::len);
    let ranges: Vec<[f64; 2]> = (0..joints)
        .map(|j| {
            let values = q.iter().map(|row| row[j]);
            [values.clone().fold(f64::INFINITY, f64::min), values.fold(f64::NEG_INFINITY, f64::max)]
        })
        .collect();
    json!({
        "joint_range_rad": ranges,
        "joint_span_deg": ranges.iter().map(|[lo, hi]| (hi - lo).to_degrees()).collect::<Vec<_>>(),
    })
}

/// The notes, `names` and `bases` (in the world) those of the arms that follow human arms.
fn notes(r: &Retargets, names: &[&str], bases: &[Pose<f64>], scale: Scale, err: &mut dyn Write) -> Result<()> {
    for (name, arm) in names.iter().zip(&r.arms) {
        writeln!(err, "note: {name}: {}", chain_note(arm))?;
        writeln!(err, "note: {name}: {}", rest_note(arm))?;
    }
    writeln!(err, "note: {AXES_NOTE}")?;
    let own: Vec<String> = names
        .iter()
        .zip(&r.arms)
        .map(|(name, arm)| {
            format!(
                "{} {:.5}: reach {:.3} m over a human arm of {:.3} units",
                name,
                arm.workspace.reach / arm.human_arm_length,
                arm.workspace.reach,
                arm.human_arm_length
            )
        })
        .collect();
    match scale {
        Scale::Auto => writeln!(
            err,
            "note: scale {:.5} m per file unit for every arm, the smallest of the arms' own ({}), so that each hand \
             fits its arm and the hands keep their motions in proportion",
            r.scale,
            own.join("; ")
        )?,
        Scale::Factor(_) => writeln!(err, "note: scale {:.5} m per file unit for every arm (--scale)", r.scale)?,
    }
    for ((name, base), arm) in names.iter().zip(bases).zip(&r.arms) {
        let w = to_world(base, arm.placed_at);
        writeln!(
            err,
            "note: {}: the path's middle placed at ({:.3}, {:.3}, {:.3}) m in its base frame ({:.3}, {:.3}, {:.3} m \
             in the world), where {:.0} % of it lies in the arm's sampled workspace above its base",
            name,
            arm.placed_at[0],
            arm.placed_at[1],
            arm.placed_at[2],
            w[0],
            w[1],
            w[2],
            100.0 * arm.placed_inside
        )?;
    }
    for note in &r.notes {
        writeln!(err, "note: {note}")?;
    }
    Ok(())
}

/// Runs `armctl retarget FILE --rig RIG`: `chains` are the `--chain ARM=SHOULDER,ELBOW,WRIST`
/// given, `request.options.chain` is unused (each rig arm's chain is in `chains` or found by its
/// side).
pub fn run(
    rig: &str,
    chains: &[String],
    request: &RetargetRequest,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let started = Instant::now();
    let options = &request.options;
    if request.play && !(request.timeout.is_finite() && request.timeout > 0.0) {
        bail!("--timeout: {} s must be a positive number", request.timeout);
    }
    let spec = RigSpec::load(rig)?;
    let given = given_chains(&spec, chains)?;
    let carriers: Vec<bool> = (0..spec.arms.len()).map(|i| is_carrier(&spec, i, given[i].as_ref())).collect();
    let followers: Vec<usize> = (0..spec.arms.len()).filter(|&i| !carriers[i]).collect();
    let mut arms: Vec<Box<dyn DynArm>> = Vec::new();
    for a in &spec.arms {
        let name = a.place.arm.as_deref().expect("a rig arm names its arm");
        let arm = calibrated(ArmSpec::load(name, None)?, a.place.calibration.as_deref())
            .and_then(crate::arm::dof::build)
            .with_context(|| format!("rig arm {}", a.name))?;
        arms.push(arm);
    }

    let bvh = crate::motion::mocap::bvh::read(&request.file)?;
    let shown = request.file.display().to_string();
    for warning in &bvh.warnings {
        writeln!(err, "warning: {shown}: {warning}")?;
    }
    // A shared joint: the rig is one tree, solved at every keyframe (see [`tree`]).
    let shared = if spec.arms.iter().any(|a| a.mount.is_some()) {
        Some(tree::RigShared::new(&spec, &arms, &carriers)?)
    } else {
        None
    };
    let mut jobs = Vec::new();
    for &i in &followers {
        let (a, arm) = (&spec.arms[i], &arms[i]);
        let chain = chain_for(&bvh, &a.name, given[i].as_deref()).with_context(|| shown.clone())?;
        jobs.push(Job { name: a.name.clone(), arm: arm.as_ref(), chain });
    }
    let r = retarget_sharing(&bvh, jobs, shared.as_ref().map(|s| s as &dyn SharedJoints), options)
        .with_context(|| shown.clone())?;

    // The followers' names and bases in the world (with the carriers at rest).
    let names: Vec<&str> = followers.iter().map(|&i| spec.arms[i].name.as_str()).collect();
    let bases: Vec<Pose<f64>> = match &shared {
        Some(s) => followers.iter().map(|&i| s.rest_bases()[i]).collect(),
        None => followers.iter().map(|&i| spec.arms[i].base).collect(),
    };
    notes(&r, &names, &bases, options.scale, err)?;
    if let Some(tree) = &r.tree {
        writeln!(
            err,
            "note: a shared joint: every keyframe solved as one tree over every joint of the rig, seeded from the \
             keyframe before; {} solved again from the arms' own joints with the carriers at rest, {} still short of \
             a target the arm alone reached",
            tree.reseeded, tree.missed
        )?;
    }
    let keyframes = match (&request.out, request.play) {
        (Some(path), _) => Some(path.clone()),
        (None, true) => Some(std::env::temp_dir().join(format!("armctl-retarget-rig-{}.csv", std::process::id()))),
        (None, false) => None,
    };
    if let Some(path) = &keyframes {
        let mut file = std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
        // Every rig arm's columns in the rig's order: a carrier's from the tree, a follower's.
        let (mut c, mut f) = (0, 0);
        let mut columns: Vec<(&str, &[Vec<f64>])> = Vec::new();
        for (i, a) in spec.arms.iter().enumerate() {
            if carriers[i] {
                columns.push((a.name.as_str(), &r.carriers[c][..]));
                c += 1;
            } else {
                columns.push((a.name.as_str(), &r.arms[f].q[..]));
                f += 1;
            }
        }
        r.write_columns(&columns, &mut file)?;
    }
    let mut plots = serde_json::Map::new();
    if let Some(plot) = &request.plot {
        for ((name, arm), robot) in names.iter().zip(&r.arms).zip(followers.iter().map(|&i| &arms[i])) {
            let path = plot_path(plot, name);
            let title = format!("{shown} onto {name} ({}): human hand (scaled) and tool", robot.spec().name);
            crate::motion::mocap::plot::draw(&path, arm, &title).with_context(|| format!("plot {}", path.display()))?;
            plots.insert(name.to_string(), json!(path.display().to_string()));
        }
    }
    let mut per_arm = serde_json::Map::new();
    for ((&i, arm), base) in followers.iter().zip(&r.arms).zip(&bases) {
        per_arm.insert(spec.arms[i].name.clone(), arm_report(arm, arms[i].as_ref(), base));
    }
    let carried: serde_json::Map<String, Value> = (0..spec.arms.len())
        .filter(|&i| carriers[i])
        .zip(&r.carriers)
        .map(|(i, q)| (spec.arms[i].name.clone(), carrier_report(q)))
        .collect();
    let closest = closest_tools(&r, &names, &bases)
        .map(|(a, b, d, t)| json!({"arms": [a, b], "distance_m": d, "t_s": t, "what": "tool points, not links"}));
    let last = r.times.len() - 1;
    crate::support::json_out::print_json(
        out,
        &json!({
            "command": "retarget",
            "file": shown,
            "rig": spec.name,
            "frames": bvh.frames.len(),
            "frames_used": r.frames_used,
            "frame_time": bvh.frame_time,
            "root_offset": r.arms[0].root_offset,
            "scale_m_per_unit": r.scale,
            "keyframes": r.times.len(),
            "keyframes_sampled": r.keyframes_sampled,
            "captured_s": (r.keyframes_sampled - 1) as f64 / r.rate,
            "duration_s": r.times[last] - r.lead_in,
            "rate_hz": r.rate,
            "lead_in_s": r.lead_in,
            "velocity_limited_steps": r.velocity_limited,
            "closest_tools": closest,
            "arms": per_arm,
            "carriers": (!carried.is_empty()).then_some(carried),
            "tree": r.tree.as_ref().map(|t| json!({"reseeded": t.reseeded, "missed": t.missed})),
            "out": request.out.as_ref().map(|p| p.display().to_string()),
            "plot": (!plots.is_empty()).then_some(plots),
            "wall_s": started.elapsed().as_secs_f64(),
        }),
    )?;
    let Some(path) = keyframes.filter(|_| request.play) else {
        return Ok(0);
    };
    let all_names: Vec<&str> = spec.arms.iter().map(|a| a.name.as_str()).collect();
    let all_bases: Vec<Pose<f64>> = spec.arms.iter().map(|a| a.base).collect();
    let played = play(&spec, &path, &all_names, &all_bases, request.timeout, out, err);
    if request.out.is_none() {
        let _ = std::fs::remove_file(&path);
    }
    played
}

/// Plays the rig keyframe file at `path` as `armctl --rig RIG play` does: read and split by
/// [`columns::read`], streamed by [`crate::rig::play::run`]. Its JSON line gets each simulated
/// arm's safety monitor figures (`safety`); a violation makes the exit code 1.
fn play(
    spec: &RigSpec,
    path: &Path,
    names: &[&str],
    bases: &[Pose<f64>],
    timeout: f64,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let parts = columns::read(path, names, bases, timeout)?;
    let mut rig = Rig::open(spec, err)?;
    let mut line = Vec::new();
    let code = crate::rig::play::run(&mut rig, parts, true, &mut line, err)?;
    // The simulated arms' boards, in the rig's order among the simulated ones (as Rig::open made them).
    let mut safety = serde_json::Map::new();
    let mut violations = 0;
    if let Some(group) = &rig.sim {
        for (i, a) in spec.arms.iter().filter(|a| a.place.sim).enumerate() {
            let board = group.board(i);
            let m = board.monitor();
            violations += m.violation_count;
            safety.insert(
                a.name.clone(),
                json!({"goals_checked": m.checked, "violations": m.violation_count,
                       "largest_step_of_limit": m.max_step_ratio}),
            );
        }
    }
    match serde_json::from_slice::<Value>(&line) {
        Ok(mut report) if !safety.is_empty() => {
            report["safety"] = Value::Object(safety);
            crate::support::json_out::print_json(out, &report)?;
        }
        _ => out.write_all(&line)?,
    }
    rig.close(err)?;
    Ok(if violations > 0 && code == 0 { 1 } else { code })
}
