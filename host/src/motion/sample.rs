//! `armctl trajectory sample`: its arguments, and the run that reads a keyframe file, samples it
//! (checking and, if asked, meeting joint limits), writes CSV or JSON and draws the plot.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;

use super::trajectory::{parse_limits, read_keyframes, sample, to_json, write_csv, Ends, Method, Options};
use super::trajectory_plot;

/// Arguments of `armctl trajectory sample`.
#[derive(Args, Debug)]
pub struct SampleArgs {
    /// Keyframe CSV file: header `t,q1,...,qN` plus optional `v1,...,vN` velocity columns.
    #[arg(long)]
    pub keyframes: PathBuf,
    /// Interpolation method.
    #[arg(long, value_enum)]
    pub method: Method,
    /// Samples per second, from the first to the last keyframe time inclusive.
    #[arg(long, default_value_t = 100.0)]
    pub rate: f64,
    /// Kochanek-Bartels tension (`--method kb`).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub tension: f64,
    /// Kochanek-Bartels continuity (`--method kb`; non-zero gives corners).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub continuity: f64,
    /// Kochanek-Bartels bias (`--method kb`).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub bias: f64,
    /// End condition of `catmull-rom` and `kb`.
    #[arg(long, value_enum, default_value = "zero")]
    pub ends: Ends,
    /// Joint limits as KEY=VALUE pairs, comma-separated: `v` (max |velocity|) and `a` (max
    /// |acceleration|) are required, `lo`/`hi` (position range) optional. A value is one number for
    /// every joint or one per joint separated by `:`, e.g. `v=1.5,a=4` or `v=1:1:2,a=4,lo=-3,hi=3`.
    /// A trajectory that breaks them is slowed down (never moved), and a note with the new
    /// duration goes to stderr.
    #[arg(long, allow_hyphen_values = true)]
    pub limits: Option<String>,
    /// Write JSON (one line) instead of CSV.
    #[arg(long)]
    pub json: bool,
    /// Also draw position, velocity and acceleration per joint to this PNG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// Runs `armctl trajectory sample`.
pub fn run(args: &SampleArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let limits = args.limits.as_deref().map(parse_limits).transpose()?;
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate must be a positive finite number of samples per second");
    }
    let keyframes = read_keyframes(&args.keyframes)?;
    if keyframes.velocities.is_some() && args.method != Method::Hermite {
        writeln!(err, "note: --method {} ignores the velocity columns (only hermite uses them)", args.method.name())?;
    }
    let options = Options {
        method: args.method,
        tcb: [args.tension, args.continuity, args.bias],
        ends: args.ends,
        rate: args.rate,
        limits,
    };
    let sampled = sample(&keyframes, &options).with_context(|| args.keyframes.display().to_string())?;
    if let Some(r) = &sampled.retiming {
        writeln!(
            err,
            "note: time-scaled to meet --limits: duration {} s -> {} s (slowest segment x{:.3}{})",
            r.old_duration,
            r.new_duration,
            r.max_stretch,
            if r.range_clamped { ", velocities reduced to stay inside lo/hi" } else { "" }
        )?;
    }
    if let Some(path) = &args.plot {
        let title = format!("{} ({})", args.keyframes.display(), args.method.name());
        trajectory_plot::draw(path, &sampled, &title)
            .with_context(|| format!("cannot write plot {}", path.display()))?;
    }
    if args.json {
        writeln!(out, "{}", to_json(&sampled))?;
    } else {
        write_csv(out, &sampled)?;
    }
    Ok(0)
}
