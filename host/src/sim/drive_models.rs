//! Which drive ([`super::drive`]) each servo model has, and the registers its drive reads (gains,
//! duty limit) and writes (speed, load or current, temperature).
//!
//! The drive's figures are in [`super::drive_table`], each with its source.

use firmware::bus::table::{sts3215, xseries, Item, Model};

use super::drive::{Drive, DriveModel, Loop};
use super::drive_table;

/// The STS3215's temperature limit (`Max_Temperature_Limit`, address 13, factory 70 °C): the
/// simulator's table has no item for it, so it is fixed.
pub const STS_TEMPERATURE_LIMIT_C: i64 = 70;

/// The drive of a servo of `model` on a supply of `volts` (the STS3215 comes in a 7.4 V and a
/// 12 V build: a reading of 10 V or more is taken for the 12 V one). `None` for a model without
/// one.
pub fn drive_model(model: &Model, volts: f64) -> Option<DriveModel> {
    Some(match model.name {
        "STS3215" if volts >= 10.0 => drive_table::STS3215_12V,
        "STS3215" => drive_table::STS3215_7V4,
        "XL330-M288" => drive_table::XL330_M288,
        "XL430-W250" => drive_table::XL430_W250,
        "XM430-W350" => drive_table::XM430_W350,
        _ => return None,
    })
}

/// How a model reports its effort.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Effort {
    /// The duty in 0.1 % (STS3215 `Present_Load`, XL430-W250 `Present_Load`).
    Duty(Item),
    /// The current, in amperes per unit (XM430-W350 2.69 mA, XL330-M288 1 mA).
    Current(Item, f64),
}

/// The registers a model's drive acts with and reports through.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveRegisters {
    p_gain: Item,
    /// The duty limit, and its value at 100 %.
    limit: (Item, f64),
    present_velocity: Item,
    /// The supply's reading, 0.1 V.
    voltage: Item,
    effort: Effort,
    temperature: Item,
    /// The overheat threshold's item (`None`: [`STS_TEMPERATURE_LIMIT_C`]).
    temperature_limit: Option<Item>,
    /// Ticks per second of one velocity unit.
    velocity_unit: f64,
}

impl DriveRegisters {
    /// Those of `model` (Feetech's or Dynamixel X's layout).
    pub fn of(model: &Model) -> Self {
        let velocity_unit = f64::from(model.velocity_unit);
        if model.protocol == firmware::bus::Protocol::Feetech {
            return Self {
                p_gain: sts3215::P_COEFFICIENT,
                limit: (sts3215::TORQUE_LIMIT, 1000.0),
                present_velocity: sts3215::PRESENT_VELOCITY,
                voltage: sts3215::PRESENT_VOLTAGE,
                effort: Effort::Duty(sts3215::PRESENT_LOAD),
                temperature: sts3215::PRESENT_TEMPERATURE,
                temperature_limit: None,
                velocity_unit,
            };
        }
        let effort = match model.name {
            "XM430-W350" => Effort::Current(xseries::PRESENT_CURRENT, 2.69e-3),
            "XL330-M288" => Effort::Current(xseries::PRESENT_CURRENT, 1e-3),
            // The XL430-W250 senses no current: address 126 is its Present_Load, in 0.1 %.
            _ => Effort::Duty(xseries::PRESENT_CURRENT),
        };
        Self {
            p_gain: xseries::POSITION_P_GAIN,
            limit: (xseries::PWM_LIMIT, 885.0),
            present_velocity: xseries::PRESENT_VELOCITY,
            voltage: xseries::PRESENT_INPUT_VOLTAGE,
            effort,
            temperature: xseries::PRESENT_TEMPERATURE,
            temperature_limit: Some(xseries::TEMPERATURE_LIMIT),
            velocity_unit,
        }
    }

    /// The loop a servo whose table reads `get` acts with: its P gain register, its duty limit,
    /// its `torque`.
    pub fn control(&self, get: impl Fn(Item) -> i64, torque: bool) -> Loop {
        let (limit, full) = self.limit;
        Loop { kp: get(self.p_gain) as f64, limit: (get(limit) as f64 / full).clamp(0.0, 1.0), torque }
    }

    /// The readings `drive` gives, each with its item: speed, temperature and, with `effort`, the
    /// load or current (a servo against a stop or an object reports the stall model's instead).
    pub fn readings(&self, drive: &Drive, per_tick: f64, effort: bool) -> Vec<(Item, i64)> {
        let ticks_per_second = drive.speed() / per_tick;
        let (effort_item, effort_value) = match self.effort {
            Effort::Duty(item) => (item, (drive.duty() * 1000.0).round() as i64),
            Effort::Current(item, unit) => (item, (drive.current() / unit).round() as i64),
        };
        let mut readings = vec![
            (self.present_velocity, (ticks_per_second / self.velocity_unit).round() as i64),
            (self.temperature, drive.temperature().round() as i64),
        ];
        if effort {
            readings.push((effort_item, effort_value));
        }
        readings
    }

    /// The item of the loop's P gain.
    pub fn p_gain(&self) -> Item {
        self.p_gain
    }

    /// The item that reads the supply, in 0.1 V.
    pub fn voltage(&self) -> Item {
        self.voltage
    }

    /// The supply (V) a servo of `model` reads from the factory (the simulator's table).
    pub fn factory_volts(&self, model: &Model) -> f64 {
        model.defaults.iter().find(|(item, _)| *item == self.voltage).map_or(0.0, |&(_, v)| v as f64 / 10.0)
    }

    /// The item that reports the temperature.
    pub fn temperature(&self) -> Item {
        self.temperature
    }

    /// The temperature (°C) at which a servo whose table reads `get` stops for overheating.
    pub fn temperature_limit(&self, get: impl Fn(Item) -> i64) -> f64 {
        self.temperature_limit.map_or(STS_TEMPERATURE_LIMIT_C, get) as f64
    }
}
