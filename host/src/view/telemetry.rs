//! The telemetry object: one status of the firmware, with the forward kinematics of its joints
//! for drawing, as `GET /api/status` answers and the websocket carries; [`Placement`], the frame
//! its positions are in (the arm's base frame, or a rig's world frame); and [`Latest`], where the
//! arm loops leave the newest one for every reader.

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

/// The frame the API speaks for one arm: its base frame in the one-arm view, the rig's world frame
/// (the arm's base somewhere in it) in `armctl view --rig`. Positions and orientations given to the
/// API are taken in that frame and converted to the base frame before the IK and the firmware, which
/// know only the base frame; those it answers (telemetry, the preview, a file's path) are put back in
/// it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Placement {
    base: Option<Pose<f64>>,
}

impl Placement {
    /// A rig's arm whose base is at `base` in the world frame.
    pub fn world(base: Pose<f64>) -> Self {
        Self { base: Some(base) }
    }

    /// The base in the API's frame: `None` when the API speaks the base frame.
    pub fn base(&self) -> Option<&Pose<f64>> {
        self.base.as_ref()
    }

    /// A pose of the base frame in the API's frame.
    pub fn pose(&self, local: &Pose<f64>) -> Pose<f64> {
        match &self.base {
            Some(base) => base.compose(local),
            None => *local,
        }
    }

    /// A point of the base frame in the API's frame.
    pub fn point(&self, local: [f64; 3]) -> [f64; 3] {
        match &self.base {
            Some(_) => self.pose(&Pose::from_translation(local.into())).translation.into(),
            None => local,
        }
    }

    /// A position and an orientation (unit quaternion, w first) of the API's frame in the base
    /// frame.
    pub fn to_base(&self, position: [f64; 3], orientation: Option<[f64; 4]>) -> ([f64; 3], Option<[f64; 4]>) {
        let Some(base) = &self.base else { return (position, orientation) };
        let inverse = base.inverse();
        let p: [f64; 3] = inverse.compose(&Pose::from_translation(position.into())).translation.into();
        let q = orientation.and_then(|q| {
            let rotation = Pose::rotation_from_quaternion_wxyz(q)?;
            Some(kinematics::quaternion_wxyz(&(inverse.rotation * rotation)))
        });
        (p, q.or(orientation))
    }
}

/// Every joint frame after its motion, then the tool frame, at `q`, in the API's frame.
pub fn frames(arm: &dyn DynArm, q: &[f64], placement: &Placement) -> anyhow::Result<Vec<Value>> {
    let mut frames: Vec<Value> = arm.joint_frames(q)?.iter().map(|f| frame(&placement.pose(f))).collect();
    frames.push(frame(&placement.pose(&arm.tool_pose(q)?)));
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
    /// Counts the changes of the obstacles, so a page redraws them when another client changed
    /// them.
    pub collision_version: u64,
}

/// The telemetry object of one status (see docs/view.md, the API), its positions in
/// `placement`'s frame.
pub fn telemetry(
    arm: &dyn DynArm,
    seq: u64,
    status: &Status,
    extras: &Extras,
    window: (f64, u32),
    placement: &Placement,
) -> anyhow::Result<Value> {
    let (rate_hz, max_us) = window;
    let measured: Vec<f64> = status.measured.iter().map(|&x| f64::from(x)).collect();
    let setpoints: Vec<f64> = status.setpoints.iter().map(|&x| f64::from(x)).collect();
    let frames = frames(arm, &measured, placement)?;
    let tool = placement.pose(&arm.tool_pose(&measured)?).translation;
    let tool_setpoint = placement.pose(&arm.tool_pose(&setpoints)?).translation;
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
        // How the firmware says the last move went (the line, the line then joints, joints;
        // where a line was blocked), as `armctl status` reports it.
        "last_move": status.last_move,
        // What goals are checked against, and the last collision stop (parts by index, as the
        // arm's collision geometry numbers them).
        "collision_check": status.collision_check,
        "last_collision": status.last_collision,
        "play": extras.play,
        "target": extras.target,
        "last_error": extras.last_error,
        "collision_version": extras.collision_version,
        "rate_hz": rate_hz,
    }))
}

/// The newest telemetry of each arm, numbered, for the websocket writers to wait on: a slow one
/// skips to the newest rather than falling behind. One slot in the one-arm view, one per arm in a
/// rig's (the arms' loops number their telemetry each on its own).
pub struct Latest {
    slots: Mutex<Vec<(u64, Arc<String>)>>,
    changed: Condvar,
}

