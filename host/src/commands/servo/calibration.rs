//! `armctl servo calibration check|write`: a LeRobot calibration file against the servos'
//! registers, as LeRobot's `is_calibrated` compares them when it connects, and the file's values
//! written to the servos, as its `write_calibration` does.
//!
//! The registers are the homing offset and the minimum and maximum position limits, and on
//! Dynamixel the Drive_Mode register, which LeRobot reads into `drive_mode` and compares whole
//! (its `write_calibration` leaves Drive_Mode to the calibration procedure; `write` here sets it
//! too, so that `check` agrees afterwards). All are EEPROM: they are written only with the servo's torque off (LeRobot writes them inside
//! `torque_disabled()`), on Feetech with the EEPROM unlocked around the writes, and a value the
//! servo already holds is not written again.

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use firmware::bus::master::Clock;
use firmware::bus::table::Model;

use super::commands::{eeprom_write, finish};
use crate::arm::calibration::{lerobot, registers, Calibration, Register};
use crate::runtime::servo_session::{Port, Session};

/// A register whose value differs from the file's.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Difference {
    /// The motor's name in the file.
    pub motor: String,
    /// Its servo id.
    pub id: u8,
    /// Which field.
    pub field: &'static str,
    /// The servo's value.
    pub servo: i64,
    /// The file's value.
    pub file: i64,
}

/// Reads every motor's registers and lists those that differ from `calibration`.
pub fn differences<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    calibration: &Calibration,
) -> Result<Vec<(Difference, Register, &'static Model)>> {
    let mut found = Vec::new();
    for (name, m) in &calibration.motors {
        let servo = session.identify(m.id).with_context(|| format!("motor {name:?}"))?;
        let model = servo.known_model()?;
        for register in registers(model) {
            let held = session.read_item(m.id, model, register.item)?;
            let file = m.value(&register);
            if held != file {
                let d = Difference { motor: name.clone(), id: m.id, field: register.field, servo: held, file };
                found.push((d, register, model));
            }
        }
    }
    Ok(found)
}

/// The file, read and checked.
pub fn read_file(path: &Path) -> Result<Calibration> {
    lerobot::read(path)
}

/// `check`: `calibration matches the servos (6 motors)` (with `json`, `{"matches": true,
/// "motors": 6}`), or one error line naming the first servo that differs and the fix.
pub fn check<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    file: &Path,
    fix: &str,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let calibration = read_file(file)?;
    let found = differences(session, &calibration)?;
    if let Some((first, _, _)) = found.first() {
        let more = match found.len() {
            1 => String::new(),
            n => format!(" (and {} more differences)", n - 1),
        };
        bail!(
            "servo {} ({}): {} is {} on the servo but {} in {}{more}: write the file's values ({fix}) or calibrate again",
            first.id,
            first.motor,
            first.field,
            first.servo,
            first.file,
            file.display()
        );
    }
    let motors = calibration.motors.len();
    super::commands::print(out, json, serde_json::json!({ "matches": true, "motors": motors }), || {
        format!("calibration matches the servos ({motors} motors)")
    })?;
    finish(session, err)
}

/// `write`: every register that differs gets the file's value, one line each; refused for a
/// servo whose torque is on (the joint would have to go limp). With `json`, one line:
/// `{"written": [{"id": 1, "motor": "shoulder_pan", "field": "homing_offset", "from": 0, "to": 12}]}`.
pub fn write<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    file: &Path,
    json: bool,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let calibration = read_file(file)?;
    let found = differences(session, &calibration)?;
    // Every value and every torque is checked before anything is written, so a refusal changes
    // nothing.
    for (d, register, model) in &found {
        let mut bytes = [0u8; 4];
        if let Err(e) = register.item.encode(d.file, model.endian, &mut bytes) {
            bail!(
                "servo {} ({}): {} {} does not fit the servo's register: {e}; nothing was written",
                d.id,
                d.motor,
                d.field,
                d.file
            );
        }
    }
    let mut checked = Vec::new();
    for (d, _, model) in &found {
        if checked.contains(&d.id) {
            continue;
        }
        checked.push(d.id);
        if session.read_item(d.id, model, model.items.torque_enable)? != 0 {
            bail!(
                "servo {}: torque is on; its calibration registers are EEPROM, written only with torque off \
                 (armctl servo torque off --id {}; the joint goes limp); nothing was written",
                d.id,
                d.id
            );
        }
    }
    let mut written = Vec::new();
    for (d, register, model) in &found {
        let servo = session.identify(d.id)?;
        eeprom_write(session, &servo, model, true, |s| s.write_item(d.id, model, register.item, d.file))
            .with_context(|| format!("servo {} ({}): {}", d.id, d.motor, d.field))?;
        if json {
            written.push(
                serde_json::json!({ "id": d.id, "motor": d.motor, "field": d.field, "from": d.servo, "to": d.file }),
            );
        } else {
            writeln!(out, "servo {} ({}): {} {} -> {}", d.id, d.motor, d.field, d.servo, d.file)?;
        }
    }
    if json {
        writeln!(out, "{}", serde_json::json!({ "written": written }))?;
    } else if found.is_empty() {
        writeln!(out, "the servos hold the file's calibration already; nothing written")?;
    }
    finish(session, err)
}
