//! Feetech SCS/STS codec against exact byte vectors, and property tests of its round trips.
//!
//! Source of the vectors, unless a test says otherwise: the Feetech "SCS communication protocol"
//! manual, section 4 (Examples 1-10), English transcription at
//! <https://wiki.juxitech.com/en/tutorials/accessories/feetech/Feetech-SCS_Communication_Protocol.html>.
//! Every checksum below was also recomputed by `CHK = !(ID + LEN + INST/ERR + params) & 0xFF`
//! (the `manual_checksums_follow_the_rule` test), so a transcription error would show.

use firmware::bus::feetech::value::{decode_u16, encode_u16, from_sign_magnitude, to_sign_magnitude, Endian};
use firmware::bus::feetech::{self, checksum::checksum, StatusError};
use firmware::bus::protocol::ErrorText;
use firmware::bus::{EncodeError, FrameLen, Instruction, InstructionPacket, ParseError, Protocol, Status, BROADCAST};
use proptest::prelude::*;

/// Encodes, compares with `bytes`, then checks frame_len, verify and parse give the packet back.
fn instruction_vector(packet: InstructionPacket<'_>, bytes: &[u8]) {
    let mut out = [0u8; 300];
    let n = feetech::encode_instruction(&packet, &mut out).unwrap();
    assert_eq!(&out[..n], bytes, "encoding of {packet:?}");
    assert_eq!(feetech::frame_len(bytes), FrameLen::Complete(bytes.len()));
    assert_eq!(feetech::verify(bytes), Ok(()));
    let mut frame = bytes.to_vec();
    assert_eq!(feetech::parse_instruction(&mut frame), Ok(packet));
}

/// The same for a status packet.
fn status_vector(status: Status<'_>, bytes: &[u8]) {
    let mut out = [0u8; 300];
    let n = feetech::encode_status(&status, &mut out).unwrap();
    assert_eq!(&out[..n], bytes, "encoding of {status:?}");
    assert_eq!(feetech::frame_len(bytes), FrameLen::Complete(bytes.len()));
    let mut frame = bytes.to_vec();
    assert_eq!(feetech::parse_status(&mut frame), Ok(status));
}

/// `FF FF` + covered + checksum, for hand-made frames.
fn with_checksum(covered: &[u8]) -> Vec<u8> {
    let mut frame = vec![0xFF, 0xFF];
    frame.extend_from_slice(covered);
    frame.push(checksum(covered));
    frame
}

