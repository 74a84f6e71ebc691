//! The servo bus simulator against the firmware's own bus master: every instruction on both
//! protocols, the servos' rules (status return level, EEPROM lock, limits, motion profile,
//! hardware alerts), injected faults, bus timing on the virtual clock, and the pty server.
//!
//! Everything runs on the virtual clock and seeded faults, so results are exact and repeatable;
//! only the pty tests touch real time, and they assert bytes, not durations.

mod support;

use std::time::{Duration, Instant};

use armctl::link::serial::{SerialTransport, StdClock};
use armctl::sim::{connect, Faults, GoalLimit, PtyServer, SharedBus, SimBus, SimConfig, SimPort, VirtualClock};
use firmware::bus::cycle::ServoGroup;
use firmware::bus::instruction::{BulkReadRecord, RecordWriter};
use firmware::bus::master::{BusConfig, Master, MasterError, NoDirectionPin, Replies};
use firmware::bus::table::{Item, Model, STS3215, XL430_W250};
use firmware::bus::timing::{cycle_time_ns, sync_read_request_len, sync_write_len, wire_time_ns};
use firmware::bus::{Instruction, Protocol, Status, BROADCAST};

type SimMaster = Master<SimPort, NoDirectionPin, VirtualClock>;

const BAUD: u32 = 1_000_000;

struct Rig {
    bus: SharedBus,
    master: SimMaster,
    clock: VirtualClock,
    model: &'static Model,
}

fn rig_with(model: &'static Model, ids: &[u8], faults: Faults) -> Rig {
    rig_at(model, ids, faults, BAUD)
}

fn rig_at(model: &'static Model, ids: &[u8], faults: Faults, baud: u32) -> Rig {
    let bus = SimBus::new(model.protocol, model, ids, baud).with_faults(faults);
    let (bus, port, clock) = connect(bus);
    let master = Master::new(port, NoDirectionPin, clock.clone(), BusConfig::new(model.protocol, baud));
    Rig { bus, master, clock, model }
}

fn rig(model: &'static Model, ids: &[u8]) -> Rig {
    rig_with(model, ids, Faults::default())
}

impl Rig {
    /// An item's value in servo `id`'s table, brought up to the present virtual time.
    fn table(&self, id: u8, item: Item) -> i64 {
        let mut bus = self.bus.borrow_mut();
        bus.advance_to(self.clock.now_ns());
        bus.servo(id).expect("servo").get(item)
    }

    fn bytes(&self, item: Item, value: i64) -> Vec<u8> {
        let mut b = vec![0u8; item.len()];
        item.encode(value, self.model.endian, &mut b).unwrap();
        b
    }

    fn write_item(&mut self, id: u8, item: Item, value: i64) {
        let data = self.bytes(item, value);
        self.master.write(id, item.address, &data).unwrap_or_else(|e| panic!("write {}: {e}", item.name));
    }

    fn read_item(&mut self, id: u8, item: Item) -> i64 {
        let mut b = vec![0u8; item.len()];
        self.master.read(id, item.address, &mut b).unwrap_or_else(|e| panic!("read {}: {e}", item.name));
        item.decode(&b, self.model.endian).unwrap()
    }
}

#[test]
fn dynamixel_answers_every_instruction() {
    let mut r = rig(&XL430_W250, &[1, 2, 3]);
    let items = r.model.items;
    let info = r.master.ping(1).unwrap();
    assert_eq!((info.model, info.firmware, info.alert), (Some(1060), Some(46), None));
    assert_eq!(r.read_item(1, items.present_position), 2048);
    assert_eq!(r.read_item(2, items.model_number), 1060);

    // Write, EEPROM (torque is off from the factory) and RAM.
    r.write_item(1, items.return_delay, 10);
    assert_eq!(r.table(1, items.return_delay), 10);
    r.write_item(1, items.status_return_level, 2);
    r.master.write(1, 65, &[1]).unwrap();
    assert_eq!(r.bus.borrow().servo(1).unwrap().table()[65], 1);

    // Reg write waits for the action.
    let goal = r.bytes(items.goal_position, 1000);
    r.master.reg_write(1, items.goal_position.address, &goal).unwrap();
    assert_eq!(r.table(1, items.goal_position), 2048);
    assert!(!r.master.action(BROADCAST).unwrap().replied);
    assert_eq!(r.table(1, items.goal_position), 1000);

    // Reboot: RAM back to factory values, EEPROM kept.
    assert!(r.master.command(1, Instruction::Reboot).unwrap().replied);
    assert_eq!(r.bus.borrow().servo(1).unwrap().table()[65], 0);
    assert_eq!(r.table(1, items.return_delay), 10);

    // Factory reset keeping id and baud: EEPROM back to factory values.
    r.master.command(1, Instruction::FactoryReset { mode: 0x02 }).unwrap();
    assert_eq!(r.table(1, items.return_delay), 250);
    assert_eq!(r.table(1, items.id), 1);
    assert_eq!(r.read_item(1, items.id), 1);

    // Clear the multi-turn position (key "DXL\"").
    assert!(r.master.command(1, Instruction::Clear { params: [0x01, 0x44, 0x58, 0x4C, 0x22] }).unwrap().replied);

    // Sync write of goals, then group reads of them.
    let mut records = [0u8; 32];
    let mut w = RecordWriter::new(&mut records);
    for (id, g) in [(1u8, 100i64), (2, 200), (3, 300)] {
        w.sync_write(id, &r.bytes(items.goal_position, g)).unwrap();
    }
    let n = w.records().len();
    r.master.sync_write(items.goal_position.address, 4, &records[..n]).unwrap();
    for (id, g) in [(1u8, 100i64), (2, 200), (3, 300)] {
        assert_eq!(r.table(id, items.goal_position), g);
    }
    let mut out = [0u8; 12];
    let report = r.master.sync_read(items.goal_position.address, 4, &[3, 1, 2], &mut out).unwrap();
    assert!(report.complete(), "{report:?}");
    let values: Vec<i64> = out.chunks(4).map(|c| items.goal_position.decode(c, r.model.endian).unwrap()).collect();
    assert_eq!(values, [300, 100, 200]);

    let mut out = [0u8; 12];
    let report = r.master.fast_sync_read(items.goal_position.address, 4, &[2, 3, 1], &mut out).unwrap();
    assert!(report.complete(), "{report:?}");
    let values: Vec<i64> = out.chunks(4).map(|c| items.goal_position.decode(c, r.model.endian).unwrap()).collect();
    assert_eq!(values, [200, 300, 100]);

    // Bulk write and bulk read of different items.
    let mut records = [0u8; 32];
    let mut w = RecordWriter::new(&mut records);
    w.bulk_write(2, 65, &[1]).unwrap();
    w.bulk_write(3, items.goal_position.address, &r.bytes(items.goal_position, 333)).unwrap();
    let n = w.records().len();
    r.master.bulk_write(&records[..n]).unwrap();
    let asked = [
        BulkReadRecord { id: 3, address: items.goal_position.address, length: 4 },
        BulkReadRecord { id: 2, address: 65, length: 1 },
    ];
    let mut out = [0u8; 5];
    let report = r.master.bulk_read(&asked, &mut out).unwrap();
    assert!(report.complete(), "{report:?}");
    assert_eq!(items.goal_position.decode(&out[..4], r.model.endian).unwrap(), 333);
    assert_eq!(out[4], 1);

    // Out of the table: data range (4) and data length (5) errors.
    let mut big = [0u8; 4];
    assert!(matches!(r.master.read(1, 200, &mut big), Err(MasterError::Refused { error: 4, .. })));
    assert!(matches!(r.master.read(1, 146, &mut big), Err(MasterError::Refused { error: 5, .. })));
    // Read-only items refuse writes with an access error.
    assert!(matches!(r.master.write(1, 132, &[0; 4]), Err(MasterError::Refused { error: 7, .. })));
}

