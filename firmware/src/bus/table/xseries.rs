//! ROBOTIS X-series on Protocol 2.0 (e-manual "XL430-W250", "XM430-W350", "XL330-M288" control
//! tables). The three share the addresses used here; they differ in model number, factory baud
//! rate and speed.

use super::{Access::*, Encoding::*, Force, Item, Items, Model};
use crate::bus::feetech::value::Endian;
use crate::bus::Protocol;

/// Model number (2 bytes, read only).
pub const MODEL_NUMBER: Item = Item::new("model_number", 0, 2, Read, Unsigned);
/// Firmware version.
pub const FIRMWARE_VERSION: Item = Item::new("firmware_version", 6, 1, Read, Unsigned);
/// Bus id, 0..=252.
pub const ID: Item = Item::new("id", 7, 1, ReadWrite, Unsigned);
/// Baud rate index: 0 9600, 1 57600, 2 115200, 3 1M, 4 2M, 5 3M, 6 4M, 7 4.5M.
pub const BAUD_RATE: Item = Item::new("baud_rate", 8, 1, ReadWrite, Unsigned);
/// Return delay in 2 µs units (factory 250 = 500 µs).
pub const RETURN_DELAY_TIME: Item = Item::new("return_delay_time", 9, 1, ReadWrite, Unsigned);
/// Drive mode (bit 0 reverse direction, bit 2 time-based profile).
pub const DRIVE_MODE: Item = Item::new("drive_mode", 10, 1, ReadWrite, Unsigned);
/// Operating mode (3 position control).
pub const OPERATING_MODE: Item = Item::new("operating_mode", 11, 1, ReadWrite, Unsigned);
/// Homing offset in ticks.
pub const HOMING_OFFSET: Item = Item::new("homing_offset", 20, 4, ReadWrite, Signed);
/// Temperature limit, °C: above it the servo raises its overheating error and drops torque
/// (factory: XL430-W250 72, XM430-W350 80, XL330-M288 70).
pub const TEMPERATURE_LIMIT: Item = Item::new("temperature_limit", 31, 1, ReadWrite, Unsigned);
/// Highest input voltage, 0.1 V: outside the two limits the servo raises its input voltage error
/// (factory: XL430-W250 140, XM430-W350 160, XL330-M288 70).
pub const MAX_VOLTAGE_LIMIT: Item = Item::new("max_voltage_limit", 32, 2, ReadWrite, Unsigned);
/// Lowest input voltage, 0.1 V (factory: XL430-W250 60, XM430-W350 95, XL330-M288 35).
pub const MIN_VOLTAGE_LIMIT: Item = Item::new("min_voltage_limit", 34, 2, ReadWrite, Unsigned);
/// Current limit in the model's current unit (XM430-W350 2.69 mA, factory 1193; XL330-M288 1 mA,
/// factory 1750); the XL430-W250 has no current sensing and no such item.
pub const CURRENT_LIMIT: Item = Item::new("current_limit", 38, 2, ReadWrite, Unsigned);
/// The motor's duty limit, in 0.113 % (885 = 100 %).
pub const PWM_LIMIT: Item = Item::new("pwm_limit", 36, 2, ReadWrite, Unsigned);
/// Velocity limit in 0.229 rev/min.
pub const VELOCITY_LIMIT: Item = Item::new("velocity_limit", 44, 4, ReadWrite, Unsigned);
/// Upper position limit in ticks.
pub const MAX_POSITION_LIMIT: Item = Item::new("max_position_limit", 48, 4, ReadWrite, Unsigned);
/// Lower position limit in ticks.
pub const MIN_POSITION_LIMIT: Item = Item::new("min_position_limit", 52, 4, ReadWrite, Unsigned);
/// Torque enable: 1 on (locks the EEPROM area), 0 off.
pub const TORQUE_ENABLE: Item = Item::new("torque_enable", 64, 1, ReadWrite, Unsigned);
/// LED.
pub const LED: Item = Item::new("led", 65, 1, ReadWrite, Unsigned);
/// Status return level: 0 ping only, 1 ping and reads, 2 all.
pub const STATUS_RETURN_LEVEL: Item = Item::new("status_return_level", 68, 1, ReadWrite, Unsigned);
/// Registered instruction (1 after a reg write, until action).
pub const REGISTERED_INSTRUCTION: Item = Item::new("registered_instruction", 69, 1, Read, Unsigned);
/// Hardware error status: bit 0 input voltage, 2 overheating, 3 motor encoder, 4 electrical
/// shock, 5 overload. Any bit sets the alert bit of every status packet.
pub const HARDWARE_ERROR_STATUS: Item = Item::new("hardware_error_status", 70, 1, Read, Unsigned);
/// The position loop's D gain (KPD = value / 16).
pub const POSITION_D_GAIN: Item = Item::new("position_d_gain", 80, 2, ReadWrite, Unsigned);
/// The position loop's P gain (KPP = value / 128).
pub const POSITION_P_GAIN: Item = Item::new("position_p_gain", 84, 2, ReadWrite, Unsigned);
/// Goal current (current-based position mode 5 caps the motor current at it), in the current
/// unit, up to the current limit.
pub const GOAL_CURRENT: Item = Item::new("goal_current", 102, 2, ReadWrite, Signed);
/// Profile acceleration in 214.577 rev/min² (0 unlimited).
pub const PROFILE_ACCELERATION: Item = Item::new("profile_acceleration", 108, 4, ReadWrite, Unsigned);
/// Profile velocity in 0.229 rev/min (0 unlimited).
pub const PROFILE_VELOCITY: Item = Item::new("profile_velocity", 112, 4, ReadWrite, Unsigned);
/// Goal position in ticks.
pub const GOAL_POSITION: Item = Item::new("goal_position", 116, 4, ReadWrite, Signed);
/// Moving (1 while the profile runs).
pub const MOVING: Item = Item::new("moving", 122, 1, Read, Unsigned);
/// Present current in the current unit (signed: the direction of the torque).
pub const PRESENT_CURRENT: Item = Item::new("present_current", 126, 2, Read, Signed);
/// Present velocity in 0.229 rev/min.
pub const PRESENT_VELOCITY: Item = Item::new("present_velocity", 128, 4, Read, Signed);
/// Present position in ticks.
pub const PRESENT_POSITION: Item = Item::new("present_position", 132, 4, Read, Signed);
/// Input voltage in 0.1 V.
pub const PRESENT_INPUT_VOLTAGE: Item = Item::new("present_input_voltage", 144, 2, Read, Unsigned);
/// Temperature in °C.
pub const PRESENT_TEMPERATURE: Item = Item::new("present_temperature", 146, 1, Read, Unsigned);

