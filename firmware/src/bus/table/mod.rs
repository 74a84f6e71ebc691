//! Typed control-table items of the supported servo models.
//!
//! A servo is configured and commanded by reading and writing its control table, a byte array
//! whose addresses and widths are fixed per model. An [`Item`] names one entry with its width, its
//! access, its memory area and how its bytes represent a number; a [`Model`] gathers the items the
//! firmware and the tools use, plus the numbers needed to simulate one (units, defaults, limits).
//! Values are `i32`: every item of these models fits in it (4-byte Dynamixel items are two's
//! complement; Feetech marks negatives with a sign bit).

pub mod sts3215;
pub mod xseries;

pub use sts3215::STS3215;
pub use xseries::{XL330_M288, XL430_W250, XM430_W350};

use super::feetech::value::{decode_u16, encode_u16, from_sign_magnitude, to_sign_magnitude, Endian};
use super::Protocol;

/// Whether the master may write an item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Read only (present values, model number).
    Read,
    /// Read and write.
    ReadWrite,
}

/// How an item's bytes represent a number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Unsigned.
    Unsigned,
    /// Two's complement (Dynamixel).
    Signed,
    /// Sign and magnitude, the sign in this bit (Feetech: bit 15 of positions and velocities).
    SignMagnitude(u8),
}

/// One control-table entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Item {
    /// The name used by the tools (`goal_position`).
    pub name: &'static str,
    /// First address.
    pub address: u16,
    /// Width in bytes: 1, 2 or 4.
    pub size: u8,
    /// Who may write it.
    pub access: Access,
    /// How the bytes represent a number.
    pub encoding: Encoding,
}

/// Why a value does not fit an item, or bytes are not one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueError {
    /// The value is outside what the item's width and encoding can hold.
    OutOfRange {
        /// The item.
        item: &'static str,
        /// The value.
        value: i64,
    },
    /// The byte count does not match the item's width.
    WrongSize {
        /// The item.
        item: &'static str,
        /// Bytes given.
        len: usize,
    },
}

impl core::fmt::Display for ValueError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::OutOfRange { item, value } => write!(f, "{value} does not fit {item}"),
            Self::WrongSize { item, len } => write!(f, "{len} bytes are not a value of {item}"),
        }
    }
}

impl Item {
    const fn new(name: &'static str, address: u16, size: u8, access: Access, encoding: Encoding) -> Self {
        Self { name, address, size, access, encoding }
    }

    /// Bytes of the item on the wire.
    pub fn len(&self) -> usize {
        usize::from(self.size)
    }

    /// Whether the item has no bytes (never, for the tables here; for completeness).
    pub fn is_empty(&self) -> bool {
        self.size == 0
    }

    /// The range of values the item can hold.
    pub fn range(&self) -> (i64, i64) {
        let bits = u32::from(self.size) * 8;
        match self.encoding {
            Encoding::Unsigned => (0, (1i64 << bits) - 1),
            Encoding::Signed => (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1),
            Encoding::SignMagnitude(bit) => {
                let max = (1i64 << bit) - 1;
                (-max, max)
            }
        }
    }

    /// Encodes `value` into `out[..self.len()]` in the model's byte order.
    pub fn encode(&self, value: i64, endian: Endian, out: &mut [u8]) -> Result<(), ValueError> {
        let (lo, hi) = self.range();
        let available = out.len();
        let out = out.get_mut(..self.len()).ok_or(ValueError::WrongSize { item: self.name, len: available })?;
        if value < lo || value > hi {
            return Err(ValueError::OutOfRange { item: self.name, value });
        }
        let raw: u32 = match self.encoding {
            Encoding::SignMagnitude(bit) => {
                // In range, so it fits both i32 and the magnitude below the sign bit.
                let v = i32::try_from(value).map_err(|_| ValueError::OutOfRange { item: self.name, value })?;
                u32::from(to_sign_magnitude(v, bit).ok_or(ValueError::OutOfRange { item: self.name, value })?)
            }
            // Two's complement truncated to the width: in range, so nothing is lost.
            _ => value as u32,
        };
        let bytes = match (self.size, endian) {
            (1, _) => [raw as u8, 0, 0, 0],
            (2, _) => {
                let [a, b] = encode_u16(raw as u16, endian);
                [a, b, 0, 0]
            }
            (_, Endian::Little) => raw.to_le_bytes(),
            (_, Endian::Big) => raw.to_be_bytes(),
        };
        // `out` is exactly `self.len()` bytes long (1, 2 or 4): a zip, so no length check can panic.
        out.iter_mut().zip(bytes).for_each(|(o, b)| *o = b);
        Ok(())
    }

