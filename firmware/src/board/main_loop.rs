//! The main loop every board runs: the host bytes its receive interrupt kept ([`RxRing`]) go to the
//! firmware, and the control tick runs on its fixed schedule. A board supplies only the hardware:
//! the ring its interrupt fills, the link's transmit side, the bus master with its clock, and how
//! to sleep until the next interrupt.
//!
//! [`MainLoop::poll`] is one pass, so the loop runs on the host too (tests); [`MainLoop::run`]
//! repeats it for ever, sleeping in between.
//!
//! # Panics
//! Nothing here panics.

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};

use super::rx_ring::RxRing;
use super::BusPort;
use crate::app::{Firmware, ReceiveLoss};
use crate::bus::master::{Clock, Master, PACKET_BUF};

/// Bytes handed to the firmware at a time.
const CHUNK: usize = 64;

/// The most received bytes one pass hands to the firmware before it turns to the control tick, so
/// that a host that never pauses (a flood, a runaway script) cannot hold the tick back for ever.
///
/// Why 512. At 1 Mbps a byte takes 10 bit times (8N1), 10 µs: 100 bytes a millisecond, 1,000 in
/// the 10 ms control period. While a byte waits, the board does not sleep between passes (see
/// [`MainLoop::run`]), so the bound does not slow the drain; it decides how much can pile up behind
/// a tick that is due. A pass is away from the ring longest while it ticks: a bus cycle, about
/// 4 ms for the SO-101's six servos at their factory return delay of 500 µs (which a board keeps),
/// 8 ms with one missing, in which 400 to 800 bytes come. A pass takes as much as the boards' ring
/// holds (511 bytes, 5.1 ms of line), so whatever the ring kept during a tick is taken before the
/// next tick, and the tick's pass and one other take more than the 1,000 bytes a period brings:
/// the bound never makes the loop fall behind a host sending at 1 Mbps; the ring may (beyond
/// 5.1 ms of ticking), and counts it. A host that waits for each reply, as armctl does, never
/// has more than one frame (256 bytes) in flight. A flood delays a due
/// tick by at most 512 bytes' work: about 5 ms when each request is answered by a reply of about
/// its length (sent at the same 1 Mbps), about 85 ms at worst, when every request is a 7-byte
/// `GetStatus` answered by a 116-byte status (5 joints, the gripper and a line given up, as
/// protocol 7 reports it: 73 of them, 74 when the pass starts on a frame's last byte). That pass
/// and a tick with every servo silent (31 ms of reply timeouts) make the longest pass: about
/// 125 ms on the F411 at 84 MHz, measured by `armctl bench loop-pass` (docs/firmware.md, "The
/// watchdog's margin"); the F411's watchdog ([`super::watchdog`]) waits at least twice
/// [`super::watchdog::WORST_PASS_US`] on the fastest LSI.
pub const DRAIN_PER_PASS: usize = 512;

/// The firmware, its bus master and its link's received bytes, on one schedule.
pub struct MainLoop<'a, const N: usize, const Q: usize, const R: usize, P, D, C, const BUF: usize = PACKET_BUF> {
    app: &'a mut Firmware<N, Q>,
    master: &'a mut Master<P, D, C, BUF>,
    rx: &'a RxRing<R>,
    /// When the next control tick is due (µs on the master's clock).
    next_tick: u64,
}

impl<'a, const N: usize, const Q: usize, const R: usize, P, D, C, const BUF: usize> MainLoop<'a, N, Q, R, P, D, C, BUF>
where
    P: Read + Write + ReadReady + BusPort,
    D: OutputPin,
    C: Clock,
{
    /// The loop, its first tick due at once.
    pub fn new(app: &'a mut Firmware<N, Q>, master: &'a mut Master<P, D, C, BUF>, rx: &'a RxRing<R>) -> Self {
        let next_tick = master.clock().now_us();
        Self { app, master, rx, next_tick }
    }

    /// The firmware the loop runs.
    pub fn firmware(&self) -> &Firmware<N, Q> {
        self.app
    }

    /// One pass: the bytes waiting go to the firmware (replies to `tx`), at most
    /// [`DRAIN_PER_PASS`] of them, then the tick if it is due. Returns when the next tick is due
    /// (µs), for the board to sleep until then (unless bytes still wait).
    pub fn poll<W: Write>(&mut self, tx: &mut W) -> u64 {
        // What the ring and the UART have lost up to now, for a status asked for below.
        self.app.set_receive_loss(ReceiveLoss { dropped: self.rx.dropped(), overruns: self.rx.overruns() });
        let mut chunk = [0u8; CHUNK];
        for _ in 0..DRAIN_PER_PASS / CHUNK {
            let n = self.rx.pop_into(&mut chunk);
            if n == 0 {
                break;
            }
            let now = self.master.clock().now_us();
            // A write error is the link's (a full or broken transmit line): the host retransmits.
            let _ = self.app.receive(chunk.get(..n).unwrap_or_default(), now, tx);
            self.follow_bus();
        }
        let now = self.master.clock().now_us();
        if now >= self.next_tick {
            let _ = self.app.tick(self.master, now, tx);
            // The next slot on the fixed schedule; missed slots are skipped, not made up.
            let period = u64::from(self.app.period_us());
            self.next_tick = (self.next_tick + period).max(self.master.clock().now_us());
        }
        self.next_tick
    }

    /// Puts the servo bus where the firmware's arm has it: after an arm on another bus was
    /// committed, the port's baud rate and the master's protocol and timing.
    fn follow_bus(&mut self) {
        let wanted = *self.app.bus();
        if wanted != *self.master.config() {
            if wanted.baud != self.master.config().baud {
                self.master.port_mut().set_baud(wanted.baud);
            }
            self.master.set_config(wanted);
        }
    }

    /// Polls for ever. Between passes `idle(next_tick, rx)` may sleep until an interrupt: it must
    /// not sleep while `rx` holds a byte or past `next_tick` (a board checks both with interrupts
    /// masked, then waits, so that a byte arriving in between still wakes it).
    pub fn run<W: Write>(mut self, tx: &mut W, mut idle: impl FnMut(u64, &RxRing<R>)) -> ! {
        loop {
            let next = self.poll(tx);
            idle(next, self.rx);
        }
    }
}