#[test]
fn feetech_answers_every_instruction() {
    let mut r = rig(&STS3215, &[1, 2, 3]);
    let items = r.model.items;
    let info = r.master.ping(2).unwrap();
    assert_eq!((info.model, info.alert), (None, None));
    assert_eq!(r.read_item(1, items.model_number), 777);
    assert_eq!(r.read_item(1, items.present_position), 2048);

    // EEPROM writes take effect whatever the lock says (the lock only decides persistence); the
    // factory's lock is 0 (Feetech's memory table).
    assert_eq!(r.table(1, items.lock.unwrap()), 0);
    r.write_item(1, items.lock.unwrap(), 1);
    r.write_item(1, items.max_position, 3000);
    assert_eq!(r.table(1, items.max_position), 3000);
    r.write_item(1, items.torque_enable, 1);
    assert_eq!(r.table(1, items.torque_enable), 1);

    // Sign-magnitude goal through a reg write and the action.
    let goal = r.bytes(items.velocity, -50);
    assert_eq!(goal, [50, 0x80]);
    r.master.reg_write(1, items.velocity.address, &goal).unwrap();
    assert_eq!(r.table(1, items.velocity), 0);
    r.master.action(BROADCAST).unwrap();
    assert_eq!(r.table(1, items.velocity), -50);

    let mut records = [0u8; 32];
    let mut w = RecordWriter::new(&mut records);
    for (id, v) in [(1u8, 11i64), (2, 22), (3, 33)] {
        w.sync_write(id, &r.bytes(items.return_delay, v)).unwrap();
    }
    let n = w.records().len();
    r.master.sync_write(items.return_delay.address, 1, &records[..n]).unwrap();
    let mut out = [0u8; 3];
    let report = r.master.sync_read(items.return_delay.address, 1, &[1, 2, 3], &mut out).unwrap();
    assert!(report.complete(), "{report:?}");
    assert_eq!(out, [11, 22, 33]);

    assert!(r.master.command(3, Instruction::Reset).unwrap().replied);
    // Read-only bytes are ignored without an error number (Feetech has none).
    r.master.write(1, items.present_position.address, &[0, 0]).unwrap();
    assert_eq!(r.read_item(1, items.present_position), 2048);
}

#[test]
fn status_return_levels_are_honoured() {
    let mut r = rig(&XL430_W250, &[1]);
    let items = r.model.items;
    // Level 1: ping and reads only; the write still takes effect.
    r.write_item(1, items.status_return_level, 1);
    assert!(matches!(r.master.write(1, 65, &[1]), Err(MasterError::NoReply { .. })));
    assert_eq!(r.table(1, Item { address: 65, ..items.torque_enable }), 1);
    assert_eq!(r.read_item(1, items.status_return_level), 1);
    let mut config = *r.master.config();
    config.replies = Replies::Reads;
    r.master.set_config(config);
    assert!(!r.master.write(1, 65, &[0]).unwrap().replied);
    // Level 0: ping only.
    r.master.write(1, items.status_return_level.address, &[0]).unwrap();
    assert!(r.master.ping(1).is_ok());
    let mut b = [0u8; 1];
    assert!(matches!(r.master.read(1, 65, &mut b), Err(MasterError::NoReply { .. })));
    let mut out = [0u8; 4];
    let report = r.master.sync_read(items.present_position.address, 4, &[1], &mut out).unwrap();
    assert_eq!(report.answered, 0);

    // Feetech level 0: ping and reads only.
    let mut r = rig(&STS3215, &[4]);
    let items = r.model.items;
    r.write_item(4, items.status_return_level, 0);
    assert!(matches!(r.master.write(4, 41, &[1]), Err(MasterError::NoReply { .. })));
    assert_eq!(r.read_item(4, items.acceleration), 1);
}

#[test]
fn eeprom_is_refused_while_torque_is_on() {
    let mut r = rig(&XL430_W250, &[1]);
    let items = r.model.items;
    r.write_item(1, items.torque_enable, 1);
    let err = r.master.write(1, items.return_delay.address, &[0]).unwrap_err();
    assert!(matches!(err, MasterError::Refused { id: 1, error: 7, .. }), "{err:?}");
    assert_eq!(err.to_string(), "servo 1: access error");
    assert_eq!(r.table(1, items.return_delay), 250);
    r.write_item(1, items.torque_enable, 0);
    r.write_item(1, items.return_delay, 0);
    assert_eq!(r.table(1, items.return_delay), 0);
}

#[test]
fn goals_beyond_the_limits_are_refused_or_clamped_and_nothing_moves_without_torque() {
    for model in [&XL430_W250, &STS3215] {
        let mut r = rig(model, &[1]);
        let items = model.items;
        r.write_item(1, items.max_position, 3000);
        r.write_item(1, items.min_position, 1000);
        // Torque off: the goal is stored, the horn stays.
        r.write_item(1, items.goal_position, 2500);
        r.clock.advance_ns(2_000_000_000);
        assert_eq!(r.read_item(1, items.present_position), 2048, "{}", model.name);
        r.write_item(1, items.torque_enable, 1);
        let beyond = |r: &mut Rig, goal: i64| {
            let data = r.bytes(items.goal_position, goal);
            r.master.write(1, items.goal_position.address, &data)
        };
        match model.protocol {
            // Dynamixel refuses a goal beyond the limits with a data limit error and keeps its goal.
            Protocol::Dxl2 => {
                let err = beyond(&mut r, 4000).unwrap_err();
                assert!(matches!(err, MasterError::Refused { error: 6, .. }), "{err:?}");
                assert_eq!(err.to_string(), "servo 1: data limit error");
                r.clock.advance_ns(5_000_000_000);
                assert_eq!(r.read_item(1, items.present_position), 2048);
            }
            // Feetech takes it and stops at the limit.
            Protocol::Feetech => {
                beyond(&mut r, 4000).unwrap();
                r.clock.advance_ns(5_000_000_000);
                assert_eq!(r.read_item(1, items.present_position), 3000);
                beyond(&mut r, 10).unwrap();
                r.clock.advance_ns(5_000_000_000);
                assert_eq!(r.read_item(1, items.present_position), 1000);
            }
        }
    }
}

/// Samples present position and moving flag every `step_ns` until the servo stops; returns
/// `(time the position read reached the servo, position, time the moving read did, moving)` of
/// each sample.
fn follow(r: &mut Rig, id: u8, step_ns: u64, limit_ns: u64) -> Vec<(u64, i64, u64, bool)> {
    let items = r.model.items;
    let read_len = r.model.protocol.instruction_len(4);
    let poll = wire_time_ns(1, BAUD);
    let mut samples = Vec::new();
    let start = r.clock.now_ns();
    while r.clock.now_ns() - start < limit_ns {
        // The port's poll for stale input, then the read's bytes: when the servo sees the read.
        let at = r.clock.now_ns() + poll + wire_time_ns(read_len, BAUD);
        let p = r.read_item(id, items.present_position);
        let at_moving = r.clock.now_ns() + poll + wire_time_ns(read_len, BAUD);
        let moving = r.read_item(id, items.moving) != 0;
        samples.push((at, p, at_moving, moving));
        if !moving && samples.len() > 1 {
            break;
        }
        r.clock.advance_ns(step_ns);
    }
    samples
}

