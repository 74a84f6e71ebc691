//! `armctl trajectory sample`'s options, turned into the request [`crate::motion::sample`] runs.

use std::path::PathBuf;

use clap::Args;

use crate::motion::sample::SampleRequest;
use crate::motion::trajectory::{Ends, Method};

/// Arguments of `armctl trajectory sample`.
#[derive(Args, Debug)]
pub struct SampleArgs {
    /// Keyframe CSV file: header `t,q1,...,qN` plus optional `v1,...,vN` velocity columns.
    #[arg(long)]
    pub keyframes: PathBuf,
    /// Interpolation method.
    #[arg(long, value_parser = crate::cli::values::method())]
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
    #[arg(long, value_parser = crate::cli::values::ends(), default_value = "zero")]
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

impl SampleArgs {
    /// The request the options make.
    pub fn request(self) -> SampleRequest {
        SampleRequest {
            keyframes: self.keyframes,
            method: self.method,
            rate: self.rate,
            tcb: [self.tension, self.continuity, self.bias],
            ends: self.ends,
            limits: self.limits,
            json: self.json,
            plot: self.plot,
        }
    }
}
