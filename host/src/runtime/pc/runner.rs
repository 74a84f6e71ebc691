//! The control loop of the PC-hosted core, on a thread of its own: ticks at the firmware's
//! period on the PC's monotonic clock, and hands the host link's bytes to the core between ticks.
//! Nothing it waits on is the terminal or a client: the link arrives through a channel, so a slow
//! client delays only its own replies, never a tick (Klipper's host keeps the same rule).
//!
//! A tick that starts late (the PC stalled, or the previous tick overran) is run at once and the
//! slots it missed are skipped, not made up: the controller counts it as late, and its limiter
//! never steps further than one period's worth, so a stall slows the motion down instead of making
//! it jump.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use firmware::bus::master::Clock;

use crate::link::channel::CoreEnd;
use crate::link::serial::StdClock;
use crate::runtime::sil::board::SimFirmware;

/// The firmware core the loop runs: any joint count, on the PC's serial port.
pub type PcCore = Box<dyn SimFirmware + Send>;

/// Ticks the loop runs after its host has gone, at most, to write a torque change the host's last
/// command asked for (a command's reply comes before the tick that writes it).
const FINISHING_TICKS: u32 = 10;

/// Loop times kept for the median (about three hours at 100 Hz); later ones count only in the
/// totals.
const MAX_SAMPLES: usize = 1 << 20;

/// What the owner asks of the loop.
const NOTHING: u8 = 0;
const STOP: u8 = 1;
const TORQUE_OFF: u8 = 2;

/// State shared between the loop and its owner.
#[derive(Debug, Default)]
pub struct Shared {
    quit: AtomicBool,
    request: AtomicU8,
    /// A stall to inject before the next tick (µs): a test's stand-in for a PC that stops
    /// scheduling the loop.
    stall_us: AtomicU64,
    moving: AtomicBool,
    ready: AtomicBool,
    torque: AtomicBool,
    stats: Mutex<Totals>,
}

/// Counts of the loop so far.
#[derive(Clone, Debug, Default)]
struct Totals {
    ticks: u64,
    late: u64,
    first_us: Option<u64>,
    last_us: u64,
    loop_us: Vec<u32>,
}

/// What the loop has done, for the summary line and the tests.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoopSummary {
    /// Control ticks run (with an arm).
    pub ticks: u64,
    /// Ticks the controller counted late (started 1.5 periods after the one before, or overran).
    pub late: u64,
    /// Seconds from the first tick to the last.
    pub seconds: f64,
    /// Ticks per second reached.
    pub rate_hz: f64,
    /// Median time one tick spent (bus transactions and compute), ms.
    pub tick_median_ms: f64,
    /// Longest tick, ms.
    pub tick_max_ms: f64,
}

impl std::fmt::Display for LoopSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ticks in {:.2} s ({:.1} Hz), bus time per tick median {:.2} ms, max {:.2} ms, {} late",
            self.ticks, self.seconds, self.rate_hz, self.tick_median_ms, self.tick_max_ms, self.late
        )
    }
}

impl Shared {
    /// Asks the loop to stop the arm (decelerating within the limits) and hold.
    pub fn request_stop(&self) {
        self.request.store(STOP, Ordering::SeqCst);
    }

    /// Asks the loop to switch the torque off.
    pub fn request_torque_off(&self) {
        self.request.store(TORQUE_OFF, Ordering::SeqCst);
    }

    /// Makes the loop sleep `stall` before its next tick.
    pub fn stall(&self, stall: Duration) {
        self.stall_us.store(u64::try_from(stall.as_micros()).unwrap_or(u64::MAX), Ordering::SeqCst);
    }

    /// Whether the arm moves, by the last tick.
    pub fn moving(&self) -> bool {
        self.moving.load(Ordering::SeqCst)
    }

    /// Whether the core runs an arm whose torque state it knows.
    pub fn ready(&self) -> bool {
        self.ready.load(Ordering::SeqCst)
    }

