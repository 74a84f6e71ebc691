//! Dynamixel Protocol 2.0 codec against the ROBOTIS e-manual's example packets, byte for byte, and
//! property tests of the round trip, the stuffing and the CRC.
//!
//! Vectors are from the e-manual page "DYNAMIXEL Protocol 2.0" (emanual.robotis.com/docs/en/dxl/
//! protocol2/, source `docs/en/dxl/protocol2.md` of ROBOTIS-GIT/emanual), section by section.

use firmware::bus::dxl2::{self, crc16, fast_sync_read_parts, FastSyncPart, StatusError};
use firmware::bus::instruction::RecordWriter;
use firmware::bus::{EncodeError, FrameLen, Instruction, InstructionPacket, ParseError, Status, BROADCAST};
use proptest::prelude::*;

/// Parses "FF FF FD ..." into bytes.
fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

/// Encode, compare the bytes; delimit, verify, parse, compare the packet.
fn check_instruction(wire: &str, packet: InstructionPacket<'_>) {
    let wire = hex(wire);
    let mut out = [0u8; 128];
    let n = dxl2::encode_instruction(&packet, &mut out).unwrap();
    assert_eq!(&out[..n], &wire[..], "encoding {packet:?}");
    assert_eq!(dxl2::frame_len(&wire), FrameLen::Complete(wire.len()));
    assert_eq!(dxl2::verify(&wire), Ok(()));
    let mut frame = wire.clone();
    assert_eq!(dxl2::parse_instruction(&mut frame), Ok(packet));
}

/// The same for a status packet.
fn check_status(wire: &str, status: Status<'_>) {
    let wire = hex(wire);
    let mut out = [0u8; 128];
    let n = dxl2::encode_status(&status, &mut out).unwrap();
    assert_eq!(&out[..n], &wire[..], "encoding {status:?}");
    assert_eq!(dxl2::frame_len(&wire), FrameLen::Complete(wire.len()));
    assert_eq!(dxl2::verify(&wire), Ok(()));
    let mut frame = wire.clone();
    assert_eq!(dxl2::parse_status(&mut frame), Ok(status));
}

