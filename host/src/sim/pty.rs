//! A [`SimBus`] served on a pseudo-terminal, for programs that open a serial port (`armctl`, the
//! firmware under QEMU).
//!
//! A thread reads the pty's master end, feeds the bus with the real time elapsed since the server
//! started (so the servos move at their real speed) and writes the replies back at once: a pty
//! has no baud rate, so wire time and return delays are not waited out in real time (the virtual
//! clock of [`super::port`] is where timing is checked). The thread keeps the slave end open
//! too, so a client closing and reopening the path does not hang up the master end. The pty is
//! its owner's alone (mode 0600, [`crate::support::pty_owner`]) before [`PtyServer::spawn`] returns.
//!
//! Two options make it more like a servo bus behind a USB serial adapter, for a firmware core run
//! on the PC against the real clock: [`SimConfig::burst`] holds the replies until the adapter's
//! latency timer expires ([`super::latency`]; bytes from the PC still reach the servos at once),
//! and [`SimConfig::limits`] checks every goal the servos receive, frame by frame in the order
//! they arrived ([`super::monitor::realtime`]), for [`PtyServer::monitor`]; whoever runs the
//! firmware tells it the control period ([`PtyServer::set_period`]).
//!
//! A hand can turn the servos' horns while they are served ([`PtyServer::place`],
//! [`PtyServer::hand`]), as a person moves a limp arm during a calibration: the serving thread
//! takes each request before it carries out the next bytes from the pty, and reports a hand's move
//! done ([`PtyServer::hand_events`]) once the horn is there and its position has been read since,
//! so that whoever reads the bus has seen where the hand stopped.
//!
//! [`PtyServer::spawn_with`] also starts the servos with horns placed and objects between jaws from
//! the server's first instant, and can record the servos' positions on a grid of real time
//! ([`super::recording`]): the serving thread writes the grid points up to each wake before it
//! carries out what woke it, and flushes the file when it stops.
//!
//! Faults a first connection meets ([`ServeOptions`]): control-table values set bypassing the bus
//! rules ([`super::SimServo::set_register`]: a 12 V supply on 7.4 V servos, heat, mixed firmware,
//! a stale goal...), hardware errors raised from the start, and an adapter that hears its own
//! transmission ([`ServeOptions::echo`]): every byte the master writes comes back to it before any
//! reply, as from a half-duplex adapter whose receiver is not gated while it transmits.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use firmware::bus::table::Model;
use firmware::bus::Protocol;
use serialport::{SerialPort, TTYPort};

use super::bus::{SimBus, WireByte};
use super::contact::ContactModel;
use super::faults::{FaultState, Faults};
use super::latency::LatencyTimer;
use super::monitor::{GoalLimit, MonitorReport, RealTimeMonitor};
use super::recording::Recorder;
use super::servo::{Jaw, SimServo};
use super::world::World;
use firmware::bus::table::Item;

/// Ticks between a duplicate servo's position and its twin's, so that their replies to a position
/// read differ and collide visibly (two real servos never stand at the same tick).
pub const TWIN_OFFSET_TICKS: i64 = 100;

/// Everything needed to build a bus, `Send` so that a server thread can build it.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    /// The protocol.
    pub protocol: Protocol,
    /// The servos' model.
    pub model: &'static Model,
    /// Their ids.
    pub ids: Vec<u8>,
    /// The baud rate.
    pub baud: u32,
    /// Faults to inject.
    pub faults: Faults,
    /// Ids that get a second servo ([`TWIN_OFFSET_TICKS`] away from the first).
    pub duplicates: Vec<u8>,
    /// The other end is an emulated UART that does not time its line (QEMU): keep `baud` whatever
    /// it sets on the pty (QEMU sets the standard rate nearest its divider, 921600 for 1 Mbps,
    /// which real servos would not notice), and do not take the gaps between its bytes, which are
    /// the emulator's scheduling, for the end of a packet.
    pub fixed_baud: bool,
    /// The latency timer of a USB serial adapter between the servos and the PC (16 ms is FTDI's
    /// default, 1 ms tuned): replies are held until its next expiry. `None`: written at once.
    pub burst: Option<Duration>,
    /// Goal limits per servo: a safety monitor then checks every goal the servos receive, over
    /// the real time between them ([`PtyServer::monitor`]). `None`: no monitor.
    pub limits: Option<Vec<GoalLimit>>,
    /// The arm's collision geometry: its links stop where they run into the table, an obstacle
    /// or each other ([`super::contact`]), and the monitor, if there is one, records every goal
    /// within its margin ([`super::monitor::collision`]). `None`: nothing is in the way.
    pub world: Option<World>,
    /// The servos' drives and what they carry ([`super::physics`]); `None`: ideal servos.
    pub physics: Option<super::Physics>,
}

