//! `armctl teleop --rig RIG`: every rig arm driven by its own leader (the rig file's
//! `[arm.leader]`), each pair in a loop of its own on a thread of its own, all on the PC's clock.
//!
//! Each pair is exactly one `armctl teleop` session ([`crate::commands::teleop::session`]); what
//! is the rig's alone is running them side by side, each pair's lines prefixed with its arm's
//! name, the figures reported per arm, and the arms kept apart (`KeepApart`): every reading of
//! a leader is checked against the last reading each other follower took, and one that would
//! bring two arms within their margin is held back (the follower stays at its last reading), and
//! counted in the report with the first two bodies named.

use std::io::Write;

use anyhow::{bail, Result};
use serde_json::json;

use std::sync::{Arc, Mutex};

use super::clearance::Clearance;
use super::RigSpec;
use crate::arm::ArmSpec;
use crate::commands::teleop::{report, report_json, session, Guard, LoopSettings, Session};
use crate::motion::teleop::leader::Reading;
use crate::support::interrupt;

/// How one pair's session went: its arm, its session, what it said, and the readings its guard
/// held back with the first one's reason.
type PairRun = (String, Result<Session>, Vec<u8>, (u64, Option<String>));

/// The last reading each follower took (`None` before it was connected).
type Taken = Arc<Mutex<Vec<Option<Vec<f64>>>>>;

/// One pair's guard: its follower kept apart from the others' last readings.
struct KeepApart {
    me: usize,
    clearance: Clearance,
    taken: Taken,
    /// Readings held back, and the first contact they would have made.
    held: u64,
    first: Option<String>,
}

impl KeepApart {
    /// With the others' last readings and `q` for this arm: the two closest bodies if too close.
    fn too_close(&self, taken: &[Option<Vec<f64>>], q: &[f64]) -> Option<String> {
        let mut all = taken.to_vec();
        all[self.me] = Some(q.to_vec());
        // A pose FK cannot place reads as too close: held, never let through.
        let placed = match self.clearance.placed(&all) {
            Ok(placed) => placed,
            Err(e) => return Some(format!("{e:#}")),
        };
        self.clearance.closest(&placed).filter(|n| n.too_close()).map(|n| n.describe())
    }
}

impl Guard for KeepApart {
    fn begin(&mut self, measured: &[f64]) {
        let mut taken = self.taken.lock().unwrap_or_else(|e| e.into_inner());
        taken[self.me] = Some(measured.to_vec());
    }

    fn check(&mut self, reading: &mut Reading) {
        // Checked and taken under one lock: the readings taken are apart, pair by pair, always.
        let mut taken = self.taken.lock().unwrap_or_else(|e| e.into_inner());
        match self.too_close(&taken, &reading.joints) {
            None => taken[self.me] = Some(reading.joints.clone()),
            Some(why) => {
                self.held += 1;
                self.first.get_or_insert(why);
                if let Some(last) = &taken[self.me] {
                    reading.joints = last.clone();
                }
            }
        }
    }
}

/// Runs `armctl teleop --rig` on the rig `file` (a rig file or a built-in rig's name); returns the
/// exit code.
pub fn run(file: &str, json: bool, settings: &LoopSettings, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let (period, lead) = (settings.period, settings.lead);
    let spec = RigSpec::load(file)?;
    let mut pairs = Vec::new();
    let mut described = Vec::new();
    for arm in &spec.arms {
        let Some(leader) = &arm.leader else {
            bail!(
                "rig {}: arm {} has no leader: add an [arm.leader] table (port = \"PORT\", or sim = true with script)",
                spec.name,
                arm.name
            );
        };
        let (target, follower) = arm.place.target_and_arm()?;
        let Some(name) = follower else { bail!("rig {}: arm {} names no arm", spec.name, arm.name) };
        described.push((arm.name.clone(), ArmSpec::load(name, None)?, arm.base, arm.mount));
        pairs.push((arm.name.clone(), target, follower.map(str::to_string), leader.clone()));
    }
    let taken: Taken = Arc::new(Mutex::new(vec![None; pairs.len()]));
    let mut guards = Vec::new();
    for me in 0..pairs.len() {
        let clearance = Clearance::new(described.clone(), Vec::new())?;
        guards.push(KeepApart { me, clearance, taken: taken.clone(), held: 0, first: None });
    }
    interrupt::catch();
    let results: Vec<PairRun> = std::thread::scope(|scope| {
        let handles: Vec<_> = pairs
            .into_iter()
            .zip(guards)
            .map(|((name, target, follower, source), mut guard)| {
                scope.spawn(move || {
                    let mut said = Vec::new();
                    let result = session(target, follower, &source, settings, None, Some(&mut guard), &mut said);
                    (name, result, said, (guard.held, guard.first))
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a teleop thread panicked")).collect()
    });
    let mut code = 0;
    let mut arms = serde_json::Map::new();
    let mut failed = Vec::new();
    for (name, result, said, (held, first)) in results {
        for line in String::from_utf8_lossy(&said).lines() {
            writeln!(err, "{name}: {line}")?;
        }
        if let Some(first) = &first {
            writeln!(
                err,
                "{name}: held back {held} readings that would have brought the arms too close; the first: {first}"
            )?;
        }
        match result {
            Ok(s) => {
                if s.ending.monitor.as_ref().is_some_and(|m| m.violation_count > 0) || s.code != 0 {
                    code = if s.code != 0 { s.code } else { 1 };
                }
                if json {
                    let mut report = report_json(&s.figures, period, lead, &s.ending);
                    report["held_apart"] = json!({"readings": held, "first": first});
                    arms.insert(name, report);
                } else {
                    writeln!(out, "== {name}")?;
                    report(&s.figures, period, lead, &s.ending, false, out)?;
                }
            }
            Err(e) => failed.push(format!("{name}: {e:#}")),
        }
    }
    if !failed.is_empty() {
        bail!("{}", failed.join("; "));
    }
    if json {
        writeln!(out, "{}", json!({"rig": spec.name, "arms": arms}))?;
    }
    Ok(code)
}
