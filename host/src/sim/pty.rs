//! A [`SimBus`] served on a pseudo-terminal, for programs that open a serial port (`armctl`, the
//! firmware under QEMU).
//!
//! A thread reads the pty's master end, feeds the bus with the real time elapsed since the server
//! started (so the servos move at their real speed) and writes the replies back at once: a pty
//! has no baud rate, so wire time and return delays are not waited out in real time (the virtual
//! clock of [`super::port`] is where timing is checked). The thread keeps the slave end open
//! too, so a client closing and reopening the path does not hang up the master end.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use firmware::bus::table::Model;
use firmware::bus::Protocol;
use serialport::{SerialPort, TTYPort};

use super::bus::SimBus;
use super::faults::{FaultState, Faults};

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
}

impl SimConfig {
    /// The bus this describes.
    pub fn build(&self) -> SimBus {
        let mut bus = SimBus::new(self.protocol, self.model, &self.ids, self.baud).with_faults(self.faults.clone());
        for &id in &self.duplicates {
            let mut twin = bus.new_servo(id);
            let at = twin.get(self.model.items.present_position) + TWIN_OFFSET_TICKS;
            twin.set_position(at, 0);
            bus.add_servo(twin);
        }
        bus
    }

    /// The bus as served on a pty: for an emulated master, a partial packet is dropped only after
    /// [`EMULATED_LINE_GAP_NS`].
    fn build_for_pty(&self) -> SimBus {
        let mut bus = self.build();
        if self.fixed_baud {
            bus.set_inter_byte_timeout(EMULATED_LINE_GAP_NS);
        }
        bus
    }
}

/// The longest gap within one packet from an emulated UART: QEMU's pty output is paced by its own
/// scheduling, with gaps of milliseconds inside a packet that a real line would not have.
pub const EMULATED_LINE_GAP_NS: u64 = 50_000_000;

/// A simulated bus on a pseudo-terminal; dropping it stops the serving thread.
#[derive(Debug)]
pub struct PtyServer {
    path: String,
    stop: Arc<AtomicBool>,
    /// New faults for the serving thread to take up (hardware-in-the-loop tests change them mid-run).
    new_faults: Arc<Mutex<Option<Faults>>>,
    thread: Option<JoinHandle<std::io::Result<()>>>,
}

impl PtyServer {
    /// Opens a pty pair and serves the bus of `config` on it.
    pub fn spawn(config: SimConfig) -> std::io::Result<PtyServer> {
        let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::from)?;
        let path = slave.name().ok_or_else(|| std::io::Error::other("the pty has no path"))?;
        // Short reads so that the thread notices a stop request quickly.
        master.set_timeout(Duration::from_millis(20)).map_err(std::io::Error::from)?;
        let stop = Arc::new(AtomicBool::new(false));
        let new_faults = Arc::new(Mutex::new(None));
        let control = Control { stop: stop.clone(), new_faults: new_faults.clone() };
        let thread = std::thread::Builder::new()
            .name("sim-servos".into())
            .spawn(move || serve(&mut master, &slave, config.build_for_pty(), !config.fixed_baud, &control))?;
        Ok(PtyServer { path, stop, new_faults, thread: Some(thread) })
    }

    /// Replaces the bus's faults from the next burst on (the random stream restarts from their seed).
    pub fn set_faults(&self, faults: Faults) {
        if let Ok(mut slot) = self.new_faults.lock() {
            *slot = Some(faults);
        }
    }

    /// The slave end's path (e.g. `/dev/pts/5`) for other programs to open.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Whether the serving thread has ended (it ends only on an I/O error or a stop request).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops serving; returns the thread's I/O error, if it ended on one.
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

/// What the owner tells the serving thread.
struct Control {
    stop: Arc<AtomicBool>,
    new_faults: Arc<Mutex<Option<Faults>>>,
}

/// Serves until stopped. The slave end is held open (a pty without one reports errors) and asked
/// for its speed before each burst: a program that sets another baud rate (after `armctl servo
/// set-baud`, say) is then heard only by servos set to that rate, as on a real bus.
fn serve(
    master: &mut TTYPort,
    slave: &TTYPort,
    mut bus: SimBus,
    follow_baud: bool,
    control: &Control,
) -> std::io::Result<()> {
    let start = Instant::now();
    let mut buf = [0u8; 512];
    while !control.stop.load(Ordering::Relaxed) {
        if let Some(faults) = control.new_faults.lock().ok().and_then(|mut slot| slot.take()) {
            *bus.faults() = FaultState::new(faults);
        }
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {
                // A quiet line: a packet left incomplete is dead, and what it held back is served.
                let replies = bus.line_idle();
                if !replies.is_empty() {
                    let bytes: Vec<u8> = replies.iter().map(|&(_, b)| b).collect();
                    master.write_all(&bytes)?;
                    master.flush()?;
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
        let now_ns = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let replies = bus.receive(&buf[..n], now_ns);
        if !replies.is_empty() {
            let bytes: Vec<u8> = replies.iter().map(|&(_, b)| b).collect();
            master.write_all(&bytes)?;
            master.flush()?;
        }
    }
    Ok(())
}

/// The SO-101's bus as the built-in firmware expects it.
pub fn so101_bus(faults: super::Faults) -> SimConfig {
    use firmware::bus::table::STS3215;
    SimConfig {
        protocol: STS3215.protocol,
        model: &STS3215,
        ids: (1..=firmware::builtin::JOINTS as u8).collect(),
        baud: 1_000_000,
        faults,
        duplicates: Vec::new(),
        // QEMU sets the pty to 921600 for its 1 Mbps divider; the servos stay at 1 Mbps.
        fixed_baud: true,
    }
}