fn packet(id: u8, instruction: Instruction<'_>) -> InstructionPacket<'_> {
    InstructionPacket { id, instruction }
}

/// The empty status every write-like instruction gets from id 1 (Write, Reg Write, Action,
/// Factory Reset, Reboot, Clear, Control Table Backup examples all show it).
const EMPTY_STATUS_ID1: &str = "FF FF FD 00 01 04 00 55 00 A1 0C";

#[test]
fn crc_check_value() {
    // CRC-16/BUYPASS catalogue check value.
    assert_eq!(crc16(b"123456789"), 0xFEE8);
}

#[test]
fn ping_examples() {
    // "Ping (0x01)", Example 1: id 1, an XM430-W210 (model 1030, firmware 38).
    check_instruction("FF FF FD 00 01 03 00 01 19 4E", packet(1, Instruction::Ping));
    check_status("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D", Status { id: 1, error: 0, params: &[0x06, 0x04, 0x26] });
    // "Ping (0x01)", Example 2: broadcast, answered by ids 1 and 2.
    check_instruction("FF FF FD 00 FE 03 00 01 31 42", packet(BROADCAST, Instruction::Ping));
    check_status("FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D", Status { id: 2, error: 0, params: &[0x06, 0x04, 0x26] });
}

#[test]
fn read_example() {
    // "Read (0x02)": Present Position (132, 4 bytes) of id 1 = 166.
    check_instruction(
        "FF FF FD 00 01 07 00 02 84 00 04 00 1D 15",
        packet(1, Instruction::Read { address: 132, length: 4 }),
    );
    check_status("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0", Status { id: 1, error: 0, params: &[0xA6, 0, 0, 0] });
}

#[test]
fn write_like_examples() {
    let empty = Status { id: 1, error: 0, params: &[] };
    // "Write (0x03)": 512 to Goal Position (116) of id 1.
    check_instruction(
        "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89",
        packet(1, Instruction::Write { address: 116, data: &[0x00, 0x02, 0x00, 0x00] }),
    );
    check_status(EMPTY_STATUS_ID1, empty);
    // "Reg Write (0x04)": 200 to Goal Velocity (104) of id 1.
    check_instruction(
        "FF FF FD 00 01 09 00 04 68 00 C8 00 00 00 AE 8E",
        packet(1, Instruction::RegWrite { address: 104, data: &[0xC8, 0, 0, 0] }),
    );
    // "Action (0x05)".
    check_instruction("FF FF FD 00 01 03 00 05 02 CE", packet(1, Instruction::Action));
    // "Factory Reset (0x06)": option 0x01, all but the id.
    check_instruction("FF FF FD 00 01 04 00 06 01 A1 E6", packet(1, Instruction::FactoryReset { mode: 0x01 }));
    // "Reboot (0x08)".
    check_instruction("FF FF FD 00 01 03 00 08 2F 4E", packet(1, Instruction::Reboot));
    // "Clear (0x10)": multi-turn position, key 44 58 4C 22.
    check_instruction(
        "FF FF FD 00 01 08 00 10 01 44 58 4C 22 B1 DC",
        packet(1, Instruction::Clear { params: [0x01, 0x44, 0x58, 0x4C, 0x22] }),
    );
}

#[test]
fn sync_examples() {
    // "Sync Read (0x82)": Present Position of ids 1 (166) and 2 (2079).
    check_instruction(
        "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA",
        packet(BROADCAST, Instruction::SyncRead { address: 132, length: 4, ids: &[1, 2] }),
    );
    check_status("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0", Status { id: 1, error: 0, params: &[0xA6, 0, 0, 0] });
    check_status(
        "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE",
        Status { id: 2, error: 0, params: &[0x1F, 0x08, 0, 0] },
    );
    // "Sync Write (0x83)": Goal Position 150 to id 1, 170 to id 2.
    check_instruction(
        "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87",
        packet(
            BROADCAST,
            Instruction::SyncWrite { address: 116, length: 4, data: &[1, 0x96, 0, 0, 0, 2, 0xAA, 0, 0, 0] },
        ),
    );
}

#[test]
fn fast_sync_read_example() {
    // "Fast Sync Read (0x8A)": Present Position of ids 3 (166), 7 (2079), 4 (1023), XC330-T288.
    check_instruction(
        "FF FF FD 00 FE 0A 00 8A 84 00 04 00 03 07 04 20 F2",
        packet(BROADCAST, Instruction::FastSyncRead { address: 132, length: 4, ids: &[3, 7, 4] }),
    );
    // The three parts, one after the other on the wire; each part's CRC is the CRC of the packet so
    // far, so the last one is the packet's CRC.
    let wire = hex("FF FF FD 00 FE 19 00 55 00 03 A6 00 00 00 84 08 \
         00 07 1F 08 00 00 16 CA \
         00 04 FF 03 00 00 D1 9E");
    let parts: [(u8, u8, &[u8]); 3] =
        [(0, 3, &[0xA6, 0, 0, 0]), (0, 7, &[0x1F, 0x08, 0, 0]), (0, 4, &[0xFF, 0x03, 0, 0])];
    check_fast_sync_reply(&wire, &parts);
}

#[test]
fn fast_sync_read_example_ja40() {
    // The same instruction on the e-manual's DYNAMIXEL-Y / JA40 protocol page ("Fast Sync Read"):
    // Present Position (580) of ids 1 (2000) and 2 (9).
    check_instruction(
        "FF FF FD 00 FE 09 00 8A 44 02 04 00 01 02 72 F2",
        packet(BROADCAST, Instruction::FastSyncRead { address: 580, length: 4, ids: &[1, 2] }),
    );
    let wire = hex("FF FF FD 00 FE 11 00 55 00 01 D0 07 00 00 0C 83 00 02 09 00 00 00 11 40");
    check_fast_sync_reply(&wire, &[(0, 1, &[0xD0, 0x07, 0, 0]), (0, 2, &[0x09, 0, 0, 0])]);
}

fn check_fast_sync_reply(wire: &[u8], parts: &[(u8, u8, &[u8])]) {
    let mut out = [0u8; 256];
    let n = dxl2::encode_fast_sync_read_status(parts, &mut out).unwrap();
    assert_eq!(&out[..n], wire);
    assert_eq!(dxl2::frame_len(wire), FrameLen::Complete(wire.len()));
    assert_eq!(dxl2::verify(wire), Ok(()));
    let mut frame = wire.to_vec();
    let status = dxl2::parse_status(&mut frame).unwrap();
    assert_eq!(status.id, BROADCAST);
    let length = parts[0].2.len();
    let got: Vec<_> = fast_sync_read_parts(&status, length).unwrap().collect();
    let want: Vec<_> = parts.iter().map(|&(error, id, data)| FastSyncPart { error, id, data }).collect();
    assert_eq!(got, want);
    assert_eq!(fast_sync_read_parts(&status, length).unwrap().len(), parts.len());
    // A wrong data length does not divide the reply into whole parts.
    assert!(fast_sync_read_parts(&status, length + 1).is_none());
}

#[test]
fn bulk_examples() {
    // "Bulk Read (0x92)": Present Voltage (144, 2 bytes) of id 1 = 119, Present Temperature (146,
    // 1 byte) of id 2 = 36.
    let mut records = [0u8; 16];
    let mut w = RecordWriter::new(&mut records);
    w.bulk_read(1, 144, 2).unwrap();
    w.bulk_read(2, 146, 1).unwrap();
    check_instruction(
        "FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05",
        packet(BROADCAST, Instruction::BulkRead { records: w.records() }),
    );
    check_status("FF FF FD 00 01 06 00 55 00 77 00 C3 69", Status { id: 1, error: 0, params: &[0x77, 0x00] });
    check_status("FF FF FD 00 02 05 00 55 00 24 8B A9", Status { id: 2, error: 0, params: &[0x24] });
    // "Bulk Write (0x93)": Max Voltage Limit (32, 2 bytes) of id 1 = 160, Temperature Limit (31,
    // 1 byte) of id 2 = 80.
    let mut records = [0u8; 16];
    let mut w = RecordWriter::new(&mut records);
    w.bulk_write(1, 32, &[0xA0, 0x00]).unwrap();
    w.bulk_write(2, 31, &[0x50]).unwrap();
    check_instruction(
        "FF FF FD 00 FE 10 00 93 01 20 00 02 00 A0 00 02 1F 00 01 00 50 B7 68",
        packet(BROADCAST, Instruction::BulkWrite { records: w.records() }),
    );
}

#[test]
fn control_table_backup_is_unknown_and_the_restore_example_has_a_bad_crc() {
    // "Control Table Backup (0x20)", Example 1: a valid packet of an instruction this codec does not
    // implement.
    let mut backup = hex("FF FF FD 00 01 08 00 20 01 43 54 52 4C 16 F5");
    assert_eq!(dxl2::parse_instruction(&mut backup), Err(ParseError::UnknownInstruction { code: 0x20 }));
    // Example 2 (restore) as printed ends `92 F5`; CRC-16/BUYPASS of its bytes is 0xF59E (`9E F5`).
    // The e-manual's vector is wrong, not the CRC: every other example agrees with it.
    let restore = hex("FF FF FD 00 01 08 00 20 02 43 54 52 4C 92 F5");
    assert_eq!(dxl2::verify(&restore), Err(ParseError::Checksum { received: 0xF592, computed: 0xF59E }));
}

#[test]
fn stuffing_vectors() {
    // e-manual, "Packet Process": after every FF FF FD from INST to the last parameter an FD is
    // inserted; LEN counts it; the CRC covers it. Vectors computed independently (Python).
    let cases: [(&str, &[u8], u16); 5] = [
        // FF FF FD inside the data.
        ("FF FF FD 00 01 0A 00 03 74 00 FF FF FD FD 00 21 E7", &[0xFF, 0xFF, 0xFD, 0x00], 116),
        // Data ending in FF FF FD: the FD goes just before the CRC.
        ("FF FF FD 00 01 0A 00 03 74 00 01 FF FF FD FD 54 4D", &[0x01, 0xFF, 0xFF, 0xFD], 116),
        // FF FF FD FD in the data: one more FD, the data's own FD kept.
        ("FF FF FD 00 01 0A 00 03 74 00 FF FF FD FD FD 2C 65", &[0xFF, 0xFF, 0xFD, 0xFD], 116),
        // Several in a row.
        (
            "FF FF FD 00 01 11 00 03 74 00 FF FF FD FD FF FF FD FD FF FF FD FD 53 B4",
            &[0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD],
            116,
        ),
        // Across the address and the data.
        ("FF FF FD 00 01 08 00 03 FF FF FD FD 01 C1 0E", &[0xFD, 0x01], 0xFFFF),
    ];
    for (wire, data, address) in cases {
        check_instruction(wire, packet(1, Instruction::Write { address, data }));
    }
    check_status(
        "FF FF FD 00 01 09 00 55 00 FF FF FD FD 00 D8 9C",
        Status { id: 1, error: 0, params: &[0xFF, 0xFF, 0xFD, 0] },
    );
}

#[test]
fn encode_refusals() {
    let mut out = [0u8; 64];
    let reset = packet(1, Instruction::Reset);
    assert_eq!(dxl2::encode_instruction(&reset, &mut out), Err(EncodeError::Unsupported { instruction: "reset" }));
    for id in [0xFD, 0xFF] {
        assert!(matches!(
            dxl2::encode_instruction(&packet(id, Instruction::Ping), &mut out),
            Err(EncodeError::BadParameter { .. })
        ));
    }
    let cut = packet(BROADCAST, Instruction::SyncWrite { address: 116, length: 4, data: &[1, 0, 0, 0] });
    assert!(matches!(dxl2::encode_instruction(&cut, &mut out), Err(EncodeError::BadParameter { .. })));
    let cut = packet(BROADCAST, Instruction::BulkRead { records: &[1, 0, 0, 4] });
    assert!(matches!(dxl2::encode_instruction(&cut, &mut out), Err(EncodeError::BadParameter { .. })));
    let cut = packet(BROADCAST, Instruction::BulkWrite { records: &[1, 116, 0, 4, 0, 9] });
    assert!(matches!(dxl2::encode_instruction(&cut, &mut out), Err(EncodeError::BadParameter { .. })));
    let broadcast_inside = packet(BROADCAST, Instruction::SyncRead { address: 132, length: 4, ids: &[1, 0xFE] });
    assert!(matches!(dxl2::encode_instruction(&broadcast_inside, &mut out), Err(EncodeError::BadParameter { .. })));
    // Too small: the exact size, stuffing included, and nothing written.
    let mut small = [0xAAu8; 16];
    let stuffed = packet(1, Instruction::Write { address: 116, data: &[0xFF, 0xFF, 0xFD, 0x00] });
    assert_eq!(
        dxl2::encode_instruction(&stuffed, &mut small),
        Err(EncodeError::BufferTooSmall { required: 17, available: 16 })
    );
    assert_eq!(small, [0xAA; 16]);
    // Too long for the 16-bit length field.
    let data = vec![0u8; 65_535];
    let mut big = vec![0u8; 70_000];
    assert!(matches!(
        dxl2::encode_instruction(&packet(1, Instruction::Write { address: 0, data: &data }), &mut big),
        Err(EncodeError::TooLong { .. })
    ));
    // The largest packet that fits: LEN = 0xFFFF = instruction, address (2), data, CRC (2).
    let data = &data[..65_535 - 5];
    let n = dxl2::encode_instruction(&packet(1, Instruction::Write { address: 0, data }), &mut big).unwrap();
    assert_eq!(n, 7 + 0xFFFF);
    assert_eq!(dxl2::frame_len(&big[..n]), FrameLen::Complete(n));
}

#[test]
fn frame_boundaries() {
    let ping = hex("FF FF FD 00 01 03 00 01 19 4E");
    assert_eq!(dxl2::frame_len(&[]), FrameLen::NeedMore(7));
    assert_eq!(dxl2::frame_len(&ping[..3]), FrameLen::NeedMore(7));
    assert_eq!(dxl2::frame_len(&ping[..7]), FrameLen::NeedMore(10));
    assert_eq!(dxl2::frame_len(&ping[..9]), FrameLen::NeedMore(10));
    let mut longer = ping.clone();
    longer.extend_from_slice(&[0xFF, 0xFF]);
    assert_eq!(dxl2::frame_len(&longer), FrameLen::Complete(10));
    // A stuffed FF FF FD FD is not a header.
    assert_eq!(dxl2::frame_len(&[0xFF, 0xFF, 0xFD, 0xFD]), FrameLen::NotAFrame);
    assert_eq!(dxl2::frame_len(&[0xFF, 0xFE]), FrameLen::NotAFrame);
    // Ids 0xFD and 0xFF are impossible.
    assert_eq!(dxl2::frame_len(&[0xFF, 0xFF, 0xFD, 0x00, 0xFD]), FrameLen::NotAFrame);
    assert_eq!(dxl2::frame_len(&[0xFF, 0xFF, 0xFD, 0x00, 0xFF]), FrameLen::NotAFrame);
    // LEN below 3.
    assert_eq!(dxl2::frame_len(&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x02, 0x00]), FrameLen::NotAFrame);
    assert_eq!(
        dxl2::verify(&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x02, 0x00, 0, 0]),
        Err(ParseError::BadLength { length: 2 })
    );
    assert_eq!(dxl2::verify(&[0xFF, 0xFF, 0xFD, 0xFD]), Err(ParseError::BadHeader));
    assert_eq!(dxl2::verify(&ping[..8]), Err(ParseError::Truncated { required: 10, available: 8 }));
}

