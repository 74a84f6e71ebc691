//! One simulated servo: its control table and what it does with each instruction.
//!
//! The table has the real addresses of [`Model`]: it starts from the model's factory values,
//! every value is encoded through [`Item::encode`] in the model's byte order (sign-magnitude on
//! Feetech), and the master reads back exactly the bytes a real servo would send.
//!
//! Rules, as on the real servos:
//! - Dynamixel refuses with an error number: 4 (data range) for an address outside the table,
//!   5 (data length) for a range that runs past it or carries no data, 7 (access) for writes to
//!   read-only items and for EEPROM writes (address below `eeprom_end`) while torque is on.
//! - Feetech has no error numbers: bytes outside the table or on read-only items are ignored.
//!   EEPROM writes take effect whatever the `lock` item says; `lock` only decides whether they
//!   survive a power cycle, which the simulator does not model.
//! - Turning torque on sets the goal to the present position, so the horn does not jump; with
//!   torque off the servo moves nothing (a hand may). A hardware error turns torque off and keeps it off until a reboot
//!   (Dynamixel) or [`SimServo::clear_hardware_error`].
//! - Goals are clamped to the position limits; the horn then follows the servo's own trapezoidal
//!   profile ([`super::motion`]) and the present position is quantised to whole ticks. With
//!   physics on the bus ([`super::physics`]), the profile is the reference of the servo's drive
//!   ([`super::drive`]), and the horn is where the drive has it: behind the profile by what its
//!   load asks, with its speed, load or current and temperature reported, and its overload and
//!   overheat protections.
//! - The homing offset shifts what the servo reports, not where the horn is. The horn's own
//!   position (the encoder's, "actual") is what the profile moves; the present position, the goal
//!   and the position limits are in the offset-corrected frame:
//!   - Feetech STS3215 (`Homing_Offset`, address 31, sign-magnitude with the sign in bit 11):
//!     `present = actual - offset`, taken modulo one turn (LeRobot's `_get_half_turn_homings`
//!     "Present_Position = Actual_Position - Homing_Offset"; the encoder is single-turn, so the
//!     corrected value wraps at 0/4095 as the raw one does);
//!   - Dynamixel X (`Homing_Offset`, address 20, 4 bytes two's complement): `present = actual +
//!     offset` (e-manual, Homing Offset(20)), not wrapped. In position control mode (operating
//!     mode 3) the e-manual says offsets outside -1024..=1024 are ignored: such an offset is held
//!     in the register but not applied.
//! - A goal is reached by turning the horn by the goal's distance from the present position in the
//!   offset-corrected frame, so a move never takes the other way round the turn.
//! - A hand can turn a horn whose torque is off ([`SimServo::hand_move`]): at once, or at a
//!   steady speed; the present position follows it.
//! - A horn whose link has run into something ([`super::contact`] finds it) is stopped there
//!   ([`SimServo::set_stop`]): it does not pass the contact that way, its load follows the goal's
//!   distance past it, and a Feetech servo pushing at overload torque for its protection time sets
//!   its overload bit ([`super::stall`]).
//! - A servo whose baud item does not match the bus's baud rate hears nothing (after changing it,
//!   or after a factory reset that restores it).
//!
//! [`SimServo::set_register`] sets any item as a fault would leave it (`armctl sim servos
//! --register`), bypassing the bus rules (read-only items too, EEPROM with torque on):
//! - readings and versions (the read-only items: voltage, temperature, firmware version, model
//!   number, load) stay as set: the simulation never recomputes them (except the load of a
//!   gripper's servo closing on an object), and a reboot or factory reset keeps them, as a supply,
//!   a heat or a firmware outlives a restart. The ping's reply carries the model number and
//!   firmware version of the table;
//! - the present position places the horn where the servo reports that value (as a hand would;
//!   the goal follows, so a torqued servo holds it there); `moving` is the servo's own and cannot
//!   be set;
//! - the hardware error status raises that hardware error ([`SimServo::set_hardware_error`]);
//! - a goal position with torque off moves nothing (a stale goal); torque enable 1 switches torque
//!   on without the bus write's side effect (goal := present position): the servo then drives to
//!   the goal its register holds, as a real one whose torque is on does, whichever of the two was
//!   set first; torque enable 0 stops it where it is. A servo with a hardware error keeps torque
//!   off (its protection);
//! - every other item takes the value as stored: a reboot brings RAM items back to their factory
//!   values and keeps EEPROM ones, as on the real servo.

use firmware::bus::table::{xseries, Access, Item, Model};
use firmware::bus::{Instruction, Protocol};

use super::drive::{radians_per_tick, Drive, DriveModel, STEP_NS};
use super::drive_models::DriveRegisters;
use super::motion::Profile;
use super::stall::{self, Stop, OVERLOAD, OVERLOAD_TORQUE, PROTECTION_TIME_NS};
use crate::arm::calibration::homing_offset_item;
use crate::arm::calibration::record::DXL_POSITION_MODE_MAX_OFFSET;

/// Dynamixel error numbers (e-manual, Protocol 2.0, "Status Packet").
pub mod error {
    /// Result fail: the instruction could not be carried out.
    pub const RESULT_FAIL: u8 = 1;
    /// Instruction error: unknown instruction, or an action without a reg write.
    pub const INSTRUCTION: u8 = 2;
    /// Data range error: the address is outside the table.
    pub const DATA_RANGE: u8 = 4;
    /// Data length error: the data runs past the table, or there is none.
    pub const DATA_LENGTH: u8 = 5;
    /// The value is outside the item's limits (a goal position beyond the position limits).
    pub const DATA_LIMIT: u8 = 6;
    /// Access error: read-only item, or EEPROM while torque is on.
    pub const ACCESS: u8 = 7;
}

/// The Dynamixel alert bit of the status error byte.
pub const ALERT: u8 = 0x80;

/// The overheating bit: Feetech's status error bit 2 and Dynamixel's hardware error status bit 2
/// (e-manual, Hardware Error Status(70)) are the same.
const OVERHEAT: u8 = firmware::bus::feetech::StatusError::OVERHEAT;

/// The horn speed (rad/s) above which a servo under torque reports itself moving though its
/// profile has ended (its drive still settling): a tick every 10 ms.
const MOVING_SPEED: f64 = 2.0 * std::f64::consts::PI / 4096.0 / 0.01;

/// Dynamixel X's operating mode 3, position control (single turn).
const DXL_POSITION_MODE: i64 = 3;

/// The key of Dynamixel's CLEAR of the multi-turn position (`0x01 'D' 'X' 'L' '"'`).
const CLEAR_KEY: [u8; 4] = [0x44, 0x58, 0x4C, 0x22];

