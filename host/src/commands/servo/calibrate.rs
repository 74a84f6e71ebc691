//! `armctl calibrate`: LeRobot's calibration procedure on an arm's servos (`so_follower.py`
//! `calibrate`, with `motors_bus.py` `set_half_turn_homings` and `record_ranges_of_motion`), its
//! result written to the servos, to an arm file and, if asked, to a LeRobot calibration file.
//!
//! 1. Torque off on every servo of the arm, the gripper's too (on Feetech, operating mode 0).
//! 2. "Move the arm to the middle of its range, then press Enter": each servo's homing offset is
//!    zeroed and its limits opened to the whole turn, its present position read, and the half-turn
//!    offset ([`record::half_turn_offset`]) written, so that it reads 2047 there.
//! 3. "Move every joint through its whole range, then press Enter": a sync read of the present
//!    positions every [`SAMPLE_PERIOD`] records each joint's lowest and highest (the full-turn
//!    wrist roll excepted, which gets the whole turn, as LeRobot does); on a terminal the
//!    positions are shown live.
//! 4. Each servo gets its range as its position limits; the arm file gets the calibration in
//!    `[servos]`, the gripper's range in `[gripper]`, and joint limits tightened to the measured
//!    range ([`record::joint_limits`]). An `--out` that exists is a person's arm file: the
//!    calibration is written into it, changing nothing else ([`toml_update`]), and anything that
//!    is not an arm file of this arm is refused before the servos are touched.
//!
//! Each step waits for a line on standard input, so a script (or a test) answers the steps from a
//! pipe. Input that ends before a step is an error, and nothing further is done. Every value is
//! checked before it is written: a homing offset out of the servo's reach (on Feetech LeRobot's
//! "Magnitude 2114 exceeds 2047") restores the servos' previous offsets and limits; a joint that was
//! not moved is refused before any limit or file is written. The calibration registers are
//! EEPROM: they are written with torque off, on Feetech with the EEPROM unlocked around each
//! servo's writes ([`super::commands::eeprom_write`]).

