//! Software in the loop: the firmware application ([`firmware::app`]) compiled for the host, the
//! simulated servo bus and the host link, all in memory on one virtual clock.
//!
//! [`Sil`] is the host's end of the link: a `Read + Write` byte transport for
//! [`crate::link::client::LinkClient`], exactly like a serial port. Time stands still while the
//! host computes and moves while it waits: a read runs the simulated board (its link input, its
//! control ticks at the firmware's period, the servo bus) until a byte arrives or the read timeout
//! of virtual time has passed. Every byte costs 10 bit times at its line's baud rate, on the link
//! as on the bus, and each servo answers after its return delay. Compute time on the board is not
//! charged (the HIL tests measure it). The same options and seed give the same run.
//!
//! - [`wire`]: one direction of the link (timing, dropped bytes, flipped bits).
//! - [`board`]: the firmware and its bus master, for any joint count.
//!
//! The safety monitor that checks every goal the servos receive is the simulator's
//! ([`crate::sim::monitor`]), re-exported here. An object to pick up ([`crate::sim::Scene`]) can be
//! put on the table ([`Sil::put_object`]): the harness then follows the tool by forward kinematics
//! of the measured joints each tick. With collision geometry ([`SilOptions::contact`]) the
//! simulated links stop where they run into something ([`crate::sim::contact`]) and the monitor
//! records every goal within the margin ([`crate::sim::monitor::collision`]).

pub mod board;
pub mod group;
pub mod wire;

use std::io::{self, ErrorKind, Read, Write};

use anyhow::Result;
use firmware::app::{Board, Firmware};
use firmware::builtin;
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::Model;
use firmware::controller::{Config, GripperState, TickReport};

use kinematics::Pose;

use crate::arm::collision::CollisionSpec;
use crate::arm::dof::DynArm;
use crate::arm::servos::{servos_of, ServoSetup};
use crate::arm::ArmSpec;
pub use crate::sim::monitor::{GoalState, SafetyMonitor, Violation};
use crate::sim::{connect, ContactModel, Faults, Scene, SharedBus, SimBus, VirtualClock, World};
use board::{for_joints, SimBoard, SimFirmware, WithFirmware, QUEUE};
use wire::Wire;

/// The gripper of `servos`, for `--object-mm` and objects on the table.
fn gripper_of(arm: &str, servos: &ServoSetup) -> Result<crate::arm::servos::GripperSpec> {
    servos.gripper.ok_or_else(|| anyhow::anyhow!("--object-mm: the simulated {arm} has no gripper"))
}

/// Puts an object `mm` wide between the jaws of `gripper` on `bus` (`None` takes it away).
fn put_object(bus: &SharedBus, gripper: &crate::arm::servos::GripperSpec, mm: Option<f64>) -> Result<()> {
    let jaw = mm.map(|mm| crate::sim::Jaw::for_object(gripper, mm)).transpose()?;
    let mut bus = bus.borrow_mut();
    let now = bus.now_ns();
    if let Some(servo) = bus.servo_mut(gripper.id) {
        servo.set_jaw(jaw, now);
    }
    Ok(())
}

/// Whether `arm` is the firmware's built-in SO-101, servos and all: the simulated board then
/// starts with it, as a board does, instead of being sent it.
fn is_builtin(arm: &ArmSpec, servos: &ServoSetup) -> bool {
    arm.name == builtin::NAME && ServoSetup::for_arm(builtin::NAME).as_ref() == Some(servos)
}

/// The servos of `arm`, which the simulated bus serves.
fn servos(arm: &ArmSpec) -> Result<ServoSetup> {
    servos_of(arm).ok_or_else(|| {
        anyhow::anyhow!("arm {} has no servos to simulate: add a [servos] table to its arm file", arm.name)
    })
}

