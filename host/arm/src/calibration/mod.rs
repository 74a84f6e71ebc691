//! An arm's calibration: per servo, its id, LeRobot's `drive_mode`, the homing offset written to
//! the servo, and the range of positions it was seen to reach (raw ticks, after the servo applied
//! its offset). The record is LeRobot's `MotorCalibration`, so a calibration made with LeRobot is
//! used as it is, and one made here is one LeRobot accepts.
//!
//! - [`lerobot`]: LeRobot's calibration file (JSON) read and written as LeRobot does, and where
//!   LeRobot keeps it.
//! - [`normalise`]: LeRobot's conversions between raw ticks and its normalised values (degrees for
//!   the body joints, 0 to 100 for the gripper), as `motors_bus.py` computes them.
//! - [`record`]: what LeRobot's calibration procedure measures and makes of an arm (homing
//!   offsets, recorded ranges, the joint limits they leave).

pub mod lerobot;
pub mod normalise;
pub mod record;

use anyhow::{bail, Result};
use firmware::bus::table::{sts3215, xseries, Item, Model};
use firmware::bus::Protocol;

/// One register of a servo that holds part of its calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Register {
    /// The control-table item.
    pub item: Item,
    /// The calibration field it holds, as messages name it.
    pub field: &'static str,
}

/// The Homing_Offset item of `model`'s family: the STS3215's at 31 (2 bytes, sign-magnitude with
/// the sign in bit 11), the X-series' at 20 (4 bytes, two's complement).
pub fn homing_offset_item(model: &Model) -> Item {
    match model.protocol {
        Protocol::Dxl2 => xseries::HOMING_OFFSET,
        Protocol::Feetech => sts3215::HOMING_OFFSET,
    }
}

/// The registers LeRobot reads back as a servo's calibration (`read_calibration`): the homing
/// offset and the position limits, and on Dynamixel the Drive_Mode register, which it reads into
/// `drive_mode` (its Feetech bus reports `drive_mode` 0 whatever the servo).
pub fn registers(model: &Model) -> Vec<Register> {
    let items = model.items;
    let mut r = vec![
        Register { item: homing_offset_item(model), field: "homing offset" },
        Register { item: items.min_position, field: "range_min" },
        Register { item: items.max_position, field: "range_max" },
    ];
    if model.protocol == Protocol::Dxl2 {
        r.push(Register { item: xseries::DRIVE_MODE, field: "drive_mode" });
    }
    r
}

impl MotorCalibration {
    /// The value the calibration gives `register`.
    pub fn value(&self, register: &Register) -> i64 {
        match register.field {
            "homing offset" => i64::from(self.homing_offset),
            "range_min" => i64::from(self.range_min),
            "range_max" => i64::from(self.range_max),
            _ => i64::from(self.drive_mode),
        }
    }
}

/// One servo's calibration (LeRobot's `MotorCalibration`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct MotorCalibration {
    /// Bus id.
    pub id: u8,
    /// 1 when the servo turns against the normalised value (LeRobot applies it in its range modes
    /// only, and on Feetech only; Dynamixel inverts in hardware through its Drive_Mode register).
    pub drive_mode: u8,
    /// The offset written to the servo's Homing_Offset register, ticks.
    pub homing_offset: i32,
    /// Lowest position recorded, ticks (offset-corrected, as the servo reports it).
    pub range_min: i32,
    /// Highest position recorded, ticks.
    pub range_max: i32,
}

/// A whole arm's calibration: the motors by name, in the file's order (LeRobot's: base first,
/// gripper last).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Calibration {
    /// Motor name and calibration, in order.
    pub motors: Vec<(String, MotorCalibration)>,
}

impl Calibration {
    /// The calibration of the motor called `name`.
    pub fn motor(&self, name: &str) -> Option<&MotorCalibration> {
        self.motors.iter().find(|(n, _)| n == name).map(|(_, m)| m)
    }

    /// The calibration of the servo with bus id `id`.
    pub fn by_id(&self, id: u8) -> Option<(&str, &MotorCalibration)> {
        self.motors.iter().find(|(_, m)| m.id == id).map(|(n, m)| (n.as_str(), m))
    }

    /// Checks what LeRobot relies on: at least one motor, distinct names and ids, `drive_mode` 0
    /// or 1, and a range of positive width (LeRobot refuses `range_min == range_max`: every
    /// normalisation divides by it). Errors name the motor.
    pub fn check(&self) -> Result<()> {
        if self.motors.is_empty() {
            bail!("the calibration names no motor");
        }
        for (i, (name, m)) in self.motors.iter().enumerate() {
            if let Some((other, _)) = self.motors[..i].iter().find(|(n, o)| n == name || o.id == m.id) {
                bail!("motors {other:?} and {name:?} have the same name or id ({})", m.id);
            }
            if m.drive_mode > 1 {
                bail!("motor {name:?}: drive_mode {} is neither 0 nor 1", m.drive_mode);
            }
            if m.range_min >= m.range_max {
                bail!(
                    "motor {name:?}: range_min {} is not below range_max {}: a range of zero width (calibrate again)",
                    m.range_min,
                    m.range_max
                );
            }
            if m.range_min < 0 {
                bail!("motor {name:?}: range_min {} is below 0", m.range_min);
            }
        }
        Ok(())
    }
}