#[test]
fn parse_refusals() {
    // A status where an instruction is expected and the reverse.
    let mut status = hex(EMPTY_STATUS_ID1);
    assert_eq!(dxl2::parse_instruction(&mut status), Err(ParseError::WrongKind));
    let mut ping = hex("FF FF FD 00 01 03 00 01 19 4E");
    assert_eq!(dxl2::parse_status(&mut ping), Err(ParseError::WrongKind));
    // A corrupted CRC.
    let mut bad = hex("FF FF FD 00 01 03 00 01 19 4F");
    assert_eq!(dxl2::parse_instruction(&mut bad), Err(ParseError::Checksum { received: 0x4F19, computed: 0x4E19 }));
    // Parameters that do not fit: a ping with a parameter, a read with three.
    for (code, params) in [(0x01u8, &[7u8][..]), (0x02, &[0x84, 0, 4]), (0x83, &[0x74, 0, 4, 0, 1, 0])] {
        let mut frame = frame_with_crc(1, code, params);
        assert_eq!(dxl2::parse_instruction(&mut frame), Err(ParseError::BadParameters { code }));
    }
    // A status with no error byte.
    let mut frame = frame_with_crc(1, 0x55, &[]);
    assert_eq!(dxl2::parse_status(&mut frame), Err(ParseError::BadLength { length: 3 }));
}

