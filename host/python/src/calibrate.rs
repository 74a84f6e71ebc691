//! `armctl calibrate` for Python (a LeRobot robot's `calibrate`): LeRobot's procedure on the
//! servos of a USB adapter, each step answered by a line on this process's standard input, the
//! result written to the servos, an arm file and LeRobot's calibration file.

use std::path::PathBuf;

use armctl::commands::servo::calibrate::{run, CalibrateRequest, DEFAULT_TIMEOUT_MS};
use armctl::runtime::connection::protocol_named;
use pyo3::prelude::*;

use crate::errors::{to_py, OrRaise};

/// Calibrates `arm`'s servos on `bus` (`protocol` sts or dxl2), prompting on standard output and
/// reading each step's Enter from standard input; writes the arm file `out` (.toml) and, if
/// given, LeRobot's file `lerobot_json`.
#[pyfunction]
#[pyo3(signature = (bus, protocol, arm, out, lerobot_json = None, baud = None))]
pub fn calibrate(
    py: Python<'_>,
    bus: String,
    protocol: &str,
    arm: String,
    out: PathBuf,
    lerobot_json: Option<PathBuf>,
    baud: Option<u32>,
) -> PyResult<()> {
    let request = CalibrateRequest {
        bus,
        protocol: protocol_named(protocol).or_raise()?,
        baud,
        arm,
        out,
        lerobot_json,
        timeout_ms: DEFAULT_TIMEOUT_MS,
    };
    let code = py
        .detach(|| {
            let (mut out, mut err) = (std::io::stdout(), std::io::stderr());
            run(request, &mut out, &mut err)
        })
        .or_raise()?;
    match code {
        0 => Ok(()),
        code => Err(to_py(anyhow::anyhow!("calibration ended with code {code}: nothing further was written"))),
    }
}