/// How the harness is set up.
#[derive(Clone, Debug, PartialEq)]
pub struct SilOptions {
    /// The arm: a preset or an arm file, with a `[servos]` table (or a preset's servos), whose
    /// servo models the simulated bus serves.
    pub arm: ArmSpec,
    /// Host link baud rate (10 bits per byte).
    pub link_baud: u32,
    /// Servo bus baud rate.
    pub bus_baud: u32,
    /// Faults on the host link, both directions (its `seed`, `drop_rate` and `bit_flip_rate`).
    pub link_faults: Faults,
    /// Faults on the servo bus.
    pub bus_faults: Faults,
    /// The firmware's control loop.
    pub control: Config,
    /// Virtual time a host read waits before it times out, ms.
    pub read_timeout_ms: u64,
    /// The width of an object between the gripper's jaws, mm (`None`: nothing to grasp).
    pub object_mm: Option<f64>,
    /// The simulated world's collision geometry: the simulated links stop where they run into
    /// the table, an obstacle or each other, and the safety monitor records every goal within its
    /// margin (`None`: nothing is in the way). By default the arm's own
    /// ([`crate::arm::collision::collision_of`]); set apart from [`SilOptions::arm`] (whose
    /// geometry is what the firmware is sent), a test can show what the simulated arm does when
    /// the firmware knows nothing of the table.
    pub contact: Option<CollisionSpec>,
    /// Whether the firmware checks the goals against the geometry it is sent (`Off`:
    /// `--no-collision-check`, for a test that must see the simulated arm reach a contact).
    pub collision_check: crate::link::arm_config::CollisionCheck,
    /// The servos: ideal (the default) or physical (they carry the arm under gravity, sag, lag,
    /// heat: [`crate::sim::physics::ServoKind`]).
    pub servos: crate::sim::physics::ServoKind,
    /// Gravity compensation given to the firmware once connected (`None`: none).
    pub gravity: Option<crate::runtime::gravity::Compensation>,
}

impl SilOptions {
    /// The defaults for `arm` (a preset's name or an arm file): 1 Mbps link and bus, no faults,
    /// 100 Hz, 20 ms read timeout.
    pub fn new(arm: &str) -> Result<Self> {
        Self::for_arm(ArmSpec::load(arm, None)?)
    }

    /// [`SilOptions::new`] for an arm already loaded; fails for one without servos.
    pub fn for_arm(arm: ArmSpec) -> Result<Self> {
        servos(&arm)?;
        Ok(Self {
            link_baud: 1_000_000,
            bus_baud: 1_000_000,
            link_faults: Faults::default(),
            bus_faults: Faults::default(),
            control: Config::default(),
            read_timeout_ms: 20,
            object_mm: None,
            contact: crate::arm::collision::collision_of(&arm),
            collision_check: Default::default(),
            servos: Default::default(),
            gravity: None,
            arm,
        })
    }
}

/// One control tick as the harness saw it.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceSample {
    /// Virtual time at the tick's start, s.
    pub time: f64,
    /// Setpoints sent (rad).
    pub setpoints: Vec<f64>,
    /// Positions read back (rad).
    pub measured: Vec<f64>,
    /// The gripper as the firmware saw it after the tick (`None` without one).
    pub gripper: Option<GripperState>,
    /// Whether the jaws held the object on the table (`None` without one: [`Sil::put_object`]).
    pub object_held: Option<bool>,
    /// Each servo's goal after the tick, read from the simulated servo (id, ticks): what the
    /// servos received, whatever the firmware thinks it sent. Empty while any torque is off.
    pub goals: Vec<(u8, i64)>,
}

/// Counts of the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SilStats {
    /// Control ticks run.
    pub ticks: u64,
    /// Ticks that started later than their slot (the previous tick or link work overran).
    pub late_ticks: u64,
    /// Ticks whose work took longer than the period.
    pub overruns: u64,
    /// Bytes the host sent and received.
    pub host_bytes: (u64, u64),
}

/// The SIL harness; the host's end of the link.
pub struct Sil {
    arm: ArmSpec,
    servos: ServoSetup,
    clock: VirtualClock,
    bus: SharedBus,
    model: &'static Model,
    board: Box<dyn SimFirmware>,
    to_board: Wire,
    to_host: Wire,
    next_tick_ns: u64,
    period_ns: u64,
    read_timeout_ns: u64,
    monitor: SafetyMonitor,
    trace: Option<Vec<TraceSample>>,
    last_report: Option<TickReport>,
    stats: SilStats,
    scratch: Vec<u8>,
    /// An object on the table, the arm whose tool can pick it up, and where that arm's base is
    /// in the object's frame.
    scene: Option<(Scene, Box<dyn DynArm>, Pose<f64>)>,
}

