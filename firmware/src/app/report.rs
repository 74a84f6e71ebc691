//! The status the firmware reports: run state, joints, queue, IK, loop timing and error counters.

use heapless::Vec;

use super::Core;
use crate::controller::Mode;
use crate::link::frame::FrameStats;
use crate::link::message::{ErrorCounters, GripperStatus, IkStatus, Joints, LoopTiming, RunState, Status};
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
        let mean = self.sum_us.checked_div(self.ticks).unwrap_or(0);
        let max = core::mem::take(&mut self.max_us);
        (u32::try_from(mean).unwrap_or(u32::MAX), max)
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
        // the double-precision library a u64 to f64 conversion would pull in on the M4F.
        let time = (now_us / 1_000_000) as f32 + (now_us % 1_000_000) as f32 * 1e-6;
        let mut errors = ErrorCounters {
            link_corrupt: link.corrupt,
            link_oversized: link.oversized,
            naks: link.naks,
            ..ErrorCounters::default()
        };
        let Some(c) = self.running() else {
            return Status {
                time,
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
            };
        };
        let counters = c.counters();
        errors.bus_timeouts = counters.missing_replies;
        errors.bus_errors = counters.bus_errors;
        errors.underruns = c.underruns();
        errors.watchdog_trips = counters.watchdog_trips;
        errors.ik_failures = counters.ik_failures;
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
        }
    }
}

/// Free slots as the link reports them.
pub(super) fn free_slots(n: usize) -> u16 {
    u16::try_from(n).unwrap_or(u16::MAX)
}