/// A simulated servo of one [`Model`].
#[derive(Clone, Debug)]
pub struct SimServo {
    model: &'static Model,
    table: Vec<u8>,
    profile: Profile,
    registered: Option<(u16, Vec<u8>)>,
    /// Feetech's error bits (Dynamixel keeps them in its hardware error status item).
    fault_bits: u8,
    /// Writes that reached the goal position item (a safety monitor tells a lost write from a
    /// held goal by it).
    goal_writes: u64,
    /// When the last of them arrived, virtual ns.
    goal_written_ns: u64,
    /// Whether the packet being carried out was corrupted on the line (the bus's fault injection
    /// says so; a real servo cannot tell).
    in_corrupted_packet: bool,
    /// Whether the last goal write came in such a packet.
    last_goal_corrupted: bool,
    /// An object between the jaws, when this servo is a gripper's.
    jaw: Option<Jaw>,
    /// When the present position was last read (a read, sync read, bulk read or fast sync read
    /// covering it), virtual ns.
    position_read_ns: Option<u64>,
    /// Read-only items set by [`SimServo::set_register`], kept through reboots and factory resets.
    pinned: Vec<(Item, i64)>,
    /// Where its link ran into something ([`super::contact`]): the horn cannot pass it that way.
    stop: Option<Stop>,
    /// Since when its load has stood at or above its overload torque, virtual ns.
    overloaded_since: Option<u64>,
    /// Its motor, gearbox and loop ([`super::drive`]), when the bus has physics: the horn is
    /// then where the drive has it, behind the profile (its reference) by what the load asks.
    drive: Option<Drive>,
}

/// An object between a gripper's jaws: the horn cannot pass `contact` going toward `closed`, and
/// pushing against it loads the servo in proportion to how far its goal lies past the contact
/// (a stiff object and the servo's proportional position loop), up to its effort limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jaw {
    /// Where the jaws meet the object, ticks.
    pub contact: i64,
    /// The jaws' closed position, ticks (which side of `contact` is blocked).
    pub closed: i64,
}

pub use super::stall::JAW_STIFFNESS;

impl Jaw {
    /// The jaws of `gripper` closing on an object `width_mm` wide (the opening taken as linear in
    /// ticks); refused unless the object fits between the open jaws.
    pub fn for_object(gripper: &crate::arm::servos::GripperSpec, width_mm: f64) -> anyhow::Result<Self> {
        if !(width_mm.is_finite() && width_mm > 0.0 && width_mm < gripper.opening_mm) {
            anyhow::bail!(
                "--object-mm: {width_mm} mm does not fit the gripper, whose jaws open {} mm: give a width above 0 and below it",
                gripper.opening_mm
            );
        }
        let stroke = f64::from(gripper.open - gripper.closed);
        let contact = (f64::from(gripper.closed) + width_mm / gripper.opening_mm * stroke).round() as i64;
        Ok(Self { contact, closed: i64::from(gripper.closed) })
    }

    /// Whether `position` lies past the contact on the closed side.
    fn blocks(&self, position: f64) -> bool {
        let closing = (self.closed - self.contact).signum() as f64;
        (position - self.contact as f64) * closing > 0.0
    }

    /// Whether `position` (reported ticks) is at the contact or past it: the jaws touch the object.
    pub fn reached(&self, position: f64) -> bool {
        let closing = (self.closed - self.contact).signum() as f64;
        (position - self.contact as f64) * closing >= 0.0
    }
}

impl SimServo {
    /// A servo fresh from the factory but with `id` and the baud item of `baud` (the factory
    /// baud when the model has no index for it), standing at half a turn (2048 ticks on these
    /// models, the middle of their range).
    pub fn new(model: &'static Model, id: u8, baud: u32) -> Self {
        let mut servo = Self {
            model,
            table: factory_table(model),
            profile: Profile::hold(0.0, 0),
            registered: None,
            fault_bits: 0,
            goal_writes: 0,
            goal_written_ns: 0,
            in_corrupted_packet: false,
            last_goal_corrupted: false,
            jaw: None,
            position_read_ns: None,
            pinned: Vec::new(),
            stop: None,
            overloaded_since: None,
            drive: None,
        };
        servo.set(model.items.id, i64::from(id));
        if let Some(index) = model.baud_index(baud) {
            servo.set(model.items.baud, i64::from(index));
        }
        let (lo, hi) = (servo.get(model.items.min_position), servo.get(model.items.max_position));
        servo.set_position((i64::from(model.ticks_per_revolution) / 2).clamp(lo.min(hi), hi.max(lo)), 0);
        servo
    }

