//! `armctl demo --rig bimanual-so101`: the demo's second scene, a handover between two arms in
//! software in the loop, both firmware cores on one virtual clock ([`crate::runtime::sil::group`]).
//!
//! The first arm's gripper picks an object from the table on its side, carries it to a point
//! between the arms and holds it there; the second arm's gripper comes to the same point from the
//! other side, closes on it, the first lets go and backs off, and the second carries it to its own
//! side and sets it down. The two tool points meet 8 mm apart, each 4 mm off the object's centre
//! on its own side (the simulated object slides between jaws within [`crate::sim::scene::REACH_M`]
//! of it; the jaws themselves are points, so nothing keeps them from meeting).
//!
//! The whole motion is one rig keyframe file (Cartesian columns in the world frame for both arms,
//! the grippers' openings in them), played by the rig's own `play` ([`crate::rig::play`]): the
//! same path `armctl --rig FILE play` takes. The object is one, shared by both grippers' scenes
//! ([`crate::sim::Scene::for_gripper`]). Reported: each gripper's grasp (when it closed on the
//! object, where the jaw stopped, the load, whether it held on every tick it was meant to), how
//! long both held it at once, where the object ended against the place point, the start skew, and
//! the safety monitor of both arms.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;

use super::{columns, play, Rig, RigSpec};
use crate::arm::servos::GripperSpec;
use crate::runtime::connection::Target;
use crate::runtime::sil::TraceSample;
use crate::sim::Scene;

/// The object (mm): as in the one-arm demo.
const OBJECT_MM: f64 = 30.0;
/// Where the first arm picks the object up, where they hand it over and where the second sets it
/// down (world frame, m; the built-in rig's bases are at y = +-0.15, facing +x).
const PICK: [f64; 3] = [0.24, 0.10, 0.03];
const HANDOVER: [f64; 3] = [0.26, 0.0, 0.16];
const PLACE: [f64; 3] = [0.24, -0.10, 0.03];
/// Each tool point's offset from the object's centre at the handover, along y towards its own
/// arm (m).
const SIDE: f64 = 0.004;
/// Height of the approach above the pick and place points (m).
const ABOVE: f64 = 0.06;
/// Keyframe spacing on the timeline (s).
const SPACING: f64 = 0.1;
/// The object counts as placed within this of the place point (mm), as in the one-arm demo.
const PLACED_WITHIN_MM: f64 = crate::commands::demo::grasp::PLACED_WITHIN_MM;
/// Openings (percent).
const OPEN: f64 = 100.0;
const CLOSED: f64 = 0.0;

/// A waypoint: time on the timeline (s), tool position (world, m), gripper opening (%).
type Waypoint = (f64, [f64; 3], f64);

