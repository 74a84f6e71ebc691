//! Feetech STS3215 (SO-100/SO-101 arms), from the Feetech STS memory table as LeRobot's
//! `tables.py` transcribes it. Multi-byte items are little-endian; positions and velocities carry
//! their sign in bit 15.

use super::{Access::*, Encoding::*, Force, Item, Items, Model};
use crate::bus::feetech::value::Endian;
use crate::bus::Protocol;

/// Firmware major version.
pub const FIRMWARE_MAJOR_VERSION: Item = Item::new("firmware_major_version", 0, 1, Read, Unsigned);
/// Firmware minor version.
pub const FIRMWARE_MINOR_VERSION: Item = Item::new("firmware_minor_version", 1, 1, Read, Unsigned);
/// Model number (777 for the STS3215).
pub const MODEL_NUMBER: Item = Item::new("model_number", 3, 2, Read, Unsigned);
/// Bus id, 0..=253.
pub const ID: Item = Item::new("id", 5, 1, ReadWrite, Unsigned);
/// Baud rate index: 0 1M, 1 500k, 2 250k, 3 128k, 4 115200, 5 76800, 6 57600, 7 38400.
pub const BAUD_RATE: Item = Item::new("baud_rate", 6, 1, ReadWrite, Unsigned);
/// Return delay in 2 µs units (factory 250 = 500 µs, see [`DEFAULTS`]).
pub const RETURN_DELAY_TIME: Item = Item::new("return_delay_time", 7, 1, ReadWrite, Unsigned);
/// Response status level: 0 replies only to ping and read, 1 to everything.
pub const RESPONSE_STATUS_LEVEL: Item = Item::new("response_status_level", 8, 1, ReadWrite, Unsigned);
/// Lower position limit in steps.
pub const MIN_POSITION_LIMIT: Item = Item::new("min_position_limit", 9, 2, ReadWrite, Unsigned);
/// Upper position limit in steps.
pub const MAX_POSITION_LIMIT: Item = Item::new("max_position_limit", 11, 2, ReadWrite, Unsigned);
/// Homing offset in steps, sign in bit 11.
pub const HOMING_OFFSET: Item = Item::new("homing_offset", 31, 2, ReadWrite, SignMagnitude(11));
/// The ceiling of the torque limit, 0.1 % of the stall torque (factory 1000); LeRobot sets 500 on
/// the SO follower's gripper.
pub const MAX_TORQUE_LIMIT: Item = Item::new("max_torque_limit", 16, 2, ReadWrite, Unsigned);
/// Protection current in 6.5 mA (factory 500; LeRobot sets 250 on the gripper).
pub const PROTECTION_CURRENT: Item = Item::new("protection_current", 28, 2, ReadWrite, Unsigned);
/// Overload torque, percent of the maximum torque: the output above which the servo's overload
/// protection timer runs (Feetech's memory table, factory 80; the output it falls back to once
/// protection trips is the "protective torque" at 34, not modelled). LeRobot sets 25 on the gripper.
pub const OVERLOAD_TORQUE: Item = Item::new("overload_torque", 36, 1, ReadWrite, Unsigned);
/// Torque limit (RAM), 0.1 % of the stall torque; at power-on it takes the max torque limit.
pub const TORQUE_LIMIT: Item = Item::new("torque_limit", 48, 2, ReadWrite, Unsigned);
/// Position loop P gain (factory 32: LeRobot `so_follower.py` `configure`, "Default is 32").
pub const P_COEFFICIENT: Item = Item::new("p_coefficient", 21, 1, ReadWrite, Unsigned);
/// Position loop D gain (factory 32, as LeRobot's `configure` says).
pub const D_COEFFICIENT: Item = Item::new("d_coefficient", 22, 1, ReadWrite, Unsigned);
/// Position loop I gain (factory 0, as LeRobot's `configure` says).
pub const I_COEFFICIENT: Item = Item::new("i_coefficient", 23, 1, ReadWrite, Unsigned);
/// Operating mode (0 position).
pub const OPERATING_MODE: Item = Item::new("operating_mode", 33, 1, ReadWrite, Unsigned);
/// Torque enable.
pub const TORQUE_ENABLE: Item = Item::new("torque_enable", 40, 1, ReadWrite, Unsigned);
/// Acceleration in 100 steps/s² (0 unlimited).
pub const ACCELERATION: Item = Item::new("acceleration", 41, 1, ReadWrite, Unsigned);
/// Goal position in steps.
pub const GOAL_POSITION: Item = Item::new("goal_position", 42, 2, ReadWrite, SignMagnitude(15));
/// Goal time in ms (0: use the goal velocity).
pub const GOAL_TIME: Item = Item::new("goal_time", 44, 2, ReadWrite, Unsigned);
/// Goal velocity in steps/s (0: as fast as the motor goes).
pub const GOAL_VELOCITY: Item = Item::new("goal_velocity", 46, 2, ReadWrite, SignMagnitude(15));
/// EEPROM lock: 0 unlocked (EEPROM writes are kept), 1 locked (factory 0).
pub const LOCK: Item = Item::new("lock", 55, 1, ReadWrite, Unsigned);
/// Present position in steps.
pub const PRESENT_POSITION: Item = Item::new("present_position", 56, 2, Read, SignMagnitude(15));
/// Present velocity in steps/s.
pub const PRESENT_VELOCITY: Item = Item::new("present_velocity", 58, 2, Read, SignMagnitude(15));
/// Present load in 0.1 % of the maximum torque, sign (direction) in bit 10 (LeRobot's
/// `Present_Load`, encoding bit 10).
pub const PRESENT_LOAD: Item = Item::new("present_load", 60, 2, Read, SignMagnitude(10));
/// Voltage in 0.1 V.
pub const PRESENT_VOLTAGE: Item = Item::new("present_voltage", 62, 1, Read, Unsigned);
/// Temperature in °C.
pub const PRESENT_TEMPERATURE: Item = Item::new("present_temperature", 63, 1, Read, Unsigned);
/// Moving (1 while the servo runs toward its goal).
pub const MOVING: Item = Item::new("moving", 66, 1, Read, Unsigned);
/// The ceiling of the acceleration item, in its unit. It lies among the "factory" items past the
/// RAM, which Feetech's published memory table leaves out (LeRobot's `tables.py` lists it;
/// `feetech.py` `configure_motors` writes 254 to it on every connection, so it is read-write).
pub const MAXIMUM_ACCELERATION: Item = Item::new("maximum_acceleration", 85, 1, ReadWrite, Unsigned);