#[test]
fn the_motion_profile_takes_the_expected_time() {
    let mut r = rig(&XL430_W250, &[1]);
    let items = r.model.items;
    let v_units = 100;
    let v = f64::from(v_units) * f64::from(r.model.velocity_unit);
    r.write_item(1, items.velocity, i64::from(v_units));
    r.write_item(1, items.torque_enable, 1);
    let write_len = r.model.protocol.instruction_len(2 + 4);
    let t_goal = r.clock.now_ns() + wire_time_ns(1, BAUD) + wire_time_ns(write_len, BAUD);
    r.write_item(1, items.goal_position, 3048);
    let samples = follow(&mut r, 1, 200_000, 2_000_000_000);
    // Constant velocity (acceleration 0 = unlimited): 1000 ticks at v ticks/s.
    let expected_end = t_goal + (1000.0 / v * 1e9) as u64;
    let tick_ns = (1e9 / v) as u64;
    for &(t, p, t_moving, moving) in &samples {
        let ideal = (2048.0 + v * (t.saturating_sub(t_goal)) as f64 * 1e-9).min(3048.0);
        assert!((p as f64 - ideal).abs() <= 1.0, "at {t} ns (goal at {t_goal}): {p} vs {ideal}");
        assert_eq!(moving, t_moving < expected_end, "moving flag at {t_moving} ns (end {expected_end})");
    }
    let arrived = samples.iter().find(|s| s.1 == 3048).expect("reached the goal").0;
    assert!(arrived + 2 * tick_ns >= expected_end && arrived <= expected_end + 200_000 + tick_ns, "{arrived}");

    // With a profile acceleration: a trapezoid, d/v + v/a.
    let a_units = 10;
    let a = f64::from(a_units) * f64::from(r.model.acceleration_unit);
    r.write_item(1, items.acceleration, i64::from(a_units));
    let t_goal = r.clock.now_ns() + wire_time_ns(1, BAUD) + wire_time_ns(write_len, BAUD);
    r.write_item(1, items.goal_position, 48);
    let samples = follow(&mut r, 1, 500_000, 5_000_000_000);
    let expected = 3000.0 / v + v / a;
    // The moving flag drops when the profile ends; the quantised position reaches the goal up to
    // half a tick earlier, which at the end of the deceleration takes sqrt(2 * 0.5 / a).
    let stopped = samples.iter().find(|s| !s.3).expect("stopped").2;
    let took = (stopped - t_goal) as f64 * 1e-9;
    assert!(took >= expected && took <= expected + 0.0005 + 0.002, "{took} s vs {expected} s");
    let arrived = samples.iter().find(|s| s.1 == 48).expect("reached the goal").0;
    let took = (arrived - t_goal) as f64 * 1e-9;
    let early = (2.0 * 0.5 / a).sqrt();
    assert!(took >= expected - early - 0.0005 && took <= expected, "{took} s vs {expected} s");
    // Accelerating: the first half-second covers far less than v * t.
    let early = samples.iter().find(|s| s.0 >= t_goal + 300_000_000).unwrap();
    let ideal = 3048.0 - 0.5 * a * ((early.0 - t_goal) as f64 * 1e-9).powi(2);
    assert!((early.1 as f64 - ideal).abs() <= 1.0, "{} vs {ideal}", early.1);
}

#[test]
fn hardware_alerts_are_reported_and_turn_torque_off() {
    let mut r = rig(&XL430_W250, &[1, 2]);
    let items = r.model.items;
    r.write_item(2, items.torque_enable, 1);
    let now = r.clock.now_ns();
    r.bus.borrow_mut().servo_mut(2).unwrap().set_hardware_error(0x20, now);
    let mut b = [0u8; 1];
    let answer = r.master.read(2, items.torque_enable.address, &mut b).unwrap();
    assert_eq!((answer.alert, b[0]), (Some(0x80), 0));
    assert_eq!(r.read_item(2, items.hardware_error.unwrap()), 0x20);
    let mut out = [0u8; 8];
    let report = r.master.sync_read(items.present_position.address, 4, &[1, 2], &mut out).unwrap();
    assert_eq!((report.answered, report.alerts), (0b11, 0b10));
    assert_eq!(r.master.ping(2).unwrap().alert, Some(0x80));
    // Torque stays off until a reboot clears the fault.
    r.write_item(2, items.torque_enable, 1);
    assert_eq!(r.table(2, items.torque_enable), 0);
    r.master.command(2, Instruction::Reboot).unwrap();
    assert_eq!(r.master.ping(2).unwrap().alert, None);

    let mut r = rig(&STS3215, &[1]);
    r.write_item(1, items_of(&STS3215).torque_enable, 1);
    let now = r.clock.now_ns();
    r.bus.borrow_mut().servo_mut(1).unwrap().set_hardware_error(0x20, now);
    let mut b = [0u8; 2];
    let answer = r.master.read(1, STS3215.items.present_position.address, &mut b).unwrap();
    assert_eq!(answer.alert, Some(0x20));
    assert_eq!(r.table(1, STS3215.items.torque_enable), 0);
}

fn items_of(model: &Model) -> firmware::bus::table::Items {
    model.items
}

#[test]
fn a_silent_servo_is_no_reply_alone_and_missing_in_a_sync_read() {
    let mut r = rig_with(&XL430_W250, &[1, 2, 3, 4], Faults { silent: vec![3], ..Faults::default() });
    let items = r.model.items;
    let mut b = [0u8; 4];
    let err = r.master.read(3, items.present_position.address, &mut b).unwrap_err();
    assert!(matches!(err, MasterError::NoReply { id: 3, attempts: 3, corrupt: 0, .. }), "{err:?}");
    for id in [1, 2, 4] {
        r.bus.borrow_mut().servo_mut(id).unwrap().set_position(1000 + i64::from(id), 0);
    }
    let ids = [1, 2, 3, 4];
    let mut out = [0u8; 16];
    let report = r.master.sync_read(items.present_position.address, 4, &ids, &mut out).unwrap();
    assert_eq!(report.missing(&ids).collect::<Vec<_>>(), [3]);
    assert_eq!(report.attempts, 3);
    let values: Vec<i64> = out.chunks(4).map(|c| items.present_position.decode(c, r.model.endian).unwrap()).collect();
    assert_eq!(values, [1001, 1002, 0, 1004]);
    // A fast sync read's chain breaks at the silent servo: nobody's data arrives.
    let report = r.master.fast_sync_read(items.present_position.address, 4, &ids, &mut out).unwrap();
    assert_eq!(report.answered, 0);
    let report = r.master.fast_sync_read(items.present_position.address, 4, &[4, 1], &mut out).unwrap();
    assert!(report.complete());
}

#[test]
fn corrupted_replies_are_retried_then_reported() {
    let mut r = rig(&XL430_W250, &[1]);
    r.bus.borrow_mut().faults().corrupt_next(1, 1);
    let mut b = [0u8; 4];
    r.master.read(1, 132, &mut b).unwrap();
    assert_eq!(i32::from_le_bytes(b), 2048);
    assert_eq!((r.master.stats().retries, r.master.stats().bad_checksums), (1, 1));

    r.bus.borrow_mut().faults().corrupt_next(1, 3);
    let err = r.master.read(1, 132, &mut b).unwrap_err();
    assert!(matches!(err, MasterError::NoReply { id: 1, attempts: 3, corrupt: 3, .. }), "{err:?}");
    assert!(err.to_string().contains("bad checksum"), "{err}");

    // On Feetech too, and by probability.
    let mut r = rig_with(&STS3215, &[1], Faults { seed: 7, corrupt_rate: 0.3, ..Faults::default() });
    for _ in 0..50 {
        r.master.ping(1).unwrap();
    }
    assert!(r.master.stats().bad_checksums > 0);
}

#[test]
fn dropped_bytes_are_recovered_by_retries() {
    for model in [&XL430_W250, &STS3215] {
        let mut r = rig_with(model, &[1, 2], Faults { seed: 3, drop_rate: 0.003, ..Faults::default() });
        let pos = model.items.present_position;
        for i in 0..200 {
            let mut b = vec![0u8; pos.len()];
            r.master.read(1 + (i % 2), pos.address, &mut b).unwrap_or_else(|e| panic!("{}: read {i}: {e}", model.name));
            assert_eq!(pos.decode(&b, model.endian).unwrap(), 2048);
        }
        let dropped = r.bus.borrow_mut().faults().stats().dropped;
        assert!(dropped > 0 && r.master.stats().retries > 0, "{}: {dropped} dropped", model.name);
    }
}