impl SimConfig {
    /// The bus this describes.
    pub fn build(&self) -> SimBus {
        let mut bus = SimBus::new(self.protocol, self.model, &self.ids, self.baud)
            .with_faults(self.faults.clone())
            .with_contact(self.world.clone().map(ContactModel::new))
            .with_physics(self.physics.clone());
        for &id in &self.duplicates {
            let mut twin = bus.new_servo(id);
            let at = twin.get(self.model.items.present_position) + TWIN_OFFSET_TICKS;
            twin.set_position(at, 0);
            bus.add_servo(twin);
        }
        bus
    }

    /// The bus as served on a pty: for an emulated master, a partial packet is dropped only after
    /// [`EMULATED_LINE_GAP_NS`]; for a program on this PC, only once a read of the pty has waited
    /// [`IDLE_READ`] for nothing. Such a program writes each packet at once, so a gap the serving
    /// thread sees inside one is its own scheduling: on a loaded PC it read the first bytes of a
    /// goal write, got the rest 2 to 6 ms later, and the servos' 1.5 ms inter-byte timeout dropped
    /// the packet, so they missed that tick's goals (42 times in 150 s beside two busy loops).
    fn build_for_pty(&self) -> SimBus {
        let mut bus = self.build();
        bus.set_inter_byte_timeout(if self.fixed_baud { EMULATED_LINE_GAP_NS } else { u64::MAX });
        bus
    }
}

/// The longest gap within one packet from an emulated UART: QEMU's pty output is paced by its own
/// scheduling, with gaps of milliseconds inside a packet that a real line would not have.
pub const EMULATED_LINE_GAP_NS: u64 = 50_000_000;

/// How long a read of the master end waits when no reply is held: short, so that the thread
/// notices a stop request quickly; a line this long quiet also ends a partial packet.
const IDLE_READ: Duration = Duration::from_millis(20);

/// What a hand does to a servo's horn, in the horn's own ticks (before its homing offset).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Hand {
    /// At `ticks` at once, unreported.
    Place { id: u8, ticks: i64 },
    /// To `from` at once, then steadily to `to` in `seconds`; reported under `ticket`.
    Move { ticket: u64, id: u8, from: i64, to: i64, seconds: f64 },
    /// An object between the jaws of gripper servo `id` (`None` takes it away), unreported.
    Object { id: u8, jaw: Option<Jaw> },
}

/// How a hand's move ended ([`PtyServer::hand`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HandEvent {
    /// The ticket [`PtyServer::hand`] returned.
    pub ticket: u64,
    /// `Ok` once the horn is where the hand took it and its position has been read since; the
    /// reason otherwise (an unknown servo, torque on, a later move of the same servo).
    pub result: Result<(), String>,
}

/// The hand's requests and reports, shared with the serving thread.
#[derive(Debug, Default)]
struct HandQueue {
    requests: VecDeque<Hand>,
    events: Vec<HandEvent>,
    next_ticket: u64,
}

/// A hand that turns the horns of a [`PtyServer`]'s servos from another thread.
#[derive(Clone, Debug)]
pub struct HandHandle(Arc<Mutex<HandQueue>>);

impl HandHandle {
    /// As [`PtyServer::hand`].
    pub fn turn(&self, id: u8, from: i64, to: i64, seconds: f64) -> u64 {
        // A poisoned lock only means the serving thread panicked; the queue is still whole.
        let mut queue = self.0.lock().unwrap_or_else(|e| e.into_inner());
        queue.next_ticket += 1;
        let ticket = queue.next_ticket;
        queue.requests.push_back(Hand::Move { ticket, id, from, to, seconds });
        ticket
    }
}

