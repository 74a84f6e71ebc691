//! What is written to the servos when the PC connects to an arm, the way LeRobot's `configure()`
//! does it, except that torque is never switched off.
//!
//! The settings ([`settings`]):
//! - Feetech STS3215, from LeRobot `motors/feetech/feetech.py` `configure_motors` and
//!   `robots/so_follower/so_follower.py` `configure`: return delay 0 (the factory 250 is 500 µs
//!   per reply, 3 ms per cycle on six servos), operating mode 0 (position, which the firmware's
//!   goals need; `configure` writes it to every servo, the gripper too), P 16, I 0, D 32 (these
//!   five EEPROM), acceleration 254 (RAM) and maximum acceleration 254. The last is at address 85,
//!   among the factory items past the RAM
//!   that Feetech's published table leaves out; it is handled as RAM (written whatever the torque,
//!   without unlocking) and LeRobot writes it on every connection anyway, as this does where it
//!   differs, so whether it survives a power cycle does not matter.
//! - Dynamixel X: return delay 0 only, as `motors/dynamixel/dynamixel.py` `configure_motors`. The
//!   rest of LeRobot's Koch and OMX `configure` is per joint (extended position mode except for the
//!   gripper, current-based position for the gripper, P 1500 I 0 D 600 on `elbow_flex` alone), so
//!   it belongs to an arm's description, not to a set-up of any arm. LeRobot writes no profile
//!   acceleration there, so the factory 0 (unlimited) stays.
//!
//! Each value is read first and written only where it differs. EEPROM items (below
//! [`Model::eeprom_end`]) are written only on a servo whose torque is off: on Dynamixel the servo
//! refuses them otherwise, and LeRobot writes Feetech's only inside `torque_disabled()` too. Where
//! torque is on they are left, with a note saying how to get them written: switching torque off
//! here would drop the arm. On Feetech the EEPROM is unlocked (`lock` 0) around the writes and
//! locked again (`lock` 1) after, so that they survive a power cycle (`feetech.py`
//! `disable_torque` and `enable_torque` pair torque with the lock the same way). RAM items are
//! written whatever the torque.
//!
//! A servo whose torque is off gets its goal set to its present position, so that whatever switches
//! torque on later holds the arm where it is instead of driving it to a stale goal (LeRobot PR
//! #3913). A servo whose torque is on holds its goal, which is left alone.
//!
//! The gripper's servo gets more ([`gripper_settings`]), so that a stalled grip does not burn it:
//! - Feetech STS3215, LeRobot's SO `configure` for its gripper: Max_Torque_Limit 500,
//!   Protection_Current 250, Overload_Torque 25 (all EEPROM).
//! - Dynamixel X, LeRobot's Koch and OMX `configure` for their grippers: operating mode 5,
//!   current-based position, whose goal current the firmware sets from the gripper's effort.

use firmware::bus::master::{Clock, MasterError};
use firmware::bus::table::{sts3215, xseries, Item, Model, ValueError};
use firmware::bus::{Id, Protocol};

use crate::link::serial::{Bus, Port};

/// One value written when connecting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setting {
    /// The item.
    pub item: Item,
    /// Its value.
    pub value: i64,
}

const fn setting(item: Item, value: i64) -> Setting {
    Setting { item, value }
}

/// LeRobot's STS3215 values: `configure_motors(return_delay_time=0, maximum_acceleration=254,
/// acceleration=254)` and `configure`'s `Operating_Mode` `OperatingMode.POSITION` (0),
/// `P_Coefficient` 16, `I_Coefficient` 0, `D_Coefficient` 32. The EEPROM items first, so that one
/// unlock covers them.
const FEETECH: [Setting; 7] = [
    setting(sts3215::RETURN_DELAY_TIME, 0),
    setting(sts3215::OPERATING_MODE, 0),
    setting(sts3215::P_COEFFICIENT, 16),
    setting(sts3215::I_COEFFICIENT, 0),
    setting(sts3215::D_COEFFICIENT, 32),
    setting(sts3215::MAXIMUM_ACCELERATION, 254),
    setting(sts3215::ACCELERATION, 254),
];

/// LeRobot's Dynamixel value: `configure_motors(return_delay_time=0)`.
const DYNAMIXEL: [Setting; 1] = [setting(xseries::RETURN_DELAY_TIME, 0)];

