//! A runtime choice between the two codecs, so that a bus (and the simulator, and `armctl`) can be
//! configured for either without generics spreading through the callers.

use super::{dxl2, feetech, EncodeError, FrameLen, InstructionPacket, ParseError, Status};

/// The serial servo protocol spoken on a bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Protocol {
    /// ROBOTIS Dynamixel Protocol 2.0 (X-series).
    Dxl2,
    /// Feetech SCS/STS. Packets are the same for both series; the byte order of multi-byte values
    /// is a property of the servo model (see [`super::table`]).
    Feetech,
}

impl Protocol {
    /// The name used on the command line and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Dxl2 => "dxl2",
            Self::Feetech => "sts",
        }
    }

    /// Encodes an instruction packet into `out`; returns the bytes written.
    pub fn encode_instruction(self, packet: &InstructionPacket<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
        match self {
            Self::Dxl2 => dxl2::encode_instruction(packet, out),
            Self::Feetech => feetech::encode_instruction(packet, out),
        }
    }

    /// Encodes a status packet into `out`; returns the bytes written.
    pub fn encode_status(self, status: &Status<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
        match self {
            Self::Dxl2 => dxl2::encode_status(status, out),
            Self::Feetech => feetech::encode_status(status, out),
        }
    }

    /// Where the frame starting at `buf[0]` ends, judged by header and length field only.
    pub fn frame_len(self, buf: &[u8]) -> FrameLen {
        match self {
            Self::Dxl2 => dxl2::frame_len(buf),
            Self::Feetech => feetech::frame_len(buf),
        }
    }

    /// Checks the checksum of a complete frame (as delimited by [`Protocol::frame_len`]).
    pub fn verify(self, frame: &[u8]) -> Result<(), ParseError> {
        match self {
            Self::Dxl2 => dxl2::verify(frame),
            Self::Feetech => feetech::verify(frame),
        }
    }

    /// Parses a complete frame as an instruction packet. Dynamixel frames are unstuffed in place,
    /// so the frame's bytes are changed.
    pub fn parse_instruction(self, frame: &mut [u8]) -> Result<InstructionPacket<'_>, ParseError> {
        match self {
            Self::Dxl2 => dxl2::parse_instruction(frame),
            Self::Feetech => feetech::parse_instruction(frame),
        }
    }

    /// Parses a complete frame as a status packet (unstuffed in place on Dynamixel).
    pub fn parse_status(self, frame: &mut [u8]) -> Result<Status<'_>, ParseError> {
        match self {
            Self::Dxl2 => dxl2::parse_status(frame),
            Self::Feetech => feetech::parse_status(frame),
        }
    }

    /// Bytes of an instruction packet with `params` parameter bytes, before any stuffing: the
    /// least the wire carries.
    pub fn instruction_len(self, params: usize) -> usize {
        match self {
            Self::Dxl2 => dxl2::instruction_len(params),
            Self::Feetech => feetech::instruction_len(params),
        }
    }

    /// Bytes of a status packet carrying `data` bytes, before any stuffing.
    pub fn status_len(self, data: usize) -> usize {
        match self {
            Self::Dxl2 => dxl2::status_len(data),
            Self::Feetech => feetech::status_len(data),
        }
    }

    /// Whether the servo's error byte reports a fault, and its one-line description.
    pub fn describe_error(self, error: u8) -> Option<ErrorText> {
        match self {
            Self::Dxl2 => dxl2::StatusError::from_byte(error).describe(),
            Self::Feetech => feetech::StatusError::from_byte(error).describe(),
        }
    }
}

/// A fixed description of a status error byte, for one-line messages without allocation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ErrorText {
    /// The fault, e.g. "CRC error" or "overload".
    pub what: &'static str,
    /// Dynamixel's alert bit: the servo has a hardware error (read its hardware error status).
    pub alert: bool,
}

impl core::fmt::Display for ErrorText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.what)?;
        if self.alert {
            f.write_str(" (alert: hardware error, see the hardware error status)")?;
        }
        Ok(())
    }
}
