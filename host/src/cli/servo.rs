//! The `armctl servo` arguments and their dispatch.
//!
//! Timeouts: each transaction waits for the reply's wire time, the servo's return delay and
//! `--timeout-ms` (default 10 ms). USB adapters hold received bytes for their latency timer before
//! passing them on (16 ms by default on FTDI chips; 1 ms once set, e.g. through
//! `/sys/bus/usb-serial/devices/ttyUSB0/latency_timer` on Linux): with such an adapter give
//! `--timeout-ms 20` or more, or servos look silent.

use std::io::Write;

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use firmware::bus::master::BusConfig;
use firmware::bus::{Id, Protocol};

use crate::cli::bus_args::ProtocolArg;
use crate::commands::servo::commands::{self, Target};
use crate::runtime::servo_session::Session;

/// Serial bus servos: scan, read and write the control table, set id and baud rate, torque.
#[derive(Args, Debug)]
pub struct ServoArgs {
    #[command(subcommand)]
    command: ServoCommand,
    /// Print the result as one line of JSON with the same content as the text (before or after
    /// the subcommand).
    #[arg(long, global = true)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
enum ServoCommand {
    /// Ping every id and list the servos that answer: `id 1: model 1060 XL430-W250, firmware 46,
    /// 57600 baud`.
    Scan {
        #[command(flatten)]
        bus: BusArgs,
        /// Ids to ping: a list of ids and ranges, e.g. `1-6` or `1,3,10-12` (default: every
        /// id of the protocol).
        #[arg(long, value_parser = parse_ids)]
        ids: Option<IdList>,
        /// Scan at every baud rate of the protocol's models, fastest first (ignores --baud).
        #[arg(long)]
        all_bauds: bool,
    },
    /// Read bytes of a servo's control table: the bytes in hex, then `name = value` for every
    /// known item among them; or named items (`--item present_position,present_load`).
    Read {
        #[command(flatten)]
        bus: BusArgs,
        /// The servo's id.
        #[arg(long, value_parser = clap::value_parser!(u8).range(0..=253))]
        id: u8,
        /// First address.
        #[arg(long, required_unless_present = "item", requires = "len")]
        addr: Option<u16>,
        /// Bytes to read.
        #[arg(long, value_parser = clap::value_parser!(u16).range(1..=commands::MAX_READ as i64), requires = "addr")]
        len: Option<u16>,
        /// Items by name instead of --addr and --len, comma-separated (as `read` prints them:
        /// present_position, goal_position, ...); read in one transaction.
        #[arg(long, conflicts_with_all = ["addr", "len"], value_delimiter = ',')]
        item: Vec<String>,
    },
    /// Write a value at an address, in the model's byte order and encoding.
    Write {
        #[command(flatten)]
        bus: BusArgs,
        /// The servo's id.
        #[arg(long, value_parser = clap::value_parser!(u8).range(0..=253))]
        id: u8,
        /// Address (of a known item, or any with --len).
        #[arg(long)]
        addr: u16,
        /// The value: decimal, negative, or 0x hexadecimal.
        #[arg(long, allow_hyphen_values = true, value_parser = parse_value)]
        value: i64,
        /// Bytes to write: 1, 2 or 4 (default: the size of the item at --addr).
        #[arg(long, value_parser = parse_len)]
        len: Option<u8>,
    },
    /// Give a servo another id (which must be free). Dynamixel: torque must be off.
    SetId {
        #[command(flatten)]
        bus: BusArgs,
        /// The servo's id now.
        #[arg(long, value_parser = clap::value_parser!(u8).range(0..=253))]
        id: u8,
        /// Its new id.
        #[arg(long, value_parser = clap::value_parser!(u8).range(0..=253))]
        new_id: u8,
    },
    /// Switch a servo to another baud rate (one its model has), then check it answers there.
    /// Dynamixel: torque must be off.
    SetBaud {
        #[command(flatten)]
        bus: BusArgs,
        /// The servo's id.
        #[arg(long, value_parser = clap::value_parser!(u8).range(0..=253))]
        id: u8,
        /// The new baud rate.
        #[arg(long)]
        new_baud: u32,
    },
    /// A LeRobot calibration file (JSON) against the servos' registers (homing offset, position
    /// limits; drive mode on Dynamixel), or written to them.
    Calibration {
        /// check (compare, as LeRobot does when it connects) or write (the file's values, to
        /// servos whose torque is off).
        #[arg(value_enum)]
        action: CalibrationAction,
        #[command(flatten)]
        bus: BusArgs,
        /// The calibration file, e.g. ~/.cache/huggingface/lerobot/calibration/robots/so_follower/my_arm.json.
        #[arg(long)]
        file: std::path::PathBuf,
    },
    /// Switch torque on or off.
    Torque {
        /// on or off.
        #[arg(value_enum)]
        state: OnOff,
        #[command(flatten)]
        bus: BusArgs,
        /// The servo's id, or `all` (a broadcast write, which no servo confirms).
        #[arg(long, value_parser = parse_target)]
        id: Target,
    },
}

/// What `calibration` does.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum CalibrationAction {
    Check,
    Write,
}

