//! What the drive commands on a rig report: typed, as one arm's are ([`crate::commands::drive::Report`]),
//! so that `--json` is the report serialised and the text its [`RigReport::text`]. Each arm's part
//! is under its name in the rig's order; positions are in the rig's world frame (m).

use firmware::link::message::RunState;
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};

use crate::commands::drive::state::StatusReport;
use crate::runtime::driver::fmt3;

/// Each arm's part of a report, by name, in the rig's order; a JSON object keyed by arm name.
#[derive(Clone, Debug, PartialEq)]
pub struct ByArm<T>(pub Vec<(String, T)>);

impl<T: Serialize> Serialize for ByArm<T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for (name, part) in &self.0 {
            map.serialize_entry(name, part)?;
        }
        map.end()
    }
}

/// A drive command's report on a rig.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum RigReport {
    /// `status`.
    Status(RigStatus),
    /// `stop`.
    Stop(RigStop),
    /// `torque`.
    Torque(RigTorque),
    /// `move`.
    Move(RigMove),
    /// `play`.
    Play(RigPlay),
}

impl RigReport {
    /// Prints the report on `out`: one line of JSON with `json`, else its [`RigReport::text`].
    pub fn print(&self, json: bool, out: &mut dyn std::io::Write) -> anyhow::Result<()> {
        if json {
            writeln!(out, "{}", serde_json::to_string(self)?)?;
        } else {
            writeln!(out, "{}", self.text())?;
        }
        Ok(())
    }

    /// The report as the command line prints it without `--json`.
    pub fn text(&self) -> String {
        match self {
            RigReport::Status(r) => r.text(),
            RigReport::Stop(r) => r.text(),
            RigReport::Torque(r) => r.text(),
            RigReport::Move(r) => r.text(),
            RigReport::Play(r) => r.text(),
        }
    }
}

/// `--rig status`: each arm's status, as `armctl status` reports it, with its tool in the world.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigStatus {
    /// The rig's name.
    pub rig: String,
    /// Each arm's.
    pub arms: ByArm<ArmStatus>,
}

/// One arm's part of [`RigStatus`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArmStatus {
    /// Its status, as one arm's `status` reports it.
    #[serde(flatten)]
    pub status: StatusReport,
    /// Its tool position in the world frame (m).
    pub tool_world: [f64; 3],
}

impl RigStatus {
    /// As printed without `--json`.
    pub fn text(&self) -> String {
        let parts: Vec<String> = self
            .arms
            .0
            .iter()
            .map(|(name, a)| {
                format!("== {name} (tool at {} m in the world frame)\n{}", fmt3(&a.tool_world), a.status.text())
            })
            .collect();
        parts.join("\n")
    }
}

/// `--rig stop`: every arm stopped, where each came to rest.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigStop {
    /// `"stop"`.
    pub command: &'static str,
    /// The rig's name.
    pub rig: String,
    /// Each arm's.
    pub arms: ByArm<ArmStopped>,
    /// What telling every arm to stop said (each arm, or which failed); text only.
    #[serde(skip)]
    pub sent: String,
}

/// One arm's part of [`RigStop`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArmStopped {
    /// Its run state after the stop.
    pub state: RunState,
    /// Its tool position in the world frame (m).
    pub tool_world: [f64; 3],
    /// Its measured joints.
    pub joints: Vec<f32>,
}

impl RigStop {
    /// As printed without `--json`.
    pub fn text(&self) -> String {
        let mut lines: Vec<String> = (self.arms.0.iter())
            .map(|(name, a)| format!("{name}: stopped, {:?} at {} m (world)", a.state, fmt3(&a.tool_world)))
            .collect();
        lines.push(format!("stop: {}", self.sent));
        lines.join("\n")
    }
}

/// `--rig torque on|off`: every arm's run state after it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigTorque {
    /// `"torque"`.
    pub command: &'static str,
    /// On or off.
    pub on: bool,
    /// The rig's name.
    pub rig: String,
    /// Each arm's run state.
    pub arms: ByArm<RunState>,
}

impl RigTorque {
    /// As printed without `--json`.
    pub fn text(&self) -> String {
        let on = if self.on { "on" } else { "off" };
        let lines: Vec<String> =
            self.arms.0.iter().map(|(name, state)| format!("{name}: torque {on}: state {state:?}")).collect();
        lines.join("\n")
    }
}

