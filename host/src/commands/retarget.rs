//! `armctl retarget FILE.bvh --arm ARM`: a motion-capture arm onto a robot arm, as joint keyframes
//! for `armctl play` (`--out`), a plot (`--plot`), and with `--play` streamed to the arm the drive
//! options name (`--sim`, `--port`, `--bus`) through the same code as `armctl play`. With
//! `--rig RIG`, every arm of a rig at once: see [`rig`].
//!
//! The report is one JSON line on stdout; the choices made (chain, rest, axes, scale, placement)
//! and warnings about the file go to stderr.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde_json::json;

use crate::arm::ArmSpec;
use crate::cli::link::LinkArgs;
use crate::commands::drive::play::Plan;
use crate::commands::drive::Operation;
use crate::motion::mocap::rest::Rest;
use crate::motion::mocap::retarget::{self, Options, Retargeted, Scale};
use crate::motion::mocap::skeleton::RootOffset;
use crate::motion::mocap::timing::Timing;

pub mod rig;
pub mod tree;

/// `armctl retarget` options.
#[derive(Args, Debug)]
pub struct RetargetArgs {
    /// The arm (--arm, required) and, with --play, where it is (--sim, --port, --bus ...); or
    /// --rig RIG, every arm of a rig (a rig file or the built-in bimanual-so101).
    #[command(flatten)]
    pub(super) link: LinkArgs,
    /// The BVH file.
    pub(super) file: PathBuf,
    /// The human arm's joints, SHOULDER,ELBOW,WRIST [default: the right arm, by the usual names].
    /// With --rig: ARM=SHOULDER,ELBOW,WRIST, once per rig arm [default: a rig arm named left or
    /// right (or with that word in its name, as left_follower) follows that human arm].
    #[arg(long, value_name = "CHAIN")]
    pub(super) chain: Vec<String>,
    /// The file's rest pose: auto (read from the rest bone directions), t-pose, a-pose or arms-down.
    #[arg(long, default_value = "auto")]
    pub(super) reference: String,
    /// Metres per file unit, or auto: the arm's reach over the human arm's length (with --rig,
    /// the smallest of the arms' own, one scale for all).
    #[arg(long, default_value = "auto")]
    pub(super) scale: String,
    /// Whether the root's OFFSET adds to its translation channels [default: guessed from the file].
    #[arg(long, value_enum)]
    pub(super) root_offset: Option<RootOffset>,
    /// Keyframes per second (lowered where a file would need more than 20,000).
    #[arg(long, default_value_t = retarget::DEFAULT_RATE)]
    pub(super) rate: f64,
    /// Only the first this many seconds of the file.
    #[arg(long)]
    pub(super) seconds: Option<f64>,
    /// Where the human moves faster than the arm's velocity limits: fit (the motion slows down
    /// there, the tool keeps the hand's path) or captured (the capture's timing kept, joint steps
    /// cut to the limit: the tool lags). With --rig, the slowest arm sets every arm's pace.
    #[arg(long, value_enum, default_value = "fit")]
    pub(super) timing: Timing,
    /// Write the joint keyframes (CSV t,q1,...,qN for armctl play) to this file; with --rig, one
    /// file with every arm's columns (t,left.q1,...,right.q1,...) for armctl --rig RIG play.
    #[arg(long)]
    pub(super) out: Option<PathBuf>,
    /// Draw the human hand's path (scaled, in the arm's frame) against the tool's to this PNG;
    /// with --rig, one PNG per arm, named FILE-ARM.png.
    #[arg(long)]
    pub(super) plot: Option<PathBuf>,
    /// Stream the keyframes to the arm (--sim, --port PORT or --bus PORT) once retargeted; with
    /// --rig, to every arm of the rig, on one timeline.
    #[arg(long)]
    pub(super) play: bool,
    /// With --play: give up this many seconds after the last keyframe's time.
    #[arg(long, default_value_t = 30.0)]
    pub(super) timeout: f64,
}

impl RetargetArgs {
    /// Whether the keyframes go to an arm: the drive options are then allowed.
    pub fn plays(&self) -> bool {
        self.play
    }
}

/// The retarget's settings; the chain is left to the caller.
pub(super) fn options(args: &RetargetArgs) -> Result<Options> {
    let reference = match args.reference.as_str() {
        "auto" => None,
        "t-pose" => Some(Rest::TPose),
        "a-pose" => Some(Rest::APose),
        "arms-down" => Some(Rest::ArmsDown),
        other => bail!("--reference {other}: expected auto, t-pose, a-pose or arms-down"),
    };
    let scale = match args.scale.as_str() {
        "auto" => Scale::Auto,
        text => Scale::Factor(
            text.parse::<f64>()
                .map_err(|_| anyhow!("--scale {text}: expected auto or a number (metres per file unit)"))?,
        ),
    };
    Ok(Options {
        chain: None,
        reference,
        scale,
        root_offset: args.root_offset,
        rate: args.rate,
        seconds: args.seconds,
        timing: args.timing,
    })
}