use std::io::{BufRead, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use firmware::bus::master::{BusConfig, Clock};
use firmware::bus::table::{sts3215, xseries, Item, Model};
use firmware::bus::{Id, Protocol};

use super::commands::eeprom_write;
use crate::arm::calibration::{homing_offset_item, lerobot, record, MotorCalibration};
use crate::arm::servos::{servos_of, ServoSetup};
use crate::arm::{toml_update, ArmSpec};
use crate::runtime::servo_session::{NoAnswer, Port, Session};

/// The baud rate when `--baud` is not given: `--bus`'s, the STS3215's factory rate.
const DEFAULT_BAUD: u32 = 1_000_000;

/// How often the positions are read while the joints are moved (LeRobot's `time.sleep(0.02)`).
pub const SAMPLE_PERIOD: Duration = Duration::from_millis(20);

/// Consecutive samples in step 2 that may go unanswered (with their retries, about two seconds)
/// before the bus is taken for lost.
const MAX_SILENT_SAMPLES: u32 = 40;

/// Dynamixel X's position control mode (operating mode 3), in which it ignores homing offsets
/// beyond [`record::DXL_POSITION_MODE_MAX_OFFSET`].
const DXL_POSITION_MODE: i64 = 3;

/// The margin added to each reply timeout when none is asked for, ms.
pub const DEFAULT_TIMEOUT_MS: u32 = 10;

/// What `armctl calibrate` is asked for (the names of its errors are the command line's options).
#[derive(Clone, Debug)]
pub struct CalibrateRequest {
    /// The servos' USB adapter's serial port (/dev/ttyUSB0, /dev/ttyACM0, COM3).
    pub bus: String,
    /// The servos' protocol.
    pub protocol: Protocol,
    /// Baud rate (`None`: 1000000, the STS3215's factory rate).
    pub baud: Option<u32>,
    /// The arm: a preset (so101, open-manipulator-x) or an arm file with a [servos] table.
    pub arm: String,
    /// The arm file to write (.toml): new, or an arm file of the same arm whose calibration keys
    /// alone change (see the module doc).
    pub out: PathBuf,
    /// Also write the calibration as LeRobot's calibration file (JSON).
    pub lerobot_json: Option<PathBuf>,
    /// Margin added to each reply timeout, ms ([`DEFAULT_TIMEOUT_MS`] by default).
    pub timeout_ms: u32,
}

/// One servo to calibrate: a joint's, or the gripper's.
#[derive(Clone, Debug)]
struct Part {
    /// LeRobot's motor name: the joint's name, or `gripper`.
    name: String,
    /// `joint 2 (shoulder_lift, servo 2)`, `the gripper (servo 6)`.
    label: String,
    id: Id,
    /// Taken as the whole turn instead of being swept.
    full_turn: bool,
}

/// What is calibrated, and where the result goes; checked before the port is opened.
struct Plan {
    arm: ArmSpec,
    servos: ServoSetup,
    parts: Vec<Part>,
    out: PathBuf,
    /// `out` exists, an arm file of this arm: the calibration is written into it
    /// ([`toml_update`]) instead of a new file.
    update: bool,
    lerobot_json: Option<PathBuf>,
}

impl Plan {
    fn new(args: &CalibrateRequest) -> Result<Self> {
        let arm = ArmSpec::load(&args.arm, None)?;
        let servos = servos_of(&arm).ok_or_else(|| {
            anyhow!(
                "arm {} has no servos to calibrate: use a preset with servos (so101, open-manipulator-x) or an arm \
                 file with a [servos] table",
                arm.name
            )
        })?;
        let protocol = args.protocol;
        if servos.model.protocol != protocol {
            bail!(
                "arm {}'s servos are {} ({}); --protocol {} does not speak to them",
                arm.name,
                servos.model.name,
                servos.model.protocol.name(),
                protocol.name()
            );
        }
        if args.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() != Some("toml") {
            bail!("--out {} must end in .toml: it is an arm file, loaded again with --arm", args.out.display());
        }
        if args.lerobot_json.as_ref() == Some(&args.out) {
            bail!("--out and --lerobot-json are the same file");
        }
        for path in std::iter::once(&args.out).chain(&args.lerobot_json) {
            let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
            if !dir.is_dir() {
                bail!("cannot write {}: there is no directory {}", path.display(), dir.display());
            }
        }
        let update = match std::fs::read_to_string(&args.out) {
            Ok(text) => {
                // A preset's servos are not in its ArmSpec: compared with them.
                let with_servos = ArmSpec { servos: Some(servos.clone()), ..arm.clone() };
                toml_update::check(&text, &with_servos).map_err(|e| refused(&args.out, &e))?;
                true
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => bail!("--out {}: cannot read it ({e}); nothing was written", args.out.display()),
        };
        let mut parts: Vec<Part> = arm
            .joints
            .iter()
            .zip(&servos.ids)
            .enumerate()
            .map(|(j, (joint, &id))| Part {
                name: joint.name.clone(),
                label: format!("joint {} ({}, servo {id})", j + 1, joint.name),
                id,
                full_turn: record::full_turn(joint),
            })
            .collect();
        if let Some(g) = servos.gripper {
            parts.push(Part {
                name: "gripper".into(),
                label: format!("the gripper (servo {})", g.id),
                id: g.id,
                full_turn: false,
            });
        }
        Ok(Self { arm, servos, parts, out: args.out.clone(), update, lerobot_json: args.lerobot_json.clone() })
    }

    fn model(&self) -> &'static Model {
        self.servos.model
    }

    fn ids(&self) -> Vec<Id> {
        self.parts.iter().map(|p| p.id).collect()
    }
}

/// Why `--out` cannot be updated, in one line.
fn refused(out: &Path, why: &anyhow::Error) -> anyhow::Error {
    anyhow!(
        "--out {} exists and is not written over: {why:#}; nothing was written (name a new file to write a new \
         arm file)",
        out.display()
    )
}

/// The person's answers: one line of input per step, read on a thread of its own so that the
/// recording can go on until the line comes.
pub struct Steps {
    lines: Receiver<()>,
}

impl Steps {
    /// Lines of `input`, read on a detached thread (it ends at the end of input, or with the
    /// process).
    pub fn from(input: impl BufRead + Send + 'static) -> Result<Self> {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("calibrate-input".into())
            .spawn(move || {
                for line in input.lines() {
                    if line.is_err() || tx.send(()).is_err() {
                        break;
                    }
                }
            })
            .context("cannot start the thread that reads standard input")?;
        Ok(Self { lines: rx })
    }

    /// Waits for the line that ends step `step`; `Err(what)` at the end of input.
    fn wait(&self, step: &str, state: &str) -> Result<()> {
        self.lines.recv().map_err(|_| ended(step, state))
    }

    /// Whether the line that ends step `step` has come (without waiting).
    fn pressed(&self, step: &str, state: &str) -> Result<bool> {
        match self.lines.try_recv() {
            Ok(()) => Ok(true),
            Err(TryRecvError::Empty) => Ok(false),
            Err(TryRecvError::Disconnected) => Err(ended(step, state)),
        }
    }
}

fn ended(step: &str, state: &str) -> anyhow::Error {
    anyhow!("standard input ended {step} (a line, Enter, answers each step): {state}; run armctl calibrate again")
}

/// Runs `armctl calibrate`, the steps answered on standard input.
pub fn run(args: CalibrateRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let plan = Plan::new(&args)?;
    if plan.servos.calibration.is_some() && !plan.update {
        writeln!(
            err,
            "note: {} holds a calibration already, and its joint limits were tightened by it: calibrating from it \
             can only tighten them further (calibrate from the preset or the URDF to start afresh)",
            args.arm
        )?;
    }
    let base = BusConfig::new(args.protocol, args.baud.unwrap_or(DEFAULT_BAUD));
    let config = BusConfig {
        margin_us: args.timeout_ms * 1000,
        idle_gap_us: (args.timeout_ms * 1000).max(base.idle_gap_us),
        ..base
    };
    let mut session = Session::open(&args.bus, config)?;
    let steps = Steps::from(std::io::BufReader::new(std::io::stdin()))?;
    let live = std::io::stdout().is_terminal();
    calibrate(&mut session, &plan, &steps, live, out, err)
}

/// One register of servo `id`.
fn read<P: Port, C: Clock>(session: &mut Session<P, C>, model: &Model, id: Id, item: Item) -> Result<i64> {
    session.read_item(id, model, item).with_context(|| format!("servo {id}: reading {}", item.name))
}

/// Writes the EEPROM `values` of servo `id` that differ from what it holds, with torque off (and
/// the Feetech lock opened around them).
fn write_eeprom<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    model: &Model,
    id: Id,
    values: &[(Item, i64)],
) -> Result<()> {
    let mut todo = Vec::new();
    for &(item, value) in values {
        if read(session, model, id, item)? != value {
            todo.push((item, value));
        }
    }
    if todo.is_empty() {
        return Ok(());
    }
    let servo = session.identify(id)?;
    eeprom_write(session, &servo, model, true, |s| {
        todo.iter().try_for_each(|&(item, value)| s.write_item(id, model, item, value))
    })
    .with_context(|| format!("servo {id}: writing its calibration registers"))
}

