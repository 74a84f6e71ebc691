//! The status the firmware reports: run state, joints, queue, IK, loop timing, error counters and
//! how the last move went.

use heapless::Vec;

use super::Core;
use crate::controller::{self, Mode};
use crate::link::frame::FrameStats;
use crate::link::message::{
    CollisionCheck, CollisionStop, ErrorCounters, GripperStatus, IkStatus, Joints, LoopTiming, MoveOutcome, PathTaken,
    RunState, Status,
};
use crate::link::session::SessionStats;

/// Loop time statistics between status reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct LoopStats {
    sum_us: u64,
    ticks: u64,
    /// Longest tick since the last status.
    max_us: u32,
}

impl LoopStats {
    pub(super) fn record(&mut self, loop_us: u32) {
        self.sum_us = self.sum_us.saturating_add(u64::from(loop_us));
        self.ticks = self.ticks.saturating_add(1);
        self.max_us = self.max_us.max(loop_us);
    }

    /// Mean since start and maximum since the last call.
    fn take(&mut self) -> (u32, u32) {
        // A 32-bit division (the M4F has no 64-bit one, and compiler_builtins' costs 900 bytes of
        // flash): exact while the busy time sums to under 2^32 µs (71 minutes of it); beyond,
        // both sums lose the same low bits, which leaves the mean good to a few parts per million.
        let shift = 32u32.saturating_sub(self.sum_us.leading_zeros());
        let (sum, ticks) = ((self.sum_us >> shift) as u32, (self.ticks >> shift) as u32);
        let mean = if self.ticks == 0 { 0 } else { sum / ticks.max(1) };
        let max = core::mem::take(&mut self.max_us);
        (mean, max)
    }
}

/// The link's error counts, taken before a request is applied.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct LinkCounts {
    corrupt: u32,
    oversized: u32,
    naks: u32,
}

impl LinkCounts {
    pub(super) fn of(frames: &FrameStats, session: &SessionStats) -> Self {
        Self {
            corrupt: frames.corrupt.saturating_add(frames.unknown_kind),
            oversized: frames.oversized,
            naks: session.naks,
        }
    }
}

fn joints(values: impl Iterator<Item = f32>) -> Joints {
    let mut out = Vec::new();
    for v in values {
        // N is at most MAX_JOINTS (checked when the firmware is built): no value is dropped.
        let _ = out.push(v);
    }
    out
}

