//! Feetech SCS/STS serial servo protocol: encoding, frame boundaries and parsing.
//!
//! Sources: the Feetech "SCS communication protocol" manual (sections cited in each file; the
//! English text is transcribed at
//! <https://wiki.juxitech.com/en/tutorials/accessories/feetech/Feetech-SCS_Communication_Protocol.html>)
//! and the SCServo SDK (`scservo_def.py`, `protocol_packet_handler.py`), which LeRobot uses for
//! the SO-100/SO-101 arms.
//!
//! ```text
//! instruction  FF FF ID LEN INST params CHK     LEN = params + 2
//! status       FF FF ID LEN ERR  data   CHK     CHK = !(ID + LEN + INST/ERR + params) & 0xFF
//! ```
//!
//! Files: [`checksum`] (the complement sum), `frame` (boundaries, header/length/checksum checks,
//! writing), `instruction` and `status` (the two packet kinds), [`StatusError`] (the error byte),
//! [`value`] (byte order and sign-magnitude values of the control table).
//!
//! The packet format is the same for SCS and STS; only multi-byte control-table values differ in
//! byte order ([`value::Endian`]). Compared with the SDK: it caps packets at 250 bytes
//! (`TXPACKET_MAX_LEN`); this codec allows anything LEN can describe (259 bytes).
//!
//! Instruction 0x0A is sent for [`crate::bus::Instruction::Reset`]: in the current manual that is a
//! state reset (rotation count), not a factory reset (0x06, "parameter restoration", which older
//! SCS manuals called RESET). 0x06, 0x08 (reboot), 0x09 (backup) and 0x0B (position calibration)
//! are parsed as [`crate::bus::ParseError::UnknownInstruction`].
//!
//! # Panics
//! Nothing here panics on any input: slices are split with patterns and `get`, sums wrap modulo
//! 256 as the protocol says, lengths saturate, and a short output buffer is
//! [`crate::bus::EncodeError::BufferTooSmall`] with nothing written.

pub mod checksum;
mod error;
mod frame;
mod instruction;
mod status;
pub mod value;

pub use error::StatusError;
pub use frame::{frame_len, verify, HEADER, MIN_FRAME};
pub use instruction::{
    encode_instruction, instruction_len, parse_instruction, ACTION, MAX_ID, MAX_READ_LENGTH, PING, READ, REG_WRITE,
    RESET, SYNC_READ, SYNC_WRITE, WRITE,
};
pub use status::{encode_status, parse_status, status_len};