/// A [`PtyServer`]'s safety monitor, shared with whoever learns the firmware's control period.
#[derive(Clone, Debug)]
pub struct MonitorHandle(Arc<Mutex<RealTimeMonitor>>);

impl MonitorHandle {
    /// The firmware's control period ([`RealTimeMonitor::set_period`]): a core run on the PC
    /// chooses it once it has timed the bus, after the servos are served.
    pub fn set_period(&self, period: Duration) {
        // A poisoned lock only means the serving thread panicked; the monitor is still whole.
        self.0.lock().unwrap_or_else(|e| e.into_inner()).set_period(period);
    }

    /// The control period the monitor judges by.
    pub fn period(&self) -> Duration {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).period()
    }
}

/// What a server starts with beside its bus ([`PtyServer::spawn_with`]).
#[derive(Debug, Default)]
pub struct ServeOptions {
    /// Horns placed by hand before the start, in their own ticks (before the homing offset), as
    /// [`PtyServer::place`] puts them but from the server's first instant, so that a recording
    /// starts with them there. A servo that is not on the bus is left out.
    pub place: Vec<(u8, i64)>,
    /// Objects between the jaws of gripper servos from the first instant, as
    /// [`PtyServer::put_object`] puts them.
    pub objects: Vec<(u8, Jaw)>,
    /// A recording of the servos' positions and goals, written by the serving thread and flushed
    /// when the server stops. Its columns are the bus's first servos, those of
    /// [`SimConfig::ids`] in order.
    pub record: Option<Recorder>,
    /// Control-table values set at time 0, after the horns are placed, in order, bypassing the bus
    /// rules ([`SimServo::set_register`]).
    pub registers: Vec<Register>,
    /// Hardware errors raised at time 0, after the registers: (servo, bits), `None` for every
    /// servo ([`SimServo::set_hardware_error`]: torque goes off and stays off).
    pub hardware_errors: Vec<(Option<u8>, u8)>,
    /// The adapter hears its own transmission: every byte from the pty goes back to it first, before
    /// the replies it causes (and through the latency timer with them, when there is one).
    pub echo: bool,
}

/// A control-table value of [`ServeOptions::registers`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Register {
    /// The servo (twins included), `None` for every servo.
    pub id: Option<u8>,
    /// The item.
    pub item: Item,
    /// Its value.
    pub value: i64,
}

/// The servos `id` names (`None`: all), twins included.
fn servos_of(bus: &mut SimBus, id: Option<u8>) -> impl Iterator<Item = &mut SimServo> {
    bus.servos_mut().iter_mut().filter(move |s| id.is_none_or(|id| s.id() == id))
}

impl ServeOptions {
    /// Places the horns and puts the objects, then sets the registers and raises the hardware
    /// errors, at time 0. Fails with the first register a servo refuses, or one naming no servo.
    pub fn set_up(&self, bus: &mut SimBus) -> Result<(), String> {
        for &(id, ticks) in &self.place {
            if let Some(servo) = bus.servo_mut(id) {
                servo.set_position(ticks, 0);
            }
        }
        for &(id, jaw) in &self.objects {
            if let Some(servo) = bus.servo_mut(id) {
                servo.set_jaw(Some(jaw), 0);
            }
        }
        for r in &self.registers {
            let mut found = false;
            for servo in servos_of(bus, r.id) {
                found = true;
                servo.set_register(r.item, r.value, 0).map_err(|e| format!("servo {}: {e}", servo.id()))?;
            }
            if let (false, Some(id)) = (found, r.id) {
                return Err(format!("no servo {id} on this bus"));
            }
        }
        for &(id, bits) in &self.hardware_errors {
            for servo in servos_of(bus, id) {
                servo.set_hardware_error(bits, 0);
            }
        }
        Ok(())
    }
}

/// A simulated bus on a pseudo-terminal; dropping it stops the serving thread (and flushes its
/// recording).
#[derive(Debug)]
pub struct PtyServer {
    path: String,
    stop: Arc<AtomicBool>,
    /// New faults for the serving thread to take up (hardware-in-the-loop tests change them mid-run).
    new_faults: Arc<Mutex<Option<Faults>>>,
    /// A hand's requests for the serving thread, and what became of them.
    hand: Arc<Mutex<HandQueue>>,
    /// The safety monitor, when there are limits; the serving thread feeds it.
    monitor: Option<Arc<Mutex<RealTimeMonitor>>>,
    thread: Option<JoinHandle<std::io::Result<()>>>,
}

