//! `armctl doctor`: what is wrong with a servo bus at first power-on, found in one command.
//!
//! What people trip over with a new arm (LeRobot's issues): every servo still at id 1; "There is
//! no status packet" from a loose cable or mixed servo firmware; a 12 V supply on 7.4 V servos; a
//! homing offset beyond ±2047; the adapter's 16 ms latency timer; a stale goal that makes the arm
//! jump when torque comes on. Each check below looks for one of them and says what to do, in a
//! line: OK, WARN or FAIL.
//!
//! - [`discover`]: the protocol and baud rate (scanned when not given), the ids, the echo;
//! - [`survey`]: what each servo says about itself (read only);
//! - [`line`]: the adapter's latency, the error rate over a few hundred sync reads, the cycle;
//! - [`checks`]: the judgments, pure functions of the above;
//! - [`finding`]: findings and their text and JSON;
//! - [`fix`]: `--fix`, the safe fixes, each confirmed.
//!
//! It writes nothing unless `--fix` is given, and then only what [`fix`] lists.

pub mod checks;
pub mod discover;
pub mod finding;
pub mod fix;
pub mod line;
pub mod survey;

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Result};
use firmware::bus::master::BusConfig;
use firmware::bus::{Id, Protocol};
use serde_json::{json, Value};

use self::checks::Expected;
use self::finding::{counts, Finding, Level};
use self::line::LineReport;
use self::survey::Reading;
use crate::runtime::connection::Place;
use crate::runtime::pc::timing::margins;
use crate::runtime::servo_session::Session;

/// What `armctl doctor` does beyond looking: the safe fixes, and how long it listens to the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DoctorRequest {
    /// Offer the safe fixes ([`fix`]), each confirmed on stdin.
    pub fix: bool,
    /// With `fix`: apply every safe fix without asking.
    pub yes: bool,
    /// Sync reads for the error rate (without retries).
    pub reads: u32,
}

/// What one look at the bus found.
struct Look {
    readings: Vec<Reading>,
    line: LineReport,
    findings: Vec<Finding>,
}

/// Runs the doctor on the servos of `place`'s bus (its protocol, baud, arm and calibration, when
/// given, narrow what is scanned and checked; a board's port or the simulation are the command
/// line's to refuse); exit code 1 when a finding is FAIL.
pub fn run(
    place: &Place,
    json: bool,
    request: &DoctorRequest,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let Some(path) = place.bus.clone() else {
        bail!("doctor needs --bus PORT: the serial port of the servos' USB adapter (armctl ports lists them)");
    };
    let expected = match &place.arm {
        Some(arm) => Some(expected_of(arm)?),
        None => None,
    };
    // A bad calibration file is refused before the bus is touched.
    let calibration = match &place.calibration {
        Some(file) => Some((file.clone(), crate::commands::servo::calibration::read_file(file)?)),
        None => None,
    };
    let preferred = expected.as_ref().map(|e| (e.expected.model.protocol, place.baud.unwrap_or(e.baud)));
    let pairs = discover::candidates(place.protocol, place.baud, preferred);
    let ids: Vec<Id> = match &expected {
        Some(e) => {
            let mut ids: Vec<Id> = e.expected.servos.iter().map(|(i, _)| *i).chain([1]).collect();
            ids.sort_unstable();
            ids.dedup();
            ids
        }
        None => discover::SCAN_IDS.collect(),
    };
    let (probe_protocol, probe_baud) = pairs[0];
    let echo = discover::hears_itself(&path, probe_protocol, probe_baud, std::time::Duration::from_millis(40))?;
    let Some(found) = discover::scan(&path, &pairs, &ids, echo, err)? else {
        let protocols: Vec<&str> = {
            let mut p: Vec<&str> = pairs.iter().map(|(p, _)| p.name()).collect();
            p.dedup();
            p
        };
        let mut findings = vec![Finding::fail(
            "bus",
            format!(
                "no servo answered on {path}: {} rate{} tried ({}), ids {}",
                pairs.len(),
                if pairs.len() == 1 { "" } else { "s" },
                protocols.join(", "),
                finding::id_list(&ids)
            ),
            "check the servos' power (their LED blinks at power-on), that the adapter's data line reaches the first servo \
             and the grounds are common, the adapter's mode jumper, and --protocol/--baud",
        )];
        findings.extend(line::adapter(&LineReport { echo, ..LineReport::default() }));
        return report(&path, None, None, &[], &findings, &[], json, out);
    };
    writeln!(
        err,
        "found {} servo(s) on {} at {} baud; checking",
        found.servos.len(),
        found.protocol.name(),
        found.baud
    )?;
    let config = BusConfig { echo, ..margins(BusConfig::new(found.protocol, found.baud), discover::SCAN_LATENCY_US) };
    let mut session = Session::open(&path, config)?;
    let names = expected.as_ref().map(|e| e.expected.servos.clone()).unwrap_or_default();
    let exp = expected.as_ref().map(|e| &e.expected);
    let look = |session: &mut Session, reads: u32| -> Result<Look> {
        let readings = survey::survey(session, &found.servos);
        let delay = readings.iter().filter_map(Reading::return_delay_us).max().unwrap_or(0);
        session.set_config(BusConfig { return_delay_us: u32::try_from(delay).unwrap_or(u32::MAX), ..session.config() });
        let clean: Vec<Id> =
            readings.iter().filter(|r| r.collision.is_none() && r.model().is_some()).map(|r| r.servo.id).collect();
        let model = readings.iter().find_map(Reading::model);
        let line = match model {
            Some(model) if !clean.is_empty() => line::measure(session, Path::new(&path), model, &clean, reads, echo),
            _ => LineReport { echo, ..LineReport::default() },
        };
        let mut findings =
            vec![Finding::ok("bus", format!("{} at {} baud on {path}", protocol_text(found.protocol), found.baud))];
        findings.extend(checks::ids(&readings, &found.garbled, exp));
        findings.extend(checks::models(&readings, exp));
        findings.extend(checks::firmware(&readings));
        findings.extend(checks::power(&readings, &names));
        findings.extend(checks::settings(&readings));
        findings.extend(checks::goals(&readings, &names));
        for r in &readings {
            for failed in &r.failed {
                findings.push(Finding::warn(
                    "survey",
                    format!("servo {}: {failed}", r.servo.id),
                    "see the line findings",
                ));
            }
        }
        if let Some((file, calibration)) = &calibration {
            match crate::commands::servo::calibration::differences(session, calibration) {
                Ok(d) => findings.extend(checks::calibration(file, &d, calibration.motors.len())),
                Err(e) => findings.push(Finding::fail(
                    "calibration",
                    format!("{}: {e:#}", file.display()),
                    "check the file is this arm's (its ids must be on the bus)",
                )),
            }
        }
        findings.extend(line::adapter(&line));
        findings.extend(line::line(&line));
        if let Some(model) = model {
            findings.extend(line::cycle(&line, model));
        }
        Ok(Look { readings, line, findings })
    };
    let mut state = look(&mut session, request.reads)?;
    let mut fixed = Vec::new();
    if request.fix {
        let stdin = std::io::stdin();
        let mut input = stdin.lock();
        let offered = fix::fixes(&state.readings, &state.line);
        if offered.is_empty() {
            writeln!(err, "nothing to fix: no safe fix applies")?;
        }
        for f in &offered {
            if !fix::confirm(f, request.yes, &mut input, err)? {
                continue;
            }
            match fix::apply(&mut session, f) {
                Ok(()) => {
                    writeln!(err, "fixed: {}", f.describe())?;
                    fixed.push(f.describe());
                }
                Err(e) => writeln!(err, "error: {}: {e:#}", f.describe())?,
            }
        }
        if !fixed.is_empty() {
            writeln!(err, "looking again")?;
            state = look(&mut session, request.reads)?;
        }
    }
    report(&path, Some(&found), Some(&state.line), &state.readings, &state.findings, &fixed, json, out)
}