const ITEMS: Items = Items {
    model_number: MODEL_NUMBER,
    firmware: FIRMWARE_VERSION,
    id: ID,
    baud: BAUD_RATE,
    return_delay: RETURN_DELAY_TIME,
    min_position: MIN_POSITION_LIMIT,
    max_position: MAX_POSITION_LIMIT,
    torque_enable: TORQUE_ENABLE,
    status_return_level: STATUS_RETURN_LEVEL,
    acceleration: PROFILE_ACCELERATION,
    velocity: PROFILE_VELOCITY,
    goal_position: GOAL_POSITION,
    moving: MOVING,
    present_position: PRESENT_POSITION,
    hardware_error: Some(HARDWARE_ERROR_STATUS),
    lock: None,
};

const BAUDS: [(u8, u32); 8] = [
    (0, 9600),
    (1, 57_600),
    (2, 115_200),
    (3, 1_000_000),
    (4, 2_000_000),
    (5, 3_000_000),
    (6, 4_000_000),
    (7, 4_500_000),
];

/// 0.229 rev/min in ticks per second (4096 ticks per revolution).
const VELOCITY_UNIT: f32 = 0.229 * 4096.0 / 60.0;
/// 214.577 rev/min² in ticks per second squared.
const ACCELERATION_UNIT: f32 = 214.577 * 4096.0 / 3600.0;