impl Sil {
    /// A board with its servos at rest at their middle position, torque off, at time 0.
    pub fn new(options: &SilOptions) -> Result<Self> {
        let arm = options.arm.clone();
        let servos = servos(&arm)?;
        let model = servos.model;
        let world = options.contact.clone().map(|geometry| World::new(&arm, geometry)).transpose()?;
        let bus = SimBus::new(model.protocol, model, &servos.bus_ids(), options.bus_baud)
            .with_faults(options.bus_faults.clone())
            .with_contact(world.clone().map(ContactModel::new))
            .with_physics(options.servos.physics(Some(&arm))?);
        let (bus, port, clock) = connect(bus);
        if options.object_mm.is_some() {
            put_object(&bus, &gripper_of(&arm.name, &servos)?, options.object_mm)?;
        }
        let bus_config = BusConfig::new(model.protocol, options.bus_baud);
        let board = Board { bus: bus_config, model, control: options.control, max_bus_baud: u32::MAX };
        let master = Master::new(port, NoDirectionPin, clock.clone(), bus_config);
        let board: Box<dyn SimFirmware> = if is_builtin(&arm, &servos) {
            // The boards' own build: the built-in SO-101 padded as on a board.
            let firmware = Firmware::<{ firmware::board::JOINTS }, QUEUE>::new(board, Some(&builtin::SO101))
                .map_err(|e| anyhow::anyhow!("simulated board: {e}"))?;
            Box::new(SimBoard { firmware, master })
        } else {
            struct OnSimBus(Master<crate::sim::SimPort, NoDirectionPin, VirtualClock>);
            impl WithFirmware for OnSimBus {
                type Output = Box<dyn SimFirmware>;
                fn call<const N: usize>(self, firmware: Firmware<N, QUEUE>) -> Box<dyn SimFirmware> {
                    Box::new(SimBoard { firmware, master: self.0 })
                }
            }
            for_joints(arm.dof(), board, OnSimBus(master))?
        };
        let period_ns = u64::from(board.period_us()) * 1000;
        // The link's faults get their own seed stream per direction, so the two differ.
        let mut upstream = options.link_faults.clone();
        upstream.seed = upstream.seed.wrapping_add(0x5EED);
        Ok(Self {
            arm,
            servos,
            clock,
            bus,
            model,
            board,
            to_board: Wire::new(options.link_baud, options.link_faults.clone()),
            to_host: Wire::new(options.link_baud, upstream),
            next_tick_ns: 0,
            period_ns,
            read_timeout_ns: options.read_timeout_ms * 1_000_000,
            monitor: world.map_or_else(SafetyMonitor::default, SafetyMonitor::with_collision),
            trace: None,
            last_report: None,
            stats: SilStats::default(),
            scratch: Vec::new(),
            scene: None,
        })
    }

    /// Virtual time, s.
    pub fn now_s(&self) -> f64 {
        self.clock.now_ns() as f64 * 1e-9
    }

    /// Puts an object `mm` wide between the gripper's jaws (`None` takes it away), now.
    pub fn set_object(&mut self, mm: Option<f64>) -> Result<()> {
        put_object(&self.bus, &gripper_of(&self.arm.name, &self.servos)?, mm)
    }

    /// Puts an object `width_mm` wide on the table at `position` (m, its centre), for the
    /// gripper to pick up: from the next tick on, its tool ([`DynArm::tool_pose`] of `arm`, the
    /// arm the firmware drives) takes it between open jaws that come within
    /// [`crate::sim::scene::REACH_M`] of it, and carries it while the jaws grip it. Replaces any
    /// object there was; the jaws let go of it first.
    pub fn put_object(&mut self, arm: Box<dyn DynArm>, width_mm: f64, position: [f64; 3]) -> Result<()> {
        let gripper = gripper_of(&self.arm.name, &self.servos)?;
        let scene = Scene::new(&gripper, width_mm, position)?;
        self.share_object(arm, Pose::identity(), scene)
    }

    /// The gripper's spec (for a [`Scene`] of its jaws); fails for an arm without one.
    pub fn gripper(&self) -> Result<crate::arm::servos::GripperSpec> {
        gripper_of(&self.arm.name, &self.servos)
    }

    /// Makes `scene` (made for this arm's gripper, often sharing its object with another arm's
    /// scene: [`Scene::for_gripper`]) this board's, with the arm's base at `base` in the scene's
    /// frame: the tool's position there is `base` composed with the forward kinematics of `arm`.
    pub fn share_object(&mut self, arm: Box<dyn DynArm>, base: Pose<f64>, scene: Scene) -> Result<()> {
        let gripper = gripper_of(&self.arm.name, &self.servos)?;
        put_object(&self.bus, &gripper, None)?;
        self.scene = Some((scene, arm, base));
        Ok(())
    }

    /// The object on the table, if there is one.
    pub fn object(&self) -> Option<&Scene> {
        self.scene.as_ref().map(|(scene, ..)| scene)
    }

    /// The simulated servo bus (to change faults or inspect servos mid-run).
    pub fn bus(&self) -> &SharedBus {
        &self.bus
    }

