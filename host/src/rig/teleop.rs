//! `armctl teleop --rig RIG`: every rig arm driven by its own leader (the rig file's
//! `[arm.leader]`), each pair in a loop of its own on a thread of its own, all on the PC's clock.
//!
//! Each pair is exactly one `armctl teleop` session ([`crate::commands::teleop::session`]); what
//! is the rig's alone is running them side by side, each pair's lines prefixed with its arm's
//! name, and the figures reported per arm.

use std::io::Write;

use anyhow::{bail, Result};
use serde_json::json;

use super::RigSpec;
use crate::commands::teleop::{report, report_json, session, LoopSettings, Session};
use crate::support::interrupt;

/// Runs `armctl teleop --rig` on the rig `file` (a rig file or a built-in rig's name); returns the
/// exit code.
pub fn run(file: &str, json: bool, settings: &LoopSettings, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let (period, lead) = (settings.period, settings.lead);
    let spec = RigSpec::load(file)?;
    let mut pairs = Vec::new();
    for arm in &spec.arms {
        let Some(leader) = &arm.leader else {
            bail!(
                "rig {}: arm {} has no leader: add an [arm.leader] table (port = \"PORT\", or sim = true with script)",
                spec.name,
                arm.name
            );
        };
        let (target, follower) = arm.place.target_and_arm()?;
        pairs.push((arm.name.clone(), target, follower.map(str::to_string), leader.clone()));
    }
    interrupt::catch();
    let results: Vec<(String, Result<Session>, Vec<u8>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = pairs
            .into_iter()
            .map(|(name, target, follower, source)| {
                scope.spawn(move || {
                    let mut said = Vec::new();
                    let result = session(target, follower, &source, settings, None, &mut said);
                    (name, result, said)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a teleop thread panicked")).collect()
    });
    let mut code = 0;
    let mut arms = serde_json::Map::new();
    let mut failed = Vec::new();
    for (name, result, said) in results {
        for line in String::from_utf8_lossy(&said).lines() {
            writeln!(err, "{name}: {line}")?;
        }
        match result {
            Ok(s) => {
                if s.ending.monitor.as_ref().is_some_and(|m| m.violation_count > 0) || s.code != 0 {
                    code = if s.code != 0 { s.code } else { 1 };
                }
                if json {
                    arms.insert(name, report_json(&s.figures, period, lead, &s.ending));
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