/// The procedure (see the module doc) on an open bus.
fn calibrate<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    plan: &Plan,
    steps: &Steps,
    live: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let model = plan.model();
    let items = model.items;
    let ids = plan.ids();
    let top = i64::from(model.ticks_per_revolution) - 1;
    let list = |ids: &[Id]| ids.iter().map(u8::to_string).collect::<Vec<_>>().join(", ");

    // Every servo is there and of the arm's model before anything is written.
    for part in &plan.parts {
        let servo = session.identify(part.id).with_context(|| format!("{} on {}", part.label, session.path()))?;
        if servo.model.map(|m| m.number) != Some(model.number) {
            bail!("{} is model {}, but the arm's servos are {}", part.label, servo.model_text(), model.name);
        }
    }

    // Step 0: torque off, position mode.
    for &id in &ids {
        session.write_item(id, model, items.torque_enable, 0).with_context(|| format!("servo {id}: torque off"))?;
        if model.protocol == Protocol::Feetech {
            write_eeprom(session, model, id, &[(sts3215::OPERATING_MODE, 0)])?;
        }
    }
    writeln!(out, "torque off on servos {}: the arm is limp, hold it", list(&ids))?;

    // Step 1: the homing offsets.
    writeln!(
        out,
        "step 1 of 2: move the arm to the middle of its range of motion (the gripper half open), then press Enter"
    )?;
    out.flush()?;
    steps.wait("before step 1", &format!("nothing was calibrated; torque is off on servos {}", list(&ids)))?;
    let homing = homing_offset_item(model);
    let mut previous = Vec::with_capacity(ids.len());
    for &id in &ids {
        let held = [homing, items.min_position, items.max_position].map(|item| read(session, model, id, item));
        let [offset, lo, hi] = held;
        previous.push([(homing, offset?), (items.min_position, lo?), (items.max_position, hi?)]);
    }
    for &id in &ids {
        write_eeprom(session, model, id, &[(homing, 0), (items.min_position, 0), (items.max_position, top)])?;
    }
    let present = session.sync_read_item(&ids, model, items.present_position)?;
    let mut offsets = Vec::with_capacity(ids.len());
    let mut refusal = None;
    for (part, &p) in plan.parts.iter().zip(&present) {
        let offset = record::half_turn_offset(model.protocol, p, model.ticks_per_revolution);
        let (reach, why) = match model.protocol {
            Protocol::Feetech => (record::MAX_HOMING_OFFSET, "the STS3215's Homing_Offset holds 11 bits"),
            Protocol::Dxl2 if read(session, model, part.id, xseries::OPERATING_MODE)? == DXL_POSITION_MODE => {
                (record::DXL_POSITION_MODE_MAX_OFFSET, "a Dynamixel X ignores a larger one in position control mode")
            }
            Protocol::Dxl2 => (record::MAX_HOMING_OFFSET, "half a turn is the most a homing needs"),
        };
        if offset.abs() > reach && refusal.is_none() {
            refusal = Some(format!(
                "{}: homing offset {offset}: magnitude exceeds {reach} ({why}): its horn reads {p} with no offset, \
                 {} ticks from the servo's middle; remount the horn so that the joint's middle is near the servo's \
                 middle (2048), then calibrate again; the servos' offsets and limits are as they were",
                part.label,
                (p - top / 2).abs()
            ));
        }
        offsets.push(offset);
    }
    if let Some(refusal) = refusal {
        for (&id, values) in ids.iter().zip(&previous) {
            write_eeprom(session, model, id, values)?;
        }
        bail!(refusal);
    }
    for (&id, &offset) in ids.iter().zip(&offsets) {
        write_eeprom(session, model, id, &[(homing, offset)])?;
    }
    let written: Vec<String> = ids.iter().zip(&offsets).map(|(id, o)| format!("servo {id} {o}")).collect();
    writeln!(out, "homing offsets written: {}", written.join(", "))?;

    // Step 2: the ranges.
    let swept: Vec<&Part> = plan.parts.iter().filter(|p| !p.full_turn).collect();
    let turning: Vec<&str> = plan.parts.iter().filter(|p| p.full_turn).map(|p| p.name.as_str()).collect();
    let except = if turning.is_empty() {
        String::new()
    } else {
        format!(" except {} (full-turn, taken as 0..{top})", turning.join(", "))
    };
    writeln!(
        out,
        "step 2 of 2: move every joint{except} through its whole range, stop to stop, the gripper from closed to open, \
         then press Enter"
    )?;
    out.flush()?;
    let swept_ids: Vec<Id> = swept.iter().map(|p| p.id).collect();
    let state = "the homing offsets are written, the position limits open (no range was recorded), no file was written";
    let (mins, maxes) = record_ranges(session, model, &swept, &swept_ids, steps, state, live, out)?;

    // The calibration, checked whole before any limit or file is written.
    let mut calibrations = Vec::with_capacity(plan.parts.len());
    for (part, &offset) in plan.parts.iter().zip(&offsets) {
        let (range_min, range_max) = match swept_ids.iter().position(|&id| id == part.id) {
            Some(k) => {
                record::check_sweep(&part.label, mins[k], maxes[k], model.ticks_per_revolution).map_err(|e| {
                    anyhow!(
                        "{e}; the homing offsets are written, the position limits open, no file written: calibrate \
                         again and move it from stop to stop"
                    )
                })?
            }
            None => (0, top as i32),
        };
        let drive_mode = match model.protocol {
            // LeRobot's Feetech bus reports drive_mode 0 whatever the servo.
            Protocol::Feetech => 0,
            // LeRobot reads Drive_Mode whole into drive_mode, and compares it when connecting.
            Protocol::Dxl2 => match read(session, model, part.id, xseries::DRIVE_MODE)? {
                m @ (0 | 1) => m as u8,
                m => bail!(
                    "{}: its Drive_Mode register is {m}; LeRobot reads it whole as drive_mode, which is 0 or 1: set it \
                     to 0 (armctl servo write --addr 10 --value 0) and calibrate again",
                    part.label
                ),
            },
        };
        let homing_offset = i32::try_from(offset).map_err(|_| anyhow!("{}: offset {offset}", part.label))?;
        calibrations.push(MotorCalibration { id: part.id, drive_mode, homing_offset, range_min, range_max });
    }
    let joints = &calibrations[..plan.arm.joints.len()];
    let gripper = calibrations.get(plan.arm.joints.len());
    let arm = record::calibrated_arm(&plan.arm, &plan.servos, joints, gripper)?;
    let file = record::lerobot_file(&plan.arm, joints, gripper);
    file.check()?;
    let (text, arm) = if plan.update {
        // Read again: the person may have edited it during the calibration.
        let text = std::fs::read_to_string(&plan.out).with_context(|| format!("cannot read {}", plan.out.display()))?;
        toml_update::with_calibration(&text, &arm).map_err(|e| refused(&plan.out, &e))?
    } else {
        let header = [
            format!("{}, calibrated by armctl calibrate (LeRobot's procedure) on {}.", plan.arm.name, session.path()),
            "The servos hold these homing offsets and position limits; the joint limits are the arm's, tightened to"
                .to_string(),
            format!("the range each joint was moved through less {} degrees a side.", record::STOP_MARGIN_DEG),
        ];
        (crate::arm::toml_writer::to_text(&arm, &header), arm)
    };

    for m in &calibrations {
        write_eeprom(
            session,
            model,
            m.id,
            &[(items.min_position, i64::from(m.range_min)), (items.max_position, i64::from(m.range_max))],
        )?;
    }
    if let Some(path) = &plan.lerobot_json {
        std::fs::write(path, lerobot::to_text(&file)).with_context(|| format!("cannot write {}", path.display()))?;
    }
    std::fs::write(&plan.out, text).with_context(|| format!("cannot write {}", plan.out.display()))?;

    for (k, (part, m)) in plan.parts.iter().zip(&calibrations).enumerate() {
        let what = match (plan.arm.joints.get(k), arm.joints.get(k)) {
            (Some(before), Some(after)) => format!(
                "joint limits {:.1} to {:.1} degrees (the arm's {:.1} to {:.1})",
                after.lower.to_degrees(),
                after.upper.to_degrees(),
                before.lower.to_degrees(),
                before.upper.to_degrees()
            ),
            _ => format!("closed at {}, open at {}", m.range_min, m.range_max),
        };
        writeln!(
            out,
            "{}: homing offset {}, range {}..{}; {what}",
            part.label, m.homing_offset, m.range_min, m.range_max
        )?;
    }
    let written_json = plan.lerobot_json.as_ref().map(|p| format!(" and {}", p.display())).unwrap_or_default();
    let how = if plan.update { " (its servos' calibration and gripper range; the rest as it was)" } else { "" };
    writeln!(
        out,
        "wrote {}{how}{written_json}; drive the arm with `armctl --bus {} --protocol {} --arm {} status`",
        plan.out.display(),
        session.path(),
        match model.protocol {
            Protocol::Feetech => "sts",
            Protocol::Dxl2 => "dxl2",
        },
        plan.out.display()
    )?;
    super::commands::finish(session, err)
}