    /// Decodes the item's value from exactly `self.len()` bytes.
    pub fn decode(&self, bytes: &[u8], endian: Endian) -> Result<i64, ValueError> {
        let wrong = ValueError::WrongSize { item: self.name, len: bytes.len() };
        let raw: u32 = match (bytes, endian) {
            ([b], _) if self.size == 1 => u32::from(*b),
            ([a, b], _) if self.size == 2 => u32::from(decode_u16([*a, *b], endian)),
            ([a, b, c, d], Endian::Little) if self.size == 4 => u32::from_le_bytes([*a, *b, *c, *d]),
            ([a, b, c, d], Endian::Big) if self.size == 4 => u32::from_be_bytes([*a, *b, *c, *d]),
            _ => return Err(wrong),
        };
        Ok(match self.encoding {
            Encoding::Unsigned => i64::from(raw),
            Encoding::Signed => match self.size {
                1 => i64::from(raw as u8 as i8),
                2 => i64::from(raw as u16 as i16),
                _ => i64::from(raw as i32),
            },
            // Feetech sign-magnitude items are at most 2 bytes wide.
            Encoding::SignMagnitude(bit) => i64::from(from_sign_magnitude(raw as u16, bit)),
        })
    }
}

/// A servo model: its control table and what a simulator needs to behave like it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Model {
    /// Product name.
    pub name: &'static str,
    /// Model number, as a ping (Dynamixel) or the model item reports it.
    pub number: u16,
    /// Firmware version the simulator reports.
    pub firmware: u8,
    /// The bus protocol.
    pub protocol: Protocol,
    /// Byte order of multi-byte items.
    pub endian: Endian,
    /// Encoder ticks per revolution.
    pub ticks_per_revolution: u32,
    /// Addresses below this are EEPROM: written only with torque off (Dynamixel) or unlocked
    /// (Feetech `lock`).
    pub eeprom_end: u16,
    /// Bytes of control table the simulator holds.
    pub table_len: u16,
    /// Baud rates by the value of the baud item.
    pub bauds: &'static [(u8, u32)],
    /// Microseconds per unit of the return delay item.
    pub return_delay_unit_us: u32,
    /// Ticks per second per unit of the profile (or goal) velocity item; its value 0 means "as
    /// fast as the motor goes".
    pub velocity_unit: f32,
    /// Ticks per second squared per unit of the profile acceleration item; 0 means unlimited.
    pub acceleration_unit: f32,
    /// The motor's no-load speed in ticks per second: the speed when the profile sets none.
    pub max_velocity: f32,
    /// The items a master uses, by role.
    pub items: Items,
    /// Factory values written into a fresh control table: (item, value). Only the simulator
    /// needs them: they are compiled in with the `factory-defaults` feature (the host crates turn
    /// it on) and empty on the boards, where they would only take flash.
    pub defaults: &'static [(Item, i64)],
    /// How the model caps and reports its effort (`None`: it cannot, as the XL430-W250, which
    /// has no current sensing).
    pub force: Option<Force>,
}

/// The items through which a model's effort (torque or current) is capped and read, and their
/// values at 100 %: what a gripper needs to grip without burning its servo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Force {
    /// The RAM item that caps the effort: STS3215 `Torque_Limit`, X-series `Goal_Current` (in
    /// current-based position mode).
    pub limit: Item,
    /// Its value at full effort.
    pub limit_full: u16,
    /// The item that reports the effort: STS3215 `Present_Load`, X-series `Present_Current`.
    pub present: Item,
    /// Its magnitude at full effort.
    pub present_full: u16,
}

/// The items of a model by role, so that code works across models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Items {
    /// Model number.
    pub model_number: Item,
    /// Firmware version.
    pub firmware: Item,
    /// Bus id.
    pub id: Item,
    /// Baud rate index (see [`Model::bauds`]).
    pub baud: Item,
    /// Return delay.
    pub return_delay: Item,
    /// Lower position limit.
    pub min_position: Item,
    /// Upper position limit.
    pub max_position: Item,
    /// Torque enable (1 on, 0 off).
    pub torque_enable: Item,
    /// Status return level (Dynamixel 0 ping only, 1 reads, 2 all; Feetech 0 none, 1 all).
    pub status_return_level: Item,
    /// Profile acceleration (Dynamixel) or acceleration (Feetech).
    pub acceleration: Item,
    /// Profile velocity (Dynamixel) or goal velocity (Feetech).
    pub velocity: Item,
    /// Goal position.
    pub goal_position: Item,
    /// Whether the servo is moving.
    pub moving: Item,
    /// Present position.
    pub present_position: Item,
    /// Dynamixel hardware error status (the alert bit's details); Feetech has none.
    pub hardware_error: Option<Item>,
    /// Feetech EEPROM lock (0 unlocked); Dynamixel has none.
    pub lock: Option<Item>,
}

