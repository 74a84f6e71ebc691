//! A USB serial adapter's latency timer, for the servo-to-PC direction of a bus on a pty.
//!
//! An FTDI chip does not pass each byte it receives to the PC at once: it holds them until its
//! latency timer expires (16 ms by default, 1 ms when tuned) and sends them in one USB transfer.
//! The timer is modelled here as free-running from the server's start: a byte is released at the
//! first multiple of the period after it reached the adapter. Bytes keep their order, as in the
//! chip's FIFO.

use std::collections::VecDeque;
use std::time::Duration;

use super::bus::WireByte;

/// Reply bytes held until the next expiry of the latency timer.
#[derive(Clone, Debug)]
pub struct LatencyTimer {
    period_ns: u64,
    /// Bytes and when they are released, ns, in order.
    held: VecDeque<(u64, u8)>,
}

impl LatencyTimer {
    /// A timer of `period` (at least 1 ns).
    pub fn new(period: Duration) -> Self {
        let period_ns = u64::try_from(period.as_nanos()).unwrap_or(u64::MAX).max(1);
        Self { period_ns, held: VecDeque::new() }
    }

    /// Holds `bytes` that reached the adapter at their times, or at `now_ns` when that is later
    /// (the simulator learns of some replies only after the fact).
    pub fn hold(&mut self, bytes: &[WireByte], now_ns: u64) {
        for &(t, b) in bytes {
            let arrived = t.max(now_ns);
            let release = (arrived / self.period_ns).saturating_add(1).saturating_mul(self.period_ns);
            // A later byte never overtakes an earlier one.
            let release = self.held.back().map_or(release, |&(r, _)| r.max(release));
            self.held.push_back((release, b));
        }
    }

    /// The bytes due by `now_ns`, in order.
    pub fn take_due(&mut self, now_ns: u64) -> Vec<u8> {
        let due = self.held.iter().take_while(|&&(r, _)| r <= now_ns).count();
        self.held.drain(..due).map(|(_, b)| b).collect()
    }

    /// When the next held byte is due, ns (`None` when none is held).
    pub fn next_release_ns(&self) -> Option<u64> {
        self.held.front().map(|&(r, _)| r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn bytes_wait_for_the_next_expiry_and_keep_their_order() {
        let mut timer = LatencyTimer::new(Duration::from_millis(16));
        assert_eq!(timer.next_release_ns(), None);
        timer.hold(&[(3 * MS, 1), (3 * MS + 10_000, 2)], 3 * MS);
        assert_eq!(timer.next_release_ns(), Some(16 * MS));
        assert!(timer.take_due(16 * MS - 1).is_empty());
        // A byte arriving after the expiry waits for the next one.
        timer.hold(&[(16 * MS + 5, 3)], 10 * MS);
        assert_eq!(timer.take_due(16 * MS), [1, 2]);
        assert_eq!(timer.next_release_ns(), Some(32 * MS));
        // Learnt of late: released at the first expiry after now.
        timer.hold(&[(20 * MS, 4)], 40 * MS);
        assert_eq!(timer.take_due(40 * MS), [3]);
        assert_eq!(timer.take_due(48 * MS), [4]);
        assert_eq!(timer.next_release_ns(), None);
    }

    #[test]
    fn a_byte_on_an_expiry_waits_a_whole_period() {
        let mut timer = LatencyTimer::new(Duration::from_millis(1));
        timer.hold(&[(5 * MS, 9)], 0);
        assert_eq!(timer.next_release_ns(), Some(6 * MS));
    }
}