impl PtyServer {
    /// Opens a pty pair, makes it its owner's alone ([`crate::support::pty_owner::make_private`]) and
    /// serves the bus of `config` on it. A `burst` of zero is refused.
    pub fn spawn(config: SimConfig) -> std::io::Result<PtyServer> {
        Self::spawn_with(config, ServeOptions::default())
    }

    /// As [`PtyServer::spawn`], the servos set up and recorded as `options` says.
    pub fn spawn_with(config: SimConfig, mut options: ServeOptions) -> std::io::Result<PtyServer> {
        if config.burst.is_some_and(|b| b.is_zero()) {
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, "the burst period must be positive"));
        }
        // The servos' set-up is tried on a bus of its own first, so that a refused register is an
        // error here rather than in the serving thread.
        options.set_up(&mut config.build()).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
        let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::from)?;
        let path = slave.name().ok_or_else(|| std::io::Error::other("the pty has no path"))?;
        // The servos take commands through it: its owner's alone before anyone learns its path.
        crate::support::pty_owner::make_private(&path).map_err(|e| std::io::Error::other(format!("{e:#}")))?;
        master.set_timeout(IDLE_READ).map_err(std::io::Error::from)?;
        let stop = Arc::new(AtomicBool::new(false));
        let new_faults = Arc::new(Mutex::new(None));
        let hand = Arc::new(Mutex::new(HandQueue::default()));
        let monitor = config.limits.clone().map(|limits| {
            let monitor = RealTimeMonitor::new(limits);
            let monitor = match config.world.clone() {
                Some(world) => monitor.with_collision(world),
                None => monitor,
            };
            Arc::new(Mutex::new(monitor))
        });
        let control = Control {
            stop: stop.clone(),
            new_faults: new_faults.clone(),
            monitor: monitor.clone(),
            hand: hand.clone(),
            pending: Vec::new(),
            recorder: options.record.take(),
        };
        let thread = std::thread::Builder::new().name("sim-servos".into()).spawn(move || {
            let outbox = Outbox { timer: config.burst.map(LatencyTimer::new), echo: options.echo };
            let mut bus = config.build_for_pty();
            // Tried above on the same bus: it cannot fail here.
            let _ = options.set_up(&mut bus);
            serve(&mut master, &slave, bus, !config.fixed_baud, control, outbox)
        })?;
        Ok(PtyServer { path, stop, new_faults, hand, monitor, thread: Some(thread) })
    }

    fn hand_queue(&self) -> std::sync::MutexGuard<'_, HandQueue> {
        // A poisoned lock only means the serving thread panicked; the queue is still whole.
        self.hand.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Puts servo `id`'s horn at `ticks` (its own position, before the homing offset), as if
    /// turned there by hand before anyone looks: applied before the next bytes from the pty are
    /// carried out, never reported. A servo that is not on the bus is left out.
    pub fn place(&self, id: u8, ticks: i64) {
        self.hand_queue().requests.push_back(Hand::Place { id, ticks });
    }

    /// Puts an object between the jaws of gripper servo `id` (`None` takes it away), as
    /// [`super::SimServo::set_jaw`] does, before the next bytes from the pty are carried out. A
    /// servo that is not on the bus is left out.
    pub fn put_object(&self, id: u8, jaw: Option<Jaw>) {
        self.hand_queue().requests.push_back(Hand::Object { id, jaw });
    }

    /// A hand turns servo `id`'s horn (torque off) to `from` at once, then steadily to `to` in
    /// `seconds`, in the horn's own ticks. Returns the ticket that [`PtyServer::hand_events`]
    /// reports it under: done once the horn is at `to` and its position has been read since, or
    /// refused (torque on, no such servo), or cut short by a later move of the same servo.
    pub fn hand(&self, id: u8, from: i64, to: i64, seconds: f64) -> u64 {
        self.hand_handle().turn(id, from, to, seconds)
    }

    /// The hand, for another thread to turn the horns with (a scripted leader arm).
    pub fn hand_handle(&self) -> HandHandle {
        HandHandle(self.hand.clone())
    }

    /// The hand's moves that ended since the last call, in the order they ended.
    pub fn hand_events(&self) -> Vec<HandEvent> {
        std::mem::take(&mut self.hand_queue().events)
    }

    /// What the safety monitor has found so far (`None` without limits).
    pub fn monitor(&self) -> Option<MonitorReport> {
        let monitor = self.monitor.as_ref()?;
        // A poisoned lock only means the serving thread panicked; what it found stands.
        let monitor = monitor.lock().unwrap_or_else(|e| e.into_inner());
        Some(monitor.report().clone())
    }

    /// Tells the safety monitor the firmware's control period (see [`MonitorHandle::set_period`]).
    pub fn set_period(&self, period: Duration) {
        if let Some(handle) = self.monitor_handle() {
            handle.set_period(period);
        }
    }

    /// The safety monitor, for whoever learns the firmware's control period (`None` without
    /// limits).
    pub fn monitor_handle(&self) -> Option<MonitorHandle> {
        self.monitor.clone().map(MonitorHandle)
    }

    /// Replaces the bus's faults from the next burst on (the random stream restarts from their seed).
    pub fn set_faults(&self, faults: Faults) {
        if let Ok(mut slot) = self.new_faults.lock() {
            *slot = Some(faults);
        }
    }

    /// The slave end's path (e.g. `/dev/pts/5`, mode 0600) for other programs of its owner to open.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Whether the serving thread has ended (it ends only on an I/O error or a stop request).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops serving (the recording, if any, catches up and is flushed); returns the thread's I/O
    /// error, if it ended on one (the recording's included).
    pub fn stop(mut self) -> std::io::Result<()> {
        self.halt()
    }

    fn halt(&mut self) -> std::io::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(std::io::Error::other("the pty server thread panicked")),
            None => Ok(()),
        }
    }
}