/// LeRobot's SO follower gripper protection (`so_follower.py` `configure`).
const FEETECH_GRIPPER: [Setting; 3] = [
    setting(sts3215::MAX_TORQUE_LIMIT, 500),
    setting(sts3215::PROTECTION_CURRENT, 250),
    setting(sts3215::OVERLOAD_TORQUE, 25),
];

/// LeRobot's Koch/OMX gripper mode (`OperatingMode.CURRENT_POSITION`).
const DYNAMIXEL_GRIPPER: [Setting; 1] = [setting(xseries::OPERATING_MODE, 5)];

/// The values written to a gripper's servo of `model` besides [`settings`].
pub fn gripper_settings(model: &Model) -> &'static [Setting] {
    match model.protocol {
        Protocol::Feetech => &FEETECH_GRIPPER,
        Protocol::Dxl2 => &DYNAMIXEL_GRIPPER,
    }
}

/// The values written to a servo of `model` when connecting.
pub fn settings(model: &Model) -> &'static [Setting] {
    // The tables have one model family per protocol (STS3215 on Feetech, X-series on Dynamixel).
    match model.protocol {
        Protocol::Feetech => &FEETECH,
        Protocol::Dxl2 => &DYNAMIXEL,
    }
}

/// A value changed, or one that would have been.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Change {
    /// The servo.
    pub id: Id,
    /// The item.
    pub item: Item,
    /// Its value before.
    pub from: i64,
    /// The value wanted.
    pub to: i64,
    /// Whether the item is EEPROM.
    pub eeprom: bool,
}

/// One servo as the set-up left it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoState {
    /// The servo.
    pub id: Id,
    /// Whether its torque was on (as read; the set-up does not change it).
    pub torque: bool,
    /// Its return delay afterwards, in microseconds.
    pub return_delay_us: u32,
}

/// What a set-up did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SetupReport {
    /// Each servo, in the order asked.
    pub servos: Vec<ServoState>,
    /// The values written, goals included, in the order written.
    pub written: Vec<Change>,
    /// EEPROM values not written because the servo's torque is on.
    pub left: Vec<Change>,
    /// Values (goals included) that already were what they should be.
    pub skipped: usize,
    /// One line per value written: `servo 3: return delay 500 µs -> 0 µs (EEPROM)`.
    pub lines: Vec<String>,
    /// One line per servo with something left, saying what and how to get it written.
    pub notes: Vec<String>,
}

impl SetupReport {
    /// The longest return delay of the servos afterwards, in microseconds: the figure for the bus
    /// master's timeouts ([`firmware::bus::master::BusConfig::return_delay_us`]).
    pub fn return_delay_us(&self) -> u32 {
        self.servos.iter().map(|s| s.return_delay_us).max().unwrap_or(0)
    }

    /// How many EEPROM values were written.
    pub fn eeprom_written(&self) -> usize {
        self.written.iter().filter(|c| c.eeprom).count()
    }
}

/// Why a set-up stopped. `E` is the port's error type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SetupError<E> {
    /// A servo did not answer at all.
    Silent {
        /// The servo.
        id: Id,
        /// What it did not answer.
        instruction: &'static str,
        /// Attempts made.
        attempts: u8,
    },
    /// Any other failed transaction (a refusal, corrupt replies, the port).
    Bus(MasterError<E>),
    /// A value that does not fit its item, or reply bytes that are not one.
    Value {
        /// The servo.
        id: Id,
        /// What is wrong.
        error: ValueError,
    },
}

impl<E> From<MasterError<E>> for SetupError<E> {
    fn from(e: MasterError<E>) -> Self {
        match e {
            MasterError::NoReply { id, instruction, attempts, corrupt: 0, .. } => {
                Self::Silent { id, instruction, attempts }
            }
            e => Self::Bus(e),
        }
    }
}

impl<E: std::fmt::Debug> std::fmt::Display for SetupError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Silent { id, instruction, attempts } => write!(
                f,
                "servo {id} does not answer (no reply to {instruction} in {attempts} attempts): check its power, \
                 its cable and that its id is {id}"
            ),
            Self::Bus(e) => write!(f, "{e}"),
            Self::Value { id, error } => write!(f, "servo {id}: {error}"),
        }
    }
}

impl<E: std::fmt::Debug> std::error::Error for SetupError<E> {}

