//! The telemetry object: one status of the firmware, with the forward kinematics of its joints
//! for drawing, as `GET /api/status` answers and the websocket carries; and [`Latest`], where the
//! arm loop leaves the newest one for every reader.

use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use firmware::link::message::{RunState, Status};
use kinematics::Pose;
use serde_json::{json, Value};

use crate::arm::dof::DynArm;

/// A pose as the page draws it: `{"p": [x, y, z], "q": [w, x, y, z]}`.
pub fn frame(pose: &Pose<f64>) -> Value {
    json!({"p": [pose.translation.x, pose.translation.y, pose.translation.z], "q": pose.quaternion_wxyz()})
}

/// Every joint frame after its motion, then the tool frame, at `q`.
pub fn frames(arm: &dyn DynArm, q: &[f64]) -> anyhow::Result<Vec<Value>> {
    let mut frames: Vec<Value> = arm.joint_frames(q)?.iter().map(frame).collect();
    frames.push(frame(&arm.tool_pose(q)?));
    Ok(frames)
}

/// The state's name as the page shows it.
pub fn state_name(state: RunState) -> String {
    format!("{state:?}")
}

/// What the arm loop knows beside the status: the file playing, the last target, the last error.
#[derive(Default)]
pub struct Extras {
    /// `null` or the playing file's progress.
    pub play: Value,
    /// `null` or the last target sent or previewed.
    pub target: Value,
    /// The last error of a request or of playing, in words.
    pub last_error: Option<String>,
    /// Keyframe queue capacity of the firmware.
    pub queue_capacity: usize,
}

/// The telemetry object of one status (see the README's API section).
pub fn telemetry(
    arm: &dyn DynArm,
    seq: u64,
    status: &Status,
    extras: &Extras,
    window: (f64, u32),
) -> anyhow::Result<Value> {
    let (rate_hz, max_us) = window;
    let measured: Vec<f64> = status.measured.iter().map(|&x| f64::from(x)).collect();
    let setpoints: Vec<f64> = status.setpoints.iter().map(|&x| f64::from(x)).collect();
    let frames = frames(arm, &measured)?;
    let tool = arm.tool_pose(&measured)?.translation;
    let tool_setpoint = arm.tool_pose(&setpoints)?.translation;
    let e = &status.errors;
    Ok(json!({
        "seq": seq,
        "time": status.time,
        "state": state_name(status.state),
        "torque": !matches!(status.state, RunState::TorqueOff),
        "measured": measured,
        "setpoints": setpoints,
        "frames": frames,
        "tool": [tool.x, tool.y, tool.z],
        "tool_setpoint": [tool_setpoint.x, tool_setpoint.y, tool_setpoint.z],
        "tool_error_mm": (tool - tool_setpoint).norm() * 1e3,
        "loop": {"mean_us": status.timing.mean_us, "max_us": max_us, "overruns": status.timing.overruns},
        "bus_errors": {"timeouts": e.bus_timeouts, "errors": e.bus_errors, "total": e.bus_timeouts + e.bus_errors},
        "errors": e,
        "lost_servos": status.lost_servos,
        "queue": {"queued": status.queued, "free": status.free_slots, "capacity": extras.queue_capacity},
        "gripper": status.gripper.map(|g| json!({
            "percent": g.opening, "setpoint_percent": g.goal, "load": g.load, "holding": g.holding,
        })),
        "play": extras.play,
        "target": extras.target,
        "last_error": extras.last_error,
        "rate_hz": rate_hz,
    }))
}

/// The newest telemetry, numbered, for the websocket writers to wait on: a slow one skips to
/// the newest rather than falling behind.
#[derive(Default)]
pub struct Latest {
    slot: Mutex<(u64, Arc<String>)>,
    changed: Condvar,
}

impl Latest {
    /// Publishes telemetry number `seq`.
    pub fn publish(&self, seq: u64, text: String) {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        *slot = (seq, Arc::new(text));
        self.changed.notify_all();
    }

    /// The newest telemetry and its number (0 before the first).
    pub fn get(&self) -> (u64, Arc<String>) {
        self.slot.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Waits up to `timeout` for telemetry newer than `seen`.
    pub fn wait_newer(&self, seen: u64, timeout: Duration) -> Option<(u64, Arc<String>)> {
        let slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        let (slot, _) =
            self.changed.wait_timeout_while(slot, timeout, |(seq, _)| *seq <= seen).unwrap_or_else(|e| e.into_inner());
        (slot.0 > seen).then(|| slot.clone())
    }
}

/// The last second of polls: how many (the telemetry rate) and the longest control tick they
/// reported. The firmware's own maximum covers only the time since the previous status, about
/// one tick, while its mean is since start: over a second, the maximum means what it says.
pub struct LastSecond {
    polls: std::collections::VecDeque<(Instant, u32)>,
}

impl Default for LastSecond {
    fn default() -> Self {
        Self { polls: std::collections::VecDeque::with_capacity(256) }
    }
}

impl LastSecond {
    /// Counts a poll now that reported `max_us`; returns the polls and the longest tick over the
    /// last second.
    pub fn push(&mut self, max_us: u32) -> (f64, u32) {
        let now = Instant::now();
        self.polls.push_back((now, max_us));
        while self.polls.front().is_some_and(|(t, _)| now.duration_since(*t) > Duration::from_secs(1)) {
            self.polls.pop_front();
        }
        (self.polls.len() as f64, self.polls.iter().map(|(_, m)| *m).max().unwrap_or(0))
    }
}