fn offset(p: [f64; 3], d: [f64; 3]) -> [f64; 3] {
    [p[0] + d[0], p[1] + d[1], p[2] + d[2]]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// The two arms' waypoints from their tools' start positions (world): the giver's and the taker's.
fn waypoints(giver_start: [f64; 3], taker_start: [f64; 3]) -> (Vec<Waypoint>, Vec<Waypoint>) {
    let up = [0.0, 0.0, ABOVE];
    let giver_at = offset(HANDOVER, [0.0, SIDE, 0.0]);
    let taker_at = offset(HANDOVER, [0.0, -SIDE, 0.0]);
    // The taker carries the object 2 * SIDE off its tool point: its tool goes that far short of
    // the place point.
    let taker_place = offset(PLACE, [0.0, -2.0 * SIDE, 0.0]);
    let giver = vec![
        (0.0, giver_start, OPEN),
        (1.5, offset(PICK, up), OPEN),
        (2.5, PICK, OPEN),
        (3.5, PICK, CLOSED),
        (3.9, PICK, CLOSED),
        (4.9, offset(PICK, up), CLOSED),
        (6.5, giver_at, CLOSED),
        (9.4, giver_at, CLOSED),
        (10.4, giver_at, OPEN),
        (10.8, giver_at, OPEN),
        (11.8, offset(giver_at, [-0.03, 0.06, 0.0]), OPEN),
        (13.3, giver_start, OPEN),
    ];
    let taker_wait = offset(taker_at, [-0.03, -0.06, 0.0]);
    let taker = vec![
        (0.0, taker_start, OPEN),
        (1.5, taker_wait, OPEN),
        (6.6, taker_wait, OPEN),
        (8.0, taker_at, OPEN),
        (9.0, taker_at, CLOSED),
        (10.8, taker_at, CLOSED),
        (12.3, offset(taker_place, up), CLOSED),
        (13.1, taker_place, CLOSED),
        (14.1, taker_place, OPEN),
        (14.3, taker_place, OPEN),
        (15.1, offset(taker_place, up), OPEN),
    ];
    (giver, taker)
}

/// The waypoints' straight lines sampled at `t` (held after the last).
fn sample(path: &[Waypoint], t: f64) -> ([f64; 3], f64) {
    for pair in path.windows(2) {
        let ((t0, a, ga), (t1, b, gb)) = (pair[0], pair[1]);
        if t <= t1 {
            let u = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
            return ([0, 1, 2].map(|i| a[i] + u * (b[i] - a[i])), ga + u * (gb - ga));
        }
    }
    let (_, p, g) = path[path.len() - 1];
    (p, g)
}

/// The rig keyframe file of both paths: one row every [`SPACING`] s from the first, Cartesian
/// columns in the world frame.
fn keyframe_file(names: [&str; 2], paths: [&[Waypoint]; 2]) -> String {
    let end = paths.iter().map(|p| p[p.len() - 1].0).fold(0.0, f64::max);
    let mut text = String::from("t");
    for name in names {
        text += &format!(",{name}.x,{name}.y,{name}.z,{name}.gripper");
    }
    text.push('\n');
    let rows = (end / SPACING).round() as usize;
    for k in 1..=rows {
        let t = k as f64 * SPACING;
        text += &format!("{t:.3}");
        for path in paths {
            let (p, g) = sample(path, t);
            text += &format!(",{:.6},{:.6},{:.6},{g:.2}", p[0], p[1], p[2]);
        }
        text.push('\n');
    }
    text
}

/// One gripper's part in the handover, read from its board's ticks.
struct Hold {
    /// When its firmware first reported holding (s on the virtual clock), and when it was told
    /// to open after that.
    from_s: Option<f64>,
    until_s: f64,
    /// Where the jaw stopped (%), and the largest load while holding (% of full effort).
    jaw_percent: f64,
    load: f64,
    /// Ticks between the two, and those on which it reported holding.
    ticks: usize,
    held: usize,
}

impl Hold {
    fn measure(trace: &[TraceSample]) -> Hold {
        let holding = |s: &TraceSample| s.gripper.is_some_and(|g| g.holding);
        let Some((first, release)) = crate::commands::demo::grasp::carry(trace) else {
            return Hold { from_s: None, until_s: f64::NAN, jaw_percent: f64::NAN, load: 0.0, ticks: 0, held: 0 };
        };
        let stopped = trace[first].gripper.map_or(0.0, |g| f64::from(g.opening));
        let carried = &trace[first..release];
        Hold {
            from_s: Some(trace[first].time),
            until_s: trace[release.saturating_sub(1).max(first)].time,
            jaw_percent: stopped,
            load: carried.iter().filter_map(|s| s.gripper).map(|g| f64::from(g.load.abs())).fold(0.0, f64::max),
            ticks: carried.len(),
            held: carried.iter().filter(|s| holding(s)).count(),
        }
    }

    fn ok(&self) -> bool {
        self.from_s.is_some() && self.ticks > 0 && self.held == self.ticks
    }

    fn json(&self, gripper: &GripperSpec) -> serde_json::Value {
        json!({"held_from_s": self.from_s, "told_to_open_s": self.from_s.map(|_| self.until_s),
               "jaw_percent": self.from_s.map(|_| self.jaw_percent),
               "jaw_mm": self.from_s.map(|_| self.jaw_percent.clamp(0.0, 100.0) / 100.0 * gripper.opening_mm),
               "load": self.load, "ticks": self.ticks, "held_ticks": self.held, "held_throughout": self.ok()})
    }

    fn line(&self, name: &str, role: &str, gripper: &GripperSpec) -> String {
        match self.from_s {
            None => format!("  {name} ({role}): never held the object"),
            Some(from) => format!(
                "  {name} ({role}): held it from {from:.2} s to {:.2} s: jaw stopped at {:.1} % ({:.1} mm), load up to {:.0} %, \
                 holding on {} of {} ticks",
                self.until_s,
                self.jaw_percent,
                self.jaw_percent.clamp(0.0, 100.0) / 100.0 * gripper.opening_mm,
                self.load,
                self.held,
                self.ticks
            ),
        }
    }
}

/// Runs the handover on the rig `name` (every arm simulated, the first two with grippers);
/// returns the exit code: 0 when both held throughout, the object ended within
/// [`PLACED_WITHIN_MM`] of the place point, and the monitors saw no violation.
pub fn run(name: &str, json_out: bool, out: &mut dyn Write) -> Result<i32> {
    let wall = Instant::now();
    let spec = RigSpec::load(name)?;
    spec.refuse_mounts("the handover demo")?;
    if spec.arms.len() != 2 {
        bail!("rig {}: the handover takes two arms; this rig has {}", spec.name, spec.arms.len());
    }
    for arm in &spec.arms {
        if !matches!(arm.place.target_and_arm()?.0, Target::Sim(_)) {
            bail!(
                "rig {}: arm {} is not simulated (sim = true): the demo runs in software in the loop",
                spec.name,
                arm.name
            );
        }
    }
    let mut quiet = std::io::sink();
    let mut rig = Rig::open(&spec, &mut quiet)?;
    // The grippers meet on the object; the rest of each arm is still an obstacle for the other.
    rig.hands_meet.push([0, 1]);
    let group = rig.sim.clone().context("the rig's simulated boards")?;
    let mut grippers = Vec::new();
    for (i, arm) in rig.arms.iter().enumerate() {
        let gripper = group.board(i).gripper().with_context(|| format!("arm {}", arm.name))?;
        grippers.push(gripper);
    }
    // One object, each gripper's scene of it, each arm's tool placed by its base.
    let giver_scene = Scene::new(&grippers[0], OBJECT_MM, PICK)?;
    let taker_scene = giver_scene.for_gripper(&grippers[1])?;
    for (i, scene) in [giver_scene, taker_scene].into_iter().enumerate() {
        let model = crate::arm::dof::build(rig.arms[i].driver.arm().clone())?;
        group.board(i).share_object(model, rig.arms[i].base, scene)?;
        group.board(i).record();
    }
    let mut starts = Vec::new();
    for i in 0..rig.arms.len() {
        let status = rig.arms[i].driver.status()?;
        starts.push(rig.tool_in_world(i, &status.measured)?);
    }
    let (giver, taker) = waypoints(starts[0], starts[1]);
    let owned = [rig.arms[0].name.clone(), rig.arms[1].name.clone()];
    let names = [owned[0].as_str(), owned[1].as_str()];
    let text = keyframe_file(names, [&giver, &taker]);
    let bases = [rig.arms[0].base, rig.arms[1].base];
    let parts = columns::split(&text, std::path::Path::new("handover"), &names, &bases, 30.0)?;
    let t_start = group.now_s();
    let Some(played) = play::play(&mut rig, parts, &mut quiet)? else {
        bail!("interrupted");
    };
    let traces: Vec<Vec<TraceSample>> = (0..2).map(|i| group.board(i).take_trace()).collect();
    let holds: Vec<Hold> = traces.iter().map(|t| Hold::measure(t)).collect();
    let object = group.board(1).object().map(Scene::position).unwrap_or([f64::NAN; 3]);
    let to_place_mm = distance(object, PLACE) * 1e3;
    let both_s = match (holds[0].from_s, holds[1].from_s) {
        (Some(a), Some(b)) => (holds[0].until_s.min(holds[1].until_s) - a.max(b)).max(0.0),
        _ => 0.0,
    };
    let monitors: Vec<_> = (0..2).map(|i| group.board(i).monitor().clone()).collect();
    let violations: u64 = monitors.iter().map(|m| m.violation_count).sum();
    let simulated_s = group.now_s() - t_start;
    let wall_s = wall.elapsed().as_secs_f64();
    let handed = holds.iter().all(Hold::ok) && both_s > 0.0 && to_place_mm <= PLACED_WITHIN_MM;
    if json_out {
        let arms: serde_json::Map<String, serde_json::Value> = (0..2)
            .map(|i| {
                let a = &played.arms[i];
                (
                    rig.arms[i].name.clone(),
                    json!({"role": if i == 0 { "gives" } else { "takes" }, "grasp": holds[i].json(&grippers[i]),
                           "keyframes": a.keyframes, "pushed": a.pushed, "end_error_m": a.end_error.0,
                           "safety": {"goals_checked": monitors[i].checked, "violations": monitors[i].violation_count,
                                      "largest_step_of_limit": monitors[i].max_step_ratio}}),
                )
            })
            .collect();
        let v = json!({"rig": rig.name, "object_mm": OBJECT_MM, "pick": PICK, "handover": HANDOVER, "place": PLACE,
                       "arms": arms, "both_held_s": both_s, "object": object, "object_to_place_mm": to_place_mm,
                       "handed_over": handed, "start_skew_s": played.skew_s, "violations": violations,
                       "simulated_s": simulated_s, "wall_s": wall_s});
        writeln!(out, "{v}")?;
    } else {
        writeln!(
            out,
            "armctl demo --rig {}: {} arms ({}), each with its own firmware core in software in the loop, one virtual clock",
            rig.name,
            rig.arms.len(),
            rig.arms.iter().map(|a| format!("{}: {}", a.name, a.driver.arm().name)).collect::<Vec<_>>().join(", ")
        )?;
        writeln!(
            out,
            "Handover: a {OBJECT_MM} mm object picked at {:?} m by {}, handed over at {:?} m, set down at {:?} m by {} (world frame)",
            PICK, names[0], HANDOVER, PLACE, names[1]
        )?;
        writeln!(out, "{}", holds[0].line(names[0], "gives", &grippers[0]))?;
        writeln!(out, "{}", holds[1].line(names[1], "takes", &grippers[1]))?;
        writeln!(out, "  both held it for {both_s:.2} s")?;
        writeln!(
            out,
            "  object set down at {:.4} {:.4} {:.4} m, {to_place_mm:.2} mm from the place point: {}",
            object[0],
            object[1],
            object[2],
            if handed { "handed over and placed" } else { "NOT HANDED OVER" }
        )?;
        writeln!(
            out,
            "Timeline: {} + {} Cartesian keyframes, {:.1} s; start skew between the arms {:.3} ms",
            played.arms[0].pushed,
            played.arms[1].pushed,
            played.seconds,
            played.skew_s * 1e3
        )?;
        for (i, m) in monitors.iter().enumerate() {
            writeln!(
                out,
                "Safety monitor, {}: {} goals checked, {} violations, largest step {:.0}% of the velocity limit",
                names[i],
                m.checked,
                m.violation_count,
                m.max_step_ratio * 100.0
            )?;
        }
        writeln!(out, "{simulated_s:.1} s simulated in {wall_s:.2} s")?;
    }
    Ok(if handed && violations == 0 { 0 } else { 1 })
}