impl Drop for PtyServer {
    fn drop(&mut self) {
        let _ = self.halt();
    }
}

/// What the owner and the serving thread share, and the hand's moves under way.
struct Control {
    stop: Arc<AtomicBool>,
    new_faults: Arc<Mutex<Option<Faults>>>,
    monitor: Option<Arc<Mutex<RealTimeMonitor>>>,
    hand: Arc<Mutex<HandQueue>>,
    /// (ticket, servo, when the horn gets there): moves waiting for a read of the position.
    pending: Vec<(u64, u8, u64)>,
    /// The recording, owned by the serving thread.
    recorder: Option<Recorder>,
}

impl Control {
    /// Carries out the hand's requests at `now_ns`, and reports the moves whose horn has arrived
    /// and been read since.
    fn hand(&mut self, bus: &mut SimBus, now_ns: u64) {
        let mut queue = self.hand.lock().unwrap_or_else(|e| e.into_inner());
        let requests: Vec<Hand> = queue.requests.drain(..).collect();
        for request in requests {
            match request {
                Hand::Place { id, ticks } => {
                    if let Some(servo) = bus.servo_mut(id) {
                        servo.set_position(ticks, now_ns);
                    }
                }
                Hand::Object { id, jaw } => {
                    if let Some(servo) = bus.servo_mut(id) {
                        servo.set_jaw(jaw, now_ns);
                    }
                }
                Hand::Move { ticket, id, from, to, seconds } => {
                    if let Some(i) = self.pending.iter().position(|(_, other, _)| *other == id) {
                        let (old, ..) = self.pending.remove(i);
                        let reason = format!("servo {id}: cut short by the next move of its horn");
                        queue.events.push(HandEvent { ticket: old, result: Err(reason) });
                    }
                    let moved = match bus.servo_mut(id) {
                        Some(servo) => servo.hand_move(from, to, seconds, now_ns),
                        None => Err(format!("no servo {id} on this bus")),
                    };
                    match moved {
                        Ok(end_ns) => self.pending.push((ticket, id, end_ns)),
                        Err(reason) => queue.events.push(HandEvent { ticket, result: Err(reason) }),
                    }
                }
            }
        }
        let read_since =
            |id: u8, end_ns: u64| bus.servo(id).and_then(|s| s.position_read_ns()).is_some_and(|read| read >= end_ns);
        let (done, waiting): (Vec<_>, Vec<_>) =
            self.pending.drain(..).partition(|&(_, id, end_ns)| read_since(id, end_ns));
        self.pending = waiting;
        queue.events.extend(done.into_iter().map(|(ticket, ..)| HandEvent { ticket, result: Ok(()) }));
    }