#[test]
fn status_errors() {
    assert_eq!(StatusError::from_byte(0).describe(), None);
    let crc = StatusError::from_byte(0x03);
    assert_eq!((crc.alert(), crc.number()), (false, 3));
    assert_eq!(crc.describe().unwrap().what, "CRC error");
    let alert = StatusError::from_byte(0x81);
    assert!(alert.alert());
    assert_eq!(alert.describe().unwrap().what, "result fail");
    assert_eq!(StatusError::from_byte(0x09).describe().unwrap().what, "unknown error 9");
}

/// A frame with the given (unstuffed) body and a correct CRC.
fn frame_with_crc(id: u8, code: u8, params: &[u8]) -> Vec<u8> {
    let len = u16::try_from(params.len() + 3).unwrap().to_le_bytes();
    let mut frame = vec![0xFF, 0xFF, 0xFD, 0x00, id, len[0], len[1], code];
    frame.extend_from_slice(params);
    let crc = crc16(&frame).to_le_bytes();
    frame.extend_from_slice(&crc);
    frame
}

// ---- property tests ----

/// Bytes that are often FF or FD, so that stuffing patterns are common.
fn byte() -> impl Strategy<Value = u8> {
    prop_oneof![3 => Just(0xFF), 2 => Just(0xFD), 1 => Just(0x00), 3 => any::<u8>()]
}

