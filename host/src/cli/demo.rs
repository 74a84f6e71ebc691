//! `armctl demo`'s options, and what they become: the one-arm demo's plain [`DemoRequest`] for
//! [`crate::commands::demo`], or with `--rig` the handover scene of [`crate::rig::handover`].

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use crate::commands::demo::{DemoRequest, PlotTo};

/// `armctl demo` options.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// The simulated arm: a preset with servos (so101 on a Feetech STS3215 bus,
    /// open-manipulator-x on a Dynamixel XM430 bus) or an arm file with a [servos] table
    /// [default: so101].
    #[arg(long, conflicts_with = "rig")]
    pub arm: Option<String>,
    /// The second scene: a rig of simulated arms (bimanual-so101, or a rig file of two
    /// simulated arms with grippers) hands an object from the first arm to the second.
    #[arg(long, value_name = "RIG")]
    pub rig: Option<String>,
    /// Where to write the PNG plot (default demo-ARM.png in the current directory).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Do not write a plot.
    #[arg(long, conflicts_with = "plot")]
    no_plot: bool,
    /// The simulated servos: ideal (the default) reach every goal along their profiles; physical
    /// ones carry the arm under gravity, sag and lag (docs/servo-model.md), and the firmware then
    /// compensates their sag.
    #[arg(long, value_name = "KIND", value_parser = ["ideal", "physical"], conflicts_with = "rig")]
    pub servos: Option<String>,
    /// With --servos physical: a payload at the tool (kg).
    #[arg(long, value_name = "KG", allow_negative_numbers = true, conflicts_with = "rig")]
    pub payload_kg: Option<f64>,
    /// Print the results as one line of JSON instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// Runs `armctl demo` (the drive options given before it already taken into `args`); returns the
/// exit code.
pub fn run(args: &DemoArgs, out: &mut dyn Write) -> Result<i32> {
    if args.arm.is_some() && args.rig.is_some() {
        bail!("--arm and --rig exclude each other: the rig file names its arms");
    }
    if let Some(rig) = &args.rig {
        if args.plot.is_some() {
            bail!("--plot draws the one-arm demo; the handover (--rig) has no plot yet");
        }
        return crate::rig::handover::run(rig, args.json, out);
    }
    let plot = match (&args.plot, args.no_plot) {
        (_, true) => PlotTo::Nowhere,
        (Some(path), false) => PlotTo::File(path.clone()),
        (None, false) => PlotTo::Default,
    };
    let servos = crate::sim::physics::servo_kind(args.servos.as_deref(), args.payload_kg)?;
    crate::commands::demo::run(&DemoRequest { arm: args.arm.clone(), plot, servos }, args.json, out)
}