    /// The model.
    pub fn model(&self) -> &'static Model {
        self.model
    }

    /// The control table as it stands.
    pub fn table(&self) -> &[u8] {
        &self.table
    }

    /// The servo's id (its id item).
    pub fn id(&self) -> u8 {
        self.get(self.model.items.id) as u8
    }

    /// The value of `item` (0 when the item lies outside the table).
    pub fn get(&self, item: Item) -> i64 {
        let range = usize::from(item.address)..usize::from(item.address) + item.len();
        self.table.get(range).and_then(|b| item.decode(b, self.model.endian).ok()).unwrap_or(0)
    }

    /// Sets `item` directly, bypassing the bus rules (for tests and scenario setup). Values that do
    /// not fit the item are ignored.
    pub fn set(&mut self, item: Item, value: i64) {
        let at = usize::from(item.address);
        if let Some(slot) = self.table.get_mut(at..at + item.len()) {
            let _ = item.encode(value, self.model.endian, slot);
        }
    }

    /// Puts the horn at `ticks` (its own, actual position, before the homing offset) at time
    /// `t_ns` (as if turned by hand), goal included; no motion. With no offset, the present
    /// position reads `ticks`.
    pub fn set_position(&mut self, ticks: i64, t_ns: u64) {
        self.profile = Profile::hold(ticks as f64, t_ns);
        let per_tick = self.radians_per_tick();
        if let Some(drive) = &mut self.drive {
            drive.place(ticks as f64 * per_tick, 0.0);
        }
        let present = self.present_of(ticks as f64);
        self.set(self.model.items.present_position, present);
        self.set(self.model.items.goal_position, present);
        self.set(self.model.items.moving, 0);
    }

    /// The homing offset in effect: the register's, except a Dynamixel's beyond
    /// [`DXL_POSITION_MODE_MAX_OFFSET`] (1024) in position control mode, which is ignored (e-manual,
    /// Homing Offset(20)).
    pub fn homing_offset(&self) -> i64 {
        let offset = self.get(homing_offset_item(self.model));
        let ignored = self.model.protocol == Protocol::Dxl2
            && self.get(xseries::OPERATING_MODE) == DXL_POSITION_MODE
            && offset.abs() > DXL_POSITION_MODE_MAX_OFFSET;
        if ignored {
            0
        } else {
            offset
        }
    }

    /// The present position (offset-corrected, fractional) of the horn at `actual` ticks.
    fn corrected(&self, actual: f64) -> f64 {
        let offset = self.homing_offset() as f64;
        match self.model.protocol {
            Protocol::Feetech => (actual - offset).rem_euclid(f64::from(self.model.ticks_per_revolution)),
            Protocol::Dxl2 => actual + offset,
        }
    }

    /// The present position the servo reports with its horn at `actual` ticks.
    fn present_of(&self, actual: f64) -> i64 {
        let tpr = i64::from(self.model.ticks_per_revolution);
        let offset = self.homing_offset();
        match self.model.protocol {
            Protocol::Feetech => (actual.round() as i64 - offset).rem_euclid(tpr),
            Protocol::Dxl2 => actual.round() as i64 + offset,
        }
    }

    /// Where the horn is at `t_ns`: its own position, before the homing offset, in ticks.
    pub fn actual_position(&self, t_ns: u64) -> f64 {
        match &self.drive {
            Some(drive) => drive.angle() / self.radians_per_tick(),
            None => self.profile.at(t_ns).0,
        }
    }

    fn radians_per_tick(&self) -> f64 {
        radians_per_tick(self.model.ticks_per_revolution)
    }

    /// Gives the servo a drive of `model` ([`super::drive`]), its horn where it stands at `t_ns`.
    pub fn enable_drive(&mut self, model: DriveModel, t_ns: u64) {
        let angle = self.actual_position(t_ns) * self.radians_per_tick();
        let celsius = self.get(DriveRegisters::of(self.model).temperature()) as f64;
        self.drive = Some(Drive::new(model, angle, t_ns - t_ns % STEP_NS).at_temperature(celsius));
    }

    /// Takes its drive away: an ideal servo again, its horn where the drive left it.
    pub fn disable_drive(&mut self) {
        if let Some(drive) = self.drive.take() {
            let at = drive.angle() / self.radians_per_tick();
            self.profile = Profile::hold(at, drive.stepped_ns());
        }
    }

    /// Whether `item` is a reading pinned by [`SimServo::set_register`] (the simulation leaves it).
    pub fn is_pinned(&self, item: Item) -> bool {
        self.pinned.iter().any(|(i, _)| *i == item)
    }

    /// Its drive, when the bus has physics.
    pub fn drive(&self) -> Option<&Drive> {
        self.drive.as_ref()
    }

    /// One step of its drive ([`Drive::step`]) with its links' `load` (N m, in the horn's
    /// direction) and `inertia` (kg m²): toward its profile, or, torque off, where a hand holds the
    /// horn (the profile a hand moves). A stop holds the horn at the contact.
    pub fn drive_step(&mut self, load: f64, inertia: f64) {
        let per_tick = self.radians_per_tick();
        let registers = DriveRegisters::of(self.model);
        let control = registers.control(|item| self.get(item), self.torque());
        let stop = self.stop.filter(|_| self.torque());
        let Some(drive) = self.drive.as_mut() else { return };
        let t = drive.stepped_ns() + STEP_NS;
        let (reference, speed) = self.profile.at(t);
        if control.torque {
            let reference = stop.map_or(reference, |s| s.clamp(reference));
            drive.step(reference * per_tick, control, load, inertia);
            if let Some(stop) = stop.filter(|s| s.blocks(drive.angle() / per_tick)) {
                drive.hold_at(stop.at * per_tick);
            }
        } else {
            drive.follow(reference * per_tick, speed * per_tick);
        }
    }

    /// A hand turns the horn (torque off): to `from` at once, then at a steady speed to `to` in
    /// `seconds` (at once when `seconds` is 0), in the horn's own ticks. Refused, with the reason,
    /// while torque is on (the servo would hold against the hand). Returns when the horn gets there.
    pub fn hand_move(&mut self, from: i64, to: i64, seconds: f64, t_ns: u64) -> Result<u64, String> {
        self.update(t_ns);
        if self.torque() {
            return Err(format!("servo {} has torque on: a hand cannot turn it", self.id()));
        }
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(format!("{seconds} is not a duration in seconds"));
        }
        let speed = (to - from).unsigned_abs() as f64 / seconds;
        self.profile = if seconds == 0.0 || from == to {
            Profile::hold(to as f64, t_ns)
        } else {
            Profile::plan(t_ns, from as f64, 0.0, to as f64, speed, f64::INFINITY)
        };
        self.update(t_ns);
        Ok(self.profile.end_ns().unwrap_or(t_ns))
    }

    /// When the present position was last read, in virtual ns (`None` before any read).
    pub fn position_read_ns(&self) -> Option<u64> {
        self.position_read_ns
    }

    /// Books a read of `length` bytes at `address` at `t_ns` (the bus calls it for group reads).
    pub fn note_read(&mut self, address: u16, length: u16, t_ns: u64) {
        if overlaps(self.model.items.present_position, usize::from(address), usize::from(length)) {
            self.position_read_ns = Some(self.position_read_ns.map_or(t_ns, |t| t.max(t_ns)));
        }
    }

    /// The baud rate the servo listens at (`None` when the baud item has no rate).
    pub fn baud(&self) -> Option<u32> {
        self.model.baud_rate(self.get(self.model.items.baud) as u8)
    }

    /// Return delay in nanoseconds, from the return delay item.
    pub fn return_delay_ns(&self) -> u64 {
        self.get(self.model.items.return_delay) as u64 * u64::from(self.model.return_delay_unit_us) * 1000
    }

    /// Writes that have reached the goal position item.
    pub fn goal_writes(&self) -> u64 {
        self.goal_writes
    }

    /// When the last write reached the goal position item, in virtual nanoseconds (0 before any).
    pub fn goal_written_ns(&self) -> u64 {
        self.goal_written_ns
    }

    /// Whether the last goal write came in a packet the simulated line had corrupted (a lost or
    /// flipped byte since the packet before) and the checksum let through.
    pub fn last_goal_corrupted(&self) -> bool {
        self.last_goal_corrupted
    }

    /// Marks the packet about to be carried out as corrupted on the line, or not.
    pub fn set_in_corrupted_packet(&mut self, corrupted: bool) {
        self.in_corrupted_packet = corrupted;
    }

    /// Whether torque is on.
    pub fn torque(&self) -> bool {
        self.get(self.model.items.torque_enable) != 0
    }

    /// Raises a hardware error: on Dynamixel `bits` go to the hardware error status item and every
    /// status carries the alert bit; on Feetech `bits` are the status error bits (e.g. 0x20
    /// overload). Torque goes off, as the real servo's protection does.
    pub fn set_hardware_error(&mut self, bits: u8, t_ns: u64) {
        self.update(t_ns);
        match self.model.items.hardware_error {
            Some(item) => self.set(item, i64::from(bits)),
            None => self.fault_bits = bits,
        }
        if bits != 0 {
            self.torque_off(t_ns);
        }
    }

    /// The hardware error bits it holds (Dynamixel's status item, Feetech's error bits).
    fn hardware_error_bits(&self) -> u8 {
        match self.model.items.hardware_error {
            Some(item) => self.get(item) as u8,
            None => self.fault_bits,
        }
    }

    /// Clears the hardware error (Dynamixel: what a reboot does).
    pub fn clear_hardware_error(&mut self) {
        match self.model.items.hardware_error {
            Some(item) => self.set(item, 0),
            None => self.fault_bits = 0,
        }
    }

    /// The error byte of a status carrying error number `number` (Dynamixel; ignored on Feetech).
    pub fn status_error(&self, number: u8) -> u8 {
        match self.model.items.hardware_error {
            Some(item) if self.get(item) != 0 => number | ALERT,
            Some(_) => number,
            None => self.fault_bits,
        }
    }

    /// Puts an object between the jaws (`None` takes it away) at `t_ns`. Jaws closed tighter than
    /// the object are opened to it first, as a hand putting it there would (goal included, so a
    /// torqued servo does not fight it). The contact is in the servo's reported (offset-corrected)
    /// ticks, as the gripper's are.
    pub fn set_jaw(&mut self, jaw: Option<Jaw>, t_ns: u64) {
        self.update(t_ns);
        if let Some(j) = jaw {
            let actual = self.actual_position(t_ns);
            let present = self.corrected(actual);
            if j.blocks(present) {
                self.set_position((actual + (j.contact as f64 - present)).round() as i64, t_ns);
            }
        }
        self.jaw = jaw;
        self.update(t_ns);
    }

    /// The object between the jaws, if any.
    pub fn jaw(&self) -> Option<Jaw> {
        self.jaw
    }

    /// Brings present position, motion (the servo's own, or a hand's with torque off), the moving
    /// flag and (for a gripper's servo with torque on) the load up to `t_ns`.
    pub fn update(&mut self, t_ns: u64) {
        let (mut p, _) = self.profile.at(t_ns);
        let mut moving = self.torque() && self.profile.moving(t_ns);
        // Whether the stall model reports the load (a stop or an object): else the drive does.
        let mut stalled = false;
        if let Some(jaw) = self.jaw.filter(|_| self.torque()) {
            stalled = true;
            // The jaw's ticks are the reported ones; the profile moves the horn's own.
            let present = self.corrected(p);
            let mut load = 0;
            if jaw.reached(present) {
                // On the object: the horn stands at the contact; the load follows the goal's
                // distance past it, capped by the effort limit.
                if jaw.blocks(present) {
                    p += jaw.contact as f64 - present;
                    self.profile = Profile::hold(p, t_ns);
                    moving = false;
                }
                let goal = self.get(self.model.items.goal_position);
                if jaw.blocks(goal as f64) {
                    load = (goal - jaw.contact).abs() * JAW_STIFFNESS;
                }
            }
            if let Some(force) = self.model.force {
                // In thousandths of full effort, then in the present item's unit.
                let cap = self.get(force.limit).abs() * 1000 / i64::from(force.limit_full.max(1));
                let closing = (jaw.closed - jaw.contact).signum();
                let value = load.min(cap).min(1000) * i64::from(force.present_full) / 1000;
                self.set(force.present, closing * value);
            }
        }
        match self.stop.filter(|_| self.torque()) {
            Some(stop) => {
                if stop.blocks(p) {
                    // Against the contact: the horn stands there (rigid, no give).
                    p = stop.at;
                    self.profile = Profile::hold(p, t_ns);
                    moving = false;
                }
                stalled = true;
                self.push_against(stop, t_ns);
            }
            None if self.drive.is_none() => self.overloaded_since = None,
            None => {}
        }
        if let Some(drive) = self.drive {
            // The horn is where the drive has it, behind the profile by what its load asks.
            p = drive.angle() / self.radians_per_tick();
            moving = self.torque() && (moving || drive.speed().abs() > MOVING_SPEED);
            let registers = DriveRegisters::of(self.model);
            for (item, value) in registers.readings(&drive, self.radians_per_tick(), !stalled) {
                // A reading a fault pinned stays as it was set (`--register`).
                if !self.is_pinned(item) {
                    self.set(item, value);
                }
            }
            match (stalled, self.torque()) {
                (false, true) => self.protect(drive.duty().abs() * 1000.0, t_ns),
                (_, false) => self.overloaded_since = None,
                (true, true) => {}
            }
            if self.torque() && drive.temperature() >= registers.temperature_limit(|item| self.get(item)) {
                // Its overheat protection: the bit set, torque off (not through
                // `set_hardware_error`, which brings the servo up to date first: this is that).
                let bits = self.hardware_error_bits() | OVERHEAT;
                match self.model.items.hardware_error {
                    Some(item) => self.set(item, i64::from(bits)),
                    None => self.fault_bits = bits,
                }
                self.torque_off(t_ns);
                return;
            }
        }
        self.set(self.model.items.present_position, self.present_of(p));
        self.set(self.model.items.moving, i64::from(moving));
    }

    /// The load of a horn held at `stop` by its goal beyond it, and a Feetech servo's overload
    /// protection (see [`super::stall`]).
    fn push_against(&mut self, stop: Stop, t_ns: u64) {
        let Some(force) = self.model.force else { return };
        let goal = self.get(self.model.items.goal_position) as f64;
        let cap = self.get(force.limit).abs() * 1000 / i64::from(force.limit_full.max(1));
        let load = stall::load(stop.push(goal - self.corrected(stop.at))).min(cap);
        let value = load * i64::from(force.present_full) / 1000;
        self.set(force.present, stop.toward.signum() as i64 * value);
        self.protect(load as f64, t_ns);
    }

    /// A Feetech servo's overload protection with its load at `load` thousandths of full effort:
    /// at or above its overload torque for [`PROTECTION_TIME_NS`], it sets its overload bit and
    /// lets go. A Dynamixel's overload is not modelled (see the module doc of `stall`).
    fn protect(&mut self, load: f64, t_ns: u64) {
        if self.model.items.hardware_error.is_some() {
            return;
        }
        let threshold = self.get(OVERLOAD_TORQUE) * 10;
        if threshold <= 0 || load < threshold as f64 {
            self.overloaded_since = None;
            return;
        }
        let since = *self.overloaded_since.get_or_insert(t_ns);
        if t_ns.saturating_sub(since) >= PROTECTION_TIME_NS {
            self.overloaded_since = None;
            self.fault_bits |= OVERLOAD;
            self.torque_off(t_ns);
        }
    }

    /// Stops the horn where its link ran into something (`None`: nothing in the way); it takes
    /// effect from the next [`SimServo::update`].
    pub fn set_stop(&mut self, stop: Option<Stop>) {
        self.stop = stop;
    }

    /// Where the horn is stopped, if it is.
    pub fn stop(&self) -> Option<Stop> {
        self.stop
    }

    /// The stop is lifted at `t_ns` (its load gone): a servo whose goal lies beyond it pushes on
    /// toward it again, as a real one does whenever what held it is gone.
    pub fn release(&mut self, t_ns: u64) {
        if self.stop.is_none() {
            return;
        }
        // Held at the contact up to now first: the push resumes from there.
        self.update(t_ns);
        self.stop = None;
        if let Some(force) = self.model.force {
            self.set(force.present, 0);
        }
        if self.torque() {
            // Pushing on from the contact: the overload timer runs on if it stalls again.
            let since = self.overloaded_since;
            self.start_move(t_ns);
            self.overloaded_since = since;
        }
    }

    /// Whether its horn is stopped with its goal beyond the stop: it pushes against it.
    pub fn pushing(&self) -> bool {
        self.stop.is_some_and(|stop| {
            let goal = self.get(self.model.items.goal_position) as f64;
            stop.push(goal - self.corrected(stop.at)) > 0.0
        })
    }

    /// Where the horn will be at `t_ns` (its own ticks), its stop included, without changing
    /// anything: for looking ahead along its motion.
    pub fn horn_at(&self, t_ns: u64) -> f64 {
        let p = self.profile.at(t_ns).0;
        match self.stop.filter(|_| self.torque()) {
            Some(stop) => stop.clamp(p),
            None => p,
        }
    }

    /// The position the servo reports (fractional, offset-corrected) with its horn at `actual`.
    pub fn reported(&self, actual: f64) -> f64 {
        self.corrected(actual)
    }

    /// A bound on how far (ticks) its horn travels from `t0_ns` to `t1_ns` ([`Profile::travel_bound`];
    /// a stop only shortens that).
    pub fn travel_bound(&self, t0_ns: u64, t1_ns: u64) -> f64 {
        self.profile.travel_bound(t0_ns, t1_ns)
    }

    /// Whether its horn moves at `t_ns` (its own profile or a hand's).
    pub fn in_motion(&self, t_ns: u64) -> bool {
        self.profile.moving(t_ns)
    }

    fn torque_off(&mut self, t_ns: u64) {
        let p = self.actual_position(t_ns);
        self.set(self.model.items.torque_enable, 0);
        // Torque off: the horn stops where it is (no coasting modelled).
        self.profile = Profile::hold(p.round(), t_ns);
        self.set(self.model.items.present_position, self.present_of(p));
        self.set(self.model.items.moving, 0);
    }

    /// Whether the status return level lets the servo answer `instruction` sent to it alone.
    pub fn answers(&self, instruction: &Instruction<'_>) -> bool {
        let level = self.get(self.model.items.status_return_level);
        let read = matches!(
            instruction,
            Instruction::Read { .. }
                | Instruction::SyncRead { .. }
                | Instruction::FastSyncRead { .. }
                | Instruction::BulkRead { .. }
        );
        match (self.model.protocol, instruction) {
            (_, Instruction::Ping) => true,
            // Dynamixel: 0 ping only, 1 ping and reads, 2 everything.
            (Protocol::Dxl2, _) if read => level >= 1,
            (Protocol::Dxl2, _) => level >= 2,
            // Feetech: 0 ping and reads, 1 everything.
            (Protocol::Feetech, _) if read => true,
            (Protocol::Feetech, _) => level >= 1,
        }
    }

    /// The data of a ping's reply: model number (LE) and firmware on Dynamixel, none on Feetech.
    pub fn ping_params(&self) -> Vec<u8> {
        match self.model.protocol {
            Protocol::Dxl2 => {
                // The table's, which a `--register` may have changed.
                let number = u16::try_from(self.get(self.model.items.model_number)).unwrap_or(self.model.number);
                let [lo, hi] = number.to_le_bytes();
                vec![lo, hi, u8::try_from(self.get(self.model.items.firmware)).unwrap_or(self.model.firmware)]
            }
            Protocol::Feetech => Vec::new(),
        }
    }

    /// `length` bytes from `address`, or a Dynamixel error number. Feetech reads past the table
    /// give zeros.
    pub fn read(&self, address: u16, length: u16) -> Result<Vec<u8>, u8> {
        let (at, len) = (usize::from(address), usize::from(length));
        if self.model.protocol == Protocol::Dxl2 {
            self.check_range(at, len)?;
        }
        Ok((at..at + len).map(|i| self.table.get(i).copied().unwrap_or(0)).collect())
    }

    fn check_range(&self, at: usize, len: usize) -> Result<(), u8> {
        if at >= self.table.len() {
            return Err(error::DATA_RANGE);
        }
        if len == 0 || at + len > self.table.len() {
            return Err(error::DATA_LENGTH);
        }
        Ok(())
    }

    /// Whether a write of `data` at `address` is allowed (Dynamixel rules; Feetech allows all).
    pub fn check_write(&self, address: u16, data: &[u8]) -> Result<(), u8> {
        if self.model.protocol != Protocol::Dxl2 {
            return Ok(());
        }
        let (at, len) = (usize::from(address), data.len());
        self.check_range(at, len)?;
        if read_only_items(self.model).any(|item| overlaps(item, at, len)) {
            return Err(error::ACCESS);
        }
        if at < usize::from(self.model.eeprom_end) && self.torque() {
            return Err(error::ACCESS);
        }
        // A goal position outside the position limits is refused with a data limit error
        // (DynamixelSDK: "The data value exceeds the limit value!"), not clamped.
        let goal = self.model.items.goal_position;
        let (g0, g1) = (usize::from(goal.address), usize::from(goal.address) + goal.len());
        if at <= g0 && at + len >= g1 {
            let value = goal.decode(&data[g0 - at..g1 - at], self.model.endian).unwrap_or(0);
            let (lo, hi) = (self.get(self.model.items.min_position), self.get(self.model.items.max_position));
            if value < lo.min(hi) || value > hi.max(lo) {
                return Err(error::DATA_LIMIT);
            }
        }
        Ok(())
    }

    /// Writes `data` at `address` at time `t_ns`, with the model's rules and side effects (torque,
    /// goal). On Dynamixel a refused write changes nothing and returns the error number.
    pub fn write(&mut self, address: u16, data: &[u8], t_ns: u64) -> Result<(), u8> {
        self.check_write(address, data)?;
        self.update(t_ns);
        let was_on = self.torque();
        let at = usize::from(address);
        let model = self.model;
        for (i, &b) in data.iter().enumerate() {
            let a = at + i;
            // Feetech: bytes of read-only items and outside the table are ignored.
            let read_only = read_only_items(model).any(|item| overlaps(item, a, 1));
            if let (false, Some(slot)) = (read_only, self.table.get_mut(a)) {
                *slot = b;
            }
        }
        let items = model.items;
        if overlaps(items.torque_enable, at, data.len()) {
            let on = self.torque();
            let faulty = self.status_error(0) != 0;
            if on && faulty {
                // Protection holds torque off until the fault is cleared.
                self.set(items.torque_enable, 0);
            } else if on && !was_on {
                let actual = self.actual_position(t_ns).round() as i64;
                self.set_position(actual, t_ns);
            } else if !on && was_on {
                self.set(items.torque_enable, 1);
                self.torque_off(t_ns);
            }
        }
        // A new offset (or operating mode, on Dynamixel) changes what the servo reports at once.
        self.update(t_ns);
        if overlaps(items.goal_position, at, data.len()) {
            self.goal_writes += 1;
            self.goal_written_ns = t_ns;
            self.last_goal_corrupted = self.in_corrupted_packet;
            if self.torque() {
                self.start_move(t_ns);
            }
        }
        Ok(())
    }

    fn start_move(&mut self, t_ns: u64) {
        let items = self.model.items;
        let (lo, hi) = (self.get(items.min_position), self.get(items.max_position));
        let goal = self.get(items.goal_position).clamp(lo.min(hi), hi.max(lo));
        let max = f64::from(self.model.max_velocity);
        let v = self.get(items.velocity).unsigned_abs() as f64 * f64::from(self.model.velocity_unit);
        let v = if v == 0.0 { max } else { v.min(max) };
        let a = self.get(items.acceleration).unsigned_abs() as f64 * f64::from(self.model.acceleration_unit);
        let a = if a == 0.0 { f64::INFINITY } else { a };
        let (p, vel) = self.profile.at(t_ns);
        // The goal is in the offset-corrected frame: the horn turns by its distance from there.
        let target = p + (goal as f64 - self.corrected(p));
        self.profile = Profile::plan(t_ns, p, vel, target, v, a);
        self.update(t_ns);
    }

    /// When the present move ends, in virtual nanoseconds (`None` when standing).
    pub fn move_end_ns(&self) -> Option<u64> {
        self.profile.end_ns().filter(|_| self.torque())
    }

    /// Carries out an instruction addressed to this servo (or broadcast) at `t_ns`; returns the
    /// reply's data, or a Dynamixel error number. Group instructions are the bus's business.
    pub fn execute(&mut self, instruction: &Instruction<'_>, t_ns: u64) -> Result<Vec<u8>, u8> {
        self.update(t_ns);
        match *instruction {
            Instruction::Ping => Ok(self.ping_params()),
            Instruction::Read { address, length } => {
                self.note_read(address, length, t_ns);
                self.read(address, length)
            }
            Instruction::Write { address, data } => self.write(address, data, t_ns).map(|()| Vec::new()),
            Instruction::RegWrite { address, data } => {
                self.check_write(address, data)?;
                self.registered = Some((address, data.to_vec()));
                Ok(Vec::new())
            }
            Instruction::Action => match self.registered.take() {
                Some((address, data)) => self.write(address, &data, t_ns).map(|()| Vec::new()),
                None if self.model.protocol == Protocol::Dxl2 => Err(error::INSTRUCTION),
                None => Ok(Vec::new()),
            },
            Instruction::Reboot => {
                self.reboot(t_ns);
                Ok(Vec::new())
            }
            Instruction::FactoryReset { mode } => {
                self.factory_reset(mode, t_ns);
                Ok(Vec::new())
            }
            Instruction::Clear { params: [mode, key @ ..] } => match mode {
                // The multi-turn count is not modelled: positions stay within one turn.
                0x01 if key == CLEAR_KEY => Ok(Vec::new()),
                0x01 => Err(error::RESULT_FAIL),
                0x02 => {
                    self.clear_hardware_error();
                    Ok(Vec::new())
                }
                _ => Err(error::DATA_RANGE),
            },
            // Feetech RESET restores the running state (turn count), which is not modelled.
            Instruction::Reset => Ok(Vec::new()),
            _ => Err(error::INSTRUCTION),
        }
    }

    /// Restart: RAM back to factory values, EEPROM kept, the horn where it is, faults cleared.
    pub fn reboot(&mut self, t_ns: u64) {
        self.update(t_ns);
        let actual = self.actual_position(t_ns).round() as i64;
        let eeprom = usize::from(self.model.eeprom_end).min(self.table.len());
        let mut table = factory_table(self.model);
        table[..eeprom].copy_from_slice(&self.table[..eeprom]);
        self.table = table;
        self.registered = None;
        self.clear_hardware_error();
        self.reapply_pinned();
        self.set_position(actual, t_ns);
    }

    /// Factory settings: everything back to factory values, except the id (`mode` 0x01) or the id
    /// and baud (`mode` 0x02); 0xFF resets those too.
    pub fn factory_reset(&mut self, mode: u8, t_ns: u64) {
        self.update(t_ns);
        let items = self.model.items;
        let (id, baud) = (self.get(items.id), self.get(items.baud));
        let actual = self.actual_position(t_ns).round() as i64;
        self.table = factory_table(self.model);
        if mode == 0x01 || mode == 0x02 {
            self.set(items.id, id);
        }
        if mode == 0x02 {
            self.set(items.baud, baud);
        }
        self.registered = None;
        self.clear_hardware_error();
        self.reapply_pinned();
        self.set_position(actual, t_ns);
    }

    fn reapply_pinned(&mut self) {
        for (item, value) in self.pinned.clone() {
            self.set(item, value);
        }
    }

    /// Sets `item` to `value` at `t_ns` as a fault or a past would leave it, bypassing the bus
    /// rules (the module doc says what each kind of item does). Refused, with the reason, when the
    /// value does not fit the item, the item lies outside the table, or it is `moving`.
    pub fn set_register(&mut self, item: Item, value: i64, t_ns: u64) -> Result<(), String> {
        let model = self.model;
        let items = model.items;
        if usize::from(item.address) + item.len() > self.table.len() {
            return Err(format!("{} has no {} in its table", model.name, item.name));
        }
        let mut bytes = [0u8; 4];
        if let Err(e) = item.encode(value, model.endian, &mut bytes) {
            let (lo, hi) = item.range();
            return Err(format!("{e} (it holds {lo} to {hi})"));
        }
        if item == items.moving {
            return Err("moving is the servo's own (1 while its profile runs): it cannot be set".to_string());
        }
        self.update(t_ns);
        if item == items.present_position {
            // The horn where the servo reports `value`, the goal with it.
            let actual = match model.protocol {
                Protocol::Feetech => value + self.homing_offset(),
                Protocol::Dxl2 => value - self.homing_offset(),
            };
            self.set_position(actual, t_ns);
            return Ok(());
        }
        if Some(item) == items.hardware_error {
            self.set_hardware_error(value as u8, t_ns);
            return Ok(());
        }
        let was_on = self.torque();
        self.set(item, value);
        if item.access == Access::Read {
            self.pinned.retain(|(pinned, _)| pinned.address != item.address);
            self.pinned.push((item, value));
        }
        let on = self.torque();
        if on && self.status_error(0) != 0 {
            // Protection holds torque off until the fault is cleared.
            self.set(items.torque_enable, 0);
        } else if was_on && !on {
            self.set(items.torque_enable, 1);
            self.torque_off(t_ns);
        } else if on && (item == items.torque_enable || item == items.goal_position) {
            self.start_move(t_ns);
        }
        // A new offset or operating mode changes what the servo reports at once.
        self.update(t_ns);
        Ok(())
    }
}

