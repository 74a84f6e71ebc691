//! The judgments: from what was read and measured to findings. Pure functions, tested on made-up
//! readings; the bus is only in [`super::survey`] and [`super::line`].
//!
//! The thresholds, and where they come from:
//! - Rated input voltage per model, for a servo whose table has no voltage limits:
//!   STS3215 4.0-7.4 V (the 7.4 V version the SO-101 kits use; Feetech's 12 V versions, C018 and
//!   C047, share its model number 777 and run to 14 V), XL430-W250 6.5-12.0 V, XM430-W350
//!   10.0-14.8 V, XL330-M288 3.7-6.0 V (makers' specifications, ROBOTIS e-manual).
//! - A servo's own voltage and temperature limits, where it has them, come first: past them the
//!   servo itself raises its voltage or overheating error and drops torque.
//! - Supplies on one bus more than 1 V apart: one supply should feed them all, so the difference
//!   is a voltage drop in a connector or a thin wire.
//! - A goal more than [`GOAL_TOLERANCE`] of a turn from the present position.

use firmware::bus::table::Model;
use firmware::bus::{Id, Protocol};

use super::finding::{id_list, Finding, Level};
use super::survey::{replies_to_all, servo_name, Reading};

/// A goal this far from the present position (fraction of a turn, about 3.6°) is a move waiting
/// to happen.
pub const GOAL_TOLERANCE: f64 = 0.01;

/// Temperatures this far below the servo's limit (°C) are a warning.
pub const TEMPERATURE_MARGIN_C: i64 = 10;

/// What the arm file says the bus holds.
#[derive(Clone, Debug)]
pub struct Expected {
    /// The arm's name.
    pub arm: String,
    /// Its servos' model.
    pub model: &'static Model,
    /// Every servo's id and the joint (or gripper) it drives.
    pub servos: Vec<(Id, String)>,
}

/// The maker's rated input voltage (min, max) of a model in 0.1 V, for servos whose table has no
/// voltage limits.
pub fn rated_voltage_dv(model: &Model) -> Option<(i64, i64)> {
    match model.number {
        777 => Some((40, 74)),
        1060 => Some((65, 120)),
        1020 => Some((100, 148)),
        1200 => Some((37, 60)),
        _ => None,
    }
}

/// The maker's overheating limit of a model, °C, for servos whose table does not hold it
/// (STS3215: 70 °C; X-series factory Temperature Limit: XL430 72, XM430 80, XL330 70).
pub fn rated_temperature_c(model: &Model) -> i64 {
    match model.number {
        1060 => 72,
        1020 => 80,
        _ => 70,
    }
}

/// `ids`: the servos the arm needs all answer, once each; every servo still at the factory id 1.
pub fn ids(readings: &[Reading], garbled: &[Id], expected: Option<&Expected>) -> Vec<Finding> {
    let mut findings = Vec::new();
    let found: Vec<Id> = readings.iter().map(|r| r.servo.id).collect();
    let colliding: Vec<Id> =
        readings.iter().filter(|r| r.collision.is_some()).map(|r| r.servo.id).chain(garbled.iter().copied()).collect();
    let wanted: Vec<Id> = expected.map(|e| e.servos.iter().map(|(i, _)| *i).collect()).unwrap_or_default();
    let factory = found.iter().chain(garbled).all(|&i| i == 1) && (colliding.contains(&1) || wanted.len() > 1);
    if factory {
        findings.push(Finding::fail(
            "ids",
            "only id 1 answers, the factory id: every servo is still at id 1 (their replies collide)",
            "connect one servo at a time and give each its id: armctl servo set-id --bus PORT --protocol P --id 1 \
             --new-id N (LeRobot: lerobot-setup-motors)",
        ));
        return findings;
    }
    for &id in &colliding {
        findings.push(Finding::fail(
            "ids",
            format!("two or more servos answer as id {id}: their replies collide"),
            format!("connect them one at a time and give each its own id (armctl servo set-id --id {id} --new-id N)"),
        ));
    }
    if let Some(e) = expected {
        let missing: Vec<Id> = wanted.iter().copied().filter(|i| !found.contains(i) && !garbled.contains(i)).collect();
        for id in &missing {
            findings.push(Finding::fail(
                "ids",
                format!("{} does not answer", servo_name(*id, &e.servos)),
                "check its cable and the one before it in the chain, and its power; if it is a new servo, it is at id 1 \
                 until set (armctl servo set-id)",
            ));
        }
        let extra: Vec<Id> = found.iter().copied().filter(|i| !wanted.contains(i)).collect();
        if !extra.is_empty() {
            findings.push(Finding::warn(
                "ids",
                format!("id {} answers but is not one of {}'s servos ({})", id_list(&extra), e.arm, id_list(&wanted)),
                "give it the id of the joint it drives (armctl servo set-id), or take it off this bus",
            ));
        }
        if missing.is_empty() && colliding.is_empty() && extra.is_empty() {
            findings.push(Finding::ok(
                "ids",
                format!("{}'s {} servos answer, ids {}", e.arm, wanted.len(), id_list(&wanted)),
            ));
        }
    } else if colliding.is_empty() {
        findings.push(Finding::ok(
            "ids",
            format!("{} servos answer, ids {} (no arm given to compare)", found.len(), id_list(&found)),
        ));
    }
    findings
}