const BAUDS: [(u8, u32); 8] =
    [(0, 1_000_000), (1, 500_000), (2, 250_000), (3, 128_000), (4, 115_200), (5, 76_800), (6, 57_600), (7, 38_400)];

/// Factory values, from Feetech's STS3215 memory table (the "st3215_memory_table" spreadsheet, its
/// "Initial value" column, as exported to TSV in the `st3215` crate's `build.rs`, docs.rs), except
/// where a line says otherwise:
/// - return delay 250 (500 µs): LeRobot `motors/feetech/feetech.py` `configure_motors` ("By default,
///   Feetech motors have a 500µs delay response time (corresponding to a value of 250 on the
///   'Return_Delay_Time' address)"), which is what servos as shipped answer. Feetech's spreadsheet
///   says 0 there, and a later Feetech STS table (wiki.aifitlab.com, "STS Servo – Memory Table
///   Analysis") marks address 7 reserved with no initial value: the published tables and the
///   servos disagree, and the simulator follows the servos;
/// - firmware 3.10: the version of the servos LeRobot's users report; the spreadsheet's column
///   shows 3.6 (the version when it was written). Servos of different batches differ, which is
///   what `--register ID:firmware_minor_version=N` shows;
/// - maximum acceleration (85): no table gives its factory value (Feetech's leaves the item out;
///   LeRobot's `tables.py` lists no values), so it stays 0 here;
/// - present voltage and temperature are readings, not factory values: 7.4 V (the SO-101's
///   supply) and 30 °C.
///
/// Items the project reads or writes whose spreadsheet value is 0 (homing offset, operating mode,
/// torque enable, acceleration, goal time and velocity) are listed too, so that the list is the
/// whole of it.
#[cfg(feature = "factory-defaults")]
const DEFAULTS: &[(Item, i64)] = &[
    (FIRMWARE_MAJOR_VERSION, 3),
    (FIRMWARE_MINOR_VERSION, 10),
    (MODEL_NUMBER, 777),
    (ID, 1),
    (BAUD_RATE, 0),
    (RETURN_DELAY_TIME, 250),
    (RESPONSE_STATUS_LEVEL, 1),
    (MIN_POSITION_LIMIT, 0),
    (MAX_POSITION_LIMIT, 4095),
    // "Maximum torque" 1000 (100 % of the stall torque), copied to the torque limit (48) at power-on.
    (MAX_TORQUE_LIMIT, 1000),
    (P_COEFFICIENT, 32),
    (D_COEFFICIENT, 32),
    (I_COEFFICIENT, 0),
    // 500 x 6.5 mA = 3.25 A.
    (PROTECTION_CURRENT, 500),
    (HOMING_OFFSET, 0),
    (OPERATING_MODE, 0),
    // 80 % of the maximum torque starts the overload timer.
    (OVERLOAD_TORQUE, 80),
    (TORQUE_ENABLE, 0),
    (ACCELERATION, 0),
    (GOAL_TIME, 0),
    (GOAL_VELOCITY, 0),
    (TORQUE_LIMIT, 1000),
    // 0: EEPROM writes are kept (the spreadsheet's initial value; LeRobot writes 0 before its
    // EEPROM writes and 1 after them anyway).
    (LOCK, 0),
    (PRESENT_VOLTAGE, 74),
    (PRESENT_TEMPERATURE, 30),
    (MAXIMUM_ACCELERATION, 0),
];

