//! The status error byte: one bit per fault condition.
//!
//! Bits, from the SCServo SDK (`ERRBIT_*` in `protocol_packet_handler.py`, also used by LeRobot's
//! Feetech bus) and the STS memory table's protection settings: bit 0 input voltage, bit 1 angle
//! sensor, bit 2 overheat, bit 3 overcurrent (`ERRBIT_OVERELE`), bit 5 overload. Bits 4, 6 and 7
//! are not defined by Feetech's SDK (the old SCS15 manual leaves them blank; some compatible
//! vendors' SDKs use bit 4 for an angle error).

use crate::bus::protocol::ErrorText;

/// The error byte of a Feetech status packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct StatusError {
    bits: u8,
}

impl StatusError {
    /// Input voltage outside the configured limits (`ERRBIT_VOLTAGE`).
    pub const VOLTAGE: u8 = 0x01;
    /// Angle (position) sensor fault (`ERRBIT_ANGLE`; the manual's "sensor").
    pub const SENSOR: u8 = 0x02;
    /// Temperature above the limit (`ERRBIT_OVERHEAT`).
    pub const OVERHEAT: u8 = 0x04;
    /// Current above the limit (`ERRBIT_OVERELE`).
    pub const OVERCURRENT: u8 = 0x08;
    /// Load above the limit for too long (`ERRBIT_OVERLOAD`).
    pub const OVERLOAD: u8 = 0x20;

    /// The error byte as received.
    pub fn from_byte(bits: u8) -> Self {
        Self { bits }
    }

    /// The raw byte.
    pub fn bits(&self) -> u8 {
        self.bits
    }

    /// Whether no fault is reported.
    pub fn is_ok(&self) -> bool {
        self.bits == 0
    }

    /// Whether every bit of `mask` (one of the constants, or several or-ed) is set.
    pub fn contains(&self, mask: u8) -> bool {
        self.bits & mask == mask
    }

    /// A one-line description, or `None` when the byte is 0.
    ///
    /// Only the lowest set bit is named, as the SDK's `getRxPacketError` does (it tests voltage,
    /// sensor, overheat, current, overload in that order and returns the first): without
    /// allocation there is no room to list several faults. Read [`StatusError::bits`] for all of
    /// them. `alert` is always `false`: Feetech has no alert bit.
    pub fn describe(&self) -> Option<ErrorText> {
        const NAMES: [&str; 8] = [
            "input voltage out of range",
            "angle sensor fault",
            "overheat",
            "overcurrent",
            "fault bit 4 (undefined by feetech)",
            "overload",
            "fault bit 6 (undefined by feetech)",
            "fault bit 7 (undefined by feetech)",
        ];
        if self.bits == 0 {
            return None;
        }
        let lowest = usize::try_from(self.bits.trailing_zeros()).ok()?;
        NAMES.get(lowest).map(|what| ErrorText { what, alert: false })
    }
}

impl From<u8> for StatusError {
    fn from(bits: u8) -> Self {
        Self::from_byte(bits)
    }
}
