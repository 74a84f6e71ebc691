//! `armctl doctor`'s options, and what they become: the drive options' place of the servos (a
//! `--bus` only: a board, the simulation and a rig are refused here) and the plain
//! [`DoctorRequest`] of [`crate::commands::doctor`].

use std::io::Write;

use anyhow::{bail, Result};
use clap::Args;

use super::link::LinkArgs;
use crate::cli::bus_args::ProtocolArg;
use crate::commands::doctor::line::DEFAULT_READS;
use crate::commands::doctor::DoctorRequest;

/// `armctl doctor`'s options. The bus, protocol, baud, arm, calibration and `--json` are the drive
/// options' own, and may come before the command as well.
#[derive(Args, Debug)]
pub struct DoctorArgs {
    /// The servos' USB adapter (`armctl ports` lists them).
    #[arg(long, value_name = "PORT")]
    bus: Option<String>,
    /// The servos' protocol, sts (Feetech) or dxl2 (Dynamixel 2.0) (default: both are tried).
    #[arg(long, value_enum)]
    protocol: Option<ProtocolArg>,
    /// The servos' baud rate (default: the usual rates are tried, the arm file's first).
    #[arg(long)]
    baud: Option<u32>,
    /// The arm the servos should make up (a preset or an arm file with a [servos] table): its ids
    /// and model are checked (default: whatever answers among ids 0 to 20).
    #[arg(long = "arm", value_name = "ARM")]
    arm: Option<String>,
    /// A LeRobot calibration file (JSON) to check the servos' homing offsets and limits against.
    #[arg(long, value_name = "FILE")]
    calibration: Option<std::path::PathBuf>,
    /// One line of JSON: the bus, every servo's readings, the line's counts and the findings.
    #[arg(long)]
    json: bool,
    /// Offer the safe fixes (return delay 0, status return level, stale goals to the present
    /// position, the adapter's latency timer), each confirmed on stdin.
    #[arg(long)]
    fix: bool,
    /// With --fix: apply every safe fix without asking.
    #[arg(long, requires = "fix")]
    yes: bool,
    /// Sync reads for the error rate (without retries).
    #[arg(long, default_value_t = DEFAULT_READS, value_parser = clap::value_parser!(u32).range(10..=100_000))]
    reads: u32,
}

/// Runs `armctl doctor` with the drive options given before it (`before`); exit code 1 when a
/// finding is FAIL.
pub fn run(before: &LinkArgs, args: DoctorArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let after = LinkArgs {
        bus: args.bus.clone(),
        protocol: args.protocol,
        baud: args.baud,
        arm: args.arm.clone(),
        calibration: args.calibration.clone(),
        json: args.json,
        ..LinkArgs::default()
    };
    let link = before.merged(&after)?;
    let refused: Vec<&str> = [
        (link.port.is_some(), "--port"),
        (link.sim, "--sim"),
        (link.rig.is_some(), "--rig"),
        (link.object_mm.is_some(), "--object-mm"),
    ]
    .into_iter()
    .filter_map(|(given, name)| given.then_some(name))
    .collect();
    if !refused.is_empty() {
        bail!("doctor looks at servos on a USB adapter (--bus PORT): {} is not for it", refused.join(", "));
    }
    let request = DoctorRequest { fix: args.fix, yes: args.yes, reads: args.reads };
    crate::commands::doctor::run(&link.place()?, link.json, &request, out, err)
}