    /// Records the grid points up to `now_ns`, the thread having woken then: called before
    /// anything that changes the servos is carried out at `now_ns`.
    fn record(&mut self, bus: &SimBus, now_ns: u64) -> std::io::Result<()> {
        match &mut self.recorder {
            Some(recorder) => recorder.catch_up(bus, now_ns),
            None => Ok(()),
        }
    }

    /// The server stops at `now_ns`: the recording catches up and is flushed.
    fn finish(&mut self, bus: &SimBus, now_ns: u64) -> std::io::Result<()> {
        match &mut self.recorder {
            Some(recorder) => recorder.finish(bus, now_ns),
            None => Ok(()),
        }
    }

    /// Carries out a burst that arrived at `at_ns`, the monitor looking at the bus after each of
    /// its frames.
    fn receive(&self, bus: &mut SimBus, bytes: &[u8], at_ns: u64) -> Vec<WireByte> {
        match &self.monitor {
            Some(monitor) => {
                let mut monitor = monitor.lock().unwrap_or_else(|e| e.into_inner());
                let replies = bus.receive_observed(bytes, at_ns, &mut |bus, frame| monitor.observe(bus, frame));
                monitor.end_burst();
                replies
            }
            None => bus.receive(bytes, at_ns),
        }
    }

    /// The line went quiet ([`SimBus::line_idle`]), the monitor looking at the bus after each frame.
    fn line_idle(&self, bus: &mut SimBus) -> Vec<WireByte> {
        match &self.monitor {
            Some(monitor) => {
                let mut monitor = monitor.lock().unwrap_or_else(|e| e.into_inner());
                bus.line_idle_observed(&mut |bus, frame| monitor.observe(bus, frame))
            }
            None => bus.line_idle(),
        }
    }
}

/// Where replies go: to the master end at once, or through the adapter's latency timer.
struct Outbox {
    timer: Option<LatencyTimer>,
    /// Whether the master's own bytes come back to it ([`ServeOptions::echo`]).
    echo: bool,
}

impl Outbox {
    /// Sends `replies` produced at `now_ns`, or holds them for the timer.
    fn send(&mut self, master: &mut TTYPort, replies: &[WireByte], now_ns: u64) -> std::io::Result<()> {
        match &mut self.timer {
            Some(timer) => {
                timer.hold(replies, now_ns);
                Ok(())
            }
            None => write_out(master, replies.iter().map(|&(_, b)| b).collect()),
        }
    }

    /// Writes the held bytes that are due by `now_ns`.
    fn release(&mut self, master: &mut TTYPort, now_ns: u64) -> std::io::Result<()> {
        match &mut self.timer {
            Some(timer) => write_out(master, timer.take_due(now_ns)),
            None => Ok(()),
        }
    }

    /// How long the next read may wait: until the next release while bytes are held.
    fn wait(&self, now_ns: u64) -> Duration {
        match self.timer.as_ref().and_then(LatencyTimer::next_release_ns) {
            Some(due) => IDLE_READ.min(Duration::from_nanos(due.saturating_sub(now_ns))),
            None => IDLE_READ,
        }
    }
}

fn write_out(master: &mut TTYPort, bytes: Vec<u8>) -> std::io::Result<()> {
    if bytes.is_empty() {
        return Ok(());
    }
    // Writes wait as long as an idle read (the read timeout is the port's only timeout).
    master.set_timeout(IDLE_READ).map_err(std::io::Error::from)?;
    master.write_all(&bytes)?;
    master.flush()
}

