//! `armctl sim servos`: a simulated servo bus served on a pseudo-terminal; `armctl sim --qemu`:
//! the real firmware binary under QEMU on such a bus, for `armctl --port`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use firmware::bus::table::Model;
use firmware::bus::{dxl2, feetech, Protocol};

use crate::arm::servos::{servos_of, ServoSetup};
use crate::arm::ArmSpec;
use crate::cli::bus_args::{model_for, ModelArg, ProtocolArg};
use crate::runtime::connection::calibrated;
#[cfg(feature = "board-tools")]
use crate::runtime::qemu::{self, Qemu, QemuConfig};
use crate::sim::monitor::MAX_VIOLATIONS;
use crate::sim::{limits_of, Faults, PtyServer, Recorder, ServeOptions, SimConfig};
use crate::support::interrupt;

/// Arguments of `armctl sim`: a subcommand, or `--qemu`.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct SimArgs {
    /// Run the real firmware (the MPS2 AN386 Cortex-M4F binary, built if needed) under
    /// qemu-system-arm, its servo bus on simulated SO-101 servos (Feetech STS3215 at 1 Mbps: the
    /// joints' ids 1-5 and the gripper's 6).
    /// Prints the host link's port on the first line of stdout and the firmware's log on stderr,
    /// then runs until interrupted.
    #[arg(long)]
    pub qemu: bool,
    /// The firmware ELF to run instead of building the board crate's.
    #[arg(long, requires = "qemu")]
    pub elf: Option<PathBuf>,
    /// Faults of the simulated servos under QEMU.
    #[command(flatten)]
    pub faults: FaultArgs,
    /// With --qemu: print the first line as JSON, {"port": PATH} (the host link's), instead of the
    /// bare path.
    #[arg(long, requires = "qemu")]
    pub json: bool,
    /// What to simulate.
    #[command(subcommand)]
    pub what: Option<SimCommand>,
}

/// Faults of a simulated bus.
#[derive(Args, Debug, Clone)]
pub struct FaultArgs {
    /// Servos that never answer (repeatable).
    #[arg(long, num_args = 1..)]
    pub silent: Vec<u8>,
    /// Probability that a reply is corrupted (one bit flipped).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
    /// Probability per byte, both directions, that it is lost.
    #[arg(long, default_value_t = 0.0)]
    pub drop_rate: f64,
    /// Probability per byte, both directions, that one of its bits flips: a noisy line (a loose
    /// cable, a long unshielded one). Replies whose checksum then fails are corrupt replies;
    /// instructions whose checksum fails are not carried out.
    #[arg(long, default_value_t = 0.0, value_name = "P")]
    pub bit_flip_rate: f64,
    /// Seed of the random faults.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl FaultArgs {
    /// The faults, once the probabilities are checked.
    pub fn faults(&self) -> Result<Faults> {
        let rates = [
            ("--corrupt-rate", self.corrupt_rate),
            ("--drop-rate", self.drop_rate),
            ("--bit-flip-rate", self.bit_flip_rate),
        ];
        for (name, p) in rates {
            if !(0.0..=1.0).contains(&p) {
                bail!("{name} must be a probability between 0 and 1");
            }
        }
        Ok(Faults {
            seed: self.seed,
            silent: self.silent.clone(),
            corrupt_rate: self.corrupt_rate,
            drop_rate: self.drop_rate,
            bit_flip_rate: self.bit_flip_rate,
        })
    }
}

/// What to simulate.
#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Serve simulated servos on a pseudo-terminal: prints its path on the first line of stdout,
    /// then serves until interrupted.
    Servos(SimServosArgs),
}