impl<const N: usize, const Q: usize> Core<N, Q> {
    /// The status at `now_us`; resets the "max since last status" loop time.
    #[inline(never)]
    pub(super) fn status(&mut self, now_us: u64, link: LinkCounts) -> Status {
        let (mean_us, max_us) = self.loops.take();
        // Whole seconds and the rest apart, in f32: the same time to f32's precision, without
        // the double-precision library a u64 to f64 conversion would pull in on the M4F. The
        // high word (each 2^32 µs, 71.6 minutes) apart too, so every division is a 32-bit one:
        // the M4F has no 64-bit divide, and compiler_builtins' costs 900 bytes of flash.
        let (high, low) = ((now_us >> 32) as u32, now_us as u32);
        let time = high as f32 * 4_294.967_3 + (low / 1_000_000) as f32 + (low % 1_000_000) as f32 * 1e-6;
        let mut errors = ErrorCounters {
            link_corrupt: link.corrupt,
            link_oversized: link.oversized,
            naks: link.naks,
            link_dropped: self.receive_loss.dropped,
            link_overruns: self.receive_loss.overruns,
            ..ErrorCounters::default()
        };
        let Some(c) = self.running() else {
            return Status {
                time,
                play_time: 0.0,
                state: RunState::TorqueOff,
                measured: Joints::new(),
                setpoints: Joints::new(),
                queued: 0,
                free_slots: 0,
                ik: IkStatus { converged: false, iterations: 0, position_error: 0.0, orientation_error: 0.0 },
                timing: LoopTiming { mean_us, max_us, overruns: 0 },
                errors,
                lost_servos: 0,
                gripper: None,
                last_move: None,
                largest_pass: 0.0,
                collision_check: CollisionCheck::NoGeometry,
                last_collision: None,
            };
        };
        let counters = c.counters();
        errors.bus_timeouts = counters.missing_replies;
        errors.bus_errors = counters.bus_errors;
        errors.underruns = c.underruns();
        errors.watchdog_trips = counters.watchdog_trips;
        errors.ik_failures = counters.ik_failures;
        errors.line_fallbacks = counters.line_fallbacks;
        let state = match c.mode() {
            Mode::Idle => RunState::TorqueOff,
            // Holding a goal the setpoint has not reached yet (the limits made it lag): moving.
            Mode::Holding if c.setpoint().velocity.iter().any(|v| *v != 0.0) => RunState::Moving,
            Mode::Holding => RunState::Idle,
            Mode::Playing if c.paused() => RunState::Paused,
            Mode::Playing | Mode::Tracking => RunState::Moving,
            Mode::Stopping => RunState::Stopping,
            Mode::EStopped if c.torque() => RunState::EStopped,
            Mode::EStopped => RunState::TorqueOff,
        };
        let ik = c.last_ik().map_or(
            IkStatus { converged: false, iterations: 0, position_error: 0.0, orientation_error: 0.0 },
            |s| IkStatus {
                converged: s.converged,
                iterations: u16::try_from(s.iterations).unwrap_or(u16::MAX),
                position_error: s.position_error,
                orientation_error: s.orientation_error,
            },
        );
        let lost_servos = c.health().iter().enumerate().fold(0u32, |acc, (j, h)| acc | (u32::from(h.lost) << j));
        Status {
            time,
            play_time: if c.mode() == Mode::Playing { c.play_time_at(now_us) } else { 0.0 },
            state,
            // The arm's own joints only: the padding after them is not the host's.
            measured: joints(c.measured().iter().copied().take(c.joints())),
            setpoints: joints(c.setpoint().position.iter().copied().take(c.joints())),
            queued: u16::try_from(c.queued()).unwrap_or(u16::MAX),
            free_slots: free_slots(c.free_slots()),
            ik,
            timing: LoopTiming { mean_us, max_us, overruns: counters.deadline_misses },
            errors,
            lost_servos,
            gripper: c.gripper().map(|g| GripperStatus {
                opening: g.opening,
                goal: g.goal,
                load: g.load,
                holding: g.holding,
            }),
            last_move: c.last_move().map(|m| MoveOutcome {
                path: match m.path {
                    controller::PathTaken::Line => PathTaken::Line,
                    controller::PathTaken::LineThenJoints => PathTaken::LineThenJoints,
                    controller::PathTaken::Joints => PathTaken::Joints,
                    controller::PathTaken::LineStopped => PathTaken::LineStopped,
                    controller::PathTaken::CollisionStopped => PathTaken::CollisionStopped,
                },
                blocked_at: m.blocked_at,
                line_length: m.line_length,
            }),
            largest_pass: c.largest_pass(),
            collision_check: collision_check(c.collision()),
            last_collision: c.collision().last().map(|stop| CollisionStop {
                body: stop.contact.body,
                other: stop.contact.other.into(),
                distance: stop.contact.distance,
                count: stop.count,
            }),
        }
    }
}

/// What goals are checked against, as the link reports it.
fn collision_check(guard: &controller::Guard) -> CollisionCheck {
    let scene = guard.scene();
    if scene.is_empty() {
        CollisionCheck::NoGeometry
    } else if guard.requested() {
        let count = |n: usize| u8::try_from(n).unwrap_or(u8::MAX);
        CollisionCheck::On { bodies: count(scene.bodies().len()), obstacles: count(scene.obstacles().len()) }
    } else {
        CollisionCheck::Off
    }
}

/// Free slots as the link reports them.
pub(super) fn free_slots(n: usize) -> u16 {
    u16::try_from(n).unwrap_or(u16::MAX)
}

#[cfg(test)]
mod tests {
    use super::LoopStats;

    /// The mean is the 64-bit division's while the sum fits 32 bits, and within a few parts per
    /// million of it far beyond; nothing recorded gives 0.
    #[test]
    fn the_mean_loop_time_without_a_64_bit_division() {
        let mut stats = LoopStats::default();
        assert_eq!(stats.take(), (0, 0));
        for us in [900, 1_000, 1_203] {
            stats.record(us);
        }
        assert_eq!(stats.take(), (1_034, 1_203));
        assert_eq!(stats.take(), (1_034, 0), "the maximum is since the last status, the mean since start");
        for (sum_us, ticks) in [(u64::from(u32::MAX), 3_000_000), (1 << 40, 123_456_789), (u64::MAX / 2, 1 << 50)] {
            let mut stats = LoopStats { sum_us, ticks, max_us: 0 };
            let exact = (sum_us / ticks) as f64;
            let (mean, _) = stats.take();
            assert!((f64::from(mean) - exact).abs() <= exact * 1e-5 + 1.0, "{sum_us} / {ticks}: {mean} for {exact}");
        }
    }
}