#[test]
fn two_servos_with_one_id_garble_the_reply() {
    let mut r = rig(&XL430_W250, &[1, 2]);
    let mut twin = r.bus.borrow().new_servo(2);
    twin.set_position(1234, 0);
    r.bus.borrow_mut().add_servo(twin);
    let mut b = [0u8; 4];
    let err = r.master.read(2, 132, &mut b).unwrap_err();
    assert!(matches!(err, MasterError::NoReply { id: 2, corrupt, .. } if corrupt > 0), "{err:?}");
    assert!(r.bus.borrow().stats().collisions > 0);
    // Both obey writes, and their identical empty statuses AND into a valid one; servo 1 is
    // unaffected.
    r.master.write(2, 65, &[1]).unwrap();
    assert!(r.bus.borrow().servos().iter().filter(|s| s.id() == 2).all(|s| s.table()[65] == 1));
    r.master.read(1, 132, &mut b).unwrap();
}

/// One control cycle for six servos: the protocol's minimum bytes, and the wire time plus return
/// delays on the virtual clock, at 1 Mbps and at 57600 baud (where a byte time is not a whole number
/// of nanoseconds). The tolerance is two poll steps (one byte time each) and 1 ns per byte of
/// rounding: before each of its two packets the master drains stale input, and the port, finding
/// nothing queued, advances the clock by one poll step; every other wait ends exactly when a byte
/// arrives.
#[test]
fn one_cycle_costs_the_wire_time_and_return_delays() {
    for baud in [BAUD, 57_600] {
        for model in [&XL430_W250, &STS3215] {
            let protocol = model.protocol;
            let ids = [1, 2, 3, 4, 5, 6];
            let mut r = rig_at(model, &ids, Faults::default(), baud);
            let group = ServoGroup::new(model, ids);
            let goals = [2048; 6];
            let mut positions = [0; 6];
            let (t0, sent0) = (r.clock.now_ns(), r.master.stats().bytes_sent);
            let report = group.cycle(&mut r.master, &goals, &mut positions).unwrap();
            assert!(report.complete(), "{} at {baud}: {report:?}", model.name);
            let (len, pos_len) = (model.items.goal_position.len(), model.items.present_position.len());
            let bytes = r.master.stats().bytes_sent - sent0;
            assert_eq!(bytes as usize, sync_write_len(protocol, 6, len) + sync_read_request_len(protocol, 6));
            let delay_us = r.bus.borrow().servo(1).unwrap().return_delay_ns() / 1000;
            let ideal = cycle_time_ns(protocol, 6, len, pos_len, baud, delay_us as u32);
            let took = r.clock.now_ns() - t0;
            let slack = 2 * wire_time_ns(1, baud) + 200;
            assert!(took >= ideal && took <= ideal + slack, "{} at {baud}: {took} ns vs {ideal} ns", model.name);
            assert_eq!(positions, [2048; 6]);
        }
    }
}

/// A group padded for a firmware built for more joints than its arm has: only the servos on the
/// bus are written and read (the wire carries as many records as a group of that size), the
/// padding joints keep their values and count as answered, and the extra servo (a gripper) keeps
/// its bit at `N` whatever the padding.
#[test]
fn a_padded_group_reads_and_writes_only_its_servos() {
    for model in [&XL430_W250, &STS3215] {
        let protocol = model.protocol;
        let mut r = rig(model, &[1, 2, 3, 6]);
        let group = ServoGroup { servos: 3, ..ServoGroup::new(model, [1, 2, 3, 4, 5]) };
        let sent0 = r.master.stats().bytes_sent;
        let item = model.items.goal_position;
        group.write_with(&mut r.master, item, &[2000, 2010, 2020, 9999, 9999], Some((6, 2030))).unwrap();
        let written = r.master.stats().bytes_sent - sent0;
        assert_eq!(written as usize, sync_write_len(protocol, 4, item.len()), "{}", model.name);
        for (id, goal) in [(1, 2000), (2, 2010), (3, 2020), (6, 2030)] {
            assert_eq!(r.table(id, item), goal, "{}", model.name);
        }
        let mut values = [0, 0, 0, -7, -8];
        let mut gripper = 0;
        let sent0 = r.master.stats().bytes_sent;
        let report =
            group.read_with(&mut r.master, model.items.present_position, &mut values, Some((6, &mut gripper))).unwrap();
        let asked = r.master.stats().bytes_sent - sent0;
        assert_eq!(asked as usize, sync_read_request_len(protocol, 4), "{}", model.name);
        assert_eq!(values[3..], [-7, -8], "padding keeps its values");
        assert_eq!((report.count, report.answered), (6, 0b11_1111), "{}: {report:?}", model.name);
        assert!(report.complete());
        // The gripper silent: its bit (5, after the five joints) is the one missing.
        let mut r = rig(model, &[1, 2, 3]);
        let report =
            group.read_with(&mut r.master, model.items.present_position, &mut values, Some((6, &mut gripper))).unwrap();
        assert_eq!(report.answered, 0b01_1111, "{}: {report:?}", model.name);
    }
}

