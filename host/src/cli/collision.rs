//! `armctl collision fit|check`: the options, turned into the requests of
//! [`crate::commands::collision`], and their reports printed as text or one line of JSON.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Subcommand};

use crate::arm::collision::obstacle::Surroundings;
use crate::arm::collision::{ObstacleSpec, DEFAULT_MARGIN};
use crate::commands::collision::{self, CheckRequest, FitRequest};
use crate::support::numbers as parse;

/// `armctl collision`.
#[derive(Args, Debug)]
pub struct CollisionArgs {
    /// fit or check.
    #[command(subcommand)]
    pub what: CollisionCommand,
}

/// What `armctl collision` does.
#[derive(Subcommand, Debug)]
pub enum CollisionCommand {
    /// Fit capsules to a URDF's <collision> elements and find the pairs never checked: prints the
    /// arm file's [collision] section
    ///
    /// A capsule per element (a mesh's, an STL file, holds all its vertices), on the joint whose
    /// moving frame carries its link; pairs closer than --margin at the zero pose or in more than
    /// 5 % of 2000 random poses are allowed, as MoveIt's setup assistant finds them; the table is
    /// the plane the base stands on. Redirect it into the arm file: `>> my-arm.toml`.
    Fit(FitArgs),
    /// The closest pair of bodies (or body and obstacle) at joint values, and whether it keeps
    /// the margin; exits 1 when it does not
    ///
    /// The arm's own geometry (a preset's, its arm file's [collision], or fitted from a URDF's
    /// <collision> elements), with --obstacle and --no-table applied.
    Check(CheckArgs),
}

/// `armctl collision fit`.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// The URDF (its meshes are found as the view finds them: beside it, or package:// above it).
    #[arg(long)]
    pub arm: Option<String>,
    /// Its tip link [default: its only leaf].
    #[arg(long)]
    pub tip: Option<String>,
    /// The distance every checked pair keeps (m).
    #[arg(long, default_value_t = DEFAULT_MARGIN)]
    pub margin: f64,
    /// One line of JSON (the bodies, the pairs and the section) instead of the section.
    #[arg(long)]
    pub json: bool,
}

/// `armctl collision check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// A preset, an arm file, or a URDF (its <collision> elements fitted first).
    #[arg(long)]
    pub arm: Option<String>,
    /// A URDF's tip link.
    #[arg(long)]
    pub tip: Option<String>,
    /// Joint values, comma-separated (rad, m for prismatic joints), one per joint.
    #[arg(long, allow_hyphen_values = true)]
    pub joints: String,
    /// An obstacle more (see `armctl --help`).
    #[arg(long = "obstacle", value_name = "SPEC")]
    pub obstacles: Vec<ObstacleSpec>,
    /// Without the table the arm stands on.
    #[arg(long)]
    pub no_table: bool,
    /// One line of JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `armctl collision ...`; returns the exit code.
pub fn run(command: CollisionCommand, out: &mut dyn Write) -> Result<i32> {
    match command {
        CollisionCommand::Fit(args) => {
            let Some(urdf) = args.arm else { bail!("--arm is missing: the URDF whose <collision> elements to fit") };
            let mut typed = format!("armctl collision fit --arm {urdf}");
            if let Some(tip) = &args.tip {
                typed.push_str(&format!(" --tip {tip}"));
            }
            if args.margin != DEFAULT_MARGIN {
                typed.push_str(&format!(" --margin {}", args.margin));
            }
            let request = FitRequest { urdf: PathBuf::from(urdf), tip: args.tip, margin: args.margin, command: typed };
            let report = collision::fit(&request)?;
            if args.json {
                writeln!(out, "{}", serde_json::to_string(&report)?)?;
            } else {
                write!(out, "{}", report.text())?;
            }
            Ok(0)
        }
        CollisionCommand::Check(args) => {
            let Some(arm) = args.arm else { bail!("--arm is missing: a preset name or a .urdf or .toml arm file") };
            let request = CheckRequest {
                arm,
                tip: args.tip,
                joints: parse::numbers(&args.joints, "--joints")?,
                surroundings: Surroundings { obstacles: args.obstacles, no_table: args.no_table },
            };
            let report = collision::check(&request)?;
            if args.json {
                writeln!(out, "{}", serde_json::to_string(&report)?)?;
            } else {
                writeln!(out, "{}", report.text())?;
            }
            Ok(if report.free { 0 } else { 1 })
        }
    }
}
