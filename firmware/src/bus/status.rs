//! The contents of a status packet (a servo's reply), protocol-neutral.

use super::Id;

/// A status packet, borrowed from the receive buffer after unstuffing.
///
/// `error` is the raw error byte: on Dynamixel bit 7 is the alert bit (see the servo's hardware
/// error status) and bits 0-6 an error number; on Feetech each bit is a fault condition. The
/// codecs describe it ([`super::dxl2::StatusError`], [`super::feetech::StatusError`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Status<'a> {
    /// The replying servo (0xFE in a Dynamixel fast sync read reply, which carries every servo's
    /// part; see [`super::dxl2::fast_sync_read_parts`]).
    pub id: Id,
    /// The raw error byte.
    pub error: u8,
    /// The data: model and firmware after a ping, the bytes read after a read.
    pub params: &'a [u8],
}
