//! `armctl --rig FILE play KEYFRAMES.csv`: every arm's keyframes on one timeline.
//!
//! Each arm's part of the file ([`super::columns`]) is checked against its arm first, so a bad file
//! sends nothing to any arm. Then every arm's queue is filled, the arms are started one right after
//! the other, and each arm's queue is topped up as its slots free, as `armctl play` does for one.
//! A push one arm refuses stops every arm. The skew between the arms is measured: the times at
//! which their playback clocks started, read from each status as the controller time less the
//! playback time. On simulated arms (one virtual clock) that is exact; on boards, whose clocks
//! differ, the host's time between the first and the last `Start` acknowledgement is reported
//! instead.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Result};
use firmware::link::message::{RunState, Status};

use super::clearance::{self, Verdict};
use super::columns::ArmPart;
use super::report::{ArmPlayedReport, ByArm, RigPlay, RigReport};
use super::Rig;
use crate::link::collision::stop;
use crate::link::session::seconds_waited;
use crate::link::session::Keyframe;
use crate::support::interrupt;

/// One arm's playback.
struct Track {
    arm: usize,
    messages: Vec<(usize, Keyframe)>,
    pushed: usize,
    switched: bool,
    /// Controller time at which its playback clock was zero, as first seen (s).
    origin: Option<f64>,
    last: Option<Status>,
    restarts: u32,
    /// The firmware's count of collision stops when the play began.
    collision_stops: Option<u32>,
}

/// Pushes one keyframe to arm `arm`; fails unless it was acknowledged.
fn push(rig: &mut Rig, arm: usize, keyframe: &Keyframe) -> Result<()> {
    Ok(rig.arms[arm].driver.session().push(keyframe)?)
}

/// Stops every arm (each stop sent before waiting for any); words for an error message.
pub fn stop_all(rig: &mut Rig) -> String {
    let failed: Vec<String> = rig
        .arms
        .iter_mut()
        .filter_map(|a| a.driver.session().stop().err().map(|e| format!("{}: {e}", a.name)))
        .collect();
    if failed.is_empty() {
        "every arm was stopped".to_string()
    } else {
        format!("stop failed on {}", failed.join("; "))
    }
}

