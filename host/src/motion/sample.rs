//! `armctl trajectory sample`: its request, and the run that reads a keyframe file, samples it
//! (checking and, if asked, meeting joint limits), writes CSV or JSON and draws the plot.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use super::trajectory::{parse_limits, read_keyframes, sample, to_json, write_csv, Ends, Method, Options};
use super::trajectory_plot;

/// What `armctl trajectory sample` is asked for, as its options say it (the names of the errors).
#[derive(Clone, Debug)]
pub struct SampleRequest {
    /// Keyframe CSV file: header `t,q1,...,qN` plus optional `v1,...,vN` velocity columns.
    pub keyframes: PathBuf,
    /// Interpolation method.
    pub method: Method,
    /// Samples per second, from the first to the last keyframe time inclusive.
    pub rate: f64,
    /// Kochanek-Bartels tension, continuity and bias (`Method::Kb`).
    pub tcb: [f64; 3],
    /// End condition of `catmull-rom` and `kb`.
    pub ends: Ends,
    /// Joint limits as typed (`v=1.5,a=4`, [`parse_limits`]): read here, so that a bad one is
    /// reported before anything else is checked.
    pub limits: Option<String>,
    /// JSON (one line) instead of CSV.
    pub json: bool,
    /// Also draw position, velocity and acceleration per joint to this PNG file.
    pub plot: Option<PathBuf>,
}

/// Runs `armctl trajectory sample`.
pub fn run(request: &SampleRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let limits = request.limits.as_deref().map(parse_limits).transpose()?;
    if !(request.rate.is_finite() && request.rate > 0.0) {
        bail!("--rate must be a positive finite number of samples per second");
    }
    let keyframes = read_keyframes(&request.keyframes)?;
    if keyframes.velocities.is_some() && request.method != Method::Hermite {
        writeln!(
            err,
            "note: --method {} ignores the velocity columns (only hermite uses them)",
            request.method.name()
        )?;
    }
    let options = Options { method: request.method, tcb: request.tcb, ends: request.ends, rate: request.rate, limits };
    let sampled = sample(&keyframes, &options).with_context(|| request.keyframes.display().to_string())?;
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
    if let Some(path) = &request.plot {
        let title = format!("{} ({})", request.keyframes.display(), request.method.name());
        trajectory_plot::draw(path, &sampled, &title)
            .with_context(|| format!("cannot write plot {}", path.display()))?;
    }
    if request.json {
        writeln!(out, "{}", to_json(&sampled))?;
    } else {
        write_csv(out, &sampled)?;
    }
    Ok(0)
}