fn ping_reply(protocol: Protocol, id: u8, params: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; 32];
    let n = protocol.encode_status(&Status { id, error: 0, params }, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn exchange(path: &str, request: &[u8], reply_len: usize) -> Vec<u8> {
    let mut port = serialport::new(path, BAUD).timeout(std::time::Duration::from_secs(5)).open().expect("open pty");
    port.write_all(request).unwrap();
    port.flush().unwrap();
    let mut reply = vec![0u8; reply_len];
    port.read_exact(&mut reply).expect("reply");
    reply
}

#[test]
fn the_pty_server_answers_a_ping() {
    let server = PtyServer::spawn(SimConfig {
        protocol: Protocol::Dxl2,
        model: &XL430_W250,
        ids: vec![1, 2],
        baud: BAUD,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: false,
        burst: None,
        limits: None,
        world: None,
        physics: None,
    })
    .unwrap();
    armctl_test_support::assert_private(server.path());
    let expected = ping_reply(Protocol::Dxl2, 1, &[0x24, 0x04, 46]);
    let ping = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
    assert_eq!(exchange(server.path(), &ping, expected.len()), expected);
    server.stop().unwrap();
}

/// Noise that looks like the start of a long packet, then a ping, in one burst: the servos drop
/// the dead candidate once the line is quiet and answer the ping, on the pty (real time) and on
/// the in-memory port (virtual time).
#[test]
fn a_ping_behind_a_false_header_in_noise_is_answered() {
    let server = PtyServer::spawn(SimConfig {
        protocol: Protocol::Feetech,
        model: &STS3215,
        ids: vec![1],
        baud: BAUD,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: false,
        burst: None,
        limits: None,
        world: None,
        physics: None,
    })
    .unwrap();
    let noisy_ping = [0xFF, 0xFF, 0x00, 0x20, 0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let expected = ping_reply(Protocol::Feetech, 1, &[]);
    assert_eq!(exchange(server.path(), &noisy_ping, expected.len()), expected);
    server.stop().unwrap();

    let mut port = armctl::sim::connect(SimBus::new(Protocol::Feetech, &STS3215, &[1], BAUD)).1;
    use embedded_io::{Read, ReadReady, Write};
    port.write_all(&noisy_ping).unwrap();
    port.flush().unwrap();
    let mut reply = Vec::new();
    while port.read_ready().unwrap() {
        let mut b = [0u8; 16];
        let n = port.read(&mut b).unwrap();
        reply.extend_from_slice(&b[..n]);
    }
    assert_eq!(reply, expected);
}

/// A Feetech bus of STS3215 servos with `ids` on a pty, replies held for `burst`, goals checked
/// against `limits`.
/// One real-time test at a time: each serves a bus on a pty on the real clock and judges the
/// times of what arrives, which other tests running beside it on two cores would stretch.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    // A test that failed holding the lock leaves it poisoned; the next one still runs.
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

fn sts_on_pty(ids: &[u8], burst: Option<Duration>, limits: Option<Vec<GoalLimit>>) -> PtyServer {
    PtyServer::spawn(SimConfig {
        protocol: Protocol::Feetech,
        model: &STS3215,
        ids: ids.to_vec(),
        baud: BAUD,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: false,
        burst,
        limits,
        world: None,
        physics: None,
    })
    .expect("pty server starts")
}

/// The firmware's master on a pty's slave end and the real clock, as on a PC, with a reply margin
/// and idle gap beyond a latency timer's period (and a loaded machine's hiccups).
fn pty_master(path: &str) -> Master<SerialTransport, NoDirectionPin, StdClock> {
    let mut config = BusConfig::new(Protocol::Feetech, BAUD);
    config.margin_us = 500_000;
    config.idle_gap_us = 50_000;
    Master::new(SerialTransport::open(path, BAUD).expect("open pty"), NoDirectionPin, StdClock::new(), config)
}

/// Pings servo 1 `rounds` times, each right after the reply before; returns the waits, sorted.
fn ping_waits(server: &PtyServer, rounds: usize) -> Vec<Duration> {
    let mut port = serialport::new(server.path(), BAUD).timeout(Duration::from_secs(5)).open().expect("open pty");
    let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let expected = ping_reply(Protocol::Feetech, 1, &[]);
    let mut reply = vec![0u8; expected.len()];
    let mut waits = Vec::new();
    // The first round only finds the timer's phase: a reply comes just after an expiry.
    for _ in 0..=rounds {
        let sent = Instant::now();
        port.write_all(&ping).unwrap();
        port.read_exact(&mut reply).expect("ping reply");
        waits.push(sent.elapsed());
        assert_eq!(reply, expected);
    }
    waits.remove(0);
    waits.sort();
    waits
}

/// With a 16 ms latency timer, a ping sent just after one reply came (just after the timer
/// expired) is answered at the next expiry, most of a period later. Only a lower bound is checked,
/// and on the median: this thread may be woken late for some rounds on a loaded machine, which
/// shortens their wait, but not for most.
#[test]
fn with_a_burst_period_the_replies_wait_for_the_latency_timer() {
    let _one = one_at_a_time();
    let server = sts_on_pty(&[1], Some(Duration::from_millis(16)), None);
    let waits = ping_waits(&server, 8);
    assert!(waits[waits.len() / 2] >= Duration::from_millis(6), "{waits:?}");
    server.stop().unwrap();
}

/// A firmware-like loop over the pty (read positions, write goals), with and without a latency
/// timer: a slow ramp of goals passes, a jump and a goal outside the range are violations.
#[test]
fn the_pty_servers_monitor_checks_every_goal_it_receives() {
    let _one = one_at_a_time();
    let items = STS3215.items;
    for burst in [None, Some(Duration::from_millis(16))] {
        // Servo 2 ramps down to the bottom of its range.
        let limit = |id, low| GoalLimit { id, goal_range: (low, 3000), max_ticks_per_s: 500.0 };
        let server = sts_on_pty(&[1, 2], burst, Some(vec![limit(1, 1000), limit(2, 2030)]));
        assert_eq!(server.monitor().expect("a monitor").checked, 0);
        let mut master = pty_master(server.path());
        for id in [1, 2] {
            master.write(id, items.torque_enable.address, &[1]).expect("torque on");
        }
        let group = ServoGroup::new(&STS3215, [1u8, 2]);
        let mut positions = [0i32; 2];
        // A tick: read the positions, then write the goals. The read also makes sure that the
        // server has seen the goals before it (the bytes arrive in order).
        let mut tick = |goals: [i32; 2]| {
            group.read_all(&mut master, items.present_position, &mut positions).expect("read positions");
            group.write_all(&mut master, items.goal_position, &goals).expect("write goals");
            group.read_all(&mut master, items.present_position, &mut positions).expect("read positions");
        };
        // 2 ticks per tick, never more than 6 (a 10 ms control period's 5 and a tick of rounding)
        // allow; each tick here reads twice with its goal write between, so it counts two.
        for k in 0..10 {
            tick([2048 + 2 * k, 2048 - 2 * k]);
        }
        let r = server.monitor().unwrap();
        assert_eq!(r.violation_count, 0, "{burst:?}: {:?}", r.violations);
        // Torque on (a fresh start each) and 10 goals each.
        assert_eq!(r.checked, 22, "{burst:?}");
        assert_eq!(
            r.servos.iter().map(|s| (s.id, s.checked, s.last_goal)).collect::<Vec<_>>(),
            [(1, 11, Some(2066)), (2, 11, Some(2030))]
        );
        assert!(r.max_step_ratio > 0.0 && r.max_step_ratio < 1.0, "{burst:?}: {}", r.max_step_ratio);

        // 500 ticks at once: 1 s of motion.
        tick([2566, 2030]);
        let r = server.monitor().unwrap();
        assert_eq!(r.violation_count, 1, "{burst:?}: {:?}", r.violations);
        assert_eq!(r.violations[0].id, 1);
        assert!(r.violations[0].what.starts_with("goal step 500 ticks"), "{}", r.violations[0].what);
        // Out of the range, in a small step.
        tick([2566, 2029]);
        let r = server.monitor().unwrap();
        assert_eq!(r.violation_count, 2, "{burst:?}: {:?}", r.violations);
        assert_eq!(r.violations[1].what, "goal 2029 outside 2030..=3000");
        assert_eq!((r.servos[0].violations, r.servos[1].violations), (1, 1));
        server.stop().unwrap();
    }
}

/// `limits_of` maps an arm as its firmware does: the goal bounds the SIL harness reads from the
/// firmware's own controller, for the built-in SO-101 and for an OpenManipulator-X sent by the host.
#[test]
fn limits_of_maps_an_arm_as_the_firmware_does() {
    use armctl::arm::servos::servos_of;
    use armctl::arm::ArmSpec;
    use armctl::link::arm_config::configure_messages;
    use armctl::link::client::{LinkClient, LinkConfig};
    use armctl::runtime::sil::{Sil, SilOptions};
    for name in ["so101", "open-manipulator-x"] {
        let arm = ArmSpec::load(name, None).unwrap();
        let mut client = LinkClient::new(Sil::new(&SilOptions::new(name).unwrap()).unwrap(), LinkConfig::default());
        if client.hello().unwrap().arm_name.is_empty() {
            for m in configure_messages(&arm, &servos_of(&arm).unwrap()).unwrap() {
                client.request(&m).unwrap();
            }
        }
        let board = client.transport().board();
        let bounds = board.bounds();
        let period_s = f64::from(board.period_us()) * 1e-6;
        let limits = armctl::sim::limits_of(&arm).unwrap();
        assert_eq!(limits.len(), bounds.len(), "{name}");
        for (l, b) in limits.iter().zip(&bounds) {
            assert_eq!((l.id, l.goal_range), (b.id, b.goal_range), "{name}");
            // The SIL's per-period step: the same speed limit, rounded up, plus a tick.
            assert_eq!((l.max_ticks_per_s * period_s).ceil() as i64 + 1, b.max_step, "{name}");
        }
    }
}

#[test]
fn armctl_sim_servos_serves_a_pty_and_refuses_bad_input() {
    let (mut child, path) =
        support::sim_servos(&["--protocol", "sts", "--ids", "1-3,7", "--pty"], std::process::Stdio::null());
    let private = std::panic::catch_unwind(|| armctl_test_support::assert_private(&path));
    let reply = std::panic::catch_unwind(|| exchange(&path, &[0xFF, 0xFF, 0x07, 0x02, 0x01, 0xF5], 6));
    child.kill().unwrap();
    child.wait().unwrap();
    private.expect("the printed pty is its owner's alone");
    assert_eq!(reply.expect("ping over the pty"), ping_reply(Protocol::Feetech, 7, &[]));

    for args in [
        &["--protocol", "dxl2", "--ids", "1-6"][..],
        &["--protocol", "dxl2", "--ids", "1-253", "--pty"],
        &["--protocol", "sts", "--ids", "1", "--model", "xl430-w250", "--pty"],
        &["--protocol", "dxl2", "--ids", "1", "--baud", "12345", "--pty"],
        &["--protocol", "dxl2", "--ids", "3-1", "--pty"],
        &["--protocol", "dxl2", "--ids", "1,x", "--pty"],
    ] {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let argv = ["armctl", "sim", "servos"].iter().chain(args);
        let code = armctl::cli::main(argv, &mut out, &mut err);
        let err = String::from_utf8(err).unwrap();
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "{args:?}: {err}");
        assert!(out.is_empty());
    }
}

/// `armctl sim servos --arm so101 --start ...`: the arm's servos and its gripper, horns where
/// `--start` put them; a hand's command on stdin is answered once the bus has read where the horn
/// got to, a limp horn only; bad commands are one `error:` line each.
#[test]
fn armctl_sim_servos_turns_horns_by_hand_on_request() {
    use std::io::{BufRead, Write};
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["sim", "servos", "--pty", "--arm", "so101", "--start", "2=3000,6=1000"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let path = lines.next().unwrap().unwrap();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let read = |id: &str| {
            let out = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
                .args(["servo", "read", "--port", &path, "--protocol", "sts", "--id", id, "--item", "present_position"])
                .output()
                .unwrap();
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
            String::from_utf8(out.stdout).unwrap().lines().last().unwrap().to_string()
        };
        assert_eq!(read("2"), "present_position = 3000");
        assert_eq!(read("6"), "present_position = 1000", "the gripper is served too");
        assert_eq!(read("1"), "present_position = 2048");
        writeln!(stdin, "sweep 2 3000 1200 0.2\nmove 9 5\nswerve 2 1\n").unwrap();
        stdin.flush().unwrap();
        let mut next = || lines.next().unwrap().unwrap();
        // A line that does not parse is answered at once, a move by the serving thread.
        let mut errors = [next(), next()];
        errors.sort();
        assert_eq!(
            errors,
            [
                "error: \"swerve 2 1\" is not `move ID TICKS` or `sweep ID FROM TO SECONDS`",
                "error: move 9 5: no servo 9 on this bus",
            ]
        );
        // The sweep ends only once its end has been read: keep reading until it says so. (Not
        // until a read shows 1200: the horn's ticks round to 1200 a fraction of a tick before the
        // sweep's end, and a read in that moment does not count.)
        let said_done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let reader = {
            let path = path.clone();
            let said_done = said_done.clone();
            std::thread::spawn(move || {
                for _ in 0..500 {
                    if said_done.load(std::sync::atomic::Ordering::SeqCst) {
                        break;
                    }
                    let out = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
                        .args([
                            "servo",
                            "read",
                            "--port",
                            &path,
                            "--protocol",
                            "sts",
                            "--id",
                            "2",
                            "--item",
                            "present_position",
                        ])
                        .output()
                        .unwrap();
                    assert!(out.status.success());
                }
            })
        };
        let done = next();
        said_done.store(true, std::sync::atomic::Ordering::SeqCst);
        assert_eq!(done, "done sweep 2 3000 1200 0.2");
        reader.join().unwrap();
        assert_eq!(read("2"), "present_position = 1200");
        let torque = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(["servo", "torque", "on", "--port", &path, "--protocol", "sts", "--id", "3"])
            .output()
            .unwrap();
        assert!(torque.status.success());
        writeln!(stdin, "move 3 100").unwrap();
        stdin.flush().unwrap();
        assert_eq!(next(), "error: move 3 100: servo 3 has torque on: a hand cannot turn it");
    }));
    child.kill().unwrap();
    child.wait().unwrap();
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}