/// `models`: each servo is the model the arm file says.
pub fn models(readings: &[Reading], expected: Option<&Expected>) -> Vec<Finding> {
    let mut findings = Vec::new();
    let mut by_model: Vec<(String, Vec<Id>)> = Vec::new();
    for r in readings {
        let text = r.servo.model_text();
        match by_model.iter_mut().find(|(t, _)| *t == text) {
            Some((_, ids)) => ids.push(r.servo.id),
            None => by_model.push((text, vec![r.servo.id])),
        }
        if let Some(e) = expected {
            if r.servo.model_number != e.model.number && e.servos.iter().any(|(i, _)| *i == r.servo.id) {
                findings.push(Finding::fail(
                    "models",
                    format!(
                        "{} is model {}, but {} has {} {}",
                        servo_name(r.servo.id, &e.servos),
                        r.servo.model_text(),
                        e.arm,
                        e.model.number,
                        e.model.name
                    ),
                    "fit the servo the arm file names, or give --arm the file of the arm you built",
                ));
            }
        }
    }
    if findings.is_empty() {
        let list: Vec<String> = by_model.iter().map(|(t, ids)| format!("{t} (id {})", id_list(ids))).collect();
        findings.push(Finding::ok("models", list.join(", ")));
    }
    findings
}

/// `firmware`: one firmware version on the whole bus.
pub fn firmware(readings: &[Reading]) -> Vec<Finding> {
    let mut versions: Vec<(String, Vec<Id>)> = Vec::new();
    for r in readings {
        let Some(v) = r.firmware_text() else { continue };
        match versions.iter_mut().find(|(t, _)| *t == v) {
            Some((_, ids)) => ids.push(r.servo.id),
            None => versions.push((v, vec![r.servo.id])),
        }
    }
    match versions.len() {
        0 => vec![Finding::warn("firmware", "no servo told its firmware version", "read it with the maker's tool")],
        1 => vec![Finding::ok("firmware", format!("every servo runs firmware {}", versions[0].0))],
        _ => {
            let list: Vec<String> = versions.iter().map(|(v, ids)| format!("{v} on id {}", id_list(ids))).collect();
            vec![Finding::warn(
                "firmware",
                format!("mixed firmware versions: {}; a known cause of lost status packets", list.join(", ")),
                "bring every servo to one version with the maker's tool (Feetech FD, Dynamixel Wizard)",
            )]
        }
    }
}