/// Step 2's recording: a sync read of `ids` every [`SAMPLE_PERIOD`] until the step's line comes;
/// each servo's lowest and highest present position. On a terminal (`live`) the positions are
/// shown as they come, overwritten in place; otherwise nothing is printed per sample.
#[allow(clippy::too_many_arguments)]
fn record_ranges<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    model: &Model,
    parts: &[&Part],
    ids: &[Id],
    steps: &Steps,
    state: &str,
    live: bool,
    out: &mut dyn Write,
) -> Result<(Vec<i64>, Vec<i64>)> {
    if ids.is_empty() {
        steps.wait("during step 2", state)?;
        return Ok((Vec::new(), Vec::new()));
    }
    let item = model.items.present_position;
    let (mut mins, mut maxes) = (vec![i64::MAX; ids.len()], vec![i64::MIN; ids.len()]);
    let (mut shown, mut silent) = (false, 0);
    loop {
        let now = match session.sync_read_item(ids, model, item) {
            Ok(now) => now,
            // A reply late on a busy PC loses one sample of a person's slow sweep; a bus silent
            // for seconds is a fault.
            Err(e) if e.downcast_ref::<NoAnswer>().is_some() && silent + 1 < MAX_SILENT_SAMPLES => {
                silent += 1;
                std::thread::sleep(SAMPLE_PERIOD);
                continue;
            }
            Err(e) if e.downcast_ref::<NoAnswer>().is_some() => {
                bail!("{e}: {MAX_SILENT_SAMPLES} samples in a row unanswered during step 2: {state}")
            }
            Err(e) => bail!("{e} during step 2: {state}"),
        };
        silent = 0;
        for (k, &p) in now.iter().enumerate() {
            mins[k] = mins[k].min(p);
            maxes[k] = maxes[k].max(p);
        }
        if live {
            if shown {
                write!(out, "\x1b[{}A", parts.len() + 1)?;
            }
            writeln!(out, "{:<16} {:>6} {:>6} {:>6}", "joint", "min", "now", "max")?;
            for (k, part) in parts.iter().enumerate() {
                writeln!(out, "{:<16} {:>6} {:>6} {:>6}", part.name, mins[k], now[k], maxes[k])?;
            }
            out.flush()?;
            shown = true;
        }
        // Enter ends the recording after a sample (a silent sample does not get here).
        if steps.pressed("during step 2", state)? {
            return Ok((mins, maxes));
        }
        std::thread::sleep(SAMPLE_PERIOD);
    }
}