/// Torque state.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum OnOff {
    On,
    Off,
}

#[derive(Args, Debug)]
struct BusArgs {
    /// Serial port (/dev/ttyUSB0, /dev/ttyACM0, COM3).
    #[arg(long)]
    port: String,
    /// Bus protocol.
    #[arg(long, value_enum)]
    protocol: ProtocolArg,
    /// Baud rate (default: the factory rate, 57600 on Dynamixel X, 1000000 on Feetech STS).
    #[arg(long)]
    baud: Option<u32>,
    /// Margin added to each reply timeout, in ms; USB adapters with a 16 ms latency timer need 20
    /// or more.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(0..=10_000))]
    timeout_ms: u32,
    /// Extra attempts after no reply or a corrupt one (default 0 for scan, 2 otherwise).
    #[arg(long)]
    retries: Option<u8>,
}

impl BusArgs {
    fn config(&self, default_retries: u8) -> BusConfig {
        let protocol = Protocol::from(self.protocol);
        let baud = self.baud.unwrap_or(match protocol {
            Protocol::Dxl2 => 57_600,
            Protocol::Feetech => 1_000_000,
        });
        let base = BusConfig::new(protocol, baud);
        BusConfig {
            margin_us: self.timeout_ms * 1000,
            // A USB adapter can deliver one packet in two transfers, up to its latency apart.
            idle_gap_us: (self.timeout_ms * 1000).max(base.idle_gap_us),
            retries: self.retries.unwrap_or(default_retries),
            ..base
        }
    }

    fn open(&self) -> Result<Session> {
        Ok(Session::open(&self.port, self.config(2))?)
    }
}

/// Ids given to `scan --ids`.
#[derive(Clone, Debug)]
struct IdList(Vec<Id>);

fn parse_ids(text: &str) -> Result<IdList, String> {
    let mut ids = crate::support::numbers::ids(text, 253, "--ids").map_err(|e| e.to_string())?;
    ids.sort_unstable();
    Ok(IdList(ids))
}

fn parse_value(text: &str) -> Result<i64, String> {
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text),
    };
    let magnitude = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => i64::from_str_radix(hex, 16),
        None => digits.parse::<i64>(),
    }
    .map_err(|_| format!("{text:?} is not an integer"))?;
    Ok(if negative { -magnitude } else { magnitude })
}

fn parse_len(text: &str) -> Result<u8, String> {
    match text {
        "1" => Ok(1),
        "2" => Ok(2),
        "4" => Ok(4),
        _ => Err("a value is 1, 2 or 4 bytes".to_string()),
    }
}

fn parse_target(text: &str) -> Result<Target, String> {
    if text == "all" {
        return Ok(Target::All);
    }
    text.parse::<Id>()
        .ok()
        .filter(|id| *id <= 253)
        .map(Target::One)
        .ok_or_else(|| format!("{text:?} is neither an id (0-253) nor all"))
}

/// An argument the protocol does not allow: one line and exit code 2, as clap's own errors.
fn usage(err: &mut dyn Write, message: &str) -> Result<i32> {
    writeln!(err, "error: {message} (see armctl servo --help)")?;
    Ok(2)
}

/// Checks `ids` against the protocol's id range (Dynamixel stops at 252, Feetech at 253).
fn check_ids(protocol: Protocol, ids: &[Id]) -> Option<String> {
    let max = match protocol {
        Protocol::Dxl2 => 252,
        Protocol::Feetech => 253,
    };
    ids.iter().find(|id| **id > max).map(|id| format!("id {id} is outside {}'s ids 0-{max}", protocol.name()))
}