/// Factory values of the three models: the "Initial Value" (or "Default Value") column of the
/// ROBOTIS e-manual's control tables, "XL430-W250-T", "XM430-W350" and "XL330-M288-T" (EEPROM and
/// RAM areas): id 1, baud index 1 (57600), return delay 250 (500 µs), drive mode 0, operating mode
/// 3 (position), homing offset 0, the temperature and voltage limits of each model (above), position limits 0 and 4095, torque off, LED off, status return
/// level 2 (all), profile acceleration and velocity 0 (unlimited), and per model the velocity
/// limit (XL430-W250 265, XM430-W350 200, XL330-M288 445) and the current limit (XM430-W350 1193,
/// XL330-M288 1750; the XL430-W250 has none), the PWM limit 885 (100 %), and the position loop's
/// P and D gains (XL430-W250 640 and 4000, XM430-W350 800 and 0, XL330-M288 400 and 0) (the
/// simulator's servos act with them).
///
/// Not factory values:
/// - goal current: the e-manual gives none ("-"); it starts at the current limit here, so that a
///   current-based position mode is not capped before anyone writes it;
/// - present input voltage and temperature are readings: each model at the supply its speed below
///   is given at (12 V for the XL430 and XM430, 5 V for the XL330: a 12 V reading there would be
///   an XL330 on the wrong supply) and 30 °C.
#[cfg(feature = "factory-defaults")]
const fn defaults(
    velocity_limit: i64,
    current_limit: i64,
    volts_x10: i64,
    (temperature_limit, max_volts_x10, min_volts_x10): (i64, i64, i64),
    (p_gain, d_gain): (i64, i64),
) -> [(Item, i64); 24] {
    [
        (ID, 1),
        (BAUD_RATE, 1),
        (RETURN_DELAY_TIME, 250),
        (DRIVE_MODE, 0),
        (OPERATING_MODE, 3),
        (HOMING_OFFSET, 0),
        (TEMPERATURE_LIMIT, temperature_limit),
        (MAX_VOLTAGE_LIMIT, max_volts_x10),
        (MIN_VOLTAGE_LIMIT, min_volts_x10),
        (PWM_LIMIT, 885),
        (CURRENT_LIMIT, current_limit),
        (VELOCITY_LIMIT, velocity_limit),
        (MAX_POSITION_LIMIT, 4095),
        (MIN_POSITION_LIMIT, 0),
        (TORQUE_ENABLE, 0),
        (LED, 0),
        (STATUS_RETURN_LEVEL, 2),
        (POSITION_D_GAIN, d_gain),
        (POSITION_P_GAIN, p_gain),
        (GOAL_CURRENT, current_limit),
        (PROFILE_ACCELERATION, 0),
        (PROFILE_VELOCITY, 0),
        (PRESENT_INPUT_VOLTAGE, volts_x10),
        (PRESENT_TEMPERATURE, 30),
    ]
}

#[cfg(feature = "factory-defaults")]
const XL430_DEFAULTS: &[(Item, i64)] = &defaults(265, 0, 120, (72, 140, 60), (640, 4000));
#[cfg(feature = "factory-defaults")]
const XM430_DEFAULTS: &[(Item, i64)] = &defaults(200, 1193, 120, (80, 160, 95), (800, 0));
#[cfg(feature = "factory-defaults")]
const XL330_DEFAULTS: &[(Item, i64)] = &defaults(445, 1750, 50, (70, 70, 35), (400, 0));
// Boards hold no factory values: only the simulator writes them into a table (see
// [`Model::defaults`]).
#[cfg(not(feature = "factory-defaults"))]
const XL430_DEFAULTS: &[(Item, i64)] = &[];
#[cfg(not(feature = "factory-defaults"))]
const XM430_DEFAULTS: &[(Item, i64)] = &[];
#[cfg(not(feature = "factory-defaults"))]
const XL330_DEFAULTS: &[(Item, i64)] = &[];

/// The effort of a model with current sensing: the goal current caps it (in current-based
/// position mode), the present current reports it; full is the factory current limit.
const fn current(full: u16) -> Option<Force> {
    Some(Force { limit: GOAL_CURRENT, limit_full: full, present: PRESENT_CURRENT, present_full: full })
}

const fn x_series(
    name: &'static str,
    number: u16,
    max_rpm: f32,
    defaults: &'static [(Item, i64)],
    force: Option<Force>,
) -> Model {
    Model {
        name,
        number,
        firmware: 46,
        protocol: Protocol::Dxl2,
        endian: Endian::Little,
        ticks_per_revolution: 4096,
        eeprom_end: 64,
        table_len: 148,
        bauds: &BAUDS,
        return_delay_unit_us: 2,
        velocity_unit: VELOCITY_UNIT,
        acceleration_unit: ACCELERATION_UNIT,
        max_velocity: max_rpm * 4096.0 / 60.0,
        items: ITEMS,
        defaults,
        force,
    }
}

/// XL430-W250 (model 1060): 57 rev/min without load at 12 V.
pub const XL430_W250: Model = x_series("XL430-W250", 1060, 57.0, XL430_DEFAULTS, None);
/// XM430-W350 (model 1020): 46 rev/min without load at 12 V.
pub const XM430_W350: Model = x_series("XM430-W350", 1020, 46.0, XM430_DEFAULTS, current(1193));
/// XL330-M288 (model 1200): 103 rev/min without load at 5 V.
pub const XL330_M288: Model = x_series("XL330-M288", 1200, 103.0, XL330_DEFAULTS, current(1750));