/// A table of the model's factory values, model number and firmware version.
fn factory_table(model: &'static Model) -> Vec<u8> {
    let mut table = vec![0u8; usize::from(model.table_len)];
    let mut put = |item: Item, value: i64| {
        let at = usize::from(item.address);
        if let Some(slot) = table.get_mut(at..at + item.len()) {
            let _ = item.encode(value, model.endian, slot);
        }
    };
    for &(item, value) in model.defaults {
        put(item, value);
    }
    put(model.items.model_number, i64::from(model.number));
    put(model.items.firmware, i64::from(model.firmware));
    table
}

/// The model's read-only items: those of its roles and of its factory values.
fn read_only_items(model: &'static Model) -> impl Iterator<Item = Item> {
    let i = model.items;
    let roles = [Some(i.model_number), Some(i.firmware), Some(i.moving), Some(i.present_position), i.hardware_error];
    roles
        .into_iter()
        .flatten()
        .chain(model.defaults.iter().map(|(item, _)| *item))
        .filter(|it| it.access == Access::Read)
}

/// Whether `item` shares a byte with `len` bytes from `at`.
fn overlaps(item: Item, at: usize, len: usize) -> bool {
    let a = usize::from(item.address);
    a < at + len && at < a + item.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::bus::table::{sts3215, STS3215, XL430_W250};

    const T0: u64 = 0;

    /// Writes `value` to `item` through the servo's own write, as the bus would.
    fn write(servo: &mut SimServo, item: Item, value: i64, t_ns: u64) {
        let mut bytes = [0u8; 4];
        item.encode(value, servo.model().endian, &mut bytes).unwrap();
        servo.write(item.address, &bytes[..item.len()], t_ns).unwrap();
    }

    fn present(servo: &mut SimServo, t_ns: u64) -> i64 {
        servo.update(t_ns);
        servo.get(servo.model().items.present_position)
    }

    #[test]
    fn feetech_reports_actual_less_offset_and_wraps_at_the_turn() {
        let mut s = SimServo::new(&STS3215, 1, 1_000_000);
        s.set_position(3000, T0);
        assert_eq!(present(&mut s, T0), 3000);
        // LeRobot's half-turn homing: offset = present - 2047 with the offset at 0.
        write(&mut s, sts3215::HOMING_OFFSET, 953, T0);
        assert_eq!(present(&mut s, T0), 2047, "the horn did not move; what it reports did");
        assert_eq!(s.actual_position(T0), 3000.0);
        // A negative offset, sign-magnitude in the register.
        s.set_position(200, T0);
        write(&mut s, sts3215::HOMING_OFFSET, 200 - 2047, T0);
        assert_eq!(s.table()[31..33], [0x37, 0x0F], "1847 with bit 11 set, little-endian");
        assert_eq!(present(&mut s, T0), 2047);
        // Turned back past the encoder's 0: the corrected position goes on smoothly.
        s.hand_move(200, -96, 0.0, T0).unwrap();
        assert_eq!(present(&mut s, T0), 1751);
        s.hand_move(4000, 4000, 0.0, T0).unwrap();
        assert_eq!(present(&mut s, T0), 1751, "4000 is -96 on a single-turn encoder");
    }

    #[test]
    fn feetech_goals_and_limits_are_in_the_corrected_frame() {
        let mut s = SimServo::new(&STS3215, 1, 1_000_000);
        s.set_position(3000, T0);
        write(&mut s, sts3215::HOMING_OFFSET, 953, T0);
        write(&mut s, sts3215::MAX_POSITION_LIMIT, 2500, T0);
        write(&mut s, sts3215::TORQUE_ENABLE, 1, T0);
        assert_eq!(s.get(sts3215::GOAL_POSITION), 2047, "torque on holds the present position");
        write(&mut s, sts3215::GOAL_POSITION, 3000, T0);
        let end = s.move_end_ns().expect("moving");
        assert_eq!(present(&mut s, end), 2500, "clamped to the limit, which is corrected");
        assert_eq!(s.actual_position(end), 3453.0);
    }

    #[test]
    fn dynamixel_reports_actual_plus_offset_and_ignores_big_ones_in_position_mode() {
        let mut s = SimServo::new(&XL430_W250, 1, 57_600);
        s.set_position(2500, T0);
        write(&mut s, xseries::HOMING_OFFSET, 2047 - 2500, T0);
        assert_eq!(present(&mut s, T0), 2047);
        // Beyond +-1024 in position control mode (3, the factory's): held, not applied.
        write(&mut s, xseries::HOMING_OFFSET, -1500, T0);
        assert_eq!(s.get(xseries::HOMING_OFFSET), -1500);
        assert_eq!((s.homing_offset(), present(&mut s, T0)), (0, 2500));
        // Extended position mode (4) applies it, and does not wrap.
        write(&mut s, xseries::OPERATING_MODE, 4, T0);
        assert_eq!(present(&mut s, T0), 1000);
        write(&mut s, xseries::HOMING_OFFSET, 1800, T0);
        assert_eq!(present(&mut s, T0), 4300);
    }

    #[test]
    fn dynamixel_goals_beyond_the_corrected_limits_are_refused_and_others_reached() {
        let mut s = SimServo::new(&XL430_W250, 1, 57_600);
        s.set_position(2500, T0);
        write(&mut s, xseries::HOMING_OFFSET, -453, T0);
        write(&mut s, xseries::MAX_POSITION_LIMIT, 3000, T0);
        write(&mut s, xseries::TORQUE_ENABLE, 1, T0);
        let mut bytes = [0u8; 4];
        xseries::GOAL_POSITION.encode(3001, s.model().endian, &mut bytes).unwrap();
        assert_eq!(s.write(xseries::GOAL_POSITION.address, &bytes, T0), Err(error::DATA_LIMIT));
        write(&mut s, xseries::GOAL_POSITION, 3000, T0);
        let end = s.move_end_ns().expect("moving");
        assert_eq!(present(&mut s, end), 3000);
        assert_eq!(s.actual_position(end), 3453.0);
    }

    #[test]
    fn a_hand_turns_a_limp_horn_steadily_and_not_a_held_one() {
        let mut s = SimServo::new(&STS3215, 2, 1_000_000);
        write(&mut s, sts3215::HOMING_OFFSET, -47, T0);
        let end = s.hand_move(1000, 3000, 2.0, T0).unwrap();
        assert_eq!(end, 2_000_000_000);
        assert_eq!(present(&mut s, T0), 1047);
        assert_eq!(present(&mut s, 500_000_000), 1547);
        assert_eq!(present(&mut s, end), 3047);
        assert_eq!(present(&mut s, end + 1_000_000_000), 3047, "it stays where the hand left it");
        assert_eq!(s.get(sts3215::MOVING), 0, "the servo itself is not moving");
        write(&mut s, sts3215::TORQUE_ENABLE, 1, end);
        assert!(s.hand_move(3000, 1000, 1.0, end).unwrap_err().contains("torque on"));
        assert_eq!(s.position_read_ns(), None);
        s.execute(&Instruction::Read { address: 56, length: 2 }, end).unwrap();
        s.note_read(40, 1, end + 5);
        assert_eq!(s.position_read_ns(), Some(end), "a read of another item does not count");
    }

    #[test]
    fn registers_set_readings_that_stay_through_ticks_and_reboots() {
        let mut s = SimServo::new(&STS3215, 1, 1_000_000);
        s.set_register(sts3215::PRESENT_VOLTAGE, 120, T0).unwrap();
        s.set_register(sts3215::PRESENT_TEMPERATURE, 75, T0).unwrap();
        s.set_register(sts3215::FIRMWARE_MINOR_VERSION, 9, T0).unwrap();
        s.set_register(sts3215::RETURN_DELAY_TIME, 0, T0).unwrap();
        s.update(1_000_000_000);
        assert_eq!((s.get(sts3215::PRESENT_VOLTAGE), s.get(sts3215::PRESENT_TEMPERATURE)), (120, 75));
        s.reboot(2_000_000_000);
        assert_eq!(s.get(sts3215::PRESENT_VOLTAGE), 120, "a 12 V supply outlives a reboot");
        assert_eq!(s.get(sts3215::FIRMWARE_MINOR_VERSION), 9);
        assert_eq!(s.get(sts3215::RETURN_DELAY_TIME), 0, "EEPROM kept by a reboot");
        s.factory_reset(0xFF, 3_000_000_000);
        assert_eq!((s.get(sts3215::PRESENT_TEMPERATURE), s.get(sts3215::RETURN_DELAY_TIME)), (75, 250));
        // Dynamixel's ping carries the table's model number and firmware.
        let mut d = SimServo::new(&XL430_W250, 1, 57_600);
        d.set_register(xseries::FIRMWARE_VERSION, 38, T0).unwrap();
        d.set_register(xseries::MODEL_NUMBER, 1020, T0).unwrap();
        assert_eq!(d.ping_params(), [0xFC, 0x03, 38]);
    }

    #[test]
    fn a_registered_goal_moves_nothing_until_torque_comes_on_and_then_is_driven_to() {
        let mut s = SimServo::new(&STS3215, 1, 1_000_000);
        s.set_register(sts3215::GOAL_POSITION, 100, T0).unwrap();
        assert_eq!((present(&mut s, 1_000_000_000), s.get(sts3215::GOAL_POSITION)), (2048, 100), "a stale goal");
        assert_eq!(s.goal_writes(), 0, "not a write from the bus");
        // Torque on by register: no goal := present, the servo drives to its goal.
        s.set_register(sts3215::TORQUE_ENABLE, 1, 1_000_000_000).unwrap();
        let end = s.move_end_ns().expect("driving to the stale goal");
        assert_eq!((present(&mut s, end), s.get(sts3215::GOAL_POSITION)), (100, 100));
        // The other order gives the same: torque first, then the goal.
        let mut s = SimServo::new(&XL430_W250, 1, 57_600);
        s.set_register(xseries::TORQUE_ENABLE, 1, T0).unwrap();
        assert!(s.move_end_ns().is_none(), "holding: its goal is where it stands");
        s.set_register(xseries::GOAL_POSITION, 3000, T0).unwrap();
        let end = s.move_end_ns().expect("moving");
        assert_eq!(present(&mut s, end), 3000);
        s.set_register(xseries::TORQUE_ENABLE, 0, end).unwrap();
        assert!(!s.torque());
    }

    #[test]
    fn registers_place_horns_raise_errors_and_refuse_what_they_cannot_set() {
        let mut s = SimServo::new(&XL430_W250, 1, 57_600);
        s.set_register(xseries::HOMING_OFFSET, 100, T0).unwrap();
        s.set_register(xseries::PRESENT_POSITION, 1000, T0).unwrap();
        assert_eq!((present(&mut s, T0), s.actual_position(T0)), (1000, 900.0), "the horn placed where it reads 1000");
        s.set_register(xseries::HARDWARE_ERROR_STATUS, 0x04, T0).unwrap();
        assert_eq!(s.status_error(0), ALERT);
        s.set_register(xseries::TORQUE_ENABLE, 1, T0).unwrap();
        assert!(!s.torque(), "protection keeps torque off");
        assert!(s.set_register(xseries::MOVING, 1, T0).unwrap_err().contains("cannot be set"));
        let err = s.set_register(xseries::STATUS_RETURN_LEVEL, 256, T0).unwrap_err();
        assert_eq!(err, "256 does not fit status_return_level (it holds 0 to 255)");
        let err = SimServo::new(&STS3215, 1, 1_000_000).set_register(xseries::PRESENT_POSITION, 0, T0).unwrap_err();
        assert!(err.contains("STS3215 has no present_position"), "{err}");
    }
}
