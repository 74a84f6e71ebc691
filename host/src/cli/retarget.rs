//! `armctl retarget` on the command line: its options, the drive options merged from before and
//! after the command and refused where they do nothing (without `--play`, beside `--rig`), the
//! text of `--reference`, `--scale` and `--chain` turned into the retarget's [`Options`]; then
//! [`crate::commands::retarget::run`] for one arm or [`crate::rig::retarget::run`] for `--rig`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{anyhow, bail, Result};
use clap::Args;

use super::link::LinkArgs;
use crate::commands::retarget::{RetargetRequest, ARM_REQUIRED};
use crate::motion::mocap::rest::Rest;
use crate::motion::mocap::retarget::{self, Options, Scale};
use crate::motion::mocap::skeleton::RootOffset;
use crate::motion::mocap::timing::Timing;

/// `armctl retarget` options.
#[derive(Args, Debug)]
pub struct RetargetArgs {
    /// The arm (--arm, required) and, with --play, where it is (--sim, --port, --bus ...); or
    /// --rig RIG, every arm of a rig (a rig file or the built-in bimanual-so101).
    #[command(flatten)]
    link: LinkArgs,
    /// The BVH file.
    file: PathBuf,
    /// The human arm's joints, SHOULDER,ELBOW,WRIST [default: the right arm, by the usual names].
    /// With --rig: ARM=SHOULDER,ELBOW,WRIST, once per rig arm [default: a rig arm named left or
    /// right (or with that word in its name, as left_follower) follows that human arm].
    #[arg(long, value_name = "CHAIN")]
    chain: Vec<String>,
    /// The file's rest pose: auto (read from the rest bone directions), t-pose, a-pose or arms-down.
    #[arg(long, default_value = "auto")]
    reference: String,
    /// Metres per file unit, or auto: the arm's reach over the human arm's length (with --rig,
    /// the smallest of the arms' own, one scale for all).
    #[arg(long, default_value = "auto")]
    scale: String,
    /// Whether the root's OFFSET adds to its translation channels [default: guessed from the file].
    #[arg(long, value_parser = super::values::root_offset())]
    root_offset: Option<RootOffset>,
    /// Keyframes per second (lowered where a file would need more than 20,000).
    #[arg(long, default_value_t = retarget::DEFAULT_RATE)]
    rate: f64,
    /// Only the first this many seconds of the file.
    #[arg(long)]
    seconds: Option<f64>,
    /// Where the human moves faster than the arm's velocity limits: fit (the motion slows down
    /// there, the tool keeps the hand's path) or captured (the capture's timing kept, joint steps
    /// cut to the limit: the tool lags). With --rig, the slowest arm sets every arm's pace.
    #[arg(long, value_parser = super::values::timing(), default_value = "fit")]
    timing: Timing,
    /// Write the joint keyframes (CSV t,q1,...,qN for armctl play) to this file; with --rig, one
    /// file with every arm's columns (t,left.q1,...,right.q1,...) for armctl --rig RIG play.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Draw the human hand's path (scaled, in the arm's frame) against the tool's to this PNG;
    /// with --rig, one PNG per arm, named FILE-ARM.png.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Stream the keyframes to the arm (--sim, --port PORT or --bus PORT) once retargeted; with
    /// --rig, to every arm of the rig, on one timeline.
    #[arg(long)]
    play: bool,
    /// With --play: give up this many seconds after the last keyframe's time.
    #[arg(long, default_value_t = 30.0)]
    timeout: f64,
}

/// Runs `armctl retarget`; `global` are the drive options given before the command.
pub fn run(global: &LinkArgs, args: RetargetArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let link = global.merged(&args.link)?;
    if let Some(rig) = &link.rig {
        link.refuse_beside_rig()?;
        let request = request(&args, options(&args)?);
        return crate::rig::retarget::run(rig, &args.chain, &request, out, err);
    }
    if args.play {
        if link.port.is_none() && link.bus.is_none() && !link.sim {
            bail!("--play streams the keyframes to an arm: give --sim, --port PORT or --bus PORT");
        }
    } else {
        refuse_without_play(&link)?;
    }
    // Before --chain's and --reference's checks, as it has always come.
    if link.arm.is_none() {
        bail!(ARM_REQUIRED);
    }
    let options = Options { chain: one_chain(&args.chain)?, ..options(&args)? };
    crate::commands::retarget::run(&link.place()?, &request(&args, options), out, err)
}

/// The request of `args` with the retarget's settings `options`.
fn request(args: &RetargetArgs, options: Options) -> RetargetRequest {
    RetargetRequest {
        file: args.file.clone(),
        options,
        out: args.out.clone(),
        plot: args.plot.clone(),
        play: args.play,
        timeout: args.timeout,
    }
}

/// The retarget's settings as typed; the chain is left to the caller.
fn options(args: &RetargetArgs) -> Result<Options> {
    let reference = match args.reference.as_str() {
        "auto" => None,
        name => Some(
            Rest::from_name(name)
                .ok_or_else(|| anyhow!("--reference {name}: expected auto, t-pose, a-pose or arms-down"))?,
        ),
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

/// Refuses the drive options that only make sense with --play.
fn refuse_without_play(link: &LinkArgs) -> Result<()> {
    // One arm's options but --arm, which names the arm to retarget onto.
    let given: Vec<&str> = link.one_arm_options().into_iter().filter(|&name| name != "--arm").collect();
    if !given.is_empty() {
        let verb = if given.len() == 1 { "is" } else { "are" };
        bail!("{} {verb} for driving an arm: add --play to stream the keyframes to it", given.join(", "));
    }
    Ok(())
}