/// Runs `armctl servo ...`; returns the exit code (0 done, 1 the bus or a servo failed or reports
/// a fault, 2 bad arguments).
pub fn run(args: ServoArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let (bus, ids) = match &args.command {
        ServoCommand::Scan { bus, ids, .. } => (bus, ids.as_ref().map_or_else(Vec::new, |l| l.0.clone())),
        ServoCommand::Read { bus, id, .. }
        | ServoCommand::Write { bus, id, .. }
        | ServoCommand::SetBaud { bus, id, .. } => (bus, vec![*id]),
        ServoCommand::SetId { bus, id, new_id } => (bus, vec![*id, *new_id]),
        ServoCommand::Torque { bus, id, .. } => (bus, if let Target::One(id) = id { vec![*id] } else { vec![] }),
        ServoCommand::Calibration { bus, .. } => (bus, vec![]),
    };
    if let Some(problem) = check_ids(bus.protocol.into(), &ids) {
        return usage(err, &problem);
    }
    let json = args.json;
    match args.command {
        ServoCommand::Scan { bus, ids, all_bauds } => {
            let config = bus.config(0);
            let ids = match ids {
                Some(IdList(ids)) => ids,
                None => (0..=253).collect(),
            };
            let protocol = config.protocol;
            // The default range is Feetech's; Dynamixel stops one id earlier.
            let ids: Vec<Id> = ids.into_iter().filter(|id| check_ids(protocol, &[*id]).is_none()).collect();
            let bauds = if all_bauds { commands::protocol_bauds(protocol) } else { vec![config.baud] };
            commands::scan(&bus.port, config, &bauds, &ids, json, out, err)
        }
        ServoCommand::Read { bus, id, addr: Some(addr), len: Some(len), .. } => {
            commands::read(&mut bus.open()?, id, addr, usize::from(len), json, out, err)
        }
        ServoCommand::Read { bus, id, item, .. } => commands::read_items(&mut bus.open()?, id, &item, json, out, err),
        ServoCommand::Write { bus, id, addr, value, len } => {
            commands::write(&mut bus.open()?, id, addr, value, len, json, out, err)
        }
        ServoCommand::SetId { bus, id, new_id } => {
            if id == new_id {
                return usage(err, "--new-id is the servo's id already");
            }
            commands::set_id(&mut bus.open()?, id, new_id, json, out, err)
        }
        ServoCommand::SetBaud { bus, id, new_baud } => commands::set_baud(bus.open()?, id, new_baud, json, out, err),
        ServoCommand::Calibration { action, bus, file } => {
            // The file is checked before the port is opened: a bad file touches no servo.
            crate::commands::servo::calibration::read_file(&file)?;
            let mut session = bus.open()?;
            match action {
                CalibrationAction::Check => {
                    let protocol = match bus.protocol {
                        ProtocolArg::Sts => "sts",
                        ProtocolArg::Dxl2 => "dxl2",
                    };
                    let baud = bus.baud.map(|b| format!(" --baud {b}")).unwrap_or_default();
                    let fix = format!(
                        "armctl servo calibration write --port {} --protocol {protocol}{baud} --file {}",
                        bus.port,
                        file.display()
                    );
                    crate::commands::servo::calibration::check(&mut session, &file, &fix, json, out, err)
                }
                CalibrationAction::Write => {
                    crate::commands::servo::calibration::write(&mut session, &file, json, out, err)
                }
            }
        }
        ServoCommand::Torque { state, bus, id } => {
            commands::torque(&mut bus.open()?, id, matches!(state, OnOff::On), json, out, err)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_id_lists() {
        assert_eq!(parse_ids("1-3,7,2").unwrap().0, [1, 2, 3, 7]);
        assert!(parse_ids("3-1").is_err());
        assert!(parse_ids("254").is_err());
        assert!(parse_ids("x").is_err());
    }

    #[test]
    fn parses_values() {
        assert_eq!(parse_value("2048"), Ok(2048));
        assert_eq!(parse_value("-5"), Ok(-5));
        assert_eq!(parse_value("0x800"), Ok(2048));
        assert!(parse_value("1.5").is_err());
    }
}