impl Default for Latest {
    fn default() -> Self {
        Self::with_arms(1)
    }
}

impl Latest {
    /// Slots for `arms` arms (at least one).
    pub fn with_arms(arms: usize) -> Self {
        Self { slots: Mutex::new(vec![(0, Arc::default()); arms.max(1)]), changed: Condvar::new() }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<(u64, Arc<String>)>> {
        self.slots.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Publishes telemetry number `seq` of arm `arm`.
    pub fn publish_arm(&self, arm: usize, seq: u64, text: String) {
        let mut slots = self.lock();
        if let Some(slot) = slots.get_mut(arm) {
            *slot = (seq, Arc::new(text));
        }
        self.changed.notify_all();
    }

    /// The newest telemetry of arm `arm` and its number (0 before the first, and for no such arm).
    pub fn get_arm(&self, arm: usize) -> (u64, Arc<String>) {
        self.lock().get(arm).cloned().unwrap_or_default()
    }

    /// Waits up to `timeout` for telemetry of any arm newer than what `seen` (one number per arm)
    /// says; returns the newest of each arm that has some, in the arms' order, and notes them seen.
    pub fn wait_any_newer(&self, seen: &mut [u64], timeout: Duration) -> Vec<Arc<String>> {
        let newer = |slots: &Vec<(u64, Arc<String>)>, seen: &[u64]| {
            slots.iter().zip(seen.iter()).any(|((seq, _), seen)| seq > seen)
        };
        let slots = self.lock();
        let (slots, _) = self
            .changed
            .wait_timeout_while(slots, timeout, |slots| !newer(slots, seen))
            .unwrap_or_else(|e| e.into_inner());
        let mut out = Vec::new();
        for ((seq, text), seen) in slots.iter().zip(seen.iter_mut()) {
            if *seq > *seen {
                *seen = *seq;
                out.push(text.clone());
            }
        }
        out
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

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn a_world_target_is_taken_to_the_base_and_back() {
        // A base 0.15 m along y, turned 90 degrees about z: world +x is the base's -y.
        let base = Pose::from_xyz_rpy([0.0, 0.15, 0.0], [0.0, 0.0, std::f64::consts::FRAC_PI_2]);
        let placement = Placement::world(base);
        let (p, q) = placement.to_base([0.2, 0.15, 0.1], Some([1.0, 0.0, 0.0, 0.0]));
        assert!(close(&p, &[0.0, -0.2, 0.1]), "{p:?}");
        // The world's identity orientation is a turn of -90 degrees about the base's z.
        let half = std::f64::consts::FRAC_1_SQRT_2;
        let q = q.unwrap();
        assert!(close(&q, &[half, 0.0, 0.0, -half]) || close(&q, &[-half, 0.0, 0.0, half]), "{q:?}");
        assert!(close(&placement.point(p), &[0.2, 0.15, 0.1]));
        // The one-arm view speaks the base frame: nothing changes.
        let alone = Placement::default();
        assert_eq!(alone.to_base([0.2, 0.1, 0.3], None), ([0.2, 0.1, 0.3], None));
        assert_eq!(alone.point([0.2, 0.1, 0.3]), [0.2, 0.1, 0.3]);
    }

    #[test]
    fn a_reader_wakes_for_any_arm_and_sees_the_newest_of_each() {
        let latest = Arc::new(Latest::with_arms(2));
        let mut seen = [0, 0];
        assert!(latest.wait_any_newer(&mut seen, Duration::from_millis(10)).is_empty());
        latest.publish_arm(1, 1, "right 1".into());
        latest.publish_arm(1, 2, "right 2".into());
        let got = latest.wait_any_newer(&mut seen, Duration::from_secs(1));
        assert_eq!(got.iter().map(|t| t.as_str()).collect::<Vec<_>>(), ["right 2"]);
        assert_eq!(seen, [0, 2]);
        let writer = {
            let latest = latest.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(30));
                latest.publish_arm(0, 1, "left 1".into());
            })
        };
        let got = latest.wait_any_newer(&mut seen, Duration::from_secs(5));
        writer.join().unwrap();
        assert_eq!(got.iter().map(|t| t.as_str()).collect::<Vec<_>>(), ["left 1"]);
        assert_eq!(latest.get_arm(7).0, 0, "no such arm: nothing yet");
        assert_eq!(latest.get_arm(0).1.as_str(), "left 1");
    }
}
