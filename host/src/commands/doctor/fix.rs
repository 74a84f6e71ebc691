//! `armctl doctor --fix`: the safe fixes, each asked for on stdin (or given by `--yes`).
//!
//! Safe means: nothing moves and nothing is lost that cannot be written back. Each fix is one
//! value:
//! - a return delay to 0 (EEPROM: only on a servo whose torque is off, so the arm does not drop);
//! - a status return level to "answer everything" (EEPROM on Feetech: the same rule);
//! - a stale goal to the present position, on a servo whose torque is off (RAM);
//! - an FTDI adapter's latency timer to 1 ms (a sysfs file, which needs write access).
//!
//! The same values `armctl --bus` writes when it connects ([`crate::runtime::pc::setup`]), whose
//! EEPROM unlocking is reused here. Ids, baud rates, calibrations and torque are never touched:
//! those need a person at the arm.

use std::io::{BufRead, Write};
use std::path::PathBuf;

use anyhow::{anyhow, Result};
use firmware::bus::master::{BusConfig, Clock, Replies};
use firmware::bus::table::{Item, Model};
use firmware::bus::Id;

use super::checks::GOAL_TOLERANCE;
use super::line::LineReport;
use super::survey::{replies_to_all, Reading};
use crate::runtime::pc::latency::ADVISED_MS;
use crate::runtime::pc::setup::{unlocked, write_value};
use crate::runtime::servo_session::{Port, Session};

/// One safe fix.
#[derive(Clone, Debug, PartialEq)]
pub enum Fix {
    /// One item of one servo.
    Item {
        /// The servo.
        id: Id,
        /// Its model.
        model: &'static Model,
        /// The item.
        item: Item,
        /// Its value now.
        from: i64,
        /// The value written.
        to: i64,
    },
    /// The adapter's latency timer file.
    LatencyTimer {
        /// The sysfs file.
        file: PathBuf,
        /// Its value now, ms.
        from: u32,
    },
}

impl Fix {
    /// One line: `servo 3: return_delay_time 250 -> 0 (EEPROM)`.
    pub fn describe(&self) -> String {
        match self {
            Self::Item { id, model, item, from, to } => {
                let kind = if item.address < model.eeprom_end { " (EEPROM)" } else { "" };
                format!("servo {id}: {} {from} -> {to}{kind}", item.name)
            }
            Self::LatencyTimer { file, from } => format!("{}: {from} -> {ADVISED_MS} ms", file.display()),
        }
    }
}

/// The safe fixes for what was found, in the order they are offered.
pub fn fixes(readings: &[Reading], line: &LineReport) -> Vec<Fix> {
    let mut list = Vec::new();
    for r in readings {
        let Some(model) = r.model() else { continue };
        let id = r.servo.id;
        // EEPROM is written only with torque off; a torqued servo is left with its finding.
        let torque_off = r.torque == Some(false);
        if let Some(from) = r.return_delay.filter(|d| *d != 0) {
            if torque_off || model.items.return_delay.address >= model.eeprom_end {
                list.push(Fix::Item { id, model, item: model.items.return_delay, from, to: 0 });
            }
        }
        let all = replies_to_all(model.protocol);
        if let Some(from) = r.status_return_level.filter(|l| *l != all) {
            if torque_off || model.items.status_return_level.address >= model.eeprom_end {
                list.push(Fix::Item { id, model, item: model.items.status_return_level, from, to: all });
            }
        }
        if let (true, Some(goal), Some(present)) = (torque_off, r.goal, r.present) {
            if ((goal - present).abs() as f64) > GOAL_TOLERANCE * f64::from(model.ticks_per_revolution) {
                list.push(Fix::Item { id, model, item: model.items.goal_position, from: goal, to: present });
            }
        }
    }
    if let Some(t) = line.latency_timer.as_ref().filter(|t| t.ms > ADVISED_MS) {
        list.push(Fix::LatencyTimer { file: t.file.clone(), from: t.ms });
    }
    list
}