    /// Whether the servos' torque is on, by the last tick.
    pub fn torque(&self) -> bool {
        self.torque.load(Ordering::SeqCst)
    }

    /// Whether a request is still waiting for the loop.
    pub fn request_pending(&self) -> bool {
        self.request.load(Ordering::SeqCst) != NOTHING
    }

    /// The loop's counts so far.
    pub fn summary(&self) -> LoopSummary {
        let Ok(t) = self.stats.lock() else { return LoopSummary::default() };
        let mut sorted = t.loop_us.clone();
        sorted.sort_unstable();
        let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0);
        let max = sorted.last().copied().unwrap_or(0);
        let seconds = t.first_us.map_or(0.0, |first| t.last_us.saturating_sub(first) as f64 * 1e-6);
        LoopSummary {
            ticks: t.ticks,
            late: t.late,
            seconds,
            rate_hz: if seconds > 0.0 { t.ticks.saturating_sub(1) as f64 / seconds } else { 0.0 },
            tick_median_ms: f64::from(median) * 1e-3,
            tick_max_ms: f64::from(max) * 1e-3,
        }
    }

    /// Asks the loop to end after its current tick.
    pub(super) fn quit(&self) {
        self.quit.store(true, Ordering::SeqCst);
    }
}

/// Runs `core` until its owner quits (or, with `end_with_host`, until the host's end of the link
/// is dropped). The clock is the one the core's bus master reads, so tick times and the master's
/// timeouts agree.
pub(super) fn run(mut core: PcCore, link: CoreEnd, mut clock: StdClock, shared: Arc<Shared>, end_with_host: bool) {
    let period = u64::from(core.period_us());
    let mut next_tick = clock.now_us();
    let mut out = Vec::new();
    // Set once the host has gone: the ticks left to write what its last command asked for.
    let mut finishing: Option<u32> = None;
    while !shared.quit.load(Ordering::SeqCst) {
        if let Some(left) = finishing.as_mut() {
            if *left == 0 || !core.torque_pending() {
                break;
            }
            *left -= 1;
        }
        let now = clock.now_us();
        if now >= next_tick {
            let stall = shared.stall_us.swap(0, Ordering::SeqCst);
            if stall > 0 {
                std::thread::sleep(Duration::from_micros(stall));
            }
            let start = clock.now_us();
            match shared.request.swap(NOTHING, Ordering::SeqCst) {
                STOP => core.stop(start),
                TORQUE_OFF => core.torque_off(start),
                _ => {}
            }
            out.clear();
            let report = core.tick(start, &mut out);
            if !send(&link, &mut out) && end_with_host {
                finishing.get_or_insert(FINISHING_TICKS);
            }
            if let Some(report) = report {
                record(&shared, start, report.loop_us, report.late);
            }
            shared.moving.store(core.moving(), Ordering::SeqCst);
            shared.ready.store(core.ready(), Ordering::SeqCst);
            shared.torque.store(core.torque(), Ordering::SeqCst);
            next_tick += period;
            let after = clock.now_us();
            if next_tick < after {
                next_tick = after;
            }
            // Bytes that came during the tick are taken before the next one, even when ticks
            // overrun back to back (a silent servo costs a bus timeout every tick): otherwise
            // the host would hear nothing for as long as the overruns last.
            while let Ok(bytes) = link.from_host.try_recv() {
                if !receive(&mut core, &link, &bytes, clock.now_us(), &mut out) && end_with_host {
                    finishing.get_or_insert(FINISHING_TICKS);
                }
            }
            continue;
        }
        match link.from_host.recv_timeout(Duration::from_micros(next_tick - now)) {
            Ok(bytes) => {
                if !receive(&mut core, &link, &bytes, clock.now_us(), &mut out) && end_with_host {
                    finishing.get_or_insert(FINISHING_TICKS);
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) if end_with_host => {
                finishing.get_or_insert(FINISHING_TICKS);
                std::thread::sleep(Duration::from_micros(next_tick - now));
            }
            // A server's link may have no client for a while: keep ticking on time.
            Err(RecvTimeoutError::Disconnected) => std::thread::sleep(Duration::from_micros(next_tick - now)),
        }
    }
}

/// Hands the host's bytes to the core and sends its replies; false once the host has gone.
fn receive(core: &mut PcCore, link: &CoreEnd, bytes: &[u8], now_us: u64, out: &mut Vec<u8>) -> bool {
    out.clear();
    core.receive(bytes, now_us, out);
    send(link, out)
}

/// Sends what the core wrote, if anything; false once the host has gone.
fn send(link: &CoreEnd, out: &mut Vec<u8>) -> bool {
    out.is_empty() || link.to_host.send(std::mem::take(out)).is_ok()
}

fn record(shared: &Shared, start_us: u64, loop_us: u32, late: bool) {
    let Ok(mut t) = shared.stats.lock() else { return };
    t.ticks += 1;
    t.late += u64::from(late);
    t.first_us.get_or_insert(start_us);
    t.last_us = start_us;
    if t.loop_us.len() < MAX_SAMPLES {
        t.loop_us.push(loop_us);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::channel;
    use crate::runtime::sil::board::{JointBounds, SimFirmware};
    use firmware::controller::{Counters, GripperState, TickReport};
    use firmware::link::session::SessionStats;

    /// A core whose every tick takes two periods (as with a servo that costs a bus timeout each
    /// tick on a short period), and which answers each chunk of bytes with the same bytes.
    struct Overrunning;

    const PERIOD_US: u32 = 2_000;

    impl SimFirmware for Overrunning {
        fn receive(&mut self, bytes: &[u8], _now_us: u64, tx: &mut Vec<u8>) {
            tx.extend_from_slice(bytes);
        }
        fn tick(&mut self, _now_us: u64, _tx: &mut Vec<u8>) -> Option<TickReport> {
            std::thread::sleep(Duration::from_micros(2 * u64::from(PERIOD_US)));
            None
        }
        fn period_us(&self) -> u32 {
            PERIOD_US
        }
        fn setpoints(&self) -> Vec<f64> {
            Vec::new()
        }
        fn measured(&self) -> Vec<f64> {
            Vec::new()
        }
        fn gripper(&self) -> Option<GripperState> {
            None
        }
        fn torque(&self) -> bool {
            false
        }
        fn bounds(&self) -> Vec<JointBounds> {
            Vec::new()
        }
        fn counters(&self) -> Option<Counters> {
            None
        }
        fn session(&self) -> SessionStats {
            SessionStats::default()
        }
        fn stop(&mut self, _now_us: u64) {}
        fn torque_off(&mut self, _now_us: u64) {}
        fn moving(&self) -> bool {
            false
        }
        fn torque_pending(&self) -> bool {
            false
        }
        fn ready(&self) -> bool {
            false
        }
    }

    /// Ticks that overrun back to back still leave room for the host: every request is answered.
    /// (Before, a late tick was followed by the next at once, and the link was never read: the
    /// host gave up on a core that was ticking.)
    #[test]
    fn the_host_is_answered_while_every_tick_overruns() {
        let (host, core) = channel::pair(Duration::from_millis(20));
        let (to_core, from_core) = host.split();
        let shared = Arc::new(Shared::default());
        let loop_shared = Arc::clone(&shared);
        let runner = std::thread::spawn(move || run(Box::new(Overrunning), core, StdClock::new(), loop_shared, false));
        for request in 0..5u8 {
            to_core.send(vec![request]).unwrap();
            let reply = from_core.recv_timeout(Duration::from_secs(5));
            assert_eq!(reply, Ok(vec![request]), "request {request} is answered");
        }
        shared.quit();
        runner.join().unwrap();
    }
}