/// The result of a set-up on port `P`.
pub type SetupResult<T, P> = Result<T, SetupError<<P as Port>::Fault>>;

/// Sets up the servos `ids` of `model` on `bus`, and the gripper's servo `gripper` with its own
/// settings too (see the module doc for what is written, and when). The bus configuration is not
/// changed: give the master [`SetupReport::return_delay_us`] after.
pub fn set_up<P: Port, C: Clock>(
    bus: &mut Bus<P, C>,
    model: &'static Model,
    ids: &[Id],
    gripper: Option<Id>,
) -> SetupResult<SetupReport, P> {
    let mut report = SetupReport::default();
    for &id in ids {
        set_up_one(bus, model, id, settings(model).iter().collect(), &mut report)?;
    }
    if let Some(id) = gripper {
        let all = settings(model).iter().chain(gripper_settings(model)).collect();
        set_up_one(bus, model, id, all, &mut report)?;
    }
    Ok(report)
}

fn set_up_one<P: Port, C: Clock>(
    bus: &mut Bus<P, C>,
    model: &'static Model,
    id: Id,
    settings: Vec<&Setting>,
    report: &mut SetupReport,
) -> SetupResult<(), P> {
    let items = model.items;
    let torque = read(bus, model, id, items.torque_enable)? != 0;
    let mut return_delay = read(bus, model, id, items.return_delay)?;
    let mut todo = Vec::new();
    let mut left = Vec::new();
    for s in settings {
        let from = read(bus, model, id, s.item)?;
        let change = Change { id, item: s.item, from, to: s.value, eeprom: s.item.address < model.eeprom_end };
        if from == s.value {
            report.skipped += 1;
        } else if change.eeprom && torque {
            left.push(change);
        } else {
            todo.push(change);
        }
    }
    let (eeprom, ram): (Vec<Change>, Vec<Change>) = todo.into_iter().partition(|c| c.eeprom);
    if !eeprom.is_empty() {
        unlocked(bus, model, id, |bus| eeprom.iter().try_for_each(|c| write(bus, model, c)))?;
    }
    ram.iter().try_for_each(|c| write(bus, model, c))?;
    for c in eeprom.iter().chain(&ram) {
        if c.item == items.return_delay {
            return_delay = c.to;
        }
        report.lines.push(line(model, c));
    }
    report.written.extend(eeprom.iter().chain(&ram));
    if !left.is_empty() {
        report.notes.push(note(model, id, &left));
        report.left.extend(left);
    }
    if !torque {
        hold_present(bus, model, id, report)?;
    }
    let unit = i64::from(model.return_delay_unit_us);
    let return_delay_us = u32::try_from(return_delay.saturating_mul(unit)).unwrap_or(u32::MAX);
    report.servos.push(ServoState { id, torque, return_delay_us });
    Ok(())
}

/// Sets a torque-off servo's goal to its present position, where they differ. A Dynamixel servo
/// refuses a goal outside its position limits (data limit error): then the goal is left, with a
/// note, rather than failing the whole set-up.
fn hold_present<P: Port, C: Clock>(
    bus: &mut Bus<P, C>,
    model: &'static Model,
    id: Id,
    report: &mut SetupReport,
) -> SetupResult<(), P> {
    let items = model.items;
    let present = read(bus, model, id, items.present_position)?;
    let goal = read(bus, model, id, items.goal_position)?;
    if goal == present {
        report.skipped += 1;
        return Ok(());
    }
    let change = Change { id, item: items.goal_position, from: goal, to: present, eeprom: false };
    match write(bus, model, &change) {
        Ok(()) => {
            report.lines.push(format!("servo {id}: goal position {goal} -> {present} (its present position)"));
            report.written.push(change);
            Ok(())
        }
        Err(SetupError::Bus(MasterError::Refused { text, .. })) => {
            report.notes.push(format!(
                "servo {id}: its goal stays {goal}: the servo refused its present position {present} as a goal \
                 ({text}); check its position limits before switching torque on"
            ));
            Ok(())
        }
        Err(e) => Err(e),
    }
}