/// How one arm's part went.
pub struct ArmPlayed {
    /// The arm's index in the rig.
    pub arm: usize,
    /// Keyframes in its part, and pushed (all of them unless the play failed).
    pub keyframes: usize,
    /// Keyframes pushed and acknowledged.
    pub pushed: usize,
    /// Its status at rest after the play.
    pub last: Status,
    /// How far it ended from its last keyframe, and the unit (rad or m).
    pub end_error: (f64, &'static str),
    /// Times its queue ran dry and it was started again.
    pub restarts: u32,
    /// Whether this play switched its torque on.
    pub switched: bool,
}

/// How a rig play went.
pub struct Played {
    /// Each arm with columns, in the file's order of arms.
    pub arms: Vec<ArmPlayed>,
    /// The last keyframe's time (s).
    pub seconds: f64,
    /// The largest skew between the arms' playback starts (s), and how it was measured.
    pub skew_s: f64,
    /// How the skew was measured.
    pub skew_from: &'static str,
}

/// Plays the parts on their arms and prints the report (`json`: one line of JSON); returns the
/// exit code (130 after Ctrl-C stopped every arm).
pub fn run(rig: &mut Rig, parts: Vec<ArmPart>, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let Some(report) = report(rig, parts, err)? else {
        return Ok(interrupt::EXIT_CODE);
    };
    RigReport::Play(report).print(json, out)?;
    Ok(0)
}

/// Plays the parts on their arms and reports how each went; `None` after Ctrl-C (every arm
/// stopped).
pub fn report(rig: &mut Rig, parts: Vec<ArmPart>, err: &mut dyn Write) -> Result<Option<RigPlay>> {
    let Some(played) = play(rig, parts, err)? else {
        return Ok(None);
    };
    let mut arms = Vec::new();
    for a in &played.arms {
        let tool_world = rig.tool_in_world(a.arm, &a.last.measured)?;
        let report = ArmPlayedReport {
            keyframes: a.keyframes,
            pushed: a.pushed,
            end_error: a.end_error.0,
            end_error_unit: a.end_error.1,
            tool_world,
            joints: a.last.measured.to_vec(),
            restarts: a.restarts,
        };
        arms.push((rig.arms[a.arm].name.clone(), report));
    }
    Ok(Some(RigPlay {
        command: "play",
        rig: rig.name.clone(),
        trajectory_s: played.seconds,
        start_skew_s: played.skew_s,
        skew_from: played.skew_from,
        arms: ByArm(arms),
    }))
}

/// Plays the parts on their arms: checked, queued, started together, topped up, waited for.
/// `None` after Ctrl-C (every arm stopped). Warnings go to `err`.
pub fn play(rig: &mut Rig, mut parts: Vec<ArmPart>, err: &mut dyn Write) -> Result<Option<Played>> {
    let seconds = parts.iter().map(|p| p.plan.seconds()).fold(0.0, f64::max);
    let timeout = parts.iter().map(|p| p.plan.timeout()).fold(0.0, f64::max);
    let mut tracks = Vec::new();
    for part in &parts {
        let driver = &rig.arms[part.arm].driver;
        let messages = part.plan.keyframes(driver)?;
        tracks.push(Track {
            arm: part.arm,
            messages,
            pushed: 0,
            switched: false,
            origin: None,
            last: None,
            restarts: 0,
            collision_stops: None,
        });
    }
    for (t, part) in tracks.iter_mut().zip(&parts) {
        let arm = &mut rig.arms[t.arm];
        let status = arm.driver.status()?;
        if !matches!(status.state, RunState::Idle | RunState::TorqueOff) {
            bail!("arm {} is busy ({:?}): wait, or `stop` it first; nothing was sent", arm.name, status.state);
        }
        t.collision_stops = status.last_collision.map(|c| c.count);
        // Each arm's own path against its own geometry, as `armctl play` checks one arm's.
        let measured: Vec<f64> = status.measured.iter().map(|&x| f64::from(x)).collect();
        if let Err(e) = part.plan.check_collisions(&arm.driver, &measured) {
            bail!("arm {}: {e:#}", arm.name);
        }
    }
    // Each arm an obstacle for the others: the whole timeline checked before anything moves, and
    // cut where two arms would come too close, so that every arm stops short of it.
    let stop_short = keep_clear(rig, &mut parts, &mut tracks)?;
    for i in 0..tracks.len() {
        let arm = &mut rig.arms[tracks[i].arm];
        match arm.driver.ready_to_move() {
            Ok((status, switched)) => {
                tracks[i].switched = switched;
                if status.queued > 0 {
                    arm.driver.session().stop()?;
                    writeln!(err, "{}: dropped {} keyframes left in the queue from before", arm.name, status.queued)?;
                }
            }
            Err(e) => {
                let name = arm.name.clone();
                undo_torque(rig, &tracks);
                bail!("arm {name}: {e:#}");
            }
        }
    }
    interrupt::catch();
    // Every queue filled before any start, so the starts do not wait on the links.
    for i in 0..tracks.len() {
        let a = tracks[i].arm;
        let capacity = rig.arms[a].driver.queue_capacity().max(1);
        while tracks[i].pushed < tracks[i].messages.len().min(capacity)
            && (tracks[i].pushed == 0 || rig.arms[a].driver.free_slots() > 0)
        {
            let (line, message) = &tracks[i].messages[tracks[i].pushed];
            if let Err(e) = push(rig, a, message) {
                let at = parts[i].plan.at(*line);
                let stopped = stop_all(rig);
                undo_torque(rig, &tracks);
                bail!("{at}: {e:#}; nothing moved ({stopped}, the queued keyframes dropped)");
            }
            tracks[i].pushed += 1;
        }
    }
    let mut start_acks = Vec::new();
    for t in &tracks {
        rig.arms[t.arm].driver.session().start()?;
        start_acks.push(Instant::now());
    }
    let host_gap_s = match (start_acks.first(), start_acks.last()) {
        (Some(first), Some(last)) => last.duration_since(*first).as_secs_f64(),
        _ => 0.0,
    };
    let started = Instant::now();
    // Each arm's controller time at its first status, for the timeout.
    let mut first_time: Vec<f32> = Vec::new();
    loop {
        if interrupt::requested() {
            let stopped = stop_all(rig);
            writeln!(err, "stopped by Ctrl-C: {stopped}")?;
            return Ok(None);
        }
        let mut pushed_any = false;
        for i in 0..tracks.len() {
            let a = tracks[i].arm;
            if tracks[i].pushed < tracks[i].messages.len() && rig.arms[a].driver.free_slots() > 0 {
                let (line, message) = &tracks[i].messages[tracks[i].pushed];
                if let Err(e) = push(rig, a, message) {
                    let at = parts[i].plan.at(*line);
                    let stopped = stop_all(rig);
                    bail!("{at}: {e:#}; {stopped} after {} keyframes of arm {}", tracks[i].pushed, rig.arms[a].name);
                }
                tracks[i].pushed += 1;
                pushed_any = true;
            }
        }
        if pushed_any {
            continue;
        }
        let mut done = true;
        for (i, t) in tracks.iter_mut().enumerate() {
            let arm = &mut rig.arms[t.arm];
            let status = arm.driver.status()?;
            if first_time.len() <= i {
                first_time.push(status.time);
            }
            if status.state == RunState::Moving && status.play_time > 0.0 && t.restarts == 0 {
                t.origin.get_or_insert(f64::from(status.time) - f64::from(status.play_time));
            }
            // A collision stop ends the play: the firmware braked this arm short of a contact
            // and holds it there; the others would play on without it.
            if status.last_collision.map(|c| c.count) != t.collision_stops {
                let pair = status.last_collision.as_ref().map(|c| stop(arm.driver.arm(), c)).unwrap_or_default();
                let name = arm.name.clone();
                let stopped = stop_all(rig);
                bail!("the firmware stopped arm {name} short of a collision: {pair} where it was going; {stopped}");
            }
            match status.state {
                RunState::Idle if t.pushed == t.messages.len() && status.queued == 0 => {}
                RunState::Idle if status.queued > 0 => {
                    t.restarts += 1;
                    arm.driver.session().start()?;
                    done = false;
                }
                RunState::TorqueOff | RunState::EStopped => {
                    let name = arm.name.clone();
                    let stopped = stop_all(rig);
                    bail!("arm {name} stopped ({:?}) during the play; {stopped}", status.state);
                }
                _ => done = false,
            }
            t.last = Some(status);
        }
        if done {
            break;
        }
        let waited = tracks
            .iter()
            .zip(&first_time)
            .filter_map(|(t, t0)| t.last.as_ref().map(|s| f64::from(s.time - t0)))
            .fold(0.0, f64::max);
        if waited > seconds + timeout || started.elapsed().as_secs_f64() > 4.0 * (seconds + timeout) + 10.0 {
            let stopped = stop_all(rig);
            bail!("timed out after {} s with an arm still moving; {stopped}", seconds_waited(waited));
        }
        let any = tracks[0].arm;
        rig.arms[any].driver.pause()?;
    }
    for t in &mut tracks {
        if let Some(status) = t.last.take() {
            t.last = Some(rig.arms[t.arm].driver.settle(status)?);
        }
    }
    if let Some(why) = stop_short {
        bail!("{why}");
    }
    for t in &tracks {
        if t.switched {
            writeln!(err, "{}: torque was off: switched it on", rig.arms[t.arm].name)?;
        }
        if t.restarts > 0 {
            writeln!(err, "warning: {}: the queue ran dry (restarted {} times)", rig.arms[t.arm].name, t.restarts)?;
        }
    }
    // The skew: exact where every arm is simulated on one clock, else the host's gap.
    let all_simulated = rig.sim.as_ref().is_some_and(|g| g.len() == rig.arms.len());
    let origins: Option<Vec<f64>> = tracks.iter().map(|t| t.origin).collect();
    let (skew_s, skew_from) = match (&origins, all_simulated) {
        (Some(o), true) if !o.is_empty() => {
            let (lo, hi) = o.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)));
            (hi - lo, "playback clocks (one virtual clock)")
        }
        _ => (host_gap_s, "host time between the Start acknowledgements"),
    };
    let mut arms = Vec::new();
    for (t, part) in tracks.into_iter().zip(&parts) {
        let last = t.last.expect("every track has a status after the loop");
        let end_error = part.plan.end_error(&rig.arms[t.arm].driver, &last.measured)?;
        arms.push(ArmPlayed {
            arm: t.arm,
            keyframes: t.messages.len(),
            pushed: t.pushed,
            last,
            end_error,
            restarts: t.restarts,
            switched: t.switched,
        });
    }
    Ok(Some(Played { arms, seconds, skew_s, skew_from }))
}