#[test]
fn armctl_sim_servos_refuses_a_bad_burst_period_and_an_arm_it_does_not_serve() {
    let sts = ["sim", "servos", "--protocol", "sts", "--pty", "--ids"];
    for (args, needle) in [
        (&["1-5", "--burst-ms", "0"][..], "--burst-ms must be more than 0 and at most 100"),
        (&["1-5", "--burst-ms", "-16"], "--burst-ms"),
        (&["1-5", "--burst-ms", "100.5"], "--burst-ms"),
        (&["1-5", "--burst-ms", "NaN"], "--burst-ms"),
        (&["1-5", "--burst-ms", "soon"], "--burst-ms"),
        (&["1-3", "--arm", "so101"], "arm so101 has servo id(s) 4,5,6 that --ids does not serve"),
        (&["1-5", "--arm", "ur5e"], "arm ur5e has no [servos] table"),
        (&["1-5", "--arm", "no-such-arm"], "--arm no-such-arm"),
        (&["1-6", "--arm", "so101", "--period-ms", "0"], "--period-ms must be 1 to 1000 (milliseconds), not 0"),
        (&["1-6", "--arm", "so101", "--period-ms", "NaN"], "--period-ms"),
        (&["1-5", "--start", "6=100"], "--start names servo 6, which is not served"),
        (&["1-5", "--start", "1=4096"], "--start 1=4096: a horn stands at 0..=4095 ticks"),
        (&["1-5", "--start", "1:100"], "--start \"1:100\" is not ID=TICKS"),
    ] {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = armctl::cli::main(["armctl"].iter().chain(&sts).chain(args), &mut out, &mut err);
        let err = String::from_utf8(err).unwrap();
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(out.is_empty());
    }
}

/// `armctl sim servos --arm so101` prints each violation of so101's limits as it happens: the
/// first 100, then one line saying the rest are only counted.
#[test]
fn armctl_sim_servos_prints_the_violations_it_finds() {
    let _one = one_at_a_time();
    use std::io::BufRead;
    let args = ["--protocol", "sts", "--ids", "1-6", "--pty", "--arm", "so101", "--burst-ms", "1"];
    let (mut child, path) = support::sim_servos(&args, std::process::Stdio::piped());
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let run = std::panic::catch_unwind(|| {
        let arm = armctl::arm::ArmSpec::load("so101", None).unwrap();
        let limits = armctl::sim::limits_of(&arm).unwrap();
        let items = STS3215.items;
        let mut master = pty_master(&path);
        let group = ServoGroup::new(&STS3215, [1u8, 2, 3, 4, 5]);
        group.write_all(&mut master, items.torque_enable, &[1; 5]).unwrap();
        let mut positions = [0i32; 5];
        // Every goal a tick outside its joint's range: 5 violations a write, 150 in all (and the
        // first steps beyond the velocity limit).
        for k in 0..30 {
            let goals = core::array::from_fn(|j| {
                let (lo, hi) = limits[j].goal_range;
                (if lo > 1 { lo - 1 - k % 2 } else { hi + 1 + k % 2 }) as i32
            });
            group.write_all(&mut master, items.goal_position, &goals).unwrap();
            group.read_all(&mut master, items.present_position, &mut positions).unwrap();
        }
        let mut lines = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(20);
        while let Ok(line) = rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            let done = line.contains("further ones are only counted");
            lines.push(line);
            if done {
                break;
            }
        }
        lines
    });
    child.kill().unwrap();
    child.wait().unwrap();
    let lines = run.expect("goals over the pty");
    assert!(lines[0].starts_with("serving 6 STS3215 servo(s)"), "{lines:?}");
    assert!(lines[0].contains("bursts every 1 ms") && lines[0].contains("limits of so101"), "{}", lines[0]);
    let violations: Vec<&String> = lines.iter().filter(|l| l.starts_with("violation: servo ")).collect();
    assert_eq!(violations.len(), 100, "{lines:?}");
    assert!(violations.iter().any(|l| l.contains("outside")), "{violations:?}");
    assert_eq!(lines.last().unwrap(), "more than 100 violations: further ones are only counted");
    assert_eq!(lines.len(), 102, "{lines:?}");
}