#[cfg(test)]
mod tests {
    use std::convert::Infallible;

    use embedded_io::{ErrorType, Read, ReadReady, Write as IoWrite};
    use firmware::bus::table::sts3215::STS3215;

    use super::*;
    use crate::sim::{connect, SimBus, SimPort, VirtualClock};

    /// A line whose first `deaf` transmissions never reach the servos: a bus that misses replies
    /// for a while (a busy PC, a loose cable).
    struct DeafFor {
        port: SimPort,
        deaf: usize,
    }

    impl ErrorType for DeafFor {
        type Error = Infallible;
    }

    impl IoWrite for DeafFor {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
            if self.deaf > 0 {
                return Ok(buf.len());
            }
            self.port.write(buf)
        }

        fn flush(&mut self) -> Result<(), Infallible> {
            if self.deaf > 0 {
                self.deaf -= 1;
                return Ok(());
            }
            self.port.flush()
        }
    }

    impl Read for DeafFor {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
            self.port.read(buf)
        }
    }

    impl ReadReady for DeafFor {
        fn read_ready(&mut self) -> Result<bool, Infallible> {
            self.port.read_ready()
        }
    }

    /// Step 2's recording on servos 1 and 2 (at 1000 and 3000) behind a line deaf for its first
    /// `deaf` transmissions, Enter already pressed.
    fn record(deaf: usize) -> Result<(Vec<i64>, Vec<i64>)> {
        let (bus, port, clock): (_, SimPort, VirtualClock) =
            connect(SimBus::new(Protocol::Feetech, &STS3215, &[1, 2], DEFAULT_BAUD));
        for (id, ticks) in [(1, 1000), (2, 3000)] {
            bus.borrow_mut().servo_mut(id).unwrap().set_position(ticks, 0);
        }
        let config = BusConfig::new(Protocol::Feetech, DEFAULT_BAUD);
        let mut session = Session::new("sim", DeafFor { port, deaf }, clock, config);
        let steps = Steps::from(std::io::Cursor::new("\n"))?;
        record_ranges(&mut session, &STS3215, &[], &[1, 2], &steps, "the state", false, &mut Vec::new())
    }

    /// A few samples unanswered (here ten, three attempts each) are samples lost, not the
    /// calibration: the recording goes on and ends at the next answered sample.
    #[test]
    fn a_few_unanswered_samples_do_not_end_the_recording() {
        assert_eq!(record(30).unwrap(), (vec![1000, 3000], vec![1000, 3000]));
    }

    /// A bus silent for [`MAX_SILENT_SAMPLES`] samples in a row is lost: one line naming the
    /// servos, the count and what state the servos were left in.
    #[test]
    fn a_bus_silent_for_seconds_ends_the_recording_in_one_line() {
        let e = record(usize::MAX).unwrap_err().to_string();
        assert_eq!(
            e,
            "servo 1, 2 did not answer a sync read of present_position (3 attempts): 40 samples in a row unanswered \
             during step 2: the state"
        );
    }
}