/// Every model the crate knows.
pub const MODELS: [&Model; 4] = [&XL430_W250, &XM430_W350, &XL330_M288, &STS3215];

impl Model {
    /// The model with this number on this protocol.
    pub fn by_number(protocol: Protocol, number: u16) -> Option<&'static Model> {
        MODELS.into_iter().find(|m| m.protocol == protocol && m.number == number)
    }

    /// The baud rate of a baud item value.
    pub fn baud_rate(&self, index: u8) -> Option<u32> {
        self.bauds.iter().find(|(i, _)| *i == index).map(|(_, b)| *b)
    }

    /// The baud item value of a baud rate.
    pub fn baud_index(&self, baud: u32) -> Option<u8> {
        self.bauds.iter().find(|(_, b)| *b == baud).map(|(i, _)| *i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dynamixel_items_are_little_endian_twos_complement() {
        let mut out = [0u8; 4];
        // e-manual WRITE example: goal position 512 is `00 02 00 00`.
        xseries::GOAL_POSITION.encode(512, Endian::Little, &mut out).unwrap();
        assert_eq!(out, [0x00, 0x02, 0x00, 0x00]);
        xseries::PRESENT_POSITION.encode(-2, Endian::Little, &mut out).unwrap();
        assert_eq!(out, [0xFE, 0xFF, 0xFF, 0xFF]);
        assert_eq!(xseries::PRESENT_POSITION.decode(&out, Endian::Little), Ok(-2));
        assert_eq!(
            xseries::TORQUE_ENABLE.encode(256, Endian::Little, &mut out),
            Err(ValueError::OutOfRange { item: "torque_enable", value: 256 })
        );
        assert_eq!(
            xseries::GOAL_POSITION.decode(&[1, 2], Endian::Little),
            Err(ValueError::WrongSize { item: "goal_position", len: 2 })
        );
    }

    #[test]
    fn feetech_items_carry_their_sign_in_a_bit() {
        let mut out = [0u8; 2];
        // Feetech manual, READ example reply: position bytes `18 05` (SCS, big-endian) = 0x1805.
        assert_eq!(sts3215::PRESENT_POSITION.decode(&[0x18, 0x05], Endian::Big), Ok(0x1805));
        sts3215::GOAL_POSITION.encode(-1, Endian::Little, &mut out).unwrap();
        assert_eq!(out, [0x01, 0x80]);
        assert_eq!(sts3215::GOAL_POSITION.decode(&out, Endian::Little), Ok(-1));
        assert_eq!(sts3215::HOMING_OFFSET.range(), (-2047, 2047));
        assert!(sts3215::HOMING_OFFSET.encode(2048, Endian::Little, &mut out).is_err());
    }

    #[test]
    fn every_item_a_model_uses_lies_inside_its_table() {
        for model in MODELS {
            let i = model.items;
            let roles = [i.return_delay, i.torque_enable, i.acceleration, i.goal_position, i.present_position];
            let defaults = model.defaults.iter().map(|(item, _)| *item);
            // LeRobot's `configure_motors` writes it, so a simulated STS3215 must hold it.
            let written = (model.protocol == Protocol::Feetech).then_some(sts3215::MAXIMUM_ACCELERATION);
            for item in roles.into_iter().chain(i.lock).chain(i.hardware_error).chain(defaults).chain(written) {
                assert!(item.address + u16::from(item.size) <= model.table_len, "{}: {}", model.name, item.name);
            }
        }
    }

    #[test]
    fn models_are_found_by_number_and_baud() {
        assert_eq!(Model::by_number(Protocol::Dxl2, 1060).map(|m| m.name), Some("XL430-W250"));
        assert_eq!(Model::by_number(Protocol::Feetech, 777).map(|m| m.name), Some("STS3215"));
        assert_eq!(Model::by_number(Protocol::Feetech, 1060), None);
        assert_eq!(XL330_M288.baud_index(1_000_000), Some(3));
        assert_eq!(STS3215.baud_rate(0), Some(1_000_000));
        assert_eq!(STS3215.baud_index(9600), None);
    }
}
