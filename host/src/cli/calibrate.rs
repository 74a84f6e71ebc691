//! `armctl calibrate`'s options, turned into the request [`crate::commands::servo::calibrate`]
//! runs, and `--json`: the outcome read back from the files written.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde_json::{json, Value};

use crate::arm::ArmSpec;
use crate::cli::bus_args::ProtocolArg;
use crate::commands::servo::calibrate::{CalibrateRequest, DEFAULT_TIMEOUT_MS};
use crate::support::json_out::print_json;

/// `armctl calibrate`'s arguments.
#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// The servos' USB adapter's serial port (/dev/ttyUSB0, /dev/ttyACM0, COM3) (required; like
    /// --protocol, --baud and --arm, it may come before the command too).
    #[arg(long, value_name = "PORT")]
    pub bus: Option<String>,
    /// The servos' protocol: sts (Feetech) or dxl2 (Dynamixel 2.0) (required).
    #[arg(long, value_enum)]
    pub protocol: Option<ProtocolArg>,
    /// Baud rate [default: 1000000].
    #[arg(long)]
    pub baud: Option<u32>,
    /// The arm: a preset (so101, open-manipulator-x) or an arm file with a [servos] table
    /// (required).
    #[arg(long)]
    pub arm: Option<String>,
    /// The arm file to write (.toml). A new file gets the arm's joints with their limits tightened
    /// to the measured ranges, its servos with their calibration, its gripper's range. An existing
    /// arm file of the same arm keeps everything its author wrote (comments, units, layout): only
    /// its [servos] calibration keys and its [gripper] range change. Any other existing file is
    /// refused, before the servos are touched.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the calibration as LeRobot's calibration file (JSON), for LeRobot or for
    /// `--calibration`.
    #[arg(long, value_name = "FILE")]
    pub lerobot_json: Option<PathBuf>,
    /// Margin added to each reply timeout, in ms; USB adapters with a 16 ms latency timer need 20
    /// or more.
    #[arg(long, default_value_t = DEFAULT_TIMEOUT_MS, value_parser = clap::value_parser!(u32).range(0..=10_000))]
    pub timeout_ms: u32,
}

impl CalibrateArgs {
    /// The request; --bus, --protocol and --arm are checked here, not by clap, as they may come
    /// before the command.
    pub fn request(self) -> Result<CalibrateRequest> {
        match (self.bus, self.protocol, self.arm) {
            (Some(bus), Some(protocol), Some(arm)) => Ok(CalibrateRequest {
                bus,
                protocol: protocol.into(),
                baud: self.baud,
                arm,
                out: self.out,
                lerobot_json: self.lerobot_json,
                timeout_ms: self.timeout_ms,
            }),
            (bus, protocol, arm) => {
                let missing =
                    [(bus.is_none(), "--bus PORT"), (protocol.is_none(), "--protocol"), (arm.is_none(), "--arm")];
                let missing: Vec<&str> = missing.into_iter().filter_map(|(m, name)| m.then_some(name)).collect();
                bail!("calibrate needs {} (see armctl calibrate --help)", missing.join(", "))
            }
        }
    }
}

/// `armctl calibrate`; with `json`, the dialog goes to `err` and its outcome, read back from the
/// arm file written, to `out` as one line of JSON.
pub fn run(args: CalibrateRequest, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    use crate::arm::calibration::{lerobot, record};
    if !json {
        return crate::commands::servo::calibrate::run(args, out, err);
    }
    /// One writer shared by the dialog's two streams.
    struct Shared<'a, 'b>(&'a std::cell::RefCell<&'b mut dyn Write>);
    impl Write for Shared<'_, '_> {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.borrow_mut().write(buf)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.0.borrow_mut().flush()
        }
    }
    let (written, lerobot_json) = (args.out.clone(), args.lerobot_json.clone());
    let shared = std::cell::RefCell::new(err);
    let code = crate::commands::servo::calibrate::run(args, &mut Shared(&shared), &mut Shared(&shared))?;
    let arm = ArmSpec::load(&written.display().to_string(), None)?;
    let servos = crate::arm::servos::servos_of(&arm)
        .ok_or_else(|| anyhow::anyhow!("{} has no [servos] table after calibrating", written.display()))?;
    let file = record::lerobot_file(
        &arm,
        servos.calibration.as_deref().unwrap_or_default(),
        servos.gripper_calibration.as_ref(),
    );
    let calibration: Value = serde_json::from_str(&lerobot::to_text(&file))?;
    let joints: Vec<Value> =
        arm.joints.iter().map(|j| json!({"name": j.name, "lower": j.lower, "upper": j.upper})).collect();
    print_json(
        out,
        &json!({
            "out": written.display().to_string(),
            "lerobot_json": lerobot_json.map(|p| p.display().to_string()),
            "joints": joints,
            "calibration": calibration,
        }),
    )?;
    Ok(code)
}