/// Arguments of `armctl sim servos`.
///
/// While it serves, each line on its standard input moves a horn as a hand would (the servo's
/// torque must be off), in the horn's own ticks, before the homing offset:
/// `move ID TICKS` puts it there at once; `sweep ID FROM TO SECONDS` puts it at FROM, then turns
/// it steadily to TO in SECONDS. Each command gets one line on stdout: `done move ID TICKS` or
/// `done sweep ID FROM TO SECONDS` once the horn is there and its position has been read since
/// (so that a program recording the bus has seen where the hand stopped: with nobody reading, it
/// does not come), or `error: ...`.
#[derive(Args, Debug)]
pub struct SimServosArgs {
    /// Bus protocol (default: that of --arm's servos).
    #[arg(long, value_enum)]
    pub protocol: Option<ProtocolArg>,
    /// Servo ids: ranges and lists, e.g. `1-6`, `1,3,5`, `1-3,7` (default: --arm's servos and its
    /// gripper's).
    #[arg(long)]
    pub ids: Option<String>,
    /// Servo model (default: --arm's, else xl430-w250 on dxl2, sts3215 on sts).
    #[arg(long, value_enum)]
    pub model: Option<ModelArg>,
    /// Where the horns stand at the start, in their own ticks (before any homing offset): e.g.
    /// `1=3100,2=900` (default: every horn at half a turn, 2048).
    #[arg(long, value_name = "ID=TICKS,...")]
    pub start: Option<String>,
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
    /// Faults.
    #[command(flatten)]
    pub faults: FaultArgs,
    /// An id that gets a second servo (their replies collide). `--ids 1 --duplicate 1` is two
    /// servos both still at the factory's id 1: a ping's replies are alike and pass, a read of
    /// their positions (100 ticks apart) garbles.
    #[arg(long)]
    pub duplicate: Vec<u8>,
    /// Set an item of the servos' control table before anything is served, after --start,
    /// bypassing the bus rules (read-only items and EEPROM with torque on too): ID is a served id
    /// or `all`, ITEM a name as `armctl servo read --item` takes it for the model
    /// (`present_voltage`, `present_temperature`, `firmware_minor_version`, `return_delay_time`,
    /// `status_return_level`, `homing_offset`, `min_position_limit`, `goal_position`,
    /// `torque_enable`...), VALUE a whole number that fits it. Readings and versions stay as set
    /// (a reboot keeps them); `present_position` places the horn there; `goal_position` with
    /// torque off moves nothing (a stale goal); `torque_enable=1` switches torque on without
    /// holding the present position: the servo drives to its goal register, as a real one does.
    /// E.g. `1:present_voltage=120` is a 12 V supply on a 7.4 V STS3215. Repeatable, applied in
    /// order.
    #[arg(long, value_name = "ID:ITEM=VALUE")]
    pub register: Vec<String>,
    /// Raise a hardware error on servo ID (or `all`) from the start: BITS (decimal or 0x..) go to
    /// Dynamixel's hardware error status (bit 0 input voltage, 2 overheating, 3 motor encoder, 4
    /// electrical shock, 5 overload; every status then has the alert bit) or are Feetech's status
    /// error bits (0 voltage, 1 sensor, 2 temperature, 3 current, 4 angle, 5 overload: the "servo
    /// status" bits of Feetech's memory table). Torque goes off and stays off, as the servo's
    /// protection does. Applied after --register. Repeatable.
    #[arg(long, value_name = "ID=BITS")]
    pub hardware_error: Vec<String>,
    /// The adapter hears its own transmission: every byte written to the pty comes back first,
    /// before any reply (a half-duplex adapter without echo suppression). With --burst-ms the
    /// echo waits for the latency timer with the replies.
    #[arg(long)]
    pub echo: bool,
    /// Deliver the replies in bursts, as a USB serial adapter does: held until its latency timer
    /// next expires, every MS milliseconds from the start (FTDI: 16 by default, 1 when tuned;
    /// more than 0, at most 100). Bytes to the servos still arrive at once.
    #[arg(long, value_name = "MS", allow_negative_numbers = true)]
    pub burst_ms: Option<f64>,
    /// Check every goal the servos receive against the joint limits and speed limit of ARM (a
    /// preset or an arm file with a `[servos]` table), mapped to ticks as its firmware maps them,
    /// each goal write against the one before over the control ticks between them (see
    /// --period-ms); each violation is one line on stderr (the first 100), and on Ctrl-C or
    /// SIGTERM a last line says how many goals were checked and how many failed. Its servo ids
    /// must be among --ids.
    #[arg(long, value_name = "ARM")]
    pub arm: Option<String>,
    /// With --arm: the firmware's control period, MS milliseconds; a goal may step the speed
    /// limit times this per control tick [default: 10, the firmware's 100 Hz]. A core on the PC
    /// chooses its period when it connects (its `control period` line): 25 behind --burst-ms 16.
    #[arg(long, value_name = "MS", requires = "arm")]
    pub period_ms: Option<f64>,
    /// With --arm: the simulated links stop where they run into the table, an obstacle or each
    /// other (the arm's collision geometry), and the monitor judges every goal against it. Off by
    /// default on this real-time simulator: a calibration's hand moves every joint stop to stop,
    /// through the table (`--sim` and the SIL tests have contact on).
    #[arg(long, requires = "arm")]
    pub contact: bool,
    /// The servos: `ideal` (the default) reach every goal exactly along their profiles;
    /// `physical` have a motor through a gearbox under their own position loop
    /// (docs/servo-model.md) and carry --arm's links under gravity (the SO-101's masses; other
    /// arms' servos carry none), so they sag, lag, draw current, warm up and can stall.
    #[arg(long, value_name = "KIND", value_parser = ["ideal", "physical"])]
    pub servos: Option<String>,
    /// With --servos physical: a payload of KG kilograms at --arm's tool frame origin. Refused when
    /// it asks a joint for more than its servo's stall torque somewhere in its range.
    #[arg(long, value_name = "KG", requires = "arm", allow_negative_numbers = true)]
    pub payload_kg: Option<f64>,
    /// An object W mm wide between the jaws of --arm's gripper: closing on it, the jaws stop there
    /// and the servo's load rises (as in `armctl --sim --object-mm`).
    #[arg(long, value_name = "W", requires = "arm", allow_negative_numbers = true)]
    pub object_mm: Option<f64>,
    /// Judge the goals by --arm as calibrated by this LeRobot calibration file (each joint's
    /// servo found by its id; the gripper's range too, when the file has it, which also places
    /// --object-mm's object) instead of by the nominal mapping. The servos' control tables are
    /// left as they are: their homing offsets are what `armctl calibrate` or LeRobot write there.
    #[arg(long, value_name = "FILE", requires = "arm")]
    pub calibration: Option<PathBuf>,
    /// Record the servos' positions to FILE (CSV, created or emptied before the pty's path is
    /// printed): a row every 2 ms of real time since the start, header `t,pos_<id>...,goal_<id>...`,
    /// t in seconds, each horn's position in ticks (2 decimals, the frame of its goal and present
    /// position) and its goal, the servos in bus order (--ids, or --arm's and its gripper's).
    /// Flushed at least every 0.5 s and when it stops (Ctrl-C, SIGTERM), so that a reader can
    /// stop it with either.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Print every stdout line as JSON: first {"pty": PATH} instead of the bare path, then
    /// {"done": "move ID TICKS"} or {"error": "..."} for each command on stdin.
    #[arg(long)]
    pub json: bool,
}