/// `--rig move`: where each moved arm's tool went.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigMove {
    /// `"move"`.
    pub command: &'static str,
    /// The rig's name.
    pub rig: String,
    /// `"one tree"` when an arm is mounted on another and every target was solved at once over
    /// every joint; absent when each arm moved as `armctl move` moves one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solved_as: Option<&'static str>,
    /// The one duration of a tree's move (s); text only.
    #[serde(skip)]
    pub tree_seconds: f64,
    /// Each moved arm's (a tree's: every arm's).
    pub arms: ByArm<ArmMoved>,
}

/// One arm's part of [`RigMove`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArmMoved {
    /// Its tool target in the world frame (m); `None` for a tree's arm without one, which kept its
    /// tool where it was.
    pub target: Option<[f64; 3]>,
    /// Its tool position reached (forward kinematics of the measured joints), world frame (m).
    pub reached: [f64; 3],
    /// The distance between the two (mm).
    pub error_mm: Option<f64>,
    /// How long its move took (s, controller time); not measured for a tree's move.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_s: Option<f64>,
    /// Its measured joints at rest.
    pub joints: Vec<f32>,
}

impl RigMove {
    /// As printed without `--json`.
    pub fn text(&self) -> String {
        let mut lines: Vec<String> = Vec::new();
        for (name, a) in &self.arms.0 {
            lines.push(match (a.target, a.error_mm, a.time_s) {
                (Some(target), Some(error), Some(took)) => format!(
                    "{name}: target {} m, reached {} m (world), error {error:.2} mm, took {took:.2} s",
                    fmt3(&target),
                    fmt3(&a.reached)
                ),
                _ => {
                    let target = a
                        .target
                        .map(|g| format!("target {} m, ", fmt3(&g)))
                        .unwrap_or_else(|| "no target, ".to_string());
                    let error = a.error_mm.map(|e| format!(", error {e:.2} mm")).unwrap_or_default();
                    format!("{name}: {target}reached {} m (world){error}", fmt3(&a.reached))
                }
            });
        }
        if self.solved_as.is_some() {
            lines.push(format!(
                "move: solved as one tree over {} arms' joints, {:.2} s",
                self.arms.0.len(),
                self.tree_seconds
            ));
        }
        lines.join("\n")
    }
}

/// `--rig play`: each arm's part of the keyframe file, played on one timeline.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigPlay {
    /// `"play"`.
    pub command: &'static str,
    /// The rig's name.
    pub rig: String,
    /// The last keyframe's time (s).
    pub trajectory_s: f64,
    /// The largest skew between the arms' playback starts (s).
    pub start_skew_s: f64,
    /// How the skew was measured.
    pub skew_from: &'static str,
    /// Each arm with columns in the file.
    pub arms: ByArm<ArmPlayedReport>,
}

/// One arm's part of [`RigPlay`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArmPlayedReport {
    /// Keyframes in its part.
    pub keyframes: usize,
    /// Keyframes pushed and acknowledged.
    pub pushed: usize,
    /// How far it ended from its last keyframe.
    pub end_error: f64,
    /// The unit of `end_error` (rad or m).
    pub end_error_unit: &'static str,
    /// Its tool position at rest, world frame (m).
    pub tool_world: [f64; 3],
    /// Its measured joints at rest.
    pub joints: Vec<f32>,
    /// Times its queue ran dry and it was started again.
    pub restarts: u32,
}

impl RigPlay {
    /// As printed without `--json`.
    pub fn text(&self) -> String {
        let mut lines: Vec<String> = (self.arms.0.iter())
            .map(|(name, a)| {
                format!(
                    "{name}: {} of {} keyframes pushed and acknowledged; tool at {} m (world), {:.4} {} from the last keyframe",
                    a.pushed,
                    a.keyframes,
                    fmt3(&a.tool_world),
                    a.end_error,
                    a.end_error_unit
                )
            })
            .collect();
        lines.push(format!(
            "play: {} arms on one timeline, {:.2} s of trajectory; start skew between the arms {:.3} ms ({})",
            self.arms.0.len(),
            self.trajectory_s,
            self.start_skew_s * 1e3,
            self.skew_from
        ));
        lines.join("\n")
    }
}
