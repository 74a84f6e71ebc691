//! The PC as the board: the firmware application ([`firmware::app`]) runs in this process, its
//! servo bus on the user's USB serial adapter (the `serialport` crate), its clock the PC's
//! monotonic clock. The host link reaches it through an in-process channel
//! ([`crate::link::channel`]), or through a pseudo-terminal when `armctl serve` keeps it running
//! for other programs. The controller, the link and the limits are the firmware's own: this module
//! adds only the clock, the bus transport and the connection steps a real arm needs.
//!
//! Connecting, in order:
//! 1. open the port (one clear line when it is missing or held by another program);
//! 2. warn when the adapter's latency timer is above 1 ms ([`latency`]);
//! 3. find every servo of the arm (none answering means the wrong protocol or baud rate), and with
//!    a LeRobot calibration, check that the servos hold it;
//! 4. set the servos up ([`setup`]);
//! 5. time the bus and choose the control period and reply timeouts ([`timing`]);
//! 6. start the control loop on its own thread ([`runner`]).
//!
//! When the link's host end is dropped (the command has ended), the loop finishes its tick and
//! ends without another word to the servos: they hold their last goal, torque as the command left it.

pub mod latency;
pub mod runner;
pub mod setup;
pub mod timing;

use std::io::Write;
use std::path::Path;
use std::sync::Arc;
use std::thread::JoinHandle;

use anyhow::{anyhow, bail, Context, Result};
use firmware::app::{Board, Firmware};
use firmware::bus::master::{BusConfig, Clock, Master, NoDirectionPin};
use firmware::bus::table::{Item, Model};
use firmware::bus::Protocol;
use firmware::controller::Config;

use crate::arm::calibration::registers;
use crate::arm::servos::{servos_of, ServoSetup};
use crate::arm::ArmSpec;
use crate::link::channel::{self, ChannelLink, CoreEnd};
use crate::link::serial::{SerialTransport, StdClock};
use crate::runtime::sil::board::{for_joints, SimBoard, WithFirmware, QUEUE};
use runner::PcCore;
pub use runner::{LoopSummary, Shared};

/// The master's margin while the servos are looked for and the bus is timed: long enough for any
/// adapter's latency timer (FTDI's can be set up to 255 ms; the default is 16).
pub(crate) const SEARCH_MARGIN_US: u32 = 100_000;

/// What to connect to.
#[derive(Clone, Debug)]
pub struct PcOptions {
    /// The adapter's serial port (`/dev/ttyUSB0`, `/dev/serial/by-id/...`, `COM3`).
    pub path: String,
    /// The servos' protocol.
    pub protocol: Protocol,
    /// The bus's baud rate.
    pub baud: u32,
    /// The arm, with its servos.
    pub arm: ArmSpec,
    /// The LeRobot calibration file the servos' calibration came from, for messages.
    pub calibration_file: Option<String>,
    /// The safety monitor of simulated servos, told the control period once it is chosen (it
    /// allows each goal write the velocity limit times the period per control tick).
    pub monitor: Option<crate::sim::MonitorHandle>,
    /// Gravity compensation given to the firmware once connected (`None`: none).
    pub gravity: Option<crate::runtime::gravity::Compensation>,
}

impl PcOptions {
    /// Simulated servos of `arm`, served on a pty of their own in real time with a USB adapter's
    /// `latency` and the simulator's safety monitor, and the options that run the core on this PC
    /// against them, as `armctl serve --sim` does. For the commands whose loop runs in real time
    /// (teleop, view), which the virtual clock of the drive commands' `--sim` would not pace.
    pub fn simulated(
        arm: ArmSpec,
        latency: Option<std::time::Duration>,
        kind: crate::sim::physics::ServoKind,
        contact: Option<crate::arm::collision::CollisionSpec>,
    ) -> Result<(Self, crate::sim::PtyServer)> {
        let protocol =
            servos_of(&arm).map(|s| s.model.protocol).ok_or_else(|| anyhow!("arm {} has no servos", arm.name))?;
        let baud = arm.bus_baud().unwrap_or(1_000_000);
        let servos = crate::sim::serve_arm(&arm, baud, latency, kind, contact)?;
        let options = PcOptions {
            path: servos.path().to_string(),
            protocol,
            baud,
            arm,
            calibration_file: None,
            monitor: servos.monitor_handle(),
            // Asked for by the caller, whose options say whether the servos' sag is compensated.
            gravity: None,
        };
        Ok((options, servos))
    }
}

