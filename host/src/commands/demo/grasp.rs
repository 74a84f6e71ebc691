//! How the demo's pick went, read from the ticks the SIL recorded while the pick-and-place path
//! played: when the firmware's own grasp detection said the gripper holds something, where the
//! tool and the jaw were then, whether it held on every tick until the gripper was told to open
//! at the place point, and where the simulated object ended up.

use anyhow::Result;
use firmware::controller::gripper::SQUEEZE;

use super::scenario::Scenario;
use super::{distance, tool};
use crate::arm::dof::DynArm;
use crate::arm::servos::GripperSpec;
use crate::runtime::sil::TraceSample;

/// How far from the place point (mm) the object may be set down for the pick to count: the
/// tool's tracking error is a fraction of this.
pub const PLACED_WITHIN_MM: f64 = 5.0;

/// What the grasp did.
#[derive(Clone, Debug, PartialEq)]
pub struct Grasp {
    /// When the firmware first reported holding, s from the path's start (`None`: never).
    pub at_s: Option<f64>,
    /// The tool's distance from the pick point then, mm.
    pub tool_to_pick_mm: f64,
    /// Where the jaw stopped, percent open.
    pub jaw_percent: f64,
    /// The same in millimetres between the jaws.
    pub jaw_mm: f64,
    /// The largest load while it was carried, percent of full effort.
    pub load: f64,
    /// Ticks from the grasp until the gripper was told to open.
    pub carried_ticks: usize,
    /// Of those, the ticks on which the firmware reported holding.
    pub held_ticks: usize,
    /// Of those, the ticks on which the simulated jaws touched the object.
    pub touching_ticks: usize,
    /// How long it was carried, s.
    pub carried_s: f64,
    /// The tool's distance from the place point when the gripper let go, mm.
    pub tool_to_place_mm: f64,
    /// Where the object ended up (m).
    pub object: [f64; 3],
    /// Its distance from the place point, mm.
    pub object_to_place_mm: f64,
}

impl Grasp {
    /// Whether it picked: held from the grasp to the release on every tick, and set the object
    /// down within [`PLACED_WITHIN_MM`] of the place point.
    pub fn picked(&self) -> bool {
        self.at_s.is_some()
            && self.carried_ticks > 0
            && self.held_ticks == self.carried_ticks
            && self.object_to_place_mm <= PLACED_WITHIN_MM
    }
}

fn distance_mm(a: [f64; 3], b: [f32; 3]) -> f64 {
    distance(a, b) * 1e3
}

/// The carry in `ticks`: from the first tick on which the firmware reports holding to the tick on
/// which the gripper is told to open (exclusive; the end of `ticks` if it never is). It is told
/// to open when its goal rises past where it stopped by more than the squeeze, which is when the
/// firmware lets go; until then it must hold on every tick. `None`: it never held.
pub fn carry(ticks: &[TraceSample]) -> Option<(usize, usize)> {
    let first = ticks.iter().position(|s| s.gripper.is_some_and(|g| g.holding))?;
    let stopped = ticks[first].gripper.map_or(0.0, |g| f64::from(g.opening));
    let let_go = stopped + f64::from(SQUEEZE) * 100.0;
    let release = ticks[first..]
        .iter()
        .position(|s| s.gripper.is_some_and(|g| f64::from(g.goal) > let_go))
        .map_or(ticks.len(), |i| first + i);
    Some((first, release))
}