/// Checks the timeline ([`clearance::timeline`]) with every arm where it stands; where two arms
/// would come too close, cuts every part at its last keyframe before (an arm left with none
/// does not move) and returns what to say once they have stopped there. Refuses, with nothing
/// sent, when no arm could move at all.
fn keep_clear(rig: &mut Rig, parts: &mut Vec<ArmPart>, tracks: &mut Vec<Track>) -> Result<Option<String>> {
    let mut current = Vec::new();
    for arm in &mut rig.arms {
        current.push(arm.driver.status()?.measured.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>());
    }
    let keyframes: Vec<(usize, &[(usize, Keyframe)])> = tracks.iter().map(|t| (t.arm, t.messages.as_slice())).collect();
    let (collision, keep, until) = match clearance::timeline(rig, &keyframes, &current)? {
        Verdict::Clear(_) => return Ok(None),
        Verdict::StopShort { collision, keep, until } => (collision, keep, until),
    };
    let said =
        format!("the arms would come too close {:.2} s into the play: {}", collision.at, collision.near.describe());
    if keep.iter().all(|&n| n == 0) {
        bail!("{said}; refused, nothing moved");
    }
    for i in (0..tracks.len()).rev() {
        match keep[i] {
            0 => {
                tracks.remove(i);
                parts.remove(i);
            }
            n => tracks[i].messages.truncate(n),
        }
    }
    Ok(Some(format!("{said}; every arm stopped short, at its last keyframe before ({until:.2} s)")))
}

/// Switches torque off again on the arms whose torque this play switched on.
fn undo_torque(rig: &mut Rig, tracks: &[Track]) {
    for t in tracks.iter().filter(|t| t.switched) {
        let _ = rig.arms[t.arm].driver.undo_torque(true);
    }
}