/// What connecting found and chose.
#[derive(Clone, Debug)]
pub struct Connected {
    /// The servos.
    pub servos: ServoSetup,
    /// The bus timing measured.
    pub measured: timing::Measured,
    /// The control period and bus configuration chosen.
    pub choice: timing::Choice,
}

impl Connected {
    /// One line saying what was measured and chosen.
    pub fn describe(&self, path: &str) -> String {
        let c = &self.choice;
        format!(
            "bus: {} servos on {path} ({} at {} baud): sync read median {:.2} ms, max {:.2} ms ({} reads); \
             control period {} ms ({} Hz), reply margin {:.1} ms",
            self.servos.bus_ids().len(),
            c.bus.protocol.name(),
            c.bus.baud,
            self.measured.median_us() as f64 * 1e-3,
            self.measured.max_us() as f64 * 1e-3,
            self.measured.reads_us.len(),
            c.period_us / 1000,
            1_000_000 / c.period_us,
            f64::from(c.bus.margin_us) * 1e-3
        )
    }
}

/// A firmware core running on this PC.
#[derive(Debug)]
pub struct Pc {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    link: Option<ChannelLink>,
    connected: Connected,
    end_with_host: bool,
}

impl Pc {
    /// Connects to the arm's servos (the steps in the module doc), printing warnings and what was
    /// written or chosen on `err`, and starts the core. With `end_with_host` the core ends once
    /// the link taken with [`Pc::take_link`] is dropped; otherwise it runs until [`Pc::shutdown`].
    pub fn start(options: &PcOptions, end_with_host: bool, err: &mut dyn Write) -> Result<Pc> {
        let servos = servos_of(&options.arm).ok_or_else(|| {
            anyhow!(
                "arm {} has no servo mapping: add a [servos] table to its arm file (the presets so101 and \
                 open-manipulator-x have one)",
                options.arm.name
            )
        })?;
        if servos.model.protocol != options.protocol {
            bail!(
                "arm {}'s servos are {} ({}); --protocol {} does not speak to them",
                options.arm.name,
                servos.model.name,
                servos.model.protocol.name(),
                options.protocol.name()
            );
        }
        if let Some(warning) = latency::warning(Path::new("/sys"), Path::new(&options.path)) {
            writeln!(err, "warning: {warning}")?;
        }
        let port = SerialTransport::open(&options.path, options.baud)?;
        let clock = StdClock::new();
        let factory = BusConfig::new(options.protocol, options.baud);
        let searching = BusConfig { margin_us: SEARCH_MARGIN_US, idle_gap_us: SEARCH_MARGIN_US, ..factory };
        let mut master = Master::new(port, NoDirectionPin, clock, searching);
        find_servos(&mut master, &options.path, &servos)?;
        check_calibration(&mut master, options, &servos)?;
        let report = setup::set_up(&mut master, servos.model, &servos.ids, servos.gripper.map(|g| g.id))?;
        for line in &report.lines {
            writeln!(err, "set-up: {line}")?;
        }
        for note in &report.notes {
            writeln!(err, "note: {note}")?;
        }
        let return_delay_us = report.return_delay_us();
        master.set_config(BusConfig { return_delay_us, ..searching });
        // The gripper rides in the joints' sync read and write: the cycle is measured with it.
        let measured = timing::measure(&mut master, servos.model, &servos.bus_ids())?;
        let bus = BusConfig { return_delay_us, ..factory };
        let choice = timing::choose(&measured, bus, servos.model, servos.bus_ids().len())?;
        master.set_config(choice.bus);
        if let Some(monitor) = &options.monitor {
            monitor.set_period(std::time::Duration::from_micros(u64::from(choice.period_us)));
        }
        let connected = Connected { servos, measured, choice };
        writeln!(err, "{}", connected.describe(&options.path))?;
        let board = Board {
            bus: choice.bus,
            model: connected.servos.model,
            control: Config { period_us: choice.period_us, ..Config::default() },
            // The PC's port stays at the baud it was opened with; the host sends the arm it
            // connected with, so its bus never changes.
            max_bus_baud: u32::MAX,
        };
        let core = core_for(options.arm.dof(), board, master)?;
        let (link, end) = channel::pair(crate::link::READ_TIMEOUT);
        let shared = Arc::new(Shared::default());
        let thread = spawn(core, end, clock, shared.clone(), end_with_host)?;
        Ok(Pc { shared, thread: Some(thread), link: Some(link), connected, end_with_host })
    }