/// The one arm's `--chain`, given at most once and naming no rig arm.
fn one_chain(given: &[String]) -> Result<Option<String>> {
    match given {
        [] => Ok(None),
        [text] if text.contains('=') => {
            bail!("--chain {text}: ARM=SHOULDER,ELBOW,WRIST names a rig's arm: add --rig RIG, or give SHOULDER,ELBOW,WRIST")
        }
        [text] => Ok(Some(text.clone())),
        _ => {
            bail!("--chain is given {} times: one arm follows one chain (with --rig, one ARM=... per arm)", given.len())
        }
    }
}

/// The drive options that only make sense with --play.
fn refuse_without_play(link: &LinkArgs) -> Result<()> {
    let given: Vec<&str> = [
        (link.port.is_some(), "--port"),
        (link.bus.is_some(), "--bus"),
        (link.protocol.is_some(), "--protocol"),
        (link.baud.is_some(), "--baud"),
        (link.sim, "--sim"),
        (link.calibration.is_some(), "--calibration"),
        (link.object_mm.is_some(), "--object-mm"),
    ]
    .into_iter()
    .filter_map(|(given, name)| given.then_some(name))
    .collect();
    if !given.is_empty() {
        let verb = if given.len() == 1 { "is" } else { "are" };
        bail!("{} {verb} for driving an arm: add --play to stream the keyframes to it", given.join(", "));
    }
    Ok(())
}

/// The chain note: which joints, found how.
pub(super) fn chain_note(r: &Retargeted) -> String {
    let [s, e, w] = &r.chain.names;
    format!("chain {s} -> {e} -> {w} ({})", r.chain.found_by)
}

/// The rest note: read from the skeleton, and taken as what.
pub(super) fn rest_note(r: &Retargeted) -> String {
    format!(
        "rest: {} (the upper arm points {:.1} degrees below horizontal at rest){}",
        r.reading.rest.name(),
        r.reading.upper_arm_droop_deg + 0.0,
        if r.rest == r.reading.rest { String::new() } else { format!("; taken as {} (--reference)", r.rest.name()) }
    )
}

/// The axes note.
pub(super) const AXES_NOTE: &str = "axes: the file's Y is up and the human faces its +Z; on the arm they face +X (its \
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

/// Runs `armctl retarget`; `global` are the drive options given before the command.
pub fn run(global: &LinkArgs, args: RetargetArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let started = Instant::now();
    let link = global.merged(&args.link)?;
    if let Some(rig) = &link.rig {
        return rig::run(rig, &link, &args, out, err);
    }
    if args.play {
        if link.port.is_none() && link.bus.is_none() && !link.sim {
            bail!("--play streams the keyframes to an arm: give --sim, --port PORT or --bus PORT");
        }
    } else {
        refuse_without_play(&link)?;
    }
    let arm_name = link.arm.clone().ok_or_else(|| anyhow!("--arm is required: the arm to retarget onto"))?;
    let options = Options { chain: one_chain(&args.chain)?, ..options(&args)? };
    let spec = crate::runtime::connection::calibrated(ArmSpec::load(&arm_name, None)?, link.calibration.as_deref())?;
    let arm = crate::arm::dof::build(spec)?;

    let bvh = crate::motion::mocap::bvh::read(&args.file)?;
    let shown = args.file.display().to_string();
    for warning in &bvh.warnings {
        writeln!(err, "warning: {shown}: {warning}")?;
    }
    let r = retarget::retarget(&bvh, arm.as_ref(), &options).with_context(|| shown.clone())?;
    notes(&r, err)?;

    let keyframes = match (&args.out, args.play) {
        (Some(path), _) => Some(path.clone()),
        (None, true) => Some(std::env::temp_dir().join(format!("armctl-retarget-{}.csv", std::process::id()))),
        (None, false) => None,
    };
    if let Some(path) = &keyframes {
        let mut file = std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
        r.write_csv(&mut file)?;
    }
    if let Some(path) = &args.plot {
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
            "out": args.out.as_ref().map(|p| p.display().to_string()),
            "plot": args.plot.as_ref().map(|p| p.display().to_string()),
            "wall_s": started.elapsed().as_secs_f64(),
        }),
    )?;
    let Some(path) = keyframes.filter(|_| args.play) else {
        return Ok(0);
    };
    // The same path as `armctl play FILE`: the file checked against the connected arm, streamed
    // with flow control, Ctrl-C stopping the arm. Its report follows as a second JSON line.
    let place = link.place();
    let code = Plan::read(&path, args.timeout)
        .and_then(|plan| crate::commands::drive::run(&place, true, &Operation::Play(plan), out, err));
    if args.out.is_none() {
        let _ = std::fs::remove_file(&path);
    }
    code
}