/// Reads the grasp from `ticks` (the path's, in order), starting at `start_s`; the object ended
/// at `object`.
pub fn measure(
    ticks: &[TraceSample],
    start_s: f64,
    arm: &dyn DynArm,
    gripper: &GripperSpec,
    scenario: &Scenario,
    object: [f64; 3],
) -> Result<Grasp> {
    let holding = |s: &TraceSample| s.gripper.is_some_and(|g| g.holding);
    let object_to_place_mm = distance_mm(object, scenario.place);
    let Some((first, release)) = carry(ticks) else {
        return Ok(Grasp {
            at_s: None,
            tool_to_pick_mm: f64::NAN,
            jaw_percent: f64::NAN,
            jaw_mm: f64::NAN,
            load: 0.0,
            carried_ticks: 0,
            held_ticks: 0,
            touching_ticks: 0,
            carried_s: 0.0,
            tool_to_place_mm: f64::NAN,
            object,
            object_to_place_mm,
        });
    };
    let stopped = ticks[first].gripper.map_or(0.0, |g| f64::from(g.opening));
    let carried = &ticks[first..release];
    let last = &ticks[release.saturating_sub(1).max(first)];
    let jaw_percent = stopped;
    Ok(Grasp {
        at_s: Some(ticks[first].time - start_s),
        tool_to_pick_mm: distance_mm(tool(arm, &ticks[first].measured)?, scenario.pick),
        jaw_percent,
        jaw_mm: jaw_percent.clamp(0.0, 100.0) / 100.0 * gripper.opening_mm,
        load: carried.iter().filter_map(|s| s.gripper).map(|g| f64::from(g.load.abs())).fold(0.0, f64::max),
        carried_ticks: carried.len(),
        held_ticks: carried.iter().filter(|s| holding(s)).count(),
        touching_ticks: carried.iter().filter(|s| s.object_held == Some(true)).count(),
        carried_s: last.time - ticks[first].time,
        tool_to_place_mm: distance_mm(tool(arm, &last.measured)?, scenario.place),
        object,
        object_to_place_mm,
    })
}

/// A number for JSON: `null` where there is none (NaN).
fn finite(x: f64) -> serde_json::Value {
    if x.is_finite() {
        serde_json::json!(x)
    } else {
        serde_json::Value::Null
    }
}

impl Grasp {
    /// The grasp as a JSON object (`null` for what a missed grasp has no value for).
    pub fn json(&self, scenario: &Scenario) -> serde_json::Value {
        serde_json::json!({
            "object_mm": scenario.object_mm, "pick": scenario.pick, "place": scenario.place,
            "picked": self.picked(), "at_s": self.at_s, "tool_to_pick_mm": finite(self.tool_to_pick_mm),
            "jaw_percent": finite(self.jaw_percent), "jaw_mm": finite(self.jaw_mm), "load": self.load,
            "carried_ticks": self.carried_ticks, "held_ticks": self.held_ticks,
            "touching_ticks": self.touching_ticks, "carried_s": self.carried_s,
            "tool_to_place_mm": finite(self.tool_to_place_mm),
            "object": self.object.map(finite), "object_to_place_mm": finite(self.object_to_place_mm),
        })
    }

    /// The table's lines about the grasp.
    pub fn lines(&self, scenario: &Scenario) -> Vec<String> {
        let p = |v: [f32; 3]| format!("{:.3} {:.3} {:.3}", v[0], v[1], v[2]);
        let mut out = vec![format!(
            "Grasp: a {} mm object at the pick point ({} m), to be set down at {} m",
            scenario.object_mm.unwrap_or_default(),
            p(scenario.pick),
            p(scenario.place)
        )];
        let Some(at) = self.at_s else {
            out.push("  the gripper never held it: NOT PICKED".to_string());
            return out;
        };
        out.push(format!(
            "  closed on it at {at:.2} s, tool {:.2} mm from the pick point: jaw stopped at {:.1} % ({:.1} mm), load {:.0} %, holding",
            self.tool_to_pick_mm, self.jaw_percent, self.jaw_mm, self.load
        ));
        out.push(format!(
            "  carried {:.2} s: held on {} of {} ticks (the simulated jaws touched it on {}); told to open {:.2} mm from the place point",
            self.carried_s, self.held_ticks, self.carried_ticks, self.touching_ticks, self.tool_to_place_mm
        ));
        let verdict = if self.picked() { "picked and placed" } else { "NOT PLACED" };
        out.push(format!(
            "  object set down at {:.4} {:.4} {:.4} m, {:.2} mm from the place point: {verdict}",
            self.object[0], self.object[1], self.object[2], self.object_to_place_mm
        ));
        out
    }
}