    /// The host's end of the link (once).
    pub fn take_link(&mut self) -> Option<ChannelLink> {
        self.link.take()
    }

    /// The state shared with the control loop: its counts, stop and torque-off requests.
    pub fn shared(&self) -> Arc<Shared> {
        self.shared.clone()
    }

    /// What connecting found and chose.
    pub fn connected(&self) -> &Connected {
        &self.connected
    }

    /// Whether the control loop has ended.
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Ends the control loop after its current tick and waits for it.
    pub fn shutdown(&mut self) -> Result<()> {
        self.shared.quit();
        match self.thread.take().map(JoinHandle::join) {
            Some(Err(_)) => bail!("the firmware core's thread panicked"),
            _ => Ok(()),
        }
    }
}

/// How long a core whose host has gone may take to write what the host's last command asked for
/// ([`runner`] gives it a few ticks) before it is ended anyway.
const FINISH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

impl Drop for Pc {
    fn drop(&mut self) {
        if self.end_with_host && self.link.is_none() {
            let started = std::time::Instant::now();
            while !self.is_finished() && started.elapsed() < FINISH_TIMEOUT {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        let _ = self.shutdown();
    }
}

fn spawn(
    core: PcCore,
    end: CoreEnd,
    clock: StdClock,
    shared: Arc<Shared>,
    end_with_host: bool,
) -> Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("firmware-core".into())
        .spawn(move || runner::run(core, end, clock, shared, end_with_host))
        .context("cannot start the firmware core's thread")
}

/// Pings every servo of the arm and checks its model; nothing is written.
fn find_servos(
    master: &mut Master<SerialTransport, NoDirectionPin, StdClock>,
    path: &str,
    servos: &ServoSetup,
) -> Result<()> {
    let model = servos.model;
    let mut missing = Vec::new();
    let all = servos.bus_ids();
    for &id in &all {
        match master.ping(id) {
            Ok(info) => {
                let number = match info.model {
                    Some(n) => Some(n),
                    None => read_model(master, model, id),
                };
                if let Some(n) = number.filter(|&n| n != model.number) {
                    let name = Model::by_number(model.protocol, n).map_or("an unknown model", |m| m.name);
                    bail!("servo {id} on {path} is model {n} ({name}), but the arm's servos are {}", model.name);
                }
            }
            Err(_) => missing.push(id),
        }
    }
    let ids = |v: &[u8]| v.iter().map(u8::to_string).collect::<Vec<_>>().join(", ");
    let baud = master.config().baud;
    if missing.len() == all.len() {
        bail!(
            "no servo answered on {path} ({} at {baud} baud, ids {}): check the servos' power, --protocol and --baud \
             (`armctl servo scan --port {path} --protocol ...` lists what is there)",
            model.protocol.name(),
            ids(&all)
        );
    }
    if !missing.is_empty() {
        let gripper = servos.gripper.filter(|g| missing.contains(&g.id)).map_or(String::new(), |g| {
            format!(" (servo {} is the gripper: an arm file without a [gripper] table drives the arm without it)", g.id)
        });
        bail!(
            "servo {} of arm ids {} did not answer on {path}: check its cable and id (`armctl servo scan`){gripper}",
            ids(&missing),
            ids(&all)
        );
    }
    Ok(())
}

/// One item of a servo's table.
fn read_item<C: Clock>(
    master: &mut Master<SerialTransport, NoDirectionPin, C>,
    model: &Model,
    id: u8,
    item: Item,
) -> Result<i64> {
    let mut raw = vec![0u8; item.len()];
    master.read(id, item.address, &mut raw).map_err(|e| anyhow!("{e}"))?;
    item.decode(&raw, model.endian).map_err(|e| anyhow!("servo {id}: {}: {e:?}", item.name))
}

/// The model number from the servo's table (Feetech pings do not carry it).
fn read_model<C: Clock>(master: &mut Master<SerialTransport, NoDirectionPin, C>, model: &Model, id: u8) -> Option<u16> {
    read_item(master, model, id, model.items.model_number).ok().and_then(|n| u16::try_from(n).ok())
}

/// Compares the calibration in use with the servos' registers, as LeRobot's `is_calibrated`
/// does when it connects; nothing is written. A difference is one line naming the servo, with
/// the fix.
fn check_calibration(
    master: &mut Master<SerialTransport, NoDirectionPin, StdClock>,
    options: &PcOptions,
    servos: &ServoSetup,
) -> Result<()> {
    let Some(calibration) = &servos.calibration else { return Ok(()) };
    let model = servos.model;
    let protocol = match model.protocol {
        Protocol::Feetech => "sts",
        Protocol::Dxl2 => "dxl2",
    };
    // A LeRobot file given with --calibration, or the arm file's [servos] calibration.
    let (source, fix) = match options.calibration_file.as_deref() {
        Some(file) => (
            file.to_string(),
            format!(
                "write the file's values (armctl servo calibration write --port {} --protocol {protocol} --file \
                 {file}, with the servos' torque off) or calibrate again",
                options.path
            ),
        ),
        None => (
            format!("arm {}'s file", options.arm.name),
            format!(
                "calibrate again (armctl calibrate --bus {} --protocol {protocol} --arm ... --out ...), or write the \
                 LeRobot file it wrote with armctl servo calibration write",
                options.path
            ),
        ),
    };
    // The joints', then the gripper's where the calibration has it: a replaced or reset gripper
    // servo would otherwise be driven with the wrong mapping.
    let joints =
        servos.ids.iter().zip(calibration).enumerate().map(|(j, (&id, m))| (id, format!("joint {}", j + 1), m));
    let gripper =
        servos.gripper.zip(servos.gripper_calibration.as_ref()).map(|(g, m)| (g.id, "gripper".to_string(), m));
    for (id, what, m) in joints.chain(gripper) {
        for register in registers(model) {
            let held = read_item(master, model, id, register.item)?;
            let want = m.value(&register);
            if held != want {
                bail!(
                    "servo {id} ({what}) does not hold the calibration: its {} is {held}, {source} says {want}; {fix}",
                    register.field,
                );
            }
        }
    }
    Ok(())
}

/// The firmware for an arm of `joints` joints (configured by the host over the link) with
/// `master` on the serial port.
fn core_for(joints: usize, board: Board, master: Master<SerialTransport, NoDirectionPin, StdClock>) -> Result<PcCore> {
    struct OnPort(Master<SerialTransport, NoDirectionPin, StdClock>);
    impl WithFirmware for OnPort {
        type Output = PcCore;
        fn call<const N: usize>(self, firmware: Firmware<N, QUEUE>) -> PcCore {
            Box::new(SimBoard { firmware, master: self.0 })
        }
    }
    for_joints(joints, board, OnPort(master))
}