    /// Where every simulated servo's horn is now (ticks, as the simulator holds it): the servos'
    /// truth, not the firmware's reading of it, which can lag a mapping the arm was sent anew.
    pub fn horns(&self) -> Vec<f64> {
        let bus = self.bus.borrow();
        let now = bus.now_ns();
        bus.servos().iter().map(|s| s.horn_at(now)).collect()
    }

    /// The host link's fault settings (host to board, board to host).
    pub fn link_faults_mut(&mut self) -> (&mut Faults, &mut Faults) {
        (self.to_board.faults_mut(), self.to_host.faults_mut())
    }

    /// Bytes lost and bits flipped on the link so far (host to board, board to host).
    pub fn link_fault_stats(&self) -> (crate::sim::FaultStats, crate::sim::FaultStats) {
        (self.to_board.fault_stats(), self.to_host.fault_stats())
    }

    /// The safety monitor's findings.
    pub fn monitor(&self) -> &SafetyMonitor {
        &self.monitor
    }

    /// The firmware side (setpoints, measured values, bounds).
    pub fn board(&self) -> &dyn SimFirmware {
        self.board.as_ref()
    }

    /// The last tick's report.
    pub fn last_report(&self) -> Option<&TickReport> {
        self.last_report.as_ref()
    }

    /// Counts of the run.
    pub fn stats(&self) -> SilStats {
        self.stats
    }

    /// Starts recording every tick (setpoints and measured values).
    pub fn record(&mut self) {
        self.trace = Some(Vec::new());
    }

    /// The recorded ticks (empty when not recording).
    pub fn take_trace(&mut self) -> Vec<TraceSample> {
        self.trace.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Lets `seconds` of virtual time pass with the host silent.
    pub fn run_for(&mut self, seconds: f64) {
        run_in_step(std::slice::from_mut(self), seconds);
    }

    /// Lets control ticks pass until the firmware has read every servo and its torque (at most
    /// [`READ_WITHIN_S`] of virtual time), as the host waits for a core on the PC: until then a
    /// status reports each joint at the middle of its range, not where its servo stands.
    pub fn settle_reads(&mut self) {
        settle_reads(std::slice::from_mut(self));
    }

    /// When the board's next event is due (link input or a control tick), ns.
    fn next_event_ns(&self) -> u64 {
        self.to_board.next_arrival_ns().map_or(self.next_tick_ns, |t| t.min(self.next_tick_ns))
    }

    /// Runs the next board event (link input or a control tick) if it is due by `limit_ns`;
    /// false when none is.
    fn step(&mut self, limit_ns: u64) -> bool {
        let next = self.next_event_ns();
        if next > limit_ns {
            return false;
        }
        self.clock.advance_to(next);
        let now_ns = self.clock.now_ns();
        self.scratch.clear();
        if self.to_board.take_arrived(now_ns, &mut self.scratch, usize::MAX) > 0 {
            let mut replies = Vec::new();
            self.board.receive(&self.scratch, now_ns / 1000, &mut replies);
            self.to_host.send(&replies, self.clock.now_ns());
        }
        if self.next_tick_ns <= now_ns {
            self.run_tick(now_ns);
        }
        true
    }

    fn run_tick(&mut self, now_ns: u64) {
        if now_ns > self.next_tick_ns + self.period_ns / 2 {
            self.stats.late_ticks += 1;
        }
        let mut telemetry = Vec::new();
        let report = self.board.tick(now_ns / 1000, &mut telemetry);
        self.stats.ticks += 1;
        if report.is_some_and(|r| u64::from(r.loop_us) * 1000 > self.period_ns) {
            self.stats.overruns += 1;
        }
        self.last_report = report;
        self.to_host.send(&telemetry, self.clock.now_ns());
        // The next slot on the fixed schedule; after an overrun the next tick starts at once
        // (slots already missed are skipped, not made up).
        self.next_tick_ns += self.period_ns;
        if self.next_tick_ns < self.clock.now_ns() {
            self.next_tick_ns = self.clock.now_ns();
        }
        let time = now_ns as f64 * 1e-9;
        if let Some((scene, arm, base)) = &mut self.scene {
            // A tool pose that cannot be computed (no joint read yet) leaves the object be.
            if let Ok(pose) = arm.tool_pose(&self.board.measured()) {
                let p = base.compose(&pose).translation;
                scene.update(&self.bus, [p.x, p.y, p.z], self.clock.now_ns());
            }
        }
        let goals = self.goals();
        let bounds = self.board.bounds();
        let held: Vec<(u8, i64)> = match (&goals, &self.trace) {
            (Some(g), Some(_)) => bounds.iter().zip(g).map(|(b, g)| (b.id, g.goal)).collect(),
            _ => Vec::new(),
        };
        self.monitor.check(time, self.period_ns as f64 * 1e-9, &bounds, goals);
        if let Some(trace) = &mut self.trace {
            trace.push(TraceSample {
                time,
                setpoints: self.board.setpoints(),
                measured: self.board.measured(),
                gripper: self.board.gripper(),
                object_held: self.scene.as_ref().map(|(scene, ..)| scene.held()),
                goals: held,
            });
        }
    }

    /// Every servo's goal (ticks) and goal write count, read from the simulated servos; `None`
    /// while any torque is off.
    fn goals(&self) -> Option<Vec<GoalState>> {
        if !self.board.torque() {
            return None;
        }
        let bus = self.bus.borrow();
        let item = self.model.items.goal_position;
        self.board
            .bounds()
            .iter()
            .map(|b| {
                bus.servo(b.id).filter(|s| s.torque()).map(|s| GoalState {
                    goal: s.get(item),
                    writes: s.goal_writes(),
                    corrupted: s.last_goal_corrupted(),
                })
            })
            .collect()
    }
}

impl Read for Sil {
    /// The bytes that have arrived, after running the board until one does; `TimedOut` after the
    /// read timeout of virtual time without any.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        read_in_step(std::slice::from_mut(self), 0, buf)
    }
}