/// Boards hold no factory values: only the simulator writes them into a table (see [`Model::defaults`]).
#[cfg(not(feature = "factory-defaults"))]
const DEFAULTS: &[(Item, i64)] = &[];

/// STS3215 (model 777): 4096 steps per revolution, 1 Mbps from the factory, about 45 rev/min
/// without load at 7.4 V (0.222 s per 60°).
pub const STS3215: Model = Model {
    name: "STS3215",
    number: 777,
    firmware: 3,
    protocol: Protocol::Feetech,
    endian: Endian::Little,
    ticks_per_revolution: 4096,
    eeprom_end: 40,
    // Up to the last "factory" item of LeRobot's `tables.py` (86, the acceleration multiplier), so
    // that a simulated servo holds `maximum_acceleration` (85).
    table_len: 87,
    bauds: &BAUDS,
    return_delay_unit_us: 2,
    velocity_unit: 1.0,
    acceleration_unit: 100.0,
    max_velocity: 45.0 * 4096.0 / 60.0,
    items: Items {
        model_number: MODEL_NUMBER,
        firmware: FIRMWARE_MAJOR_VERSION,
        id: ID,
        baud: BAUD_RATE,
        return_delay: RETURN_DELAY_TIME,
        min_position: MIN_POSITION_LIMIT,
        max_position: MAX_POSITION_LIMIT,
        torque_enable: TORQUE_ENABLE,
        status_return_level: RESPONSE_STATUS_LEVEL,
        acceleration: ACCELERATION,
        velocity: GOAL_VELOCITY,
        goal_position: GOAL_POSITION,
        moving: MOVING,
        present_position: PRESENT_POSITION,
        hardware_error: None,
        lock: Some(LOCK),
    },
    defaults: DEFAULTS,
    // The torque limit caps the output, the present load reports it, both in 0.1 %.
    force: Some(Force { limit: TORQUE_LIMIT, limit_full: 1000, present: PRESENT_LOAD, present_full: 1000 }),
};