/// The arm file's servos, named.
struct ArmExpectation {
    expected: Expected,
    baud: u32,
}

fn expected_of(arm: &str) -> Result<ArmExpectation> {
    let spec = crate::arm::ArmSpec::load(arm, None)?;
    let Some(servos) = crate::arm::servos::servos_of(&spec) else {
        bail!("arm {}: it has no [servos] table, so doctor cannot know which servos to expect", spec.name);
    };
    let mut named: Vec<(Id, String)> =
        servos.ids.iter().zip(&spec.joints).map(|(id, joint)| (*id, joint.name.clone())).collect();
    if let Some(g) = servos.gripper {
        named.push((g.id, "gripper".to_string()));
    }
    Ok(ArmExpectation {
        expected: Expected { arm: spec.name.clone(), model: servos.model, servos: named },
        baud: servos.baud,
    })
}

fn protocol_text(p: Protocol) -> &'static str {
    match p {
        Protocol::Feetech => "Feetech STS/SCS (sts)",
        Protocol::Dxl2 => "Dynamixel Protocol 2.0 (dxl2)",
    }
}

#[allow(clippy::too_many_arguments)]
fn report(
    path: &str,
    found: Option<&discover::Found>,
    line: Option<&LineReport>,
    readings: &[Reading],
    findings: &[Finding],
    fixed: &[String],
    json: bool,
    out: &mut dyn Write,
) -> Result<i32> {
    let code = i32::from(findings.iter().any(|f| f.level == Level::Fail));
    if json {
        let servos: Vec<Value> = readings.iter().map(reading_json).collect();
        let timing = line.and_then(|l| l.timing.as_ref()).and_then(|t| t.as_ref().ok());
        let value = json!({
            "port": path,
            "protocol": found.map(|f| f.protocol.name()),
            "baud": found.map(|f| f.baud),
            "echo": line.map(|l| l.echo),
            "servos": servos,
            "line": line.map(|l| json!({
                "reads": l.reads,
                "replies": l.replies,
                "lost": l.lost,
                "corrupt": l.corrupt,
                "latency_us": timing.map(|t| t.latency_us()),
                "cycle_us": timing.map(|t| t.cycle_us()),
                "latency_timer_ms": l.latency_timer.as_ref().map(|t| t.ms),
            })),
            "fixed": fixed,
            "findings": findings,
            "counts": counts(findings),
        });
        writeln!(out, "{value}")?;
    } else {
        finding::print(findings, out)?;
    }
    Ok(code)
}

fn reading_json(r: &Reading) -> Value {
    json!({
        "id": r.servo.id,
        "model_number": r.servo.model_number,
        "model": r.model().map(|m| m.name),
        "firmware": r.firmware_text(),
        "voltage": r.voltage_dv.map(|v| v as f64 / 10.0),
        "temperature_c": r.temperature_c,
        "hardware_error": r.hardware_error,
        "return_delay_us": r.return_delay_us(),
        "status_return_level": r.status_return_level,
        "torque": r.torque,
        "goal": r.goal,
        "present": r.present,
        "homing_offset": r.homing_offset,
        "collision": r.collision.is_some(),
    })
}
