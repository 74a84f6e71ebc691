//! The options of `armctl bench bus|rate|mcu|loop-pass|pc`, turned into the requests
//! [`crate::commands::bench`] runs: the protocol and model names become the firmware's model here.
//! (`bench ik`'s options are in the command list itself, [`super::BenchCommand`].)

use anyhow::Result;
use clap::Args;
use firmware::bus::Protocol;

use crate::cli::bus_args::{model_for, ModelArg, ProtocolArg};
use crate::commands::bench::bus::BusBenchRequest;
use crate::commands::bench::pc::PcBenchRequest;
use crate::commands::bench::rate::{RateBenchRequest, SERVOS};

/// Arguments of `armctl bench bus`.
#[derive(Args, Debug)]
pub struct BusBenchArgs {
    /// Bus protocol.
    #[arg(long, value_enum)]
    protocol: ProtocolArg,
    /// Number of servos (ids 1..=N), 1 to 16.
    #[arg(long, default_value_t = 6)]
    servos: usize,
    /// Baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    baud: u32,
    /// Servo model (default xl430-w250 on dxl2, sts3215 on sts).
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// The servos' return delay in microseconds (default: the model's factory setting, 500 us on
    /// the X-series, 0 on the STS3215); rounded down to the model's 2 us unit.
    #[arg(long)]
    return_delay_us: Option<u32>,
    /// Control cycles simulated (the median is reported).
    #[arg(long, default_value_t = 100)]
    cycles: usize,
    /// Changes nothing: the output is JSON already (one indented object).
    #[arg(long)]
    pub json: bool,
}

impl BusBenchArgs {
    /// The request; an error line when `--model` speaks another protocol than `--protocol`.
    pub fn request(&self) -> Result<BusBenchRequest> {
        Ok(BusBenchRequest {
            model: model_for(self.protocol.into(), self.model)?,
            servos: self.servos,
            baud: self.baud,
            return_delay_us: self.return_delay_us,
            cycles: self.cycles,
        })
    }
}

/// Arguments of `armctl bench rate`.
#[derive(Args, Debug)]
pub struct RateBenchArgs {
    /// Bus protocol.
    #[arg(long, value_enum)]
    protocol: ProtocolArg,
    /// Number of servos: 6 only (the bench drives the UR5e preset's 6-joint chain).
    #[arg(long, default_value_t = SERVOS)]
    servos: usize,
    /// Baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    baud: u32,
    /// Servo model (default xl430-w250 on dxl2, sts3215 on sts).
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// The servos' return delay in microseconds, set on the simulated servos and in the master's
    /// bus configuration; rounded down to the model's 2 us unit.
    #[arg(long, default_value_t = 0)]
    return_delay_us: u32,
    /// Virtual seconds each schedule runs (compute time is free on the virtual clock).
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// One JSON object (indented) instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl RateBenchArgs {
    /// The request; an error line when `--model` speaks another protocol than `--protocol`.
    pub fn request(&self) -> Result<RateBenchRequest> {
        Ok(RateBenchRequest {
            model: model_for(self.protocol.into(), self.model)?,
            servos: self.servos,
            baud: self.baud,
            return_delay_us: self.return_delay_us,
            seconds: self.seconds,
            json: self.json,
        })
    }
}

/// Arguments of `armctl bench mcu`.
#[derive(Args, Debug)]
pub struct McuBenchArgs {
    /// One JSON object (indented) instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `armctl bench loop-pass`.
#[derive(Args, Debug)]
pub struct LoopPassBenchArgs {
    /// Seconds of wall time the run at -icount shift=3 floods the link (the one at shift 0, three
    /// times as long).
    #[arg(long, default_value_t = crate::commands::bench::loop_pass::DEFAULT_SECONDS)]
    pub seconds: f64,
    /// One JSON object (indented) instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `armctl bench pc`.
#[derive(Args, Debug)]
pub struct PcBenchArgs {
    /// Bus protocol.
    #[arg(long, value_enum)]
    protocol: ProtocolArg,
    /// Number of servos (ids 1..=N), 1 to 8.
    #[arg(long, default_value_t = 6)]
    servos: usize,
    /// Baud rate.
    #[arg(long, default_value_t = 1_000_000)]
    baud: u32,
    /// Deliver the servos' replies in bursts every MS milliseconds (a USB adapter's latency timer:
    /// 16 on FTDI by default); none when not given.
    #[arg(long, value_name = "MS")]
    burst_ms: Option<u64>,
    /// Seconds of motion measured.
    #[arg(long, default_value_t = 5.0)]
    seconds: f64,
    /// Changes nothing: the output is one line of JSON already.
    #[arg(long)]
    pub json: bool,
}

impl PcBenchArgs {
    /// The request, with the protocol's usual servo model (the bench has no `--model`).
    pub fn request(&self) -> Result<PcBenchRequest> {
        Ok(PcBenchRequest {
            model: model_for(Protocol::from(self.protocol), None)?,
            servos: self.servos,
            baud: self.baud,
            burst_ms: self.burst_ms,
            seconds: self.seconds,
        })
    }
}

/// Arguments of `armctl bench plan`.
#[derive(Args, Debug)]
pub struct PlanBenchArgs {
    /// Arm: a preset or an arm file.
    #[arg(long, default_value = "so101")]
    pub arm: String,
    /// Blocked moves planned.
    #[arg(long, default_value_t = 200)]
    pub moves: usize,
    /// Seed of the move sampler.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Random shortcuts tried on each path before its corners are skipped (the planner's own
    /// setting by default): fewer plan faster, more give shorter paths.
    #[arg(long, default_value_t = crate::motion::plan::DEFAULT_SHORTCUTS)]
    pub shortcuts: usize,
    /// One JSON object (indented) instead of the summary line.
    #[arg(long)]
    pub json: bool,
}

impl PlanBenchArgs {
    /// The request.
    pub fn request(&self) -> crate::commands::bench::plan::PlanBenchRequest {
        crate::commands::bench::plan::PlanBenchRequest {
            arm: self.arm.clone(),
            moves: self.moves,
            seed: self.seed,
            shortcuts: self.shortcuts,
        }
    }
}

/// Arguments of `armctl bench servos`.
#[derive(Args, Debug)]
pub struct ServosBenchArgs {
    /// Arm: a preset or an arm file with servos.
    #[arg(long, default_value = "so101")]
    pub arm: String,
    /// Virtual seconds simulated, each timed (1 to 600).
    #[arg(long, default_value_t = 20)]
    pub seconds: usize,
    /// One JSON object (indented) instead of the summary line.
    #[arg(long)]
    pub json: bool,
}

impl ServosBenchArgs {
    /// The request.
    pub fn request(&self) -> crate::commands::bench::servos::ServosBenchRequest {
        crate::commands::bench::servos::ServosBenchRequest { arm: self.arm.clone(), seconds: self.seconds }
    }
}
