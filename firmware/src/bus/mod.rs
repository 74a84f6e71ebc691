//! Serial servo buses: Dynamixel Protocol 2.0 and Feetech SCS/STS.
//!
//! Layers, bottom up:
//! - [`instruction`] and [`status`]: the protocol-neutral packet contents, borrowed from a buffer.
//! - [`dxl2`] and [`feetech`]: the codecs. Each encodes instruction and status packets into a byte
//!   slice, finds frame boundaries in received bytes and parses complete frames, checksum first.
//! - [`protocol`]: a runtime choice between the two codecs, so a bus can be picked by configuration.
//! - [`stream`]: a bounded streaming decoder that turns UART bytes, one by one or in bursts, into
//!   complete frames, resynchronising after garbage, partial packets and bad checksums.
//! - [`master`]: transactions over `embedded-io` with per-transaction timeouts, retries, a
//!   half-duplex direction pin, and sync reads that report which ids did not answer.
//! - [`timing`]: wire time of packets and control cycles at a baud rate.
//! - [`table`] and [`mapping`]: typed control-table items of the supported servo models, and the
//!   per-joint conversion between radians and ticks.
//!
//! # Panics
//! No function in this module panics on any input bytes or any argument: every length is checked
//! before it is used, and a buffer too small is an error value ([`EncodeError::BufferTooSmall`]).

pub mod cycle;
pub mod dxl2;
pub mod feetech;
pub mod instruction;
pub mod mapping;
pub mod master;
pub mod protocol;
pub mod status;
pub mod stream;
pub mod table;
pub mod timing;

pub use instruction::{Instruction, InstructionPacket};
pub use protocol::Protocol;
pub use status::Status;

/// A servo id on the bus.
pub type Id = u8;

/// The broadcast id of both protocols: every servo obeys it, and replies only where the protocol
/// says so (ping, sync read, bulk read on Dynamixel).
pub const BROADCAST: Id = 0xFE;

/// Why a packet could not be encoded. Nothing is written to the bus in that case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// The output slice cannot hold the packet.
    BufferTooSmall {
        /// Bytes the packet needs.
        required: usize,
        /// Bytes the slice has.
        available: usize,
    },
    /// The packet is longer than the protocol's length field can describe.
    TooLong {
        /// Bytes the packet would need.
        length: usize,
    },
    /// The protocol has no such instruction (e.g. bulk read on Feetech).
    Unsupported {
        /// The instruction's name.
        instruction: &'static str,
    },
    /// An address, length or id does not fit the protocol (e.g. an address above 255 on Feetech,
    /// sync-write data that is not a whole number of records, an id above the protocol's range).
    BadParameter {
        /// What is wrong, for a one-line message.
        reason: &'static str,
    },
}

/// Why received bytes are not a valid packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseError {
    /// Fewer bytes than the smallest packet, or than the length field promises.
    Truncated {
        /// Bytes the packet needs.
        required: usize,
        /// Bytes there are.
        available: usize,
    },
    /// The bytes do not start with the protocol's header.
    BadHeader,
    /// The length field is impossible (below the protocol's minimum) or disagrees with the
    /// frame's size.
    BadLength {
        /// The value of the length field.
        length: usize,
    },
    /// The checksum (CRC-16 on Dynamixel, the complement sum on Feetech) does not match.
    Checksum {
        /// The checksum carried by the packet.
        received: u16,
        /// The checksum computed over the packet.
        computed: u16,
    },
    /// The instruction byte is not one the protocol defines.
    UnknownInstruction {
        /// The instruction byte.
        code: u8,
    },
    /// A status packet where an instruction was expected, or the other way round.
    WrongKind,
    /// The parameters do not fit the instruction (wrong count, records not whole).
    BadParameters {
        /// The instruction byte.
        code: u8,
    },
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BufferTooSmall { required, available } => {
                write!(f, "packet needs {required} bytes, buffer has {available}")
            }
            Self::TooLong { length } => write!(f, "packet of {length} bytes exceeds the protocol's length field"),
            Self::Unsupported { instruction } => write!(f, "the protocol has no {instruction} instruction"),
            Self::BadParameter { reason } => write!(f, "{reason}"),
        }
    }
}

impl core::fmt::Display for ParseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Truncated { required, available } => {
                write!(f, "truncated packet: {available} of {required} bytes")
            }
            Self::BadHeader => write!(f, "no packet header"),
            Self::BadLength { length } => write!(f, "impossible length field {length}"),
            Self::Checksum { received, computed } => {
                write!(f, "bad checksum: received {received:#06x}, computed {computed:#06x}")
            }
            Self::UnknownInstruction { code } => write!(f, "unknown instruction {code:#04x}"),
            Self::WrongKind => write!(f, "status packet where an instruction was expected, or the reverse"),
            Self::BadParameters { code } => write!(f, "parameters do not fit instruction {code:#04x}"),
        }
    }
}

/// Where a frame ends in bytes that start at a header candidate; see [`protocol::Protocol::frame_len`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameLen {
    /// The bytes so far are a valid beginning; at least this many bytes are needed in all to know
    /// more (or to complete the frame).
    NeedMore(usize),
    /// A complete frame of this many bytes (its checksum not yet checked).
    Complete(usize),
    /// The bytes cannot start a frame (wrong header, impossible length): drop the first byte and
    /// look again.
    NotAFrame,
}