/// `power`: input voltage within each servo's range and the same on every servo, temperature,
/// and hardware error flags.
pub fn power(readings: &[Reading], names: &[(Id, String)]) -> Vec<Finding> {
    let mut findings = Vec::new();
    let mut volts = Vec::new();
    // Voltage verdicts, one per servo, grouped after the loop: one supply feeds them all.
    let mut supply: Vec<(Id, Level, String, &'static str)> = Vec::new();
    for r in readings {
        let (Some(model), Some(v)) = (r.model(), r.voltage_dv) else { continue };
        volts.push(v);
        let name = servo_name(r.servo.id, names);
        let own = r.voltage_limits_dv;
        let Some((lo, hi)) = own.or_else(|| rated_voltage_dv(model)) else { continue };
        let whose = if own.is_some() { "its own limits" } else { "its rating" };
        let range = format!("{:.1}-{:.1} V", lo as f64 / 10.0, hi as f64 / 10.0);
        let reads = format!("{:.1} V", v as f64 / 10.0);
        if v > hi {
            let hint = if model.number == 777 && own.is_none() && v <= 140 {
                "; right only if these are Feetech's 12 V STS3215 (C018, C047), else a 12 V supply on 7.4 V servos"
            } else {
                ""
            };
            let level = if own.is_some() || model.number != 777 || v > 140 { Level::Fail } else { Level::Warn };
            let fix = "switch the power off and use the supply the servos are rated for (SO-101 kits: 7.4 V for the \
                       7.4 V servos, 12 V for the 12 V ones)";
            supply.push((r.servo.id, level, format!("{reads}, above {whose} {range}{hint}"), fix));
        } else if v < lo {
            supply.push((
                r.servo.id,
                Level::Fail,
                format!("{reads}, below {whose} {range}: too weak a supply, or 7.4 V on 12 V servos"),
                "use the supply the servos are rated for, and check it holds its voltage under load",
            ));
        }
        if let Some(t) = r.temperature_c {
            let limit = r.temperature_limit_c.unwrap_or_else(|| rated_temperature_c(model));
            if t >= limit {
                findings.push(Finding::fail(
                    "power",
                    format!("{name} is at {t} °C, at its overheating limit of {limit} °C"),
                    "switch torque off and let it cool; it is held against a load or stalled",
                ));
            } else if t >= limit - TEMPERATURE_MARGIN_C {
                findings.push(Finding::warn(
                    "power",
                    format!(
                        "{name} is at {t} °C, within {TEMPERATURE_MARGIN_C} °C of its overheating limit {limit} °C"
                    ),
                    "let it cool, and look for a joint that holds a load all the time",
                ));
            }
        }
        if let Some(bits) = r.hardware_error.filter(|b| *b != 0) {
            let protocol = model.protocol;
            findings.push(Finding::fail(
                "power",
                format!("{name} reports a hardware error: {}", hardware_error_text(protocol, bits)),
                match protocol {
                    Protocol::Dxl2 => {
                        "remove the cause (supply, load, heat), then reboot the servo (power cycle) to clear it"
                    }
                    Protocol::Feetech => {
                        "remove the cause (supply, load, heat); the flag clears when the condition does"
                    }
                },
            ));
        }
    }
    let mut grouped: Vec<(Vec<Id>, Level, String, &'static str)> = Vec::new();
    for (id, level, text, fix) in supply {
        match grouped.iter_mut().find(|(_, l, t, _)| *l == level && *t == text) {
            Some((ids, ..)) => ids.push(id),
            None => grouped.push((vec![id], level, text, fix)),
        }
    }
    let supply_findings = grouped.into_iter().map(|(ids, level, text, fix)| {
        let message = match ids.as_slice() {
            [id] => format!("{} reads {text}", servo_name(*id, names)),
            _ => format!("id {} read {text}", id_list(&ids)),
        };
        Finding { level, check: "power", message, fix: Some(fix.to_string()) }
    });
    findings.splice(0..0, supply_findings);
    if let (Some(lo), Some(hi)) = (volts.iter().min(), volts.iter().max()) {
        if hi - lo > 10 {
            findings.push(Finding::warn(
                "power",
                format!(
                    "the servos read {:.1} to {:.1} V: more than 1 V apart on one supply",
                    *lo as f64 / 10.0,
                    *hi as f64 / 10.0
                ),
                "a loose power connector or a thin wire drops the voltage along the chain: reseat and check them",
            ));
        }
    }
    if findings.is_empty() && !volts.is_empty() {
        findings.push(Finding::ok(
            "power",
            format!(
                "{:.1} V on every servo, within its range; temperatures and error flags fine",
                volts.iter().sum::<i64>() as f64 / volts.len() as f64 / 10.0
            ),
        ));
    }
    findings
}

/// The error bits in words.
pub fn hardware_error_text(protocol: Protocol, bits: u8) -> String {
    let found = crate::runtime::servo_session::hardware_error_names(protocol, bits);
    if found.is_empty() {
        format!("error bits {bits:#04x}")
    } else {
        format!("{} (bits {bits:#04x})", found.join(", "))
    }
}

/// `settings`: return delay 0 and replies to every instruction.
pub fn settings(readings: &[Reading]) -> Vec<Finding> {
    let mut findings = Vec::new();
    let slow: Vec<&Reading> = readings.iter().filter(|r| r.return_delay_us().is_some_and(|us| us > 0)).collect();
    if !slow.is_empty() {
        let ids: Vec<Id> = slow.iter().map(|r| r.servo.id).collect();
        let worst = slow.iter().filter_map(|r| r.return_delay_us()).max().unwrap_or(0);
        findings.push(Finding::warn(
            "settings",
            format!(
                "id {} wait up to {worst} µs before each reply (return delay; the factory value is 500 µs): {:.1} ms of every \
                 control cycle on {} servos",
                id_list(&ids),
                worst as f64 * readings.len() as f64 / 1000.0,
                readings.len()
            ),
            "armctl doctor --fix writes 0 (EEPROM, with torque off), as `armctl --bus` and LeRobot do when they connect",
        ));
    }
    for r in readings {
        let (Some(model), Some(level)) = (r.model(), r.status_return_level) else { continue };
        let all = replies_to_all(model.protocol);
        if level != all {
            findings.push(Finding::fail(
                "settings",
                format!(
                    "servo {} has status return level {level}: it does not answer writes, so every write waits for a \
                     reply that never comes",
                    r.servo.id
                ),
                format!("armctl doctor --fix writes {all} (answer every instruction)"),
            ));
        }
    }
    if findings.is_empty() {
        findings.push(Finding::ok("settings", "return delay 0 and replies to every instruction, on every servo"));
    }
    findings
}

/// `goals`: no servo's goal waits away from where it stands.
pub fn goals(readings: &[Reading], names: &[(Id, String)]) -> Vec<Finding> {
    let mut findings = Vec::new();
    for r in readings {
        let (Some(model), Some(goal), Some(present), Some(torque)) = (r.model(), r.goal, r.present, r.torque) else {
            continue;
        };
        let tpr = f64::from(model.ticks_per_revolution);
        let ticks = (goal - present).abs();
        if (ticks as f64) <= GOAL_TOLERANCE * tpr {
            continue;
        }
        let degrees = ticks as f64 * 360.0 / tpr;
        let name = servo_name(r.servo.id, names);
        findings.push(if torque {
            Finding::warn(
                "goals",
                format!("{name} has torque on and stands {degrees:.0}° ({ticks} ticks) from its goal: it is blocked or overloaded"),
                "look what holds the joint; switch its torque off (armctl servo torque off) before freeing it",
            )
        } else {
            Finding::warn(
                "goals",
                format!(
                    "{name}'s goal is {degrees:.0}° ({ticks} ticks) from where it stands: switching torque on would swing it \
                     there at full speed"
                ),
                "armctl doctor --fix sets the goal to the present position (armctl --bus does it when it connects)",
            )
        });
    }
    if findings.is_empty() {
        findings.push(Finding::ok("goals", "every goal is where its servo stands"));
    }
    findings
}

/// `calibration`: the servos hold the calibration file's homing offsets and limits, and the file's
/// values fit the registers (LeRobot's "Magnitude 2114 exceeds 2047": an offset taken with a
/// joint far from the middle of its range).
pub fn calibration(
    file: &std::path::Path,
    differences: &[(
        crate::commands::servo::calibration::Difference,
        crate::arm::calibration::Register,
        &'static Model,
    )],
    motors: usize,
) -> Vec<Finding> {
    let mut findings = Vec::new();
    for (d, register, model) in differences {
        let mut bytes = [0u8; 4];
        if let Err(e) = register.item.encode(d.file, model.endian, &mut bytes) {
            findings.push(Finding::fail(
                "calibration",
                format!("{}: {} {} in {} does not fit the {}'s register ({e})", d.motor, d.field, d.file, file.display(), model.name),
                "calibrate again, with every joint in the middle of its range when the offsets are taken (armctl calibrate)",
            ));
        } else {
            findings.push(Finding::fail(
                "calibration",
                format!("servo {} ({}): {} is {} on the servo but {} in {}", d.id, d.motor, d.field, d.servo, d.file, file.display()),
                format!(
                    "write the file's values with torque off (armctl servo calibration write --file {}), or calibrate again",
                    file.display()
                ),
            ));
        }
    }
    if findings.is_empty() {
        findings.push(Finding::ok("calibration", format!("the servos hold {} ({motors} motors)", file.display())));
    }
    findings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::doctor::survey::healthy;
    use firmware::bus::table::{STS3215, XL430_W250};

    fn reading(id: Id, model: &'static Model) -> Reading {
        healthy(id, model)
    }

    fn so101() -> Expected {
        Expected { arm: "so101".into(), model: &STS3215, servos: (1..=6).map(|i| (i, format!("j{i}"))).collect() }
    }

    fn levels(findings: &[Finding]) -> Vec<Level> {
        findings.iter().map(|f| f.level).collect()
    }

    #[test]
    fn a_clean_arm_is_ok_everywhere() {
        let rs: Vec<Reading> = (1..=6).map(|i| reading(i, &STS3215)).collect();
        let e = so101();
        for f in [
            ids(&rs, &[], Some(&e)),
            models(&rs, Some(&e)),
            firmware(&rs),
            power(&rs, &e.servos),
            settings(&rs),
            goals(&rs, &e.servos),
        ] {
            assert_eq!(levels(&f), [Level::Ok], "{f:?}");
        }
    }

    #[test]
    fn missing_extra_and_factory_ids() {
        let e = so101();
        let rs: Vec<Reading> = [1, 2, 3, 5, 6, 9].iter().map(|&i| reading(i, &STS3215)).collect();
        let f = ids(&rs, &[], Some(&e));
        assert_eq!(levels(&f), [Level::Fail, Level::Warn], "{f:?}");
        assert!(f[0].message.contains("servo 4 (j4) does not answer"));
        assert!(f[1].message.contains("id 9 answers"));
        let mut one = reading(1, &STS3215);
        one.collision = Some("garbled".into());
        let f = ids(&[one], &[], Some(&e));
        assert_eq!(levels(&f), [Level::Fail]);
        assert!(f[0].message.contains("factory id"), "{f:?}");
    }

    #[test]
    fn voltages_judged_by_the_servos_own_limits_first() {
        let mut r = reading(1, &STS3215);
        r.voltage_dv = Some(120);
        let f = power(&[r.clone()], &[]);
        assert_eq!(levels(&f), [Level::Warn], "12 V on an STS3215 without limits: the 12 V version or not");
        r.voltage_limits_dv = Some((40, 80));
        let f = power(&[r.clone()], &[]);
        assert_eq!(levels(&f), [Level::Fail]);
        assert!(f[0].message.contains("above its own limits 4.0-8.0 V"), "{}", f[0].message);
        let mut twin = r.clone();
        twin.servo.id = 2;
        let f = power(&[r.clone(), twin], &[]);
        assert_eq!(levels(&f), [Level::Fail], "one supply, one finding: {f:?}");
        assert!(f[0].message.starts_with("id 1-2 read 12.0 V, above"), "{}", f[0].message);
        let mut x = reading(2, &XL430_W250);
        x.voltage_dv = Some(50);
        assert_eq!(levels(&power(&[x], &[])), [Level::Fail]);
    }

    #[test]
    fn heat_errors_and_a_sagging_chain() {
        let mut hot = reading(1, &STS3215);
        hot.temperature_c = Some(65);
        let mut err = reading(2, &STS3215);
        err.hardware_error = Some(0x20);
        let mut low = reading(3, &STS3215);
        low.voltage_dv = Some(60);
        let f = power(&[hot, err, low], &[]);
        assert_eq!(levels(&f), [Level::Warn, Level::Fail, Level::Warn], "{f:?}");
        assert!(f[1].message.contains("overload"));
        assert!(f[2].message.contains("more than 1 V apart"));
    }

    #[test]
    fn settings_and_goals() {
        let mut slow = reading(1, &STS3215);
        slow.return_delay = Some(250);
        let mut mute = reading(2, &STS3215);
        mute.status_return_level = Some(0);
        let f = settings(&[slow, mute]);
        assert_eq!(levels(&f), [Level::Warn, Level::Fail]);
        assert!(f[0].message.contains("500 µs"), "{}", f[0].message);
        let mut stale = reading(1, &STS3215);
        stale.goal = Some(3048);
        let mut held = reading(2, &STS3215);
        held.torque = Some(true);
        held.goal = Some(1000);
        let f = goals(&[stale, held], &[]);
        assert_eq!(levels(&f), [Level::Warn, Level::Warn]);
        assert!(f[0].message.contains("88°") && f[0].message.contains("swing"), "{}", f[0].message);
        assert!(f[1].message.contains("blocked"));
    }

    #[test]
    fn mixed_firmware_is_a_warning() {
        let mut old = reading(4, &STS3215);
        old.firmware_minor = Some(9);
        let f = firmware(&[reading(1, &STS3215), old]);
        assert_eq!(levels(&f), [Level::Warn]);
        assert!(f[0].message.contains("3.10 on id 1, 3.9 on id 4"), "{}", f[0].message);
    }
}
