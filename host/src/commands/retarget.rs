//! `armctl retarget FILE.bvh --arm ARM`: a motion-capture arm onto a robot arm, as joint keyframes
//! for `armctl play` (`--out`), a plot (`--plot`), and with `--play` streamed to the arm the drive
//! options name (`--sim`, `--port`, `--bus`) through the same code as `armctl play`. With
//! `--rig RIG`, every arm of a rig at once: `crate::rig::retarget`, which shares this module's
//! request and notes. The command line's options are `crate::cli::retarget`'s.
//!
//! The report is one JSON line on stdout; the choices made (chain, rest, axes, scale, placement)
//! and warnings about the file go to stderr.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use serde_json::json;

use crate::arm::ArmSpec;
use crate::commands::drive::play::Plan;
use crate::commands::drive::Operation;
use crate::motion::mocap::retarget::{self, Options, Retargeted};
use crate::runtime::connection::{calibrated, Place};

/// What `armctl retarget` is asked for, one arm's or a rig's: the file, the retarget's settings
/// and where the keyframes go. Its values are checked where they are used (the file when read,
/// `timeout` by the play), so every front end gets the same errors.
#[derive(Clone, Debug)]
pub struct RetargetRequest {
    /// The BVH file.
    pub file: PathBuf,
    /// The retarget's settings; with a rig, `chain` is `None` (each rig arm's chain is the rig's
    /// to give).
    pub options: Options,
    /// Where to write the joint keyframes (with a rig, every arm's columns in one file).
    pub out: Option<PathBuf>,
    /// Where to draw the hand's path against the tool's (with a rig, one PNG per arm).
    pub plot: Option<PathBuf>,
    /// Whether to stream the keyframes to the arm (the rig's arms) once retargeted.
    pub play: bool,
    /// With `play`: give up this many seconds after the last keyframe's time.
    pub timeout: f64,
}

/// The error of a one-arm retarget without an arm.
pub const ARM_REQUIRED: &str = "--arm is required: the arm to retarget onto";

/// The chain note: which joints, found how.
pub fn chain_note(r: &Retargeted) -> String {
    let [s, e, w] = &r.chain.names;
    format!("chain {s} -> {e} -> {w} ({})", r.chain.found_by)
}

/// The rest note: read from the skeleton, and taken as what.
pub fn rest_note(r: &Retargeted) -> String {
    format!(
        "rest: {} (the upper arm points {:.1} degrees below horizontal at rest){}",
        r.reading.rest.name(),
        r.reading.upper_arm_droop_deg + 0.0,
        if r.rest == r.reading.rest { String::new() } else { format!("; taken as {} (--reference)", r.rest.name()) }
    )
}

/// The axes note.
pub const AXES_NOTE: &str = "axes: the file's Y is up and the human faces its +Z; on the arm they face +X (its \
                                    front), up is +Z, their left +Y; the hand is taken relative to the shoulder in \
                                    the torso's frame";

fn notes(r: &Retargeted, err: &mut dyn Write) -> Result<()> {
    writeln!(err, "note: {}", chain_note(r))?;
    writeln!(err, "note: {}", rest_note(r))?;
    writeln!(err, "note: {AXES_NOTE}")?;
    writeln!(
        err,
        "note: scale {:.5} m per file unit (arm reach {:.3} m, human arm {:.3} units); the path's middle placed at \
         ({:.3}, {:.3}, {:.3}) m, where {:.0} % of it lies in the arm's sampled workspace above its base",
        r.scale,
        r.workspace.reach,
        r.human_arm_length,
        r.placed_at[0],
        r.placed_at[1],
        r.placed_at[2],
        100.0 * r.placed_inside
    )?;
    for note in &r.notes {
        writeln!(err, "note: {note}")?;
    }
    Ok(())
}

/// Runs `armctl retarget` onto the arm `place` names (its `arm` required; where it is, for
/// `request.play`): the report is one JSON line on `out`, then with `play` the play's.
pub fn run(place: &Place, request: &RetargetRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let started = Instant::now();
    let arm_name = place.arm.as_deref().ok_or_else(|| anyhow!(ARM_REQUIRED))?;
    let spec = calibrated(ArmSpec::load(arm_name, None)?, place.calibration.as_deref())?;
    let arm = crate::arm::dof::build(spec)?;

    let bvh = crate::motion::mocap::bvh::read(&request.file)?;
    let shown = request.file.display().to_string();
    for warning in &bvh.warnings {
        writeln!(err, "warning: {shown}: {warning}")?;
    }
    let r = retarget::retarget(&bvh, arm.as_ref(), &request.options).with_context(|| shown.clone())?;
    notes(&r, err)?;

    let keyframes = match (&request.out, request.play) {
        (Some(path), _) => Some(path.clone()),
        (None, true) => Some(std::env::temp_dir().join(format!("armctl-retarget-{}.csv", std::process::id()))),
        (None, false) => None,
    };
    if let Some(path) = &keyframes {
        let mut file = std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
        r.write_csv(&mut file)?;
    }
    if let Some(path) = &request.plot {
        let title = format!("{} onto {}: human hand (scaled) and tool", shown, arm.spec().name);
        crate::motion::mocap::plot::draw(path, &r, &title).with_context(|| format!("plot {}", path.display()))?;
    }
    let tracking = r.tracking_mm();
    crate::support::json_out::print_json(
        out,
        &json!({
            "command": "retarget",
            "file": shown,
            "arm": arm.spec().name,
            "frames": bvh.frames.len(),
            "frames_used": r.frames_used,
            "frame_time": bvh.frame_time,
            "chain": r.chain.names,
            "rest_detected": r.reading.rest.name(),
            "rest_used": r.rest.name(),
            // + 0.0 turns the -0.0 of a horizontal bone into 0.
            "upper_arm_droop_deg": r.reading.upper_arm_droop_deg + 0.0,
            "root_offset": r.root_offset,
            "scale_m_per_unit": r.scale,
            "placed_at": r.placed_at,
            "keyframes": r.times.len(),
            "keyframes_sampled": r.keyframes_sampled,
            "captured_s": (r.keyframes_sampled - 1) as f64 / r.rate,
            "duration_s": r.times[r.times.len() - 1] - r.lead_in,
            "rate_hz": r.rate,
            "lead_in_s": r.lead_in,
            "inside_workspace": r.reachable_fraction(),
            "oriented": r.oriented,
            "velocity_limited_steps": r.velocity_limited,
            "reconfigurations": r.reconfigured.iter().filter(|c| **c).count(),
            "jumps": r.jumps,
            "tracking_mm": tracking,
            "out": request.out.as_ref().map(|p| p.display().to_string()),
            "plot": request.plot.as_ref().map(|p| p.display().to_string()),
            "wall_s": started.elapsed().as_secs_f64(),
        }),
    )?;
    let Some(path) = keyframes.filter(|_| request.play) else {
        return Ok(0);
    };
    // The same path as `armctl play FILE`: the file checked against the connected arm, streamed
    // with flow control, Ctrl-C stopping the arm. Its report follows as a second JSON line.
    let code = Plan::read(&path, request.timeout)
        .and_then(|plan| crate::commands::drive::run(place, true, &Operation::Play(plan), out, err));
    if request.out.is_none() {
        let _ = std::fs::remove_file(&path);
    }
    code
}