/// `--start`: (id, ticks) pairs, each id served, each position on the encoder's turn.
fn start_positions(text: Option<&str>, ids: &[u8], model: &Model) -> Result<Vec<(u8, i64)>> {
    let Some(text) = text else { return Ok(Vec::new()) };
    let top = i64::from(model.ticks_per_revolution) - 1;
    let mut start = Vec::new();
    for part in text.split(',').map(str::trim) {
        let parsed = part
            .split_once('=')
            .and_then(|(id, ticks)| Some((id.trim().parse::<u8>().ok()?, ticks.trim().parse::<i64>().ok()?)));
        let Some((id, ticks)) = parsed else {
            bail!("--start {part:?} is not ID=TICKS (e.g. 1=3100)");
        };
        if !ids.contains(&id) {
            bail!("--start names servo {id}, which is not served (--ids)");
        }
        if !(0..=top).contains(&ticks) {
            bail!("--start {id}={ticks}: a horn stands at 0..={top} ticks on {}", model.name);
        }
        if start.iter().any(|(other, _)| *other == id) {
            bail!("--start names servo {id} twice");
        }
        start.push((id, ticks));
    }
    Ok(start)
}

/// A servo id of `--register` or `--hardware-error`: a served one, or `all` (`None`).
fn served_id(text: &str, ids: &[u8], flag: &str, part: &str) -> Result<Option<u8>> {
    let text = text.trim();
    if text == "all" {
        return Ok(None);
    }
    let Ok(id) = text.parse::<u8>() else {
        bail!("{flag} {part:?}: {text:?} is not a servo id or `all`");
    };
    if !ids.contains(&id) {
        bail!("{flag} {part:?} names servo {id}, which is not served (--ids)");
    }
    Ok(Some(id))
}