fn bytes(max: usize) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(byte(), 0..max)
}

fn servo_id() -> impl Strategy<Value = u8> {
    prop_oneof![0u8..=252, Just(0), Just(252)]
}

fn packet_id() -> impl Strategy<Value = u8> {
    prop_oneof![3 => servo_id(), 1 => Just(BROADCAST)]
}

fn word() -> impl Strategy<Value = u16> {
    prop_oneof![Just(0xFFFF), Just(0xFDFF), Just(0xFFFD), any::<u16>()]
}

/// An instruction with owned parameters; [`Owned::packet`] borrows it.
#[derive(Clone, Debug)]
enum Owned {
    Ping,
    Read(u16, u16),
    Write(u16, Vec<u8>),
    RegWrite(u16, Vec<u8>),
    Action,
    FactoryReset(u8),
    Reboot,
    Clear([u8; 5]),
    SyncRead(u16, u16, Vec<u8>),
    FastSyncRead(u16, u16, Vec<u8>),
    SyncWrite(u16, u16, Vec<u8>),
    BulkRead(Vec<u8>),
    BulkWrite(Vec<u8>),
}

impl Owned {
    fn instruction(&self) -> Instruction<'_> {
        match self {
            Self::Ping => Instruction::Ping,
            Self::Read(address, length) => Instruction::Read { address: *address, length: *length },
            Self::Write(address, data) => Instruction::Write { address: *address, data },
            Self::RegWrite(address, data) => Instruction::RegWrite { address: *address, data },
            Self::Action => Instruction::Action,
            Self::FactoryReset(mode) => Instruction::FactoryReset { mode: *mode },
            Self::Reboot => Instruction::Reboot,
            Self::Clear(params) => Instruction::Clear { params: *params },
            Self::SyncRead(address, length, ids) => Instruction::SyncRead { address: *address, length: *length, ids },
            Self::FastSyncRead(address, length, ids) => {
                Instruction::FastSyncRead { address: *address, length: *length, ids }
            }
            Self::SyncWrite(address, length, data) => {
                Instruction::SyncWrite { address: *address, length: *length, data }
            }
            Self::BulkRead(records) => Instruction::BulkRead { records },
            Self::BulkWrite(records) => Instruction::BulkWrite { records },
        }
    }
}