/// The next event of any board of `sils` (link input or a control tick).
fn next_event_ns(sils: &[Sil]) -> u64 {
    sils.iter().map(Sil::next_event_ns).min().unwrap_or(u64::MAX)
}

/// Runs every board of `sils` whose next event is the earliest of all, if that is due by
/// `limit_ns`, and brings every clock to its time; false when none is due. The boards share one
/// time line: no board's clock runs ahead of another's.
fn step_in_step(sils: &mut [Sil], limit_ns: u64) -> bool {
    let next = next_event_ns(sils);
    if next > limit_ns {
        return false;
    }
    for sil in sils.iter_mut() {
        if sil.next_event_ns() == next {
            sil.step(next);
        }
        sil.clock.advance_to(next);
    }
    true
}

/// How long a simulated board may take to read its servos after it is configured (s).
pub const READ_WITHIN_S: f64 = 1.0;

/// [`Sil::settle_reads`] for boards on one clock.
pub(crate) fn settle_reads(sils: &mut [Sil]) {
    let period = sils.iter().map(|s| s.period_ns).max().unwrap_or(1) as f64 * 1e-9;
    let mut waited = 0.0;
    while waited < READ_WITHIN_S && !sils.iter().all(|s| s.board.ready()) {
        run_in_step(sils, period);
        waited += period;
    }
}

/// Lets `seconds` of virtual time pass on every board of `sils`, the host silent.
fn run_in_step(sils: &mut [Sil], seconds: f64) {
    let Some(first) = sils.first() else { return };
    let until = first.clock.now_ns() + (seconds * 1e9) as u64;
    while step_in_step(sils, until) {}
    for sil in sils {
        sil.clock.advance_to(until);
    }
}

/// [`Read::read`] for the host end of `sils[reader]`: runs every board of `sils` in step until a
/// byte for that host arrives; `TimedOut` after its read timeout of virtual time without any.
fn read_in_step(sils: &mut [Sil], reader: usize, buf: &mut [u8]) -> io::Result<usize> {
    if buf.is_empty() {
        return Ok(0);
    }
    let deadline = sils[reader].clock.now_ns() + sils[reader].read_timeout_ns;
    loop {
        let sil = &mut sils[reader];
        let now_ns = sil.clock.now_ns();
        let mut got = Vec::new();
        let n = sil.to_host.take_arrived(now_ns, &mut got, buf.len());
        if n > 0 {
            buf[..n].copy_from_slice(&got);
            sil.stats.host_bytes.1 += n as u64;
            return Ok(n);
        }
        let arrival = sil.to_host.next_arrival_ns();
        let limit = arrival.map_or(deadline, |t| t.min(deadline));
        if !step_in_step(sils, limit) {
            for sil in sils.iter_mut() {
                sil.clock.advance_to(limit);
            }
            if limit >= deadline && arrival.is_none_or(|t| t > deadline) {
                return Err(io::Error::new(ErrorKind::TimedOut, "no bytes from the simulated board"));
            }
        }
    }
}

impl Write for Sil {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.to_board.send(buf, self.clock.now_ns());
        self.stats.host_bytes.0 += buf.len() as u64;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