/// The item `name` of `model`: its own name, or the other protocol's name of the same role
/// (`status_return_level` and `response_status_level`, `present_voltage` and
/// `present_input_voltage`), so that one set of fault names serves both.
fn item_named(model: &Model, name: &str) -> Option<firmware::bus::table::Item> {
    if let Some(item) = crate::commands::servo::items::named(model, name) {
        return Some(item);
    }
    match name {
        "status_return_level" | "response_status_level" => Some(model.items.status_return_level),
        "present_voltage" | "present_input_voltage" => ["present_voltage", "present_input_voltage"]
            .iter()
            .find_map(|n| crate::commands::servo::items::named(model, n)),
        _ => None,
    }
}

/// `--register ID:ITEM=VALUE`s, parsed and checked against `model` (whether each value fits, and
/// what a servo refuses, is checked when the servos are set up).
fn registers(texts: &[String], ids: &[u8], model: &Model) -> Result<Vec<crate::sim::Register>> {
    let mut out = Vec::new();
    for part in texts.iter().map(|t| t.trim()) {
        let parsed = part.split_once(':').and_then(|(id, rest)| Some((id, rest.split_once('=')?)));
        let Some((id, (name, value))) = parsed else {
            bail!("--register {part:?} is not ID:ITEM=VALUE (e.g. 1:present_voltage=120)");
        };
        let id = served_id(id, ids, "--register", part)?;
        let name = name.trim();
        let Some(item) = item_named(model, name) else {
            let known: Vec<&str> = crate::commands::servo::items::all(model).iter().map(|i| i.name).collect();
            bail!("--register {part:?}: {} has no item {name:?} (it has {})", model.name, known.join(", "));
        };
        let Ok(value) = value.trim().parse::<i64>() else {
            bail!("--register {part:?}: {:?} is not a whole number", value.trim());
        };
        let (lo, hi) = item.range();
        if value < lo || value > hi {
            bail!("--register {part:?}: {value} does not fit {} (it holds {lo} to {hi})", item.name);
        }
        out.push(crate::sim::Register { id, item, value });
    }
    Ok(out)
}

/// `--hardware-error ID=BITS`s: (servo or every servo, bits 1 to 255).
fn hardware_errors(texts: &[String], ids: &[u8]) -> Result<Vec<(Option<u8>, u8)>> {
    let mut out = Vec::new();
    for part in texts.iter().map(|t| t.trim()) {
        let Some((id, bits)) = part.split_once('=') else {
            bail!("--hardware-error {part:?} is not ID=BITS (e.g. 1=0x04, overheating)");
        };
        let id = served_id(id, ids, "--hardware-error", part)?;
        let bits = bits.trim();
        let parsed = match bits.strip_prefix("0x").or_else(|| bits.strip_prefix("0X")) {
            Some(hex) => u8::from_str_radix(hex, 16).ok(),
            None => bits.parse::<u8>().ok(),
        };
        match parsed {
            Some(b) if b != 0 => out.push((id, b)),
            _ => bail!("--hardware-error {part:?}: the bits are a number from 1 to 255 (decimal or 0x..)"),
        }
    }
    Ok(out)
}

/// The latency timer of `--burst-ms`.
fn burst(ms: Option<f64>) -> Result<Option<Duration>> {
    match ms {
        None => Ok(None),
        Some(ms) if ms > 0.0 && ms <= 100.0 => Ok(Some(Duration::from_nanos(((ms * 1e6).round() as u64).max(1)))),
        Some(ms) => bail!("--burst-ms must be more than 0 and at most 100 (milliseconds), not {ms}"),
    }
}

/// `--period-ms` as a duration.
fn period(ms: Option<f64>) -> Result<Option<Duration>> {
    match ms {
        None => Ok(None),
        Some(ms) if (1.0..=1000.0).contains(&ms) => Ok(Some(Duration::from_secs_f64(ms * 1e-3))),
        Some(ms) => bail!("--period-ms must be 1 to 1000 (milliseconds), not {ms}"),
    }
}