fn elapsed_ns(start: Instant) -> u64 {
    u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// Serves until stopped. The slave end is held open (a pty without one reports errors) and asked
/// for its speed before each burst: a program that sets another baud rate (after `armctl servo
/// set-baud`, say) is then heard only by servos set to that rate, as on a real bus.
fn serve(
    master: &mut TTYPort,
    slave: &TTYPort,
    mut bus: SimBus,
    follow_baud: bool,
    mut control: Control,
    mut outbox: Outbox,
) -> std::io::Result<()> {
    let start = Instant::now();
    let mut last_rx_ns = 0;
    let mut buf = [0u8; 512];
    while !control.stop.load(Ordering::Relaxed) {
        if let Some(faults) = control.new_faults.lock().ok().and_then(|mut slot| slot.take()) {
            *bus.faults() = FaultState::new(faults);
        }
        let now_ns = elapsed_ns(start);
        // Each wake: first the recording up to now, from the servos as they stood before it.
        control.record(&bus, now_ns)?;
        control.hand(&mut bus, now_ns);
        outbox.release(master, now_ns)?;
        master.set_timeout(outbox.wait(now_ns)).map_err(std::io::Error::from)?;
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {
                // A quiet line: a packet left incomplete is dead, and what it held back is served.
                // (A shorter wait, for a release, is no sign of a quiet line.)
                let now_ns = elapsed_ns(start);
                control.record(&bus, now_ns)?;
                if bus.physics().is_some() {
                    // Physical servos are integrated step by step: kept up to date while the line
                    // is quiet, so that the next request finds them there, not a catch-up of the
                    // whole quiet time that would make it wait past its timeout.
                    bus.advance_to(now_ns);
                }
                if now_ns.saturating_sub(last_rx_ns) >= IDLE_READ.as_nanos() as u64 {
                    let replies = control.line_idle(&mut bus);
                    outbox.send(master, &replies, now_ns)?;
                }
                continue;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if n == 0 {
            continue;
        }
        if let (true, Ok(baud)) = (follow_baud, slave.baud_rate()) {
            bus.set_baud(baud);
        }
        let now_ns = elapsed_ns(start);
        control.record(&bus, now_ns)?;
        // The hand's requests made before these bytes were sent come first.
        control.hand(&mut bus, now_ns);
        last_rx_ns = now_ns;
        let replies = control.receive(&mut bus, &buf[..n], now_ns);
        if outbox.echo {
            // The adapter hears what it sent before anything the servos answer.
            let echo: Vec<WireByte> = buf[..n].iter().map(|&b| (now_ns, b)).collect();
            outbox.send(master, &echo, now_ns)?;
        }
        outbox.send(master, &replies, now_ns)?;
    }
    control.finish(&bus, elapsed_ns(start))
}

/// The bus of `arm`'s servos (its `[servos]` table, or its preset's): the joints' and the
/// gripper's, their model and protocol at its baud rate, with the safety monitor on their goal
/// limits ([`super::monitor::limits_of`]) and the arm's collision geometry when it has some
/// ([`World::of`]: links stop at contacts, the monitor records goals within the margin). A board's UART may set the pty's rate to the nearest
/// standard one: the servos stay at the arm's.
pub fn arm_bus(arm: &crate::arm::ArmSpec, faults: super::Faults) -> anyhow::Result<SimConfig> {
    let servos =
        crate::arm::servos::servos_of(arm).ok_or_else(|| anyhow::anyhow!("arm {} has no [servos] table", arm.name))?;
    Ok(SimConfig {
        protocol: servos.model.protocol,
        model: servos.model,
        ids: servos.bus_ids(),
        baud: servos.baud,
        faults,
        duplicates: Vec::new(),
        fixed_baud: true,
        burst: None,
        limits: Some(super::monitor::limits_of(arm)?),
        world: World::of(arm)?,
        physics: super::physics::ServoKind::default().physics(Some(arm))?,
    })
}

/// `arm`'s servos served on a pty at `baud` for a firmware core on this PC to drive as it drives a
/// USB adapter (`armctl serve --sim`, `armctl teleop --sim`): the servos follow the rate the
/// core sets, replies come in `burst`s as through an adapter's latency timer, and the safety
/// monitor checks every goal; `servos` physical or ideal; the links stop where they run into
/// `contact`'s bodies (the arm's own geometry, [`crate::arm::collision::collision_of`], or with
/// obstacles only the simulator knows; `None`: nothing is in the way).
pub fn serve_arm(
    arm: &crate::arm::ArmSpec,
    baud: u32,
    burst: Option<Duration>,
    servos: super::physics::ServoKind,
    contact: Option<crate::arm::collision::CollisionSpec>,
) -> anyhow::Result<PtyServer> {
    let physics = servos.physics(Some(arm))?;
    let world = contact.map(|geometry| World::new(arm, geometry)).transpose()?;
    let config =
        SimConfig { baud, fixed_baud: false, burst, physics, world, ..arm_bus(arm, super::Faults::default())? };
    PtyServer::spawn(config).map_err(|e| anyhow::anyhow!("cannot serve the simulated servos on a pseudo-terminal: {e}"))
}

/// The SO-101's bus as the built-in firmware expects it: the five joints' servos and the gripper's.
pub fn so101_bus(faults: super::Faults) -> SimConfig {
    use firmware::bus::table::STS3215;
    SimConfig {
        protocol: STS3215.protocol,
        model: &STS3215,
        ids: (1..=firmware::builtin::JOINTS as u8).chain([firmware::builtin::GRIPPER.id]).collect(),
        baud: 1_000_000,
        faults,
        duplicates: Vec::new(),
        // QEMU sets the pty to 921600 for its 1 Mbps divider; the servos stay at 1 Mbps.
        fixed_baud: true,
        burst: None,
        limits: None,
        world: None,
        // The preset's physics: the built-in arm is the SO-101 preset.
        physics: crate::arm::presets::by_name("so101")
            .ok()
            .and_then(|arm| super::physics::ServoKind::default().physics(Some(&arm)).ok().flatten()),
    }
}

#[cfg(test)]
mod tests {
    use std::io::{Read, Write};

    use firmware::bus::table::{sts3215, STS3215};

    use super::*;

    fn sts(ids: &[u8], duplicates: &[u8]) -> SimConfig {
        SimConfig {
            protocol: Protocol::Feetech,
            model: &STS3215,
            ids: ids.to_vec(),
            baud: 1_000_000,
            faults: Faults::default(),
            duplicates: duplicates.to_vec(),
            fixed_baud: false,
            burst: None,
            limits: None,
            world: None,
            physics: None,
        }
    }

    #[test]
    fn registers_reach_twins_and_all_then_hardware_errors_switch_torque_off() {
        let config = sts(&[1, 2], &[1]);
        let register = |id, item, value| Register { id, item, value };
        let options = ServeOptions {
            registers: vec![
                register(Some(1), sts3215::PRESENT_VOLTAGE, 120),
                register(None, sts3215::TORQUE_ENABLE, 1),
                register(Some(2), sts3215::PRESENT_TEMPERATURE, 80),
            ],
            hardware_errors: vec![(Some(2), 0x04)],
            ..ServeOptions::default()
        };
        let mut bus = config.build();
        options.set_up(&mut bus).unwrap();
        let of = |id: u8, item| bus.servos().iter().filter(|s| s.id() == id).map(|s| s.get(item)).collect::<Vec<_>>();
        assert_eq!(of(1, sts3215::PRESENT_VOLTAGE), [120, 120], "both servos at id 1");
        assert_eq!(of(2, sts3215::PRESENT_VOLTAGE), [74]);
        assert_eq!(of(1, sts3215::TORQUE_ENABLE), [1, 1]);
        assert_eq!(of(2, sts3215::TORQUE_ENABLE), [0], "the hardware error came after and won");
        let missing = ServeOptions { registers: vec![register(Some(7), sts3215::ID, 3)], ..ServeOptions::default() };
        assert_eq!(missing.set_up(&mut config.build()), Err("no servo 7 on this bus".to_string()));
        let refused = ServeOptions { registers: vec![register(None, sts3215::MOVING, 1)], ..ServeOptions::default() };
        assert!(PtyServer::spawn_with(config, refused).is_err(), "refused before anything is served");
    }

    #[test]
    fn an_echoing_adapter_hears_its_bytes_before_the_reply() {
        let server =
            PtyServer::spawn_with(sts(&[1], &[]), ServeOptions { echo: true, ..ServeOptions::default() }).unwrap();
        let mut port = serialport::new(server.path(), 1_000_000).timeout(Duration::from_secs(5)).open().unwrap();
        let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
        port.write_all(&ping).unwrap();
        let mut heard = [0u8; 12];
        port.read_exact(&mut heard).unwrap();
        assert_eq!(heard, [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB, 0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
        server.stop().unwrap();
    }
}