/// Runs `writes` with a Feetech servo's EEPROM unlocked (`lock` 0), then locks it again (`lock` 1),
/// also when a write failed (best effort: the write's error is the one returned). Dynamixel has
/// no lock: torque off is what opens its EEPROM.
pub fn unlocked<P: Port, C: Clock>(
    bus: &mut Bus<P, C>,
    model: &'static Model,
    id: Id,
    writes: impl FnOnce(&mut Bus<P, C>) -> SetupResult<(), P>,
) -> SetupResult<(), P> {
    let Some(lock) = model.items.lock else { return writes(bus) };
    write_value(bus, model, id, lock, 0)?;
    let result = writes(bus);
    let relocked = write_value(bus, model, id, lock, 1);
    result.and(relocked)
}

fn read<P: Port, C: Clock>(bus: &mut Bus<P, C>, model: &Model, id: Id, item: Item) -> SetupResult<i64, P> {
    let mut bytes = [0u8; 4];
    let bytes = bytes.get_mut(..item.len()).unwrap_or_default();
    bus.read(id, item.address, bytes)?;
    item.decode(bytes, model.endian).map_err(|error| SetupError::Value { id, error })
}

fn write<P: Port, C: Clock>(bus: &mut Bus<P, C>, model: &Model, change: &Change) -> SetupResult<(), P> {
    write_value(bus, model, change.id, change.item, change.to)
}

/// Writes one item's value (encoded in the model's byte order) and waits for the status.
pub fn write_value<P: Port, C: Clock>(
    bus: &mut Bus<P, C>,
    model: &Model,
    id: Id,
    item: Item,
    value: i64,
) -> SetupResult<(), P> {
    let mut bytes = [0u8; 4];
    item.encode(value, model.endian, &mut bytes).map_err(|error| SetupError::Value { id, error })?;
    bus.write(id, item.address, bytes.get(..item.len()).unwrap_or_default())?;
    Ok(())
}

/// An item's value as a person reads it: the return delay in microseconds, the rest as stored.
fn shown(model: &Model, item: Item, value: i64) -> String {
    if item == model.items.return_delay {
        format!("{} µs", value.saturating_mul(i64::from(model.return_delay_unit_us)))
    } else {
        value.to_string()
    }
}

/// `return delay` for `return_delay_time`, `p coefficient` for `p_coefficient`.
fn label(model: &Model, item: Item) -> String {
    if item == model.items.return_delay {
        "return delay".to_string()
    } else {
        item.name.replace('_', " ")
    }
}

/// `servo 3: return delay 500 µs -> 0 µs (EEPROM)`.
fn line(model: &Model, c: &Change) -> String {
    let memory = if c.eeprom { " (EEPROM)" } else { "" };
    let (from, to) = (shown(model, c.item, c.from), shown(model, c.item, c.to));
    format!("servo {}: {} {from} -> {to}{memory}", c.id, label(model, c.item))
}