/// `--arm`, calibrated by `--calibration` when it is given (its mapping only: what the monitor
/// judges goals by, and where an `--object-mm` meets the gripper's jaws).
fn arm_spec(args: &SimServosArgs) -> Result<Option<ArmSpec>> {
    let Some(name) = args.arm.as_deref() else { return Ok(None) };
    let arm = ArmSpec::load(name, None).with_context(|| format!("--arm {name}"))?;
    match args.calibration.as_deref() {
        None => Ok(Some(arm)),
        Some(file) => calibrated(arm, Some(file)).context("--calibration").map(Some),
    }
}

/// The goal limits of `arm`, whose servos must all be served.
fn limits(arm: Option<&ArmSpec>, ids: &[u8]) -> Result<Option<Vec<crate::sim::GoalLimit>>> {
    let Some(arm) = arm else { return Ok(None) };
    let limits = limits_of(arm)?;
    let missing: Vec<String> = limits.iter().filter(|l| !ids.contains(&l.id)).map(|l| l.id.to_string()).collect();
    if !missing.is_empty() {
        bail!("arm {} has servo id(s) {} that --ids does not serve", arm.name, missing.join(","));
    }
    Ok(Some(limits))
}

/// `--object-mm`: the gripper servo and the object between its jaws, checked.
/// (`--arm`'s servos, its gripper's among them, are all served: [`limits`] checks that.)
fn object(args: &SimServosArgs, servos: Option<&ServoSetup>) -> Result<Option<(u8, crate::sim::Jaw)>> {
    let Some(mm) = args.object_mm else { return Ok(None) };
    let name = args.arm.as_deref().unwrap_or_default();
    let gripper = servos
        .and_then(|s| s.gripper)
        .ok_or_else(|| anyhow::anyhow!("--object-mm: arm {name} has no gripper (its [gripper] table)"))?;
    Ok(Some((gripper.id, crate::sim::Jaw::for_object(&gripper, mm)?)))
}

/// Checks the arguments and builds the bus description.
pub fn config(args: &SimServosArgs) -> Result<SimConfig> {
    Ok(prepare(args)?.0)
}

/// Checks the arguments; builds the bus description and what the servos start with (the horns of
/// `--start`, the object of `--object-mm`; the recording is opened apart, once all is checked).
fn prepare(args: &SimServosArgs) -> Result<(SimConfig, ServeOptions)> {
    let spec = arm_spec(args)?;
    let arm = spec.as_ref().and_then(servos_of);
    let protocol = match (args.protocol, &arm) {
        (Some(p), _) => Protocol::from(p),
        (None, Some(servos)) => servos.model.protocol,
        (None, None) => bail!("--protocol is required (sts or dxl2), unless --arm names an arm with servos"),
    };
    let max_id = match protocol {
        Protocol::Dxl2 => dxl2::MAX_ID,
        Protocol::Feetech => feetech::MAX_ID,
    };
    let model = match (args.model, &arm) {
        (None, Some(servos)) if servos.model.protocol == protocol => servos.model,
        (model, _) => model_for(protocol, model)?,
    };
    let ids = match (&args.ids, &arm) {
        (Some(ids), _) => crate::support::numbers::ids(ids, u8::MAX, "--ids")?,
        (None, Some(servos)) => servos.ids.iter().copied().chain(servos.gripper.map(|g| g.id)).collect(),
        (None, None) => bail!("--ids is required (e.g. 1-6), unless --arm names an arm with servos"),
    };
    let all = ids.iter().chain(&args.faults.silent).chain(&args.duplicate);
    if let Some(id) = all.into_iter().find(|&&id| id > max_id) {
        bail!("id {id} is outside {}'s range 0-{max_id}", protocol.name());
    }
    if model.baud_index(args.baud).is_none() {
        let known: Vec<String> = model.bauds.iter().map(|(_, b)| b.to_string()).collect();
        bail!("{} has no baud index for {} (it knows {})", model.name, args.baud, known.join(", "));
    }
    let faults = args.faults.faults()?;
    let burst = burst(args.burst_ms)?;
    // Checked here with the rest; the server is told it once it runs.
    period(args.period_ms)?;
    let limits = limits(spec.as_ref(), &ids)?;
    let place = start_positions(args.start.as_deref(), &ids, model)?;
    let objects = object(args, arm.as_ref())?.into_iter().collect();
    let registers = registers(&args.register, &ids, model)?;
    let hardware_errors = hardware_errors(&args.hardware_error, &ids)?;
    // The arm's geometry, when it has some: its links stop where they run into something.
    let world = if args.contact { spec.as_ref().map(crate::sim::World::of).transpose()?.flatten() } else { None };
    let config = SimConfig {
        protocol,
        model,
        ids,
        baud: args.baud,
        faults,
        duplicates: args.duplicate.clone(),
        fixed_baud: args.fixed_baud,
        burst,
        limits,
        world,
        physics: crate::sim::physics::servo_kind(args.servos.as_deref(), args.payload_kg)?.physics(spec.as_ref())?,
    };
    let options = ServeOptions { place, objects, record: None, registers, hardware_errors, echo: args.echo };
    // What a servo refuses (`moving`), before anything is served.
    options.set_up(&mut config.build()).map_err(|e| anyhow::anyhow!("--register: {e}"))?;
    Ok((config, options))
}