#[test]
fn id_lists_parse() {
    assert_eq!(armctl::support::numbers::ids("1-3,7", u8::MAX, "--ids").unwrap(), [1, 2, 3, 7]);
    assert_eq!(armctl::support::numbers::ids("1,3,5", u8::MAX, "--ids").unwrap(), [1, 3, 5]);
    assert!(armctl::support::numbers::ids("", u8::MAX, "--ids").is_err());
}

/// `armctl sim servos --arm so101 --object-mm 30`: the PC-hosted core (`--bus`) closes the
/// gripper on the simulated object; the jaws stop at 30 mm with the load up and the firmware says
/// it holds something; a second command (a second core, the torque left on) opens it. Every goal
/// the gripper received kept to its speed, its first ramp step after the torque came on included.
/// A width that does not fit, or no arm to name the gripper, is one line.
#[test]
fn armctl_sim_servos_puts_an_object_between_the_jaws() {
    let _one = one_at_a_time();
    use std::io::Read;
    let args = ["--pty", "--arm", "so101", "--object-mm", "30"];
    let (mut child, path) = support::sim_servos(&args, std::process::Stdio::piped());
    let gripper = |action: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(["--bus", &path, "--protocol", "sts", "--arm", "so101", "--json", "gripper", action])
            .output()
            .unwrap()
    };
    let (closed, opened) = (gripper("close"), gripper("open"));
    child.kill().unwrap();
    child.wait().unwrap();
    let mut monitor = String::new();
    child.stderr.take().unwrap().read_to_string(&mut monitor).unwrap();
    for out in [&closed, &opened] {
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let json = |out: &std::process::Output| -> serde_json::Value {
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).lines().last().unwrap()).unwrap()
    };
    let g = json(&closed);
    assert_eq!(g["holding"], true, "{g}");
    assert!((g["opening_mm"].as_f64().unwrap() - 30.0).abs() < 0.2, "{g}");
    assert!(g["load"].as_f64().unwrap().abs() >= 10.0, "{g}");
    let g = json(&opened);
    assert!(g["holding"] == false && g["opening"].as_f64().unwrap() > 98.0, "{g}");
    assert!(!monitor.contains("violation"), "{monitor}");

    for (args, expected) in [
        (&["--arm", "so101", "--object-mm", "95"][..], "does not fit the gripper"),
        (&["--arm", "so101", "--object-mm", "NaN"], "does not fit the gripper"),
        (&["--arm", "so101", "--object-mm", "-3"], "does not fit the gripper"),
        (&["--arm", "so101", "--ids", "1-5", "--object-mm", "30"], "6 that --ids does not serve"),
        (&["--protocol", "sts", "--ids", "1", "--object-mm", "30"], "--arm"),
    ] {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let argv = ["armctl", "sim", "servos", "--pty"].iter().chain(args);
        let code = armctl::cli::main(argv, &mut out, &mut err);
        let err = String::from_utf8(err).unwrap();
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1 && err.contains(expected), "{args:?}: {err}");
        assert!(out.is_empty());
    }
}

/// `armctl servo read --item ITEM` of servo `id` on the pty at `path`: the item's line, or the
/// error it printed.
fn read_on(path: &str, protocol: &str, id: u8, item: &str) -> Result<String, String> {
    let id = id.to_string();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["servo", "read", "--port", path, "--protocol", protocol, "--baud", "1000000", "--timeout-ms", "200"])
        .args(["--id", &id, "--item", item])
        .output()
        .unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).trim().to_string();
    match out.status.success() {
        true => Ok(text(&out.stdout).lines().last().unwrap_or_default().to_string()),
        false => Err(text(&out.stderr)),
    }
}

/// Runs `check` on the pty of `armctl sim servos --pty ARGS`, then stops the server (also when
/// `check` panics).
fn with_sim_servos(args: &[&str], check: impl FnOnce(&str)) {
    let args: Vec<&str> = ["--pty"].iter().chain(args).copied().collect();
    let (mut child, path) = support::sim_servos(&args, std::process::Stdio::null());
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(&path)));
    child.kill().unwrap();
    child.wait().unwrap();
    if let Err(panic) = result {
        std::panic::resume_unwind(panic);
    }
}

/// `--register`: a 12 V supply and a hot servo, mixed firmware, a stale goal, a wrong status
/// return level, read back by a client; the readings stay on later reads, and the stale goal moves
/// nothing.
#[test]
fn armctl_sim_servos_sets_registers_a_client_reads() {
    let _one = one_at_a_time();
    let args = [
        "--protocol",
        "sts",
        "--ids",
        "1-3",
        "--register",
        "1:present_voltage=120",
        "--register",
        "2:present_temperature=75",
        "--register",
        "all:firmware_minor_version=9",
        "--register",
        "3:firmware_minor_version=10",
        "--register",
        "2:goal_position=100",
        "--register",
        "3:homing_offset=-2100",
    ];
    // -2100 does not fit the STS3215's sign-magnitude offset (bit 11): refused in one line.
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let argv = ["armctl", "sim", "servos", "--pty"].iter().chain(&args);
    assert_eq!(armctl::cli::main(argv, &mut out, &mut err), 2);
    let err = String::from_utf8(err).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("-2100 does not fit homing_offset (it holds -2047 to 2047)"), "{err}");

    let args: Vec<&str> =
        args[..args.len() - 2].iter().copied().chain(["--register", "3:homing_offset=-900"]).collect();
    with_sim_servos(&args, |path| {
        let read = |id, item| read_on(path, "sts", id, item).unwrap();
        for _ in 0..2 {
            assert_eq!(read(1, "present_voltage"), "present_voltage = 120");
            assert_eq!(read(2, "present_voltage"), "present_voltage = 74", "the others at 7.4 V");
            assert_eq!(read(2, "present_temperature"), "present_temperature = 75");
            assert_eq!(read(1, "firmware_minor_version"), "firmware_minor_version = 9");
            assert_eq!(read(3, "firmware_minor_version"), "firmware_minor_version = 10");
            assert_eq!(read(3, "homing_offset"), "homing_offset = -900");
            assert_eq!(read(2, "goal_position"), "goal_position = 100", "a stale goal");
            assert_eq!(read(2, "present_position"), "present_position = 2048", "torque off: nothing moved");
            std::thread::sleep(Duration::from_millis(100));
        }
    });
    // A status return level that makes writes go unanswered (Dynamixel 1: pings and reads only).
    with_sim_servos(&["--protocol", "dxl2", "--ids", "1", "--register", "1:status_return_level=1"], |path| {
        assert_eq!(read_on(path, "dxl2", 1, "status_return_level").unwrap(), "status_return_level = 1");
    });
    // The other protocol's name of the same item is taken too.
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--register", "1:status_return_level=0"], |path| {
        assert_eq!(read_on(path, "sts", 1, "response_status_level").unwrap(), "response_status_level = 0");
    });
}