fn packet(id: u8, instruction: Instruction<'_>) -> InstructionPacket<'_> {
    InstructionPacket { id, instruction }
}

// ---- The manual's examples -------------------------------------------------------------------

#[test]
fn example_1_ping() {
    // Manual 4.1 Example 1 (also in shared/reference/protocols.md).
    instruction_vector(packet(1, Instruction::Ping), &[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]);
    status_vector(Status { id: 1, error: 0, params: &[] }, &[0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
}

#[test]
fn example_2_read_present_position() {
    // Manual 4.2 Example 2: id 1, address 0x38 (present position), 2 bytes; the reply carries
    // 18 05, little-endian 0x0518 = 1304.
    instruction_vector(
        packet(1, Instruction::Read { address: 0x38, length: 2 }),
        &[0xFF, 0xFF, 0x01, 0x04, 0x02, 0x38, 0x02, 0xBE],
    );
    let reply = [0xFF, 0xFF, 0x01, 0x04, 0x00, 0x18, 0x05, 0xDD];
    status_vector(Status { id: 1, error: 0, params: &[0x18, 0x05] }, &reply);
    assert_eq!(decode_u16([0x18, 0x05], Endian::Little), 1304);
}

#[test]
fn example_3_broadcast_write_of_the_id() {
    // Manual 4.3 Example 3: broadcast, address 5 (id), value 1. No reply (broadcast).
    instruction_vector(
        packet(BROADCAST, Instruction::Write { address: 5, data: &[1] }),
        &[0xFF, 0xFF, 0xFE, 0x04, 0x03, 0x05, 0x01, 0xF4],
    );
}

#[test]
fn example_4_write_goal_position_time_speed() {
    // Manual 4.3 Example 4: id 1, from 0x2A: position 2048, time 0, speed 1000, little-endian.
    let data = [0x00, 0x08, 0x00, 0x00, 0xE8, 0x03];
    instruction_vector(
        packet(1, Instruction::Write { address: 0x2A, data: &data }),
        &[0xFF, 0xFF, 0x01, 0x09, 0x03, 0x2A, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, 0xD5],
    );
    status_vector(Status { id: 1, error: 0, params: &[] }, &[0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
}

#[test]
fn example_5_reg_write_to_ten_servos() {
    // Manual 4.4 Example 5: the same goal as Example 4 registered on ids 1 to 10, with the replies.
    // The manual lists checksums D4 (id 1) down to CB (id 10) and replies FC down to F3.
    let data = [0x00, 0x08, 0x00, 0x00, 0xE8, 0x03];
    for id in 1u8..=10 {
        let command = [0xFF, 0xFF, id, 0x09, 0x04, 0x2A, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, 0xD5 - id];
        instruction_vector(packet(id, Instruction::RegWrite { address: 0x2A, data: &data }), &command);
        status_vector(Status { id, error: 0, params: &[] }, &[0xFF, 0xFF, id, 0x02, 0x00, 0xFD - id]);
    }
}

#[test]
fn example_6_action() {
    // Manual 4.5 Example 6: broadcast ACTION; no reply.
    instruction_vector(packet(BROADCAST, Instruction::Action), &[0xFF, 0xFF, 0xFE, 0x02, 0x05, 0xFA]);
}

#[test]
fn example_7_sync_write() {
    // Manual 4.6 Example 7: ids 1-4, from 0x2A, 6 bytes each (position 2048, time 0, speed 1000).
    // LEN = (L + 1) * n + 4 = 7 * 4 + 4 = 0x20.
    let records = [
        0x01, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, //
        0x02, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, //
        0x03, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, //
        0x04, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03,
    ];
    let mut bytes = vec![0xFF, 0xFF, 0xFE, 0x20, 0x83, 0x2A, 0x06];
    bytes.extend_from_slice(&records);
    bytes.push(0x58);
    instruction_vector(packet(BROADCAST, Instruction::SyncWrite { address: 0x2A, length: 6, data: &records }), &bytes);
}

#[test]
fn example_8_sync_read_and_its_replies() {
    // Manual 4.7 Example 8: ids 1 and 2, 8 bytes from 0x38 (position, speed, load, voltage,
    // temperature); each servo answers with its own status packet, in the order of the ids.
    instruction_vector(
        packet(BROADCAST, Instruction::SyncRead { address: 0x38, length: 8, ids: &[1, 2] }),
        &[0xFF, 0xFF, 0xFE, 0x06, 0x82, 0x38, 0x08, 0x01, 0x02, 0x36],
    );
    status_vector(
        Status { id: 1, error: 0, params: &[0x00, 0x08, 0x00, 0x00, 0x00, 0x00, 0x79, 0x1E] },
        &[0xFF, 0xFF, 0x01, 0x0A, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x00, 0x79, 0x1E, 0x55],
    );
    status_vector(
        Status { id: 2, error: 0, params: &[0xFF, 0x07, 0x00, 0x00, 0x00, 0x00, 0x77, 0x23] },
        &[0xFF, 0xFF, 0x02, 0x0A, 0x00, 0xFF, 0x07, 0x00, 0x00, 0x00, 0x00, 0x77, 0x23, 0x53],
    );
    // The first reply's position: 00 08 little-endian = 2048; 0x79 = 12.1 V, 0x1E = 30 degrees.
    assert_eq!(decode_u16([0x00, 0x08], Endian::Little), 2048);
}

#[test]
fn example_9_reset() {
    // Manual 4.8 Example 9: state reset (rotation count) of id 1, code 0x0A.
    instruction_vector(packet(1, Instruction::Reset), &[0xFF, 0xFF, 0x01, 0x02, 0x0A, 0xF2]);
    status_vector(Status { id: 1, error: 0, params: &[] }, &[0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC]);
}

#[test]
fn feetech_instructions_without_a_variant_are_unknown() {
    // Manual 4.9 Example 10 (position calibration, 0x0B), Example 11 (calibration to 1024, whose
    // parameter 00 04 is little-endian 1024), 4.10 (parameter restoration, 0x06), 4.11 (backup,
    // 0x09), 4.12 (reboot, 0x08): valid frames, but no `Instruction` variant carries them.
    let frames: [&[u8]; 5] = [
        &[0xFF, 0xFF, 0x01, 0x02, 0x0B, 0xF1],
        &[0xFF, 0xFF, 0x01, 0x04, 0x0B, 0x00, 0x04, 0xEB],
        &[0xFF, 0xFF, 0x01, 0x02, 0x06, 0xF6],
        &[0xFF, 0xFF, 0x01, 0x02, 0x09, 0xF3],
        &[0xFF, 0xFF, 0x01, 0x02, 0x08, 0xF4],
    ];
    for bytes in frames {
        assert_eq!(feetech::verify(bytes), Ok(()));
        let code = bytes[4];
        assert_eq!(feetech::parse_instruction(&mut bytes.to_vec()), Err(ParseError::UnknownInstruction { code }));
    }
    assert_eq!(decode_u16([0x00, 0x04], Endian::Little), 1024);
}

#[test]
fn manual_checksums_follow_the_rule() {
    // Every example frame's last byte is the complement sum of the bytes after the header.
    let frames: [&[u8]; 6] = [
        &[0xFF, 0xFF, 0x01, 0x04, 0x02, 0x38, 0x02, 0xBE],
        &[0xFF, 0xFF, 0x01, 0x04, 0x00, 0x18, 0x05, 0xDD],
        &[0xFF, 0xFF, 0xFE, 0x04, 0x03, 0x05, 0x01, 0xF4],
        &[0xFF, 0xFF, 0x01, 0x09, 0x03, 0x2A, 0x00, 0x08, 0x00, 0x00, 0xE8, 0x03, 0xD5],
        &[0xFF, 0xFF, 0xFE, 0x06, 0x82, 0x38, 0x08, 0x01, 0x02, 0x36],
        &[0xFF, 0xFF, 0x01, 0x02, 0x0A, 0xF2],
    ];
    for f in frames {
        let (chk, covered) = f[2..].split_last().unwrap();
        assert_eq!(checksum(covered), *chk, "{f:02X?}");
    }
}

// ---- Hand-computed vectors (no published example) ---------------------------------------------

#[test]
fn status_with_an_error_bit() {
    // Hand-computed, no published example: id 1 reports overload (bit 5):
    // 0x01 + 0x02 + 0x20 = 0x23, !0x23 = 0xDC.
    let bytes = [0xFF, 0xFF, 0x01, 0x02, 0x20, 0xDC];
    status_vector(Status { id: 1, error: 0x20, params: &[] }, &bytes);
    let text = Protocol::Feetech.describe_error(0x20).unwrap();
    assert_eq!(text, ErrorText { what: "overload", alert: false });
    // The same bytes read as an instruction: 0x20 is no instruction.
    assert_eq!(feetech::parse_instruction(&mut bytes.to_vec()), Err(ParseError::UnknownInstruction { code: 0x20 }));
}

#[test]
fn sync_read_of_sts3215_positions() {
    // Hand-computed, no published example: LeRobot's read of present position (56 = 0x38, 2 bytes)
    // of ids 1-6: FE + 0A + 82 + 38 + 02 = 0x1C4, + 01..06 (0x15) = 0x1D9, low byte 0xD9,
    // !0xD9 = 0x26.
    instruction_vector(
        packet(BROADCAST, Instruction::SyncRead { address: 0x38, length: 2, ids: &[1, 2, 3, 4, 5, 6] }),
        &[0xFF, 0xFF, 0xFE, 0x0A, 0x82, 0x38, 0x02, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x26],
    );
}

// ---- Refusals --------------------------------------------------------------------------------

#[test]
fn dynamixel_only_instructions_are_unsupported() {
    let mut out = [0u8; 64];
    let cases = [
        (Instruction::FactoryReset { mode: 0xFF }, "factory reset"),
        (Instruction::Reboot, "reboot"),
        (Instruction::Clear { params: [1, 0x44, 0x58, 0x4C, 0x22] }, "clear"),
        (Instruction::FastSyncRead { address: 132, length: 4, ids: &[1] }, "fast sync read"),
        (Instruction::BulkRead { records: &[1, 132, 0, 4, 0] }, "bulk read"),
        (Instruction::BulkWrite { records: &[1, 116, 0, 1, 0, 9] }, "bulk write"),
    ];
    for (instruction, name) in cases {
        let err = feetech::encode_instruction(&packet(1, instruction), &mut out);
        assert_eq!(err, Err(EncodeError::Unsupported { instruction: name }));
    }
    assert_eq!(out, [0u8; 64], "nothing written");
}

#[test]
fn parameters_that_do_not_fit_are_refused() {
    let mut out = [0u8; 300];
    let bad = |p: InstructionPacket<'_>, out: &mut [u8]| {
        matches!(feetech::encode_instruction(&p, out), Err(EncodeError::BadParameter { .. }))
    };
    assert!(bad(packet(1, Instruction::Read { address: 256, length: 2 }), &mut out));
    assert!(bad(packet(1, Instruction::Read { address: 0x38, length: 256 }), &mut out));
    assert!(bad(packet(1, Instruction::Read { address: 0x38, length: 254 }), &mut out));
    assert!(bad(packet(1, Instruction::Read { address: 0x38, length: 0 }), &mut out));
    assert!(bad(packet(1, Instruction::Write { address: 300, data: &[1] }), &mut out));
    assert!(bad(packet(1, Instruction::Write { address: 40, data: &[] }), &mut out));
    assert!(bad(packet(254 + 1, Instruction::Ping), &mut out));
    assert!(!bad(packet(253, Instruction::Ping), &mut out));
    assert!(!bad(packet(BROADCAST, Instruction::Ping), &mut out));
    assert!(bad(packet(BROADCAST, Instruction::SyncRead { address: 56, length: 2, ids: &[1, BROADCAST] }), &mut out));
    // Sync-write data of 1.5 records of id + 2 bytes.
    assert!(bad(packet(BROADCAST, Instruction::SyncWrite { address: 42, length: 2, data: &[1, 0, 8, 2] }), &mut out));
    assert!(bad(packet(BROADCAST, Instruction::SyncWrite { address: 42, length: 2, data: &[0xFF, 0, 8] }), &mut out));
    assert!(bad(packet(BROADCAST, Instruction::SyncWrite { address: 42, length: 0, data: &[] }), &mut out));
    // LEN is one byte: 253 parameters fit (LEN 255), 254 do not.
    let data = [0u8; 253];
    assert_eq!(
        feetech::encode_instruction(&packet(1, Instruction::Write { address: 0, data: &data[..252] }), &mut out),
        Ok(259)
    );
    assert_eq!(
        feetech::encode_instruction(&packet(1, Instruction::Write { address: 0, data: &data }), &mut out),
        Err(EncodeError::TooLong { length: 260 })
    );
    assert!(matches!(
        feetech::encode_status(&Status { id: BROADCAST, error: 0, params: &[] }, &mut out),
        Err(EncodeError::BadParameter { .. })
    ));
}

#[test]
fn a_small_buffer_is_an_error_and_stays_untouched() {
    let mut out = [0xAAu8; 7];
    let read = packet(1, Instruction::Read { address: 0x38, length: 2 });
    assert_eq!(
        feetech::encode_instruction(&read, &mut out),
        Err(EncodeError::BufferTooSmall { required: 8, available: 7 })
    );
    assert_eq!(out, [0xAA; 7]);
    let mut none: [u8; 0] = [];
    let status = Status { id: 1, error: 0, params: &[] };
    assert_eq!(
        feetech::encode_status(&status, &mut none),
        Err(EncodeError::BufferTooSmall { required: 6, available: 0 })
    );
}

#[test]
fn frame_boundaries() {
    use FrameLen::*;
    assert_eq!(feetech::frame_len(&[]), NeedMore(4));
    assert_eq!(feetech::frame_len(&[0xFF]), NeedMore(4));
    assert_eq!(feetech::frame_len(&[0xFF, 0xFF, 0x01]), NeedMore(4));
    assert_eq!(feetech::frame_len(&[0xFF, 0xFF, 0x01, 0x04, 0x02]), NeedMore(8));
    assert_eq!(feetech::frame_len(&[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB, 0xFF]), Complete(6));
    assert_eq!(feetech::frame_len(&[0x00]), NotAFrame);
    assert_eq!(feetech::frame_len(&[0xFF, 0x00]), NotAFrame);
    // FF FF FF: the header may start one byte later.
    assert_eq!(feetech::frame_len(&[0xFF, 0xFF, 0xFF]), NotAFrame);
    assert_eq!(feetech::frame_len(&[0xFF, 0xFF, 0x01, 0x01]), NotAFrame);
    assert_eq!(feetech::instruction_len(2), 8);
    assert_eq!(feetech::status_len(8), 14);
}

#[test]
fn verify_reports_what_is_wrong() {
    let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let mut bad = ping;
    bad[5] = 0xFA;
    assert_eq!(feetech::verify(&bad), Err(ParseError::Checksum { received: 0xFA, computed: 0xFB }));
    assert_eq!(feetech::verify(&ping[..5]), Err(ParseError::Truncated { required: 6, available: 5 }));
    assert_eq!(feetech::verify(&ping[..3]), Err(ParseError::Truncated { required: 6, available: 3 }));
    assert_eq!(feetech::verify(&[0xFF, 0xFE, 0x01]), Err(ParseError::BadHeader));
    assert_eq!(feetech::verify(&[0xFF, 0xFF, 0xFF, 0x02, 0x01, 0xFB]), Err(ParseError::BadHeader));
    assert_eq!(feetech::verify(&[0xFF, 0xFF, 0x01, 0x01, 0x01, 0xFB]), Err(ParseError::BadLength { length: 1 }));
    // A frame longer than its LEN: refused, so a corrupted LEN cannot shorten a frame.
    assert_eq!(feetech::verify(&[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB, 0x00]), Err(ParseError::BadLength { length: 2 }));
}

#[test]
fn wrong_parameter_counts_are_bad_parameters() {
    let cases: [(&[u8], u8); 7] = [
        (&[0x01, 0x03, 0x01, 0x00], 0x01),                   // ping with a parameter
        (&[0x01, 0x03, 0x02, 0x38], 0x02),                   // read without a length
        (&[0x01, 0x04, 0x02, 0x38, 0x00], 0x02),             // read of 0 bytes
        (&[0x01, 0x03, 0x03, 0x28], 0x03),                   // write without data
        (&[0xFE, 0x04, 0x82, 0x38, 0xFE], 0x82),             // sync read without length (3 params)
        (&[0xFE, 0x06, 0x83, 0x2A, 0x02, 0x01, 0x00], 0x83), // sync write, record cut short
        (&[0xFE, 0x03, 0x05, 0x00], 0x05),                   // action with a parameter
    ];
    for (covered, code) in cases {
        let mut frame = with_checksum(covered);
        assert_eq!(feetech::parse_instruction(&mut frame), Err(ParseError::BadParameters { code }), "{covered:02X?}");
    }
}

#[test]
fn the_protocol_switch_reaches_this_codec() {
    let mut out = [0u8; 16];
    let n = Protocol::Feetech.encode_instruction(&packet(1, Instruction::Ping), &mut out).unwrap();
    assert_eq!(&out[..n], &[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]);
    assert_eq!(Protocol::Feetech.frame_len(&out[..n]), FrameLen::Complete(6));
    assert_eq!(Protocol::Feetech.verify(&out[..n]), Ok(()));
    assert_eq!(Protocol::Feetech.instruction_len(0), 6);
    assert_eq!(Protocol::Feetech.describe_error(0), None);
}

// ---- Error byte ------------------------------------------------------------------------------

#[test]
fn error_byte_names_its_lowest_fault() {
    assert_eq!(StatusError::from_byte(0).describe(), None);
    let what = |b: u8| StatusError::from_byte(b).describe().unwrap().what;
    assert_eq!(what(0x01), "input voltage out of range");
    assert_eq!(what(0x02), "angle sensor fault");
    assert_eq!(what(0x04), "overheat");
    assert_eq!(what(0x08), "overcurrent");
    assert_eq!(what(0x20), "overload");
    assert_eq!(what(0x21), "input voltage out of range");
    assert_eq!(what(0x80), "fault bit 7 (undefined by feetech)");
    for b in 1..=255u8 {
        assert!(!StatusError::from_byte(b).describe().unwrap().alert);
    }
    assert!(StatusError::from_byte(0x24).contains(StatusError::OVERHEAT | StatusError::OVERLOAD));
}

// ---- Values ----------------------------------------------------------------------------------

#[test]
fn sign_magnitude_and_byte_order() {
    // STS position -1: sign bit 15 and magnitude 1; on the wire little-endian 01 80.
    assert_eq!(to_sign_magnitude(-1, 15), Some(0x8001));
    assert_eq!(encode_u16(0x8001, Endian::Little), [0x01, 0x80]);
    assert_eq!(from_sign_magnitude(0x8001, 15), -1);
    // -500 is 0x81F4 (0x8000 | 500): bytes F4 81 on an STS.
    assert_eq!(to_sign_magnitude(-500, 15).map(|v| encode_u16(v, Endian::Little)), Some([0xF4, 0x81]));
    // SCS is big-endian: 1304 = 0x0518 travels as 05 18.
    assert_eq!(encode_u16(1304, Endian::Big), [0x05, 0x18]);
    assert_eq!(decode_u16([0x05, 0x18], Endian::Big), 1304);
    // Homing offset: sign at bit 11, |v| <= 2047.
    assert_eq!(to_sign_magnitude(-2047, 11), Some(0x0FFF));
    assert_eq!(to_sign_magnitude(2048, 11), None);
    assert_eq!(to_sign_magnitude(-2048, 11), None);
    assert_eq!(to_sign_magnitude(32768, 15), None);
    assert_eq!(to_sign_magnitude(i32::MIN, 15), None);
    assert_eq!(to_sign_magnitude(1, 16), None);
    assert_eq!(to_sign_magnitude(32767, 15), Some(0x7FFF));
    // Negative zero decodes to 0; bits above the sign bit are not part of the number.
    assert_eq!(from_sign_magnitude(0x8000, 15), 0);
    assert_eq!(from_sign_magnitude(0xF801, 11), -1);
    assert_eq!(from_sign_magnitude(0xFFFF, 16), 0xFFFF);
}

// ---- Properties ------------------------------------------------------------------------------

/// An owned instruction, so that proptest can generate it; `view` borrows the bus type.
#[derive(Clone, Debug)]
enum Owned {
    Ping,
    Read(u8, u8),
    Write(u8, Vec<u8>),
    RegWrite(u8, Vec<u8>),
    Action,
    SyncRead(u8, u8, Vec<u8>),
    SyncWrite(u8, u8, Vec<u8>),
    Reset,
}

impl Owned {
    fn view(&self) -> Instruction<'_> {
        match self {
            Self::Ping => Instruction::Ping,
            Self::Read(a, l) => Instruction::Read { address: (*a).into(), length: (*l).into() },
            Self::Write(a, d) => Instruction::Write { address: (*a).into(), data: d },
            Self::RegWrite(a, d) => Instruction::RegWrite { address: (*a).into(), data: d },
            Self::Action => Instruction::Action,
            Self::SyncRead(a, l, ids) => Instruction::SyncRead { address: (*a).into(), length: (*l).into(), ids },
            Self::SyncWrite(a, l, d) => Instruction::SyncWrite { address: (*a).into(), length: (*l).into(), data: d },
            Self::Reset => Instruction::Reset,
        }
    }

    fn params(&self) -> usize {
        match self {
            Self::Ping | Self::Action | Self::Reset => 0,
            Self::Read(..) => 2,
            Self::Write(_, d) | Self::RegWrite(_, d) => 1 + d.len(),
            Self::SyncRead(_, _, v) | Self::SyncWrite(_, _, v) => 2 + v.len(),
        }
    }
}

fn servo_id() -> impl Strategy<Value = u8> {
    0u8..=253
}

fn packet_id() -> impl Strategy<Value = u8> {
    prop_oneof![servo_id(), Just(BROADCAST)]
}

fn instruction() -> impl Strategy<Value = Owned> {
    let data = prop::collection::vec(any::<u8>(), 1..=252);
    let sync_write = (1u8..=8).prop_flat_map(|len| {
        let record = (servo_id(), prop::collection::vec(any::<u8>(), usize::from(len)));
        let max = 251 / (usize::from(len) + 1);
        (any::<u8>(), Just(len), prop::collection::vec(record, 0..=max))
    });
    prop_oneof![
        Just(Owned::Ping),
        Just(Owned::Action),
        Just(Owned::Reset),
        (any::<u8>(), 1u8..=253).prop_map(|(a, l)| Owned::Read(a, l)),
        (any::<u8>(), data.clone()).prop_map(|(a, d)| Owned::Write(a, d)),
        (any::<u8>(), data).prop_map(|(a, d)| Owned::RegWrite(a, d)),
        (any::<u8>(), 1u8..=253, prop::collection::vec(servo_id(), 0..=251))
            .prop_map(|(a, l, ids)| Owned::SyncRead(a, l, ids)),
        sync_write.prop_map(|(a, l, records)| {
            let data = records.into_iter().flat_map(|(id, d)| std::iter::once(id).chain(d)).collect();
            Owned::SyncWrite(a, l, data)
        }),
    ]
}

proptest! {
    #[test]
    fn instructions_round_trip(id in packet_id(), owned in instruction()) {
        let packet = InstructionPacket { id, instruction: owned.view() };
        let mut out = [0u8; 300];
        let n = feetech::encode_instruction(&packet, &mut out).unwrap();
        prop_assert_eq!(n, feetech::instruction_len(owned.params()));
        let frame = &out[..n];
        for k in 0..n {
            prop_assert!(matches!(feetech::frame_len(&frame[..k]), FrameLen::NeedMore(m) if m > k && m <= n));
        }
        prop_assert_eq!(feetech::frame_len(&out), FrameLen::Complete(n));
        prop_assert_eq!(feetech::verify(frame), Ok(()));
        let mut copy = frame.to_vec();
        prop_assert_eq!(feetech::parse_instruction(&mut copy), Ok(packet));
    }

    #[test]
    fn statuses_round_trip(id in servo_id(), error in any::<u8>(), data in prop::collection::vec(any::<u8>(), 0..=253)) {
        let status = Status { id, error, params: &data };
        let mut out = [0u8; 300];
        let n = feetech::encode_status(&status, &mut out).unwrap();
        prop_assert_eq!(n, feetech::status_len(data.len()));
        prop_assert_eq!(feetech::frame_len(&out[..n]), FrameLen::Complete(n));
        prop_assert_eq!(feetech::verify(&out[..n]), Ok(()));
        let mut copy = out[..n].to_vec();
        prop_assert_eq!(feetech::parse_status(&mut copy), Ok(status));
    }

    #[test]
    fn every_single_bit_flip_is_detected(id in packet_id(), owned in instruction(), seed in any::<prop::sample::Index>()) {
        // Header flips are bad headers, LEN flips wrong lengths (the frame must be exactly
        // 4 + LEN bytes), any other flip changes the complement sum by 2^k mod 256, never 0.
        let packet = InstructionPacket { id, instruction: owned.view() };
        let mut out = [0u8; 300];
        let n = feetech::encode_instruction(&packet, &mut out).unwrap();
        let bit = seed.index(n * 8);
        let mut frame = out[..n].to_vec();
        frame[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(feetech::verify(&frame).is_err(), "flip of bit {} in {:02X?}", bit, frame);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = feetech::frame_len(&bytes);
        let _ = feetech::verify(&bytes);
        let _ = feetech::parse_instruction(&mut bytes.clone());
        let _ = feetech::parse_status(&mut bytes.clone());
    }

    #[test]
    fn accepted_frames_encode_back_to_themselves(
        id in 0u8..=0xFE, kind in any::<u8>(), params in prop::collection::vec(any::<u8>(), 0..=253)
    ) {
        // Frames with a correct checksum reach the parsers; whatever they accept is canonical.
        let len = u8::try_from(params.len() + 2).unwrap();
        let mut covered = vec![id, len, kind];
        covered.extend_from_slice(&params);
        let frame = with_checksum(&covered);
        prop_assert_eq!(feetech::frame_len(&frame), FrameLen::Complete(frame.len()));
        let mut out = [0u8; 300];
        if let Ok(packet) = feetech::parse_instruction(&mut frame.clone()) {
            let n = feetech::encode_instruction(&packet, &mut out).unwrap();
            prop_assert_eq!(&out[..n], &frame[..]);
        }
        let mut copy = frame.clone();
        let status = feetech::parse_status(&mut copy).unwrap();
        if id <= 253 {
            let n = feetech::encode_status(&status, &mut out).unwrap();
            prop_assert_eq!(&out[..n], &frame[..]);
        }
    }
}