/// Runs a `sim` command. Bad arguments are one `error:` line on `err` and exit code 2.
pub fn run(args: SimArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    match args.what {
        Some(SimCommand::Servos(servos)) => run_servos(servos, out, err),
        None if args.qemu => run_qemu(args.elf, &args.faults, args.json, out, err),
        None => {
            writeln!(err, "error: name what to simulate: `armctl sim servos ...` or `armctl sim --qemu`")?;
            Ok(2)
        }
    }
}

/// `armctl sim --qemu`, in an armctl built without the `board-tools` feature it needs.
#[cfg(not(feature = "board-tools"))]
fn run_qemu(_: Option<PathBuf>, _: &FaultArgs, _: bool, _: &mut dyn Write, _: &mut dyn Write) -> Result<i32> {
    Err(crate::runtime::board::without_tools("sim --qemu"))
}

/// `armctl sim --qemu`.
#[cfg(feature = "board-tools")]
fn run_qemu(
    elf: Option<PathBuf>,
    faults: &FaultArgs,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let faults = match faults.faults() {
        Ok(f) => f,
        Err(e) => {
            writeln!(err, "error: {e:#}")?;
            return Ok(2);
        }
    };
    if !qemu::available() {
        writeln!(err, "error: qemu-system-arm is not installed (Debian: apt-get install qemu-system-arm)")?;
        return Ok(1);
    }
    let elf = match elf {
        Some(elf) => elf,
        None => qemu::build(qemu::FIRMWARE_BIN)?,
    };
    let bus = PtyServer::spawn(crate::sim::so101_bus(faults)).context("cannot open a pseudo-terminal")?;
    let mut board = Qemu::start(&QemuConfig::new(elf, Some(bus.path().to_string())))?;
    board.wait_started(qemu::START_TIMEOUT)?;
    if json {
        crate::support::json_out::print_json(out, &serde_json::json!({ "port": board.link_path() }))?;
    } else {
        writeln!(out, "{}", board.link_path())?;
    }
    out.flush()?;
    writeln!(
        err,
        "firmware under QEMU: host link on {link} (e.g. `armctl --port {link} status`), servo bus on {}; \
         interrupt to stop",
        bus.path(),
        link = board.link_path()
    )?;
    err.flush()?;
    let interruptible = crate::support::interrupt::catch();
    let mut logged = 0;
    loop {
        let lines = board.log().lines_from(logged);
        logged += lines.len();
        for line in lines {
            writeln!(err, "firmware: {line}")?;
        }
        err.flush()?;
        if let Some(status) = board.exited()? {
            writeln!(err, "error: QEMU ended ({status})")?;
            return Ok(1);
        }
        if bus.is_finished() {
            bus.stop().context("the simulated bus stopped")?;
            return Ok(1);
        }
        if interruptible && crate::support::interrupt::requested() {
            // Dropping `board` and `bus` stops QEMU and removes its working directory.
            return Ok(crate::support::interrupt::EXIT_CODE);
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// `armctl sim servos`.
fn run_servos(args: SimServosArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    if !args.pty {
        writeln!(err, "error: --pty is required (the simulated bus is served on a pseudo-terminal)")?;
        return Ok(2);
    }
    let (config, mut options) = match prepare(&args) {
        Ok(c) => c,
        Err(e) => {
            // One line, even for an arm file whose parser's message spans several.
            let message = format!("{e:#}");
            writeln!(err, "error: {}", message.lines().map(str::trim).collect::<Vec<_>>().join(" "))?;
            return Ok(2);
        }
    };
    // Created before anything is served, so before any program can open the pty.
    if let Some(file) = &args.record {
        match Recorder::create(file, &config.ids) {
            Ok(recorder) => options.record = Some(recorder),
            Err(e) => {
                writeln!(err, "error: --record {}: {e}", file.display())?;
                return Ok(2);
            }
        }
    }
    let server = PtyServer::spawn_with(config.clone(), options).context("cannot open a pseudo-terminal")?;
    if let Some(period) = period(args.period_ms)? {
        server.set_period(period);
    }
    if args.json {
        crate::support::json_out::print_json(out, &serde_json::json!({ "pty": server.path() }))?;
    } else {
        writeln!(out, "{}", server.path())?;
    }
    out.flush()?;
    let ids: Vec<String> = config.ids.iter().map(u8::to_string).collect();
    let mut extras = String::new();
    if let Some(b) = config.burst {
        extras.push_str(&format!(", replies in bursts every {} ms", b.as_secs_f64() * 1e3));
    }
    if let Some(arm) = &args.arm {
        let period = server.monitor_handle().map_or(crate::sim::DEFAULT_PERIOD, |m| m.period());
        extras.push_str(&format!(
            ", goals checked against the limits of {arm} at a {} ms control period",
            period.as_secs_f64() * 1e3
        ));
    }
    if let Some(file) = &args.calibration {
        extras.push_str(&format!(" as calibrated by {}", file.display()));
    }
    if let Some(mm) = args.object_mm {
        extras.push_str(&format!(", a {mm} mm object between the gripper's jaws"));
    }
    if let Some(file) = &args.record {
        extras.push_str(&format!(", positions recorded to {} every 2 ms", file.display()));
    }
    if !args.register.is_empty() {
        extras.push_str(&format!(", registers set: {}", args.register.join(" ")));
    }
    if !args.hardware_error.is_empty() {
        extras.push_str(&format!(", hardware errors: {}", args.hardware_error.join(" ")));
    }
    if args.echo {
        extras.push_str(", the adapter echoes what it sends");
    }
    writeln!(
        err,
        "serving {} {} servo(s) (ids {}) on {} at {} baud{extras}, {}; interrupt to stop",
        config.ids.len(),
        config.model.name,
        ids.join(","),
        config.protocol.name(),
        config.baud,
        server.path()
    )?;
    err.flush()?;
    // Serve until interrupted (Ctrl-C or SIGTERM: the server then stops, which flushes the
    // recording; where the signal cannot be caught its default action ends the process, and the
    // recording keeps what its last flush wrote) or until the server fails; with a monitor, print
    // what it finds as it finds it; take the hand's commands from stdin.
    let interruptible = interrupt::catch();
    let poll = Duration::from_millis(if config.limits.is_some() { 50 } else { 200 });
    let mut printed = Printed::default();
    let mut hand = HandLines::from_stdin();
    while !server.is_finished() {
        if interruptible && interrupt::requested() {
            printed.print(&server, err)?;
            if let Some(report) = server.monitor() {
                writeln!(err, "safety monitor: {}", report.summary())?;
            }
            server.stop().context("the simulated bus stopped")?;
            return Ok(interrupt::EXIT_CODE);
        }
        hand.serve(&server, poll, args.json, out)?;
        printed.print(&server, err)?;
    }
    printed.print(&server, err)?;
    server.stop().context("the simulated bus stopped")?;
    Ok(1)
}

/// How often the hand's moves under way are looked at: the wait before a `done` line.
const HAND_POLL: Duration = Duration::from_millis(10);

/// The hand's commands from stdin, and the moves under way (ticket, the command as echoed).
struct HandLines {
    lines: Option<std::sync::mpsc::Receiver<String>>,
    pending: Vec<(u64, String)>,
}

impl HandLines {
    /// Reads stdin on a thread of its own (detached: it ends with the process or at end of input).
    fn from_stdin() -> Self {
        let (tx, rx) = std::sync::mpsc::channel();
        let spawned = std::thread::Builder::new().name("sim-hand".into()).spawn(move || {
            for line in std::io::stdin().lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self { lines: spawned.ok().map(|_| rx), pending: Vec::new() }
    }

    /// Waits up to `poll` for a command (less while moves are under way), carries it out, and
    /// prints the lines of the moves that ended (as JSON with `json`).
    fn serve(&mut self, server: &PtyServer, poll: Duration, json: bool, out: &mut dyn Write) -> Result<()> {
        let mut answer = |key: &str, text: String| -> Result<()> {
            if json {
                crate::support::json_out::print_json(out, &serde_json::json!({ key: text }))
            } else if key == "done" {
                Ok(writeln!(out, "done {text}")?)
            } else {
                Ok(writeln!(out, "error: {text}")?)
            }
        };
        let wait = if self.pending.is_empty() { poll } else { HAND_POLL };
        match self.lines.as_ref().map(|rx| rx.recv_timeout(wait)) {
            Some(Ok(line)) => match hand_command(&line) {
                Ok(None) => {}
                Ok(Some((id, from, to, seconds, echo))) => {
                    let ticket = server.hand(id, from, to, seconds);
                    self.pending.push((ticket, echo));
                }
                Err(e) => answer("error", e.to_string())?,
            },
            Some(Err(std::sync::mpsc::RecvTimeoutError::Timeout)) => {}
            // End of input: no more commands; the moves under way are still reported.
            Some(Err(std::sync::mpsc::RecvTimeoutError::Disconnected)) | None => {
                self.lines = None;
                std::thread::sleep(wait);
            }
        }
        for event in server.hand_events() {
            let Some(i) = self.pending.iter().position(|(t, _)| *t == event.ticket) else { continue };
            let (_, echo) = self.pending.remove(i);
            match event.result {
                Ok(()) => answer("done", echo)?,
                Err(reason) => answer("error", format!("{echo}: {reason}"))?,
            }
        }
        out.flush()?;
        Ok(())
    }
}

/// A hand's command: (id, from, to, seconds, the command as echoed in its reply line).
type HandCommand = (u8, i64, i64, f64, String);

/// Parses `move ID TICKS` or `sweep ID FROM TO SECONDS`; `None` for a blank line.
fn hand_command(line: &str) -> Result<Option<HandCommand>> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let id = |w: &str| w.parse::<u8>().map_err(|_| anyhow::anyhow!("{w:?} is not a servo id"));
    let ticks = |w: &str| w.parse::<i64>().map_err(|_| anyhow::anyhow!("{w:?} is not a whole number of ticks"));
    match words.as_slice() {
        [] => Ok(None),
        ["move", i, t] => {
            let (i, t) = (id(i)?, ticks(t)?);
            Ok(Some((i, t, t, 0.0, format!("move {i} {t}"))))
        }
        ["sweep", i, from, to, seconds] => {
            let (i, from, to) = (id(i)?, ticks(from)?, ticks(to)?);
            let s: f64 = seconds
                .parse()
                .ok()
                .filter(|s: &f64| s.is_finite() && *s >= 0.0)
                .ok_or_else(|| anyhow::anyhow!("{seconds:?} is not a duration in seconds"))?;
            Ok(Some((i, from, to, s, format!("sweep {i} {from} {to} {seconds}"))))
        }
        _ => bail!("{:?} is not `move ID TICKS` or `sweep ID FROM TO SECONDS`", line.trim()),
    }
}

/// The monitor's violations and goals within the margin printed so far.
#[derive(Default)]
struct Printed {
    lines: usize,
    said_more: bool,
    contacts: usize,
}

impl Printed {
    /// Prints the violations and the goals within the margin found since the last call, one line
    /// each, the first [`MAX_VIOLATIONS`] of each only; then one line saying that the rest of the
    /// violations are only counted (the summary counts the rest of the goals).
    fn print(&mut self, server: &PtyServer, err: &mut dyn Write) -> Result<()> {
        let Some(report) = server.monitor() else { return Ok(()) };
        for v in report.violations.iter().skip(self.lines) {
            writeln!(err, "violation: {v}")?;
        }
        self.lines = report.violations.len();
        let contacts = report.contacts.as_ref().map_or(&[][..], |c| &c.contacts[..]);
        for c in contacts.iter().skip(self.contacts) {
            writeln!(err, "within the margin: {c}")?;
        }
        self.contacts = contacts.len();
        if !self.said_more && report.violation_count > self.lines as u64 {
            writeln!(err, "more than {MAX_VIOLATIONS} violations: further ones are only counted")?;
            self.said_more = true;
        }
        err.flush()?;
        Ok(())
    }
}
