//! Reading what each servo says about itself, once: the values the checks judge. Nothing here
//! writes to a servo.
//!
//! Items are found by name in the model's table ([`crate::commands::servo::items`]), so that a model
//! without one (no voltage limit, no minor firmware version) just leaves it unknown.

use firmware::bus::master::Clock;
use firmware::bus::table::Model;
use firmware::bus::{Id, Protocol};

use crate::commands::servo::commands::duplicate_check;
use crate::commands::servo::items;
use crate::runtime::servo_session::{Port, Servo, Session};

/// One servo's state as read.
#[derive(Clone, Debug)]
pub struct Reading {
    /// Id, model and firmware from the ping (and the model item on Feetech).
    pub servo: Servo,
    /// Feetech's minor firmware version (Dynamixel has one firmware number).
    pub firmware_minor: Option<i64>,
    /// Input voltage, 0.1 V.
    pub voltage_dv: Option<i64>,
    /// The servo's own voltage limits (min, max), 0.1 V, where its table has them.
    pub voltage_limits_dv: Option<(i64, i64)>,
    /// Internal temperature, °C.
    pub temperature_c: Option<i64>,
    /// The servo's own temperature limit, °C, where its table has it.
    pub temperature_limit_c: Option<i64>,
    /// Hardware error bits: Dynamixel's hardware error status item, Feetech's status error byte
    /// (0 when the servo reports none).
    pub hardware_error: Option<u8>,
    /// Return delay, in the item's unit ([`Model::return_delay_unit_us`]).
    pub return_delay: Option<i64>,
    /// Status return level.
    pub status_return_level: Option<i64>,
    /// Torque enable.
    pub torque: Option<bool>,
    /// Goal position, ticks.
    pub goal: Option<i64>,
    /// Present position, ticks.
    pub present: Option<i64>,
    /// The homing offset register.
    pub homing_offset: Option<i64>,
    /// A read of it came back garbled: two servos answer as this id.
    pub collision: Option<String>,
    /// Reads that failed, one line each.
    pub failed: Vec<String>,
}

impl Reading {
    /// The model, when the tables know it.
    pub fn model(&self) -> Option<&'static Model> {
        self.servo.model
    }

    /// The firmware version as people write it: `3.10` on Feetech, `46` on Dynamixel.
    pub fn firmware_text(&self) -> Option<String> {
        let major = self.servo.firmware?;
        Some(match self.firmware_minor {
            Some(minor) => format!("{major}.{minor}"),
            None => major.to_string(),
        })
    }

    /// The return delay in microseconds.
    pub fn return_delay_us(&self) -> Option<i64> {
        Some(self.return_delay? * i64::from(self.model()?.return_delay_unit_us))
    }
}

/// The first item of `names` the model has.
fn item_named(model: &Model, names: &[&str]) -> Option<firmware::bus::table::Item> {
    names.iter().find_map(|n| items::named(model, n))
}

/// Reads every servo of `servos`.
pub fn survey<P: Port, C: Clock>(session: &mut Session<P, C>, servos: &[Servo]) -> Vec<Reading> {
    servos.iter().map(|servo| read_one(session, servo)).collect()
}

fn read_one<P: Port, C: Clock>(session: &mut Session<P, C>, servo: &Servo) -> Reading {
    let mut reading = Reading {
        servo: *servo,
        firmware_minor: None,
        voltage_dv: None,
        voltage_limits_dv: None,
        temperature_c: None,
        temperature_limit_c: None,
        hardware_error: None,
        return_delay: None,
        status_return_level: None,
        torque: None,
        goal: None,
        present: None,
        homing_offset: None,
        collision: duplicate_check(session, servo),
        failed: Vec::new(),
    };
    let Some(model) = servo.model else { return reading };
    let id = servo.id;
    let mut get = |names: &[&str], reading: &mut Reading| -> Option<i64> {
        let item = item_named(model, names)?;
        match session.read_item(id, model, item) {
            Ok(value) => Some(value),
            Err(e) => {
                reading.failed.push(format!("{}: {e}", item.name));
                None
            }
        }
    };
    reading.firmware_minor = get(&["firmware_minor_version"], &mut reading);
    reading.voltage_dv = get(&["present_voltage", "present_input_voltage"], &mut reading);
    let min_v = get(&["min_voltage_limit"], &mut reading);
    let max_v = get(&["max_voltage_limit"], &mut reading);
    reading.voltage_limits_dv = min_v.zip(max_v);
    reading.temperature_c = get(&["present_temperature"], &mut reading);
    reading.temperature_limit_c = get(&["max_temperature_limit", "temperature_limit"], &mut reading);
    reading.return_delay = get(&[model.items.return_delay.name], &mut reading);
    reading.status_return_level = get(&[model.items.status_return_level.name], &mut reading);
    reading.torque = get(&[model.items.torque_enable.name], &mut reading).map(|t| t != 0);
    reading.goal = get(&[model.items.goal_position.name], &mut reading);
    reading.present = get(&[model.items.present_position.name], &mut reading);
    reading.homing_offset = get(&["homing_offset"], &mut reading);
    reading.hardware_error = match model.items.hardware_error {
        Some(item) => get(&[item.name], &mut reading).map(|bits| bits as u8),
        // Feetech reports its error bits in every status: the session kept the first it saw.
        None => Some(session.alerts().iter().find(|(i, _)| *i == id).map_or(0, |(_, bits)| *bits)),
    };
    reading
}

/// `servo 3`, or `servo 3 (elbow_flex)` when the arm names it.
pub fn servo_name(id: Id, names: &[(Id, String)]) -> String {
    match names.iter().find(|(i, _)| *i == id) {
        Some((_, name)) => format!("servo {id} ({name})"),
        None => format!("servo {id}"),
    }
}

/// The status return level at which a servo answers every instruction: what the firmware's
/// master expects ([`firmware::bus::master::Replies::All`]).
pub fn replies_to_all(protocol: Protocol) -> i64 {
    match protocol {
        Protocol::Dxl2 => 2,
        Protocol::Feetech => 1,
    }
}

/// A healthy servo of `model` as the checks' tests start from: firmware 3.10, 7.4 V, 30 °C, no
/// error, return delay 0, answering everything, torque off, standing at its goal (2048).
#[cfg(test)]
pub fn healthy(id: Id, model: &'static Model) -> Reading {
    Reading {
        servo: Servo { id, model_number: model.number, model: Some(model), firmware: Some(3) },
        firmware_minor: Some(10),
        voltage_dv: Some(74),
        voltage_limits_dv: None,
        temperature_c: Some(30),
        temperature_limit_c: None,
        hardware_error: Some(0),
        return_delay: Some(0),
        status_return_level: Some(replies_to_all(model.protocol)),
        torque: Some(false),
        goal: Some(2048),
        present: Some(2048),
        homing_offset: Some(0),
        collision: None,
        failed: Vec::new(),
    }
}
