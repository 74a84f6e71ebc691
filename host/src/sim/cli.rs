//! `armctl sim servos`: a simulated servo bus served on a pseudo-terminal.

use std::io::Write;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use firmware::bus::{dxl2, feetech, Protocol};

use super::faults::Faults;
use super::pty::{PtyServer, SimConfig};
use crate::bus_args::{model_for, ModelArg, ProtocolArg};

/// What to simulate.
#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Serve simulated servos on a pseudo-terminal: prints its path on the first line of stdout,
    /// then serves until interrupted.
    Servos(SimServosArgs),
}

/// Arguments of `armctl sim servos`.
#[derive(Args, Debug)]
pub struct SimServosArgs {
    /// Bus protocol.
    #[arg(long, value_enum)]
    pub protocol: ProtocolArg,
    /// Servo ids: ranges and lists, e.g. `1-6`, `1,3,5`, `1-3,7`.
    #[arg(long)]
    pub ids: String,
    /// Servo model (default xl430-w250 on dxl2, sts3215 on sts).
    #[arg(long, value_enum)]
    pub model: Option<ModelArg>,
    /// Baud rate (one the model has a baud index for).
    #[arg(long, default_value_t = 1_000_000)]
    pub baud: u32,
    /// Serve on a pseudo-terminal (required: the only transport for now).
    #[arg(long)]
    pub pty: bool,
    /// Keep --baud whatever baud rate the other end sets on the pty (QEMU's UARTs set the
    /// standard rate nearest their divider: 921600 for 1 Mbps).
    #[arg(long)]
    pub fixed_baud: bool,
    /// Servos that never answer (repeatable).
    #[arg(long, num_args = 1..)]
    pub silent: Vec<u8>,
    /// Probability that a reply is corrupted (one bit flipped).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
    /// Probability per byte, both directions, that it is lost.
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// An id that gets a second servo (their replies collide).
    #[arg(long)]
    pub duplicate: Vec<u8>,
    /// Seed of the random faults.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Parses `1-6`, `1,3,5`, `1-3,7` into ids in the order given, without repeats.
pub fn parse_ids(text: &str) -> Result<Vec<u8>> {
    let mut ids = Vec::new();
    for part in text.split(',').map(str::trim) {
        let number = |s: &str| s.trim().parse::<u8>().with_context(|| format!("--ids: `{s}` is not an id (0-255)"));
        let (lo, hi) = match part.split_once('-') {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(part)?, number(part)?),
        };
        if lo > hi {
            bail!("--ids: range `{part}` runs backwards");
        }
        for id in lo..=hi {
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
    }
    Ok(ids)
}

/// Checks the arguments and builds the bus description.
pub fn config(args: &SimServosArgs) -> Result<SimConfig> {
    let protocol = Protocol::from(args.protocol);
    let max_id = match protocol {
        Protocol::Dxl2 => dxl2::MAX_ID,
        Protocol::Feetech => feetech::MAX_ID,
    };
    let model = model_for(protocol, args.model)?;
    let ids = parse_ids(&args.ids)?;
    let all = ids.iter().chain(&args.silent).chain(&args.duplicate);
    if let Some(id) = all.into_iter().find(|&&id| id > max_id) {
        bail!("id {id} is outside {}'s range 0-{max_id}", protocol.name());
    }
    if model.baud_index(args.baud).is_none() {
        let known: Vec<String> = model.bauds.iter().map(|(_, b)| b.to_string()).collect();
        bail!("{} has no baud index for {} (it knows {})", model.name, args.baud, known.join(", "));
    }
    for (name, p) in [("--corrupt-rate", args.corrupt_rate), ("--drop-rate", args.drop_rate)] {
        if !(0.0..=1.0).contains(&p) {
            bail!("{name} must be a probability between 0 and 1");
        }
    }
    let faults = Faults {
        seed: args.seed,
        silent: args.silent.clone(),
        corrupt_rate: args.corrupt_rate,
        drop_rate: args.drop_rate,
        bit_flip_rate: 0.0,
    };
    Ok(SimConfig {
        protocol,
        model,
        ids,
        baud: args.baud,
        faults,
        duplicates: args.duplicate.clone(),
        fixed_baud: args.fixed_baud,
    })
}

/// Runs a `sim` command. Bad arguments are one `error:` line on `err` and exit code 2.
pub fn run(command: SimCommand, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let SimCommand::Servos(args) = command;
    if !args.pty {
        writeln!(err, "error: --pty is required (the simulated bus is served on a pseudo-terminal)")?;
        return Ok(2);
    }
    let config = match config(&args) {
        Ok(c) => c,
        Err(e) => {
            writeln!(err, "error: {e:#}")?;
            return Ok(2);
        }
    };
    let server = PtyServer::spawn(config.clone()).context("cannot open a pseudo-terminal")?;
    writeln!(out, "{}", server.path())?;
    out.flush()?;
    let ids: Vec<String> = config.ids.iter().map(u8::to_string).collect();
    writeln!(
        err,
        "serving {} {} servo(s) (ids {}) on {} at {} baud, {}; interrupt to stop",
        config.ids.len(),
        config.model.name,
        ids.join(","),
        config.protocol.name(),
        config.baud,
        server.path()
    )?;
    err.flush()?;
    // Serve until interrupted (SIGINT's default action ends the process) or the server fails.
    while !server.is_finished() {
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    server.stop().context("the simulated bus stopped")?;
    Ok(1)
}