fn owned() -> impl Strategy<Value = Owned> {
    let sync_write = (word(), 0u16..6).prop_flat_map(|(address, length)| {
        prop::collection::vec((servo_id(), prop::collection::vec(byte(), usize::from(length))), 0..5).prop_map(
            move |records| {
                let data = records.into_iter().flat_map(|(id, d)| std::iter::once(id).chain(d)).collect();
                Owned::SyncWrite(address, length, data)
            },
        )
    });
    let bulk_read = prop::collection::vec((servo_id(), word(), word()), 0..5).prop_map(|records| {
        let mut buf = vec![0u8; records.len() * 5];
        let mut w = RecordWriter::new(&mut buf);
        for (id, address, length) in records {
            w.bulk_read(id, address, length).unwrap();
        }
        Owned::BulkRead(w.records().to_vec())
    });
    let bulk_write = prop::collection::vec((servo_id(), word(), bytes(6)), 0..5).prop_map(|records| {
        let mut buf = vec![0u8; 256];
        let mut w = RecordWriter::new(&mut buf);
        for (id, address, data) in records {
            w.bulk_write(id, address, &data).unwrap();
        }
        Owned::BulkWrite(w.records().to_vec())
    });
    prop_oneof![
        Just(Owned::Ping),
        (word(), word()).prop_map(|(a, l)| Owned::Read(a, l)),
        (word(), bytes(40)).prop_map(|(a, d)| Owned::Write(a, d)),
        (word(), bytes(40)).prop_map(|(a, d)| Owned::RegWrite(a, d)),
        Just(Owned::Action),
        byte().prop_map(Owned::FactoryReset),
        Just(Owned::Reboot),
        prop::array::uniform5(byte()).prop_map(Owned::Clear),
        (word(), word(), prop::collection::vec(servo_id(), 0..8)).prop_map(|(a, l, ids)| Owned::SyncRead(a, l, ids)),
        (word(), word(), prop::collection::vec(servo_id(), 0..8))
            .prop_map(|(a, l, ids)| Owned::FastSyncRead(a, l, ids)),
        sync_write,
        bulk_read,
        bulk_write,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn instructions_round_trip(id in packet_id(), owned in owned()) {
        let packet = InstructionPacket { id, instruction: owned.instruction() };
        let mut out = vec![0u8; 1024];
        let n = dxl2::encode_instruction(&packet, &mut out).unwrap();
        prop_assert!(n >= dxl2::instruction_len(0));
        let frame = &mut out[..n];
        prop_assert_eq!(dxl2::frame_len(frame), FrameLen::Complete(n));
        prop_assert_eq!(dxl2::verify(frame), Ok(()));
        prop_assert_eq!(dxl2::parse_instruction(frame), Ok(packet));
    }

    #[test]
    fn statuses_round_trip(id in packet_id(), error in any::<u8>(), params in bytes(40)) {
        let status = Status { id, error, params: &params };
        let mut out = vec![0u8; 256];
        let n = dxl2::encode_status(&status, &mut out).unwrap();
        prop_assert!(n >= dxl2::status_len(params.len()));
        let frame = &mut out[..n];
        prop_assert_eq!(dxl2::frame_len(frame), FrameLen::Complete(n));
        prop_assert_eq!(dxl2::verify(frame), Ok(()));
        prop_assert_eq!(dxl2::parse_status(frame), Ok(status));
    }

    #[test]
    fn fast_sync_replies_round_trip(
        length in 0usize..6,
        parts in prop::collection::vec((any::<u8>(), servo_id(), bytes(6)), 1..6),
    ) {
        let parts: Vec<(u8, u8, Vec<u8>)> =
            parts.into_iter().map(|(e, id, mut d)| { d.resize(length, 0xFF); (e, id, d) }).collect();
        let borrowed: Vec<(u8, u8, &[u8])> = parts.iter().map(|(e, id, d)| (*e, *id, &d[..])).collect();
        let mut out = vec![0u8; 256];
        let n = dxl2::encode_fast_sync_read_status(&borrowed, &mut out).unwrap();
        let frame = &mut out[..n];
        prop_assert_eq!(dxl2::frame_len(frame), FrameLen::Complete(n));
        prop_assert_eq!(dxl2::verify(frame), Ok(()));
        let status = dxl2::parse_status(frame).unwrap();
        let got: Vec<_> = fast_sync_read_parts(&status, length).unwrap().collect();
        let want: Vec<_> = borrowed.iter().map(|&(error, id, data)| FastSyncPart { error, id, data }).collect();
        prop_assert_eq!(got, want);
    }

    #[test]
    fn a_flipped_bit_is_detected(id in packet_id(), owned in owned(), bit in any::<prop::sample::Index>()) {
        let packet = InstructionPacket { id, instruction: owned.instruction() };
        let mut out = vec![0u8; 1024];
        let n = dxl2::encode_instruction(&packet, &mut out).unwrap();
        let frame = &mut out[..n];
        let bit = bit.index(n * 8);
        frame[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(dxl2::frame_len(frame) != FrameLen::Complete(n) || dxl2::verify(frame).is_err());
    }

    #[test]
    fn arbitrary_bytes_never_panic(mut buf in prop_oneof![
        bytes(64),
        bytes(64).prop_map(|tail| [&[0xFF, 0xFF, 0xFD, 0x00][..], &tail].concat()),
    ]) {
        let _ = dxl2::frame_len(&buf);
        let _ = dxl2::verify(&buf);
        let _ = dxl2::parse_instruction(&mut buf.clone());
        let _ = dxl2::parse_status(&mut buf);
    }

    #[test]
    fn frames_past_the_crc_never_panic(id in any::<u8>(), code in byte(), params in bytes(48), length in 0usize..8) {
        // A correct CRC, so the parsers run on whatever follows.
        let mut frame = frame_with_crc(id, code, &params);
        let _ = dxl2::parse_instruction(&mut frame.clone());
        if let Ok(status) = dxl2::parse_status(&mut frame) {
            if let Some(parts) = fast_sync_read_parts(&status, length) {
                let _ = parts.count();
            }
        }
    }
}