/// Applies one fix.
pub fn apply<P: Port, C: Clock>(session: &mut Session<P, C>, fix: &Fix) -> Result<()> {
    match fix {
        Fix::Item { id, model, item, to, .. } => {
            let (id, item, to) = (*id, *item, *to);
            // A servo whose status return level is being fixed does not answer writes yet: they
            // are sent without waiting for a status, and the value is read back instead.
            let silent_writes = item == model.items.status_return_level;
            let config = session.config();
            if silent_writes {
                session.set_config(BusConfig { replies: Replies::PingOnly, ..config });
            }
            let bus = session.master_mut();
            let result = if item.address < model.eeprom_end {
                unlocked(bus, model, id, |bus| write_value(bus, model, id, item, to))
            } else {
                write_value(bus, model, id, item, to)
            };
            session.set_config(config);
            result.map_err(|e| anyhow!("{e}"))?;
            if silent_writes {
                // A status the servo sent after all is stale input for this read, which drops it.
                std::thread::sleep(std::time::Duration::from_micros(session.master_mut().reply_timeout_us(1, 0)));
                let now = session.read_item(id, model, item)?;
                if now != to {
                    anyhow::bail!("servo {id}: {} reads {now} after writing {to}", item.name);
                }
            }
            Ok(())
        }
        Fix::LatencyTimer { file, .. } => std::fs::write(file, format!("{ADVISED_MS}\n")).map_err(|e| {
            anyhow!("{}: {e} (write it as root: echo {ADVISED_MS} | sudo tee {})", file.display(), file.display())
        }),
    }
}

/// Asks on `prompt` whether to apply `fix`; `yes` answers for the person. Anything but `y` or
/// `yes`, and the end of the input, is no.
pub fn confirm(fix: &Fix, yes: bool, input: &mut dyn BufRead, prompt: &mut dyn Write) -> Result<bool> {
    if yes {
        return Ok(true);
    }
    write!(prompt, "fix {}? [y/N] ", fix.describe())?;
    prompt.flush()?;
    let mut answer = String::new();
    input.read_line(&mut answer)?;
    let yes = matches!(answer.trim().to_ascii_lowercase().as_str(), "y" | "yes");
    if answer.is_empty() {
        writeln!(prompt)?;
    }
    Ok(yes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::doctor::survey::healthy;
    use firmware::bus::table::STS3215;

    fn reading(torque: bool) -> Reading {
        Reading {
            return_delay: Some(250),
            status_return_level: Some(0),
            torque: Some(torque),
            goal: Some(3000),
            ..healthy(3, &STS3215)
        }
    }

    #[test]
    fn a_torque_off_servo_gets_every_fix_a_torqued_one_none_of_its_eeprom() {
        let line = LineReport::default();
        let off = fixes(&[reading(false)], &line);
        let lines: Vec<String> = off.iter().map(Fix::describe).collect();
        assert_eq!(
            lines,
            [
                "servo 3: return_delay_time 250 -> 0 (EEPROM)",
                "servo 3: response_status_level 0 -> 1 (EEPROM)",
                "servo 3: goal_position 3000 -> 2048"
            ]
        );
        assert!(fixes(&[reading(true)], &line).is_empty());
    }

    #[test]
    fn only_yes_confirms() {
        let fix = &fixes(&[reading(false)], &LineReport::default())[0];
        for (answer, want) in [("y\n", true), ("yes\n", true), ("n\n", false), ("\n", false), ("", false)] {
            let mut prompt = Vec::new();
            assert_eq!(confirm(fix, false, &mut answer.as_bytes(), &mut prompt).unwrap(), want, "{answer:?}");
            assert!(String::from_utf8(prompt).unwrap().starts_with("fix servo 3: return_delay_time"));
        }
        assert!(confirm(fix, true, &mut "".as_bytes(), &mut Vec::new()).unwrap());
    }
}