/// One line on what a torque-on servo kept, and how to get it written.
fn note(model: &Model, id: Id, left: &[Change]) -> String {
    let kept: Vec<String> = left
        .iter()
        .map(|c| {
            format!("{} {} (wanted {})", label(model, c.item), shown(model, c.item, c.from), shown(model, c.item, c.to))
        })
        .collect();
    format!(
        "servo {id}: torque is on, so its EEPROM was left as it is: {}; switch its torque off (the joint goes limp) \
         and connect again to have it written",
        kept.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;
    use std::rc::Rc;

    use embedded_io::{ErrorType, Read, ReadReady, Write};
    use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
    use firmware::bus::stream::StreamDecoder;
    use firmware::bus::table::{STS3215, XL430_W250};
    use firmware::bus::Instruction;

    use super::*;
    use crate::sim::{connect, Faults, SharedBus, SimBus, SimPort, VirtualClock};

    const BAUD: u32 = 1_000_000;
    const IDS: [Id; 3] = [1, 2, 3];

    /// The simulator's port, keeping a copy of every byte the master sends.
    struct Recorder {
        port: SimPort,
        sent: Rc<RefCell<Vec<u8>>>,
    }

    impl ErrorType for Recorder {
        type Error = <SimPort as ErrorType>::Error;
    }

    impl Read for Recorder {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
            self.port.read(buf)
        }
    }

    impl ReadReady for Recorder {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            self.port.read_ready()
        }
    }

    impl Write for Recorder {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            self.sent.borrow_mut().extend_from_slice(buf);
            self.port.write(buf)
        }

        fn flush(&mut self) -> Result<(), Self::Error> {
            self.port.flush()
        }
    }

    struct Rig {
        sim: SharedBus,
        bus: Bus<Recorder, VirtualClock>,
        clock: VirtualClock,
        sent: Rc<RefCell<Vec<u8>>>,
        model: &'static Model,
    }

    /// Servos 1 to 3 of `model` as they leave the factory (return delay 250, 500 µs, on both
    /// protocols: the simulator starts from the models' factory tables).
    fn rig(model: &'static Model, faults: Faults) -> Rig {
        let (sim, port, clock) = connect(SimBus::new(model.protocol, model, &IDS, BAUD).with_faults(faults));
        for servo in sim.borrow().servos() {
            assert_eq!(servo.get(model.items.return_delay), 250, "{}: the factory's return delay", model.name);
        }
        let sent = Rc::new(RefCell::new(Vec::new()));
        let port = Recorder { port, sent: sent.clone() };
        let bus = Master::new(port, NoDirectionPin, clock.clone(), BusConfig::new(model.protocol, BAUD));
        Rig { sim, bus, clock, sent, model }
    }

    impl Rig {
        /// An item's value in servo `id`'s simulated table, now.
        fn table(&self, id: Id, item: Item) -> i64 {
            let mut sim = self.sim.borrow_mut();
            sim.advance_to(self.clock.now_ns());
            sim.servo(id).expect("servo").get(item)
        }

        fn set(&self, id: Id, item: Item, value: i64) {
            self.sim.borrow_mut().servo_mut(id).expect("servo").set(item, value);
        }

        fn goal_writes(&self, id: Id) -> u64 {
            self.sim.borrow().servo(id).expect("servo").goal_writes()
        }

        /// Writes through the bus, with the servo's own rules (torque on holds the present position).
        fn write(&mut self, id: Id, item: Item, value: i64) {
            write_value(&mut self.bus, self.model, id, item, value).unwrap_or_else(|e| panic!("{e}"));
        }

        /// The writes the master sent since the last call: (id, address, value bytes).
        fn writes_sent(&self) -> Vec<(Id, u16, Vec<u8>)> {
            let bytes = std::mem::take(&mut *self.sent.borrow_mut());
            let mut decoder = StreamDecoder::<1024>::new(self.model.protocol);
            let mut writes = Vec::new();
            let mut rest = bytes.as_slice();
            while !rest.is_empty() {
                rest = &rest[decoder.extend(rest)..];
                while let Some(frame) = decoder.next_frame() {
                    let mut frame = frame.to_vec();
                    let packet = self.model.protocol.parse_instruction(&mut frame).expect("an instruction");
                    if let Instruction::Write { address, data } = packet.instruction {
                        writes.push((packet.id, address, data.to_vec()));
                    }
                }
            }
            writes
        }
    }

    fn names(changes: &[Change]) -> Vec<(Id, &'static str)> {
        changes.iter().map(|c| (c.id, c.item.name)).collect()
    }

    #[test]
    fn factory_stss_get_lerobots_values_once() {
        let mut r = rig(&STS3215, Faults::default());
        // One servo left in wheel mode (a position servo from the factory otherwise).
        r.set(3, sts3215::OPERATING_MODE, 1);
        let report = set_up(&mut r.bus, &STS3215, &IDS, None).unwrap();
        for id in IDS {
            assert_eq!(r.table(id, sts3215::RETURN_DELAY_TIME), 0);
            assert_eq!(r.table(id, sts3215::OPERATING_MODE), 0);
            assert_eq!(r.table(id, sts3215::P_COEFFICIENT), 16);
            assert_eq!(r.table(id, sts3215::I_COEFFICIENT), 0);
            assert_eq!(r.table(id, sts3215::D_COEFFICIENT), 32);
            assert_eq!(r.table(id, sts3215::MAXIMUM_ACCELERATION), 254);
            assert_eq!(r.table(id, sts3215::ACCELERATION), 254);
            assert_eq!(r.table(id, sts3215::LOCK), 1, "servo {id}: EEPROM locked again");
        }
        // Per servo: return delay and P (EEPROM, from 250 and 32), both accelerations (from 0);
        // I and D are already the factory's 0 and 32, the goal is the present position, and the
        // mode is 0 except on servo 3.
        assert_eq!(report.written.len(), 13);
        assert_eq!(report.eeprom_written(), 7);
        assert_eq!(report.skipped, 11);
        assert!(report.lines.contains(&"servo 3: operating mode 1 -> 0 (EEPROM)".to_string()), "{:?}", report.lines);
        assert!(report.left.is_empty() && report.notes.is_empty(), "{:?}", report.notes);
        assert_eq!(
            &report.lines[..4],
            [
                "servo 1: return delay 500 µs -> 0 µs (EEPROM)",
                "servo 1: p coefficient 32 -> 16 (EEPROM)",
                "servo 1: maximum acceleration 0 -> 254",
                "servo 1: acceleration 0 -> 254",
            ]
        );
        assert_eq!(report.return_delay_us(), 0);
        assert!(report.servos.iter().all(|s| !s.torque && s.return_delay_us == 0), "{:?}", report.servos);

        // The EEPROM writes of each servo sit between unlocking and locking it.
        let writes = r.writes_sent();
        let servo1: Vec<(u16, Vec<u8>)> =
            writes.iter().filter(|(id, ..)| *id == 1).map(|(_, a, d)| (*a, d.clone())).collect();
        let lock = sts3215::LOCK.address;
        assert_eq!(
            servo1,
            [
                (lock, vec![0]),
                (sts3215::RETURN_DELAY_TIME.address, vec![0]),
                (sts3215::P_COEFFICIENT.address, vec![16]),
                (lock, vec![1]),
                (sts3215::MAXIMUM_ACCELERATION.address, vec![254]),
                (sts3215::ACCELERATION.address, vec![254]),
            ]
        );

        let again = set_up(&mut r.bus, &STS3215, &IDS, None).unwrap();
        assert!(again.written.is_empty() && again.lines.is_empty(), "{:?}", again.lines);
        assert_eq!(again.skipped, 24);
        assert!(r.writes_sent().is_empty(), "nothing to write, not even the lock");
    }

    #[test]
    fn factory_dynamixels_get_return_delay_0_once() {
        let mut r = rig(&XL430_W250, Faults::default());
        let report = set_up(&mut r.bus, &XL430_W250, &IDS, None).unwrap();
        assert_eq!(
            names(&report.written),
            [(1, "return_delay_time"), (2, "return_delay_time"), (3, "return_delay_time")]
        );
        assert_eq!(report.eeprom_written(), 3);
        assert_eq!(report.skipped, 3, "the goals are the present positions");
        assert_eq!(report.lines[2], "servo 3: return delay 500 µs -> 0 µs (EEPROM)");
        for id in IDS {
            assert_eq!(r.table(id, xseries::RETURN_DELAY_TIME), 0);
            assert_eq!(r.table(id, xseries::PROFILE_ACCELERATION), 0, "LeRobot writes none");
        }
        assert_eq!(report.return_delay_us(), 0);
        r.writes_sent();

        let again = set_up(&mut r.bus, &XL430_W250, &IDS, None).unwrap();
        assert!(again.written.is_empty() && again.notes.is_empty());
        assert_eq!(again.skipped, 6);
        assert!(r.writes_sent().is_empty());
    }

    /// Servo 2 with torque on, on its way to a goal it was sent; servos 1 and 3 with torque off.
    fn torqued_servo_keeps_its_eeprom_and_goal(model: &'static Model) -> (Rig, SetupReport) {
        let mut r = rig(model, Faults::default());
        let items = model.items;
        r.write(2, items.torque_enable, 1);
        r.write(2, items.goal_position, 2600);
        r.clock.advance_ns(20_000_000);
        assert_ne!(r.table(2, items.present_position), 2600, "still moving: goal and present differ");
        let goal_writes = r.goal_writes(2);
        let report = set_up(&mut r.bus, model, &IDS, None).unwrap();
        assert_eq!(r.table(2, items.return_delay), 250, "EEPROM kept");
        assert_eq!(r.table(2, items.torque_enable), 1, "torque not switched off");
        assert_eq!((r.table(2, items.goal_position), r.goal_writes(2)), (2600, goal_writes), "goal not written");
        assert_eq!(r.table(1, items.return_delay), 0);
        assert_eq!(r.table(3, items.return_delay), 0);
        assert_eq!(report.notes.len(), 1, "{:?}", report.notes);
        assert!(report.notes[0]
            .starts_with("servo 2: torque is on, so its EEPROM was left as it is: return delay 500 µs (wanted 0 µs)"));
        assert!(report.notes[0].contains("switch its torque off"), "{}", report.notes[0]);
        assert!(report.written.iter().all(|c| c.id != 2 || !c.eeprom));
        let torque: Vec<(Id, bool)> = report.servos.iter().map(|s| (s.id, s.torque)).collect();
        assert_eq!(torque, [(1, false), (2, true), (3, false)]);
        assert_eq!(report.return_delay_us(), 500, "servo 2 still answers after 500 µs");
        (r, report)
    }

    #[test]
    fn a_torqued_sts_keeps_its_eeprom_and_goal_and_gets_its_ram() {
        let (r, report) = torqued_servo_keeps_its_eeprom_and_goal(&STS3215);
        assert_eq!(names(&report.left), [(2, "return_delay_time"), (2, "p_coefficient")]);
        assert!(report.notes[0].ends_with("return delay 500 µs (wanted 0 µs), p coefficient 32 (wanted 16); switch its torque off (the joint goes limp) and connect again to have it written"), "{}", report.notes[0]);
        assert_eq!(r.table(2, sts3215::P_COEFFICIENT), 32);
        assert_eq!(r.table(2, sts3215::ACCELERATION), 254, "RAM is written with torque on");
        assert_eq!(r.table(2, sts3215::MAXIMUM_ACCELERATION), 254);
        assert!(!r.writes_sent().iter().any(|(id, address, _)| *id == 2 && *address == sts3215::LOCK.address));
    }

    #[test]
    fn a_torqued_dynamixel_keeps_its_eeprom_and_goal() {
        let (_, report) = torqued_servo_keeps_its_eeprom_and_goal(&XL430_W250);
        assert_eq!(names(&report.left), [(2, "return_delay_time")]);
    }

    fn a_torque_off_servo_gets_its_goal_at_its_present_position(model: &'static Model) {
        let mut r = rig(model, Faults::default());
        let items = model.items;
        r.set(3, items.goal_position, 1000);
        let report = set_up(&mut r.bus, model, &IDS, None).unwrap();
        assert_eq!(r.table(3, items.goal_position), 2048);
        assert_eq!(r.table(3, items.present_position), 2048, "torque off: nothing moved");
        assert_eq!(
            report.lines.last().map(String::as_str),
            Some("servo 3: goal position 1000 -> 2048 (its present position)")
        );
        assert_eq!(report.written.iter().filter(|c| c.item == items.goal_position).count(), 1, "only servo 3's goal");
    }

    #[test]
    fn a_torque_off_sts_gets_its_goal_at_its_present_position() {
        a_torque_off_servo_gets_its_goal_at_its_present_position(&STS3215);
    }

    #[test]
    fn a_torque_off_dynamixel_gets_its_goal_at_its_present_position() {
        a_torque_off_servo_gets_its_goal_at_its_present_position(&XL430_W250);
    }

    #[test]
    fn a_dynamixel_that_refuses_its_present_position_as_goal_gets_a_note() {
        let mut r = rig(&XL430_W250, Faults::default());
        // Turned by hand past a limit set after: the present position is no valid goal.
        r.set(1, xseries::MAX_POSITION_LIMIT, 1500);
        r.set(1, xseries::GOAL_POSITION, 1000);
        let report = set_up(&mut r.bus, &XL430_W250, &IDS, None).unwrap();
        assert_eq!(r.table(1, xseries::GOAL_POSITION), 1000);
        assert_eq!(report.notes.len(), 1);
        assert!(
            report.notes[0].starts_with("servo 1: its goal stays 1000: the servo refused its present position 2048"),
            "{}",
            report.notes[0]
        );
        assert_eq!(r.table(2, xseries::RETURN_DELAY_TIME), 0, "the others are still set up");
    }

    fn a_silent_servo_is_named(model: &'static Model) {
        let mut r = rig(model, Faults { silent: vec![2], ..Faults::default() });
        let e = set_up(&mut r.bus, model, &IDS, None).unwrap_err();
        assert!(matches!(e, SetupError::Silent { id: 2, .. }), "{e:?}");
        let text = e.to_string();
        assert!(
            !text.contains('\n') && text.starts_with("servo 2 does not answer (no reply to read in 3 attempts)"),
            "{text}"
        );
    }

    #[test]
    fn a_silent_sts_is_named() {
        a_silent_servo_is_named(&STS3215);
    }

    #[test]
    fn a_silent_dynamixel_is_named() {
        a_silent_servo_is_named(&XL430_W250);
    }
}