/// `--register` refuses what it cannot set in one line each: an id not served, an unknown item, a
/// value that does not fit, `moving`, and text that is not ID:ITEM=VALUE; so do bad
/// `--hardware-error`s and bit-flip rates.
#[test]
fn armctl_sim_servos_refuses_bad_registers_and_errors() {
    for (extra, needle) in [
        (&["--register", "9:present_voltage=120"][..], "names servo 9, which is not served"),
        (&["--register", "1:present_voltag=120"], "STS3215 has no item \"present_voltag\""),
        (&["--register", "1:present_voltage=300"], "300 does not fit present_voltage (it holds 0 to 255)"),
        (&["--register", "1:present_voltage=1.5"], "\"1.5\" is not a whole number"),
        (&["--register", "1:moving=1"], "moving is the servo's own"),
        (&["--register", "present_voltage=120"], "is not ID:ITEM=VALUE"),
        (&["--register", "x:present_voltage=120"], "\"x\" is not a servo id or `all`"),
        (&["--hardware-error", "1"], "is not ID=BITS"),
        (&["--hardware-error", "1=0"], "the bits are a number from 1 to 255"),
        (&["--hardware-error", "1=0x100"], "the bits are a number from 1 to 255"),
        (&["--hardware-error", "4=1"], "names servo 4, which is not served"),
        (&["--bit-flip-rate", "1.5"], "--bit-flip-rate must be a probability"),
    ] {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let argv = ["armctl", "sim", "servos", "--pty", "--protocol", "sts", "--ids", "1-3"].iter().chain(extra);
        let code = armctl::cli::main(argv, &mut out, &mut err);
        let err = String::from_utf8(err).unwrap();
        assert_eq!(code, 2, "{extra:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {needle:?} not in {err}");
    }
}

/// `--hardware-error`: a Dynamixel's status carries the alert bit and its hardware error status
/// says which; torque cannot be switched on. On Feetech the status error byte carries the bits.
#[test]
fn armctl_sim_servos_raises_hardware_errors_a_client_sees() {
    let _one = one_at_a_time();
    with_sim_servos(&["--protocol", "dxl2", "--ids", "1-2", "--hardware-error", "1=0x04"], |path| {
        let mut master = pty_master_for(path, Protocol::Dxl2);
        let mut b = [0u8; 1];
        let answer = master.read(1, 70, &mut b).unwrap();
        assert_eq!((b[0], answer.alert.is_some()), (4, true), "overheating, and the alert bit");
        assert!(master.read(2, 70, &mut b).unwrap().alert.is_none(), "servo 2 is well");
        let _ = master.write(1, 64, &[1]);
        master.read(1, 64, &mut b).unwrap();
        assert_eq!(b[0], 0, "protection keeps torque off");
    });
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--hardware-error", "all=0x20"], |path| {
        let mut master = pty_master_for(path, Protocol::Feetech);
        let mut b = [0u8; 2];
        assert_eq!(master.read(1, 56, &mut b).unwrap().alert, Some(0x20), "overload in the status byte");
    });
}

/// `--bit-flip-rate`: on a noisy line some of a few hundred reads fail (corrupt or unanswered
/// instructions) and most get through; without it none fail.
#[test]
fn armctl_sim_servos_flips_bits_on_a_noisy_line() {
    let _one = one_at_a_time();
    let failures = |args: &[&str]| {
        let mut failed = 0;
        with_sim_servos(args, |path| {
            let mut master = pty_master_for(path, Protocol::Feetech);
            let mut b = [0u8; 2];
            for _ in 0..200 {
                failed += usize::from(master.read(1, 56, &mut b).is_err());
            }
        });
        failed
    };
    let noisy = failures(&["--protocol", "sts", "--ids", "1", "--bit-flip-rate", "0.01"]);
    assert!((5..150).contains(&noisy), "{noisy} of 200 reads failed at 1 % per byte");
    assert_eq!(failures(&["--protocol", "sts", "--ids", "1"]), 0);
}

/// `--echo`: the ping's own bytes come back first, then its reply.
#[test]
fn armctl_sim_servos_echoes_what_the_adapter_sends() {
    let _one = one_at_a_time();
    let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let reply = ping_reply(Protocol::Feetech, 1, &[]);
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--echo"], |path| {
        assert_eq!(exchange(path, &ping, ping.len() + reply.len()), [&ping[..], &reply].concat());
    });
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--echo", "--burst-ms", "16"], |path| {
        assert_eq!(exchange(path, &ping, ping.len() + reply.len()), [&ping[..], &reply].concat());
    });
}

/// What a doctor meets with flags that were there before: every servo still at id 1 (a ping
/// passes, a position read collides), the FTDI latency timer (replies wait most of 16 ms), and a
/// model other than the arm file's (`--model` over `--arm`'s).
#[test]
fn armctl_sim_servos_shows_duplicates_latency_and_another_model() {
    let _one = one_at_a_time();
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--duplicate", "1"], |path| {
        let mut master = pty_master_for(path, Protocol::Feetech);
        assert!(master.ping(1).is_ok(), "alike replies AND into a valid one");
        let mut b = [0u8; 2];
        let err = master.read(1, 56, &mut b).unwrap_err();
        assert!(matches!(err, MasterError::NoReply { id: 1, corrupt, .. } if corrupt > 0), "{err:?}");
    });
    with_sim_servos(&["--protocol", "sts", "--ids", "1", "--burst-ms", "16"], |path| {
        let waits = ping_waits_on(path, 8);
        assert!(waits[waits.len() / 2] >= Duration::from_millis(6), "{waits:?}");
    });
    with_sim_servos(&["--arm", "open-manipulator-x", "--model", "xl430-w250"], |path| {
        assert_eq!(read_on(path, "dxl2", 11, "model_number").unwrap(), "model_number = 1060", "not the XM430's 1020");
        let mut master = pty_master_for(path, Protocol::Dxl2);
        assert_eq!(master.ping(15).unwrap().model, Some(1060), "the gripper's servo too");
    });
}

/// The firmware's master on the pty at `path`, as [`pty_master`] for either protocol.
fn pty_master_for(path: &str, protocol: Protocol) -> Master<SerialTransport, NoDirectionPin, StdClock> {
    let mut config = BusConfig::new(protocol, BAUD);
    config.margin_us = 500_000;
    config.idle_gap_us = 50_000;
    config.retries = 0;
    Master::new(SerialTransport::open(path, BAUD).expect("open pty"), NoDirectionPin, StdClock::new(), config)
}

/// As [`ping_waits`], on the pty at `path`.
fn ping_waits_on(path: &str, rounds: usize) -> Vec<Duration> {
    let mut port = serialport::new(path, BAUD).timeout(Duration::from_secs(5)).open().expect("open pty");
    let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let mut reply = vec![0u8; ping_reply(Protocol::Feetech, 1, &[]).len()];
    let mut waits = Vec::new();
    for _ in 0..=rounds {
        let sent = Instant::now();
        port.write_all(&ping).unwrap();
        port.read_exact(&mut reply).expect("ping reply");
        waits.push(sent.elapsed());
    }
    waits.remove(0);
    waits.sort();
    waits
}

/// A packet that reaches the servos in two pieces 5 ms apart: on a line, the servos' 1.5 ms
/// inter-byte timeout drops it; served on a pty to a program on this PC (no gap timeout: the gap
/// is the serving thread's scheduling, [`armctl::sim::PtyServer`]) it is carried out, and only a
/// quiet line ([`SimBus::line_idle`]) drops a piece left alone.
#[test]
fn a_packet_in_two_pieces_is_dropped_on_a_gap_only_with_a_gap_timeout() {
    let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
    let ms = 1_000_000;
    let answers = |timeout: Option<u64>, idle: bool| {
        let mut bus = SimBus::new(Protocol::Feetech, &STS3215, &[1], BAUD);
        if let Some(ns) = timeout {
            bus.set_inter_byte_timeout(ns);
        }
        assert!(bus.receive(&ping[..3], 10 * ms).is_empty());
        if idle {
            assert!(bus.line_idle().is_empty());
        }
        !bus.receive(&ping[3..], 15 * ms).is_empty()
    };
    assert!(!answers(None, false), "the servos' own 1.5 ms timeout drops it");
    assert!(answers(Some(u64::MAX), false), "no gap timeout: carried out");
    assert!(!answers(Some(u64::MAX), true), "a quiet line still drops the first piece");
}
