//! The simulated bus: servos sharing one line, fed instruction bytes, answering on a virtual
//! timeline.
//!
//! Timing follows the wire: a byte takes 10 bits at the baud rate ([`wire_time_ns`]); a servo starts
//! its reply its return delay after the instruction's last byte; in a sync or bulk read each servo
//! starts its return delay after the previous reply ended, in the order asked (a silent servo's turn
//! is skipped); a broadcast ping is answered by every servo in id order the same way. A Dynamixel
//! fast sync read gets one combined reply, starting after the first servo's return delay; a servo
//! missing from its chain cuts the reply short there, as on the real bus.
//!
//! The line is open-drain: replies that overlap in time (two servos with one id) collide, and
//! each byte on the wire is the bitwise AND of the bytes sent in the same byte time.

use firmware::bus::dxl2::encode_fast_sync_read_status;
use firmware::bus::instruction::{bulk_read_records, bulk_write_records, sync_write_records};
use firmware::bus::stream::StreamDecoder;
use firmware::bus::table::Model;
use firmware::bus::timing::wire_time_ns;
use firmware::bus::{Instruction, InstructionPacket, ParseError, Protocol, Status, BROADCAST};

use super::contact::ContactModel;
use super::drive_models::drive_model;
use super::faults::{FaultState, Faults};
use super::physics::Physics;
use super::servo::{error, SimServo};

/// The longest gap between the bytes of one instruction packet (e-manual: 1.5 ms); after it a
/// servo drops a partial packet.
pub const INTER_BYTE_TIMEOUT_NS: u64 = 1_500_000;

/// A byte of a reply and when its stop bit has arrived at the master, in virtual nanoseconds.
pub type WireByte = (u64, u8);

/// What the bus has seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Instruction packets decoded.
    pub instructions: u64,
    /// Status packets sent (before collisions and byte faults).
    pub replies: u64,
    /// Bytes that collided with another servo's.
    pub collisions: u64,
    /// Group reads decoded (sync read, bulk read, fast sync read): the reads a control tick
    /// starts with.
    pub group_reads: u64,
}

/// One instruction frame the bus has just carried out, for an observer that looks at the servos
/// after each ([`SimBus::receive_observed`]), in the order they came, however many one burst held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// When its last byte arrived, in virtual nanoseconds.
    pub t_ns: u64,
    /// Whether it was a group read of the present position: the read a control tick starts with.
    pub reads_position: bool,
}

/// A reply as one servo puts it on the wire.
struct Pending {
    start_ns: u64,
    bytes: Vec<u8>,
}

/// A bus of simulated servos of one model.
#[derive(Clone, Debug)]
pub struct SimBus {
    protocol: Protocol,
    model: &'static Model,
    baud: u32,
    servos: Vec<SimServo>,
    decoder: StreamDecoder<1024>,
    faults: FaultState,
    now_ns: u64,
    last_rx_ns: u64,
    /// The gap after which a partial packet is dropped ([`INTER_BYTE_TIMEOUT_NS`] unless changed).
    inter_byte_timeout_ns: u64,
    /// Bytes handed to the decoder so far.
    fed: u64,
    /// The index (in `fed`) of the last byte flipped on the line.
    last_flip_at: Option<u64>,
    /// The index of the last byte fed right after a lost one: a frame was corrupted by the loss
    /// if that byte and the one before it are both inside it.
    last_gap_at: Option<u64>,
    /// A byte was lost just before the next one fed.
    lost_before: bool,
    /// Whether the frame being carried out was corrupted.
    corrupted: bool,
    stats: BusStats,
    /// Whether the frame being carried out is a group read of the present position.
    reads_position: bool,
    /// The arm's geometry, when its links can run into something.
    contact: Option<ContactModel>,
    /// The servos' drives and the arm's load on them ([`super::physics`]); `None`: ideal servos
    /// that follow their profiles exactly.
    physics: Option<Physics>,
}

impl SimBus {
    /// Servos of `model` with `ids` on a bus at `baud`, no faults.
    ///
    /// # Panics
    /// When `model` does not speak `protocol` (a programming error; the CLI checks it first).
    pub fn new(protocol: Protocol, model: &'static Model, ids: &[u8], baud: u32) -> Self {
        assert_eq!(model.protocol, protocol, "{} does not speak {}", model.name, protocol.name());
        Self {
            protocol,
            model,
            baud,
            servos: ids.iter().map(|&id| SimServo::new(model, id, baud)).collect(),
            decoder: StreamDecoder::new(protocol),
            faults: FaultState::new(Faults::default()),
            now_ns: 0,
            last_rx_ns: 0,
            inter_byte_timeout_ns: INTER_BYTE_TIMEOUT_NS,
            fed: 0,
            last_flip_at: None,
            last_gap_at: None,
            lost_before: false,
            corrupted: false,
            stats: BusStats::default(),
            reads_position: false,
            contact: None,
            physics: None,
        }
    }

    /// Sets the gap after which the servos drop a partial packet: longer than the servos' own for a
    /// master whose bytes come with gaps its line does not have (an emulator's UART on a pty);
    /// `u64::MAX` for none, where the gaps between bursts are the reader's own scheduling: then
    /// only [`SimBus::line_idle`] ends a partial packet.
    pub fn set_inter_byte_timeout(&mut self, ns: u64) {
        self.inter_byte_timeout_ns = ns;
    }

    /// The same bus with `faults`.
    pub fn with_faults(mut self, faults: Faults) -> Self {
        self.faults = FaultState::new(faults);
        self
    }

    /// The protocol.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// The servos' model.
    pub fn model(&self) -> &'static Model {
        self.model
    }

    /// The baud rate.
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// Changes the line's baud rate (the master switched): only servos set to it hear from now on.
    pub fn set_baud(&mut self, baud: u32) {
        self.baud = baud;
    }

    /// The time of the bus's motion, in virtual nanoseconds.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Counters so far.
    pub fn stats(&self) -> BusStats {
        self.stats
    }

    /// The faults, to inspect or change them (e.g. [`FaultState::corrupt_next`]).
    pub fn faults(&mut self) -> &mut FaultState {
        &mut self.faults
    }

    /// Every servo, in the order added.
    pub fn servos(&self) -> &[SimServo] {
        &self.servos
    }

    /// The (first) servo with `id`.
    pub fn servo(&self, id: u8) -> Option<&SimServo> {
        self.servos.iter().find(|s| s.id() == id)
    }

    /// The (first) servo with `id`, to change it.
    pub fn servo_mut(&mut self, id: u8) -> Option<&mut SimServo> {
        self.servos.iter_mut().find(|s| s.id() == id)
    }

    /// Every servo, to change them.
    pub fn servos_mut(&mut self) -> &mut [SimServo] {
        &mut self.servos
    }

    /// Adds a servo (e.g. a second one with an id already on the bus).
    pub fn add_servo(&mut self, mut servo: SimServo) {
        if self.physics.is_some() {
            enable_drive(&mut servo, self.now_ns);
        }
        self.servos.push(servo);
    }

    /// Gives every servo its drive and the arm's load ([`super::physics`]); `None`: ideal servos.
    pub fn set_physics(&mut self, physics: Option<Physics>) {
        for servo in &mut self.servos {
            match physics {
                Some(_) => enable_drive(servo, self.now_ns),
                None => servo.disable_drive(),
            }
        }
        self.physics = physics;
    }

    /// The same bus with `physics` ([`SimBus::set_physics`]).
    pub fn with_physics(mut self, physics: Option<Physics>) -> Self {
        self.set_physics(physics);
        self
    }

    /// The physics, if the bus has it.
    pub fn physics(&self) -> Option<&Physics> {
        self.physics.as_ref()
    }

    /// A fresh servo of the bus's model and baud, for [`SimBus::add_servo`].
    pub fn new_servo(&self, id: u8) -> SimServo {
        SimServo::new(self.model, id, self.baud)
    }

    /// The arm's geometry, which stops its servos where its links run into something (`None`:
    /// nothing is in the way of any motion).
    pub fn set_contact(&mut self, contact: Option<ContactModel>) {
        self.contact = contact;
    }

    /// The same bus with `contact` ([`SimBus::set_contact`]).
    pub fn with_contact(mut self, contact: Option<ContactModel>) -> Self {
        self.contact = contact;
        self
    }

    /// The contact model, if the bus has one.
    pub fn contact(&self) -> Option<&ContactModel> {
        self.contact.as_ref()
    }

    /// Moves the servos' motion forward to `t_ns`, stopping those whose links run into something.
    pub fn advance_to(&mut self, t_ns: u64) {
        let from = self.now_ns;
        self.now_ns = self.now_ns.max(t_ns);
        if let Some(contact) = &mut self.contact {
            contact.advance(&mut self.servos, from, self.now_ns);
        }
        if let Some(physics) = &mut self.physics {
            physics.advance(&mut self.servos, self.now_ns);
        }
        for s in &mut self.servos {
            s.update(self.now_ns);
        }
    }

    /// Takes instruction bytes whose last byte arrived at `at_ns` (they were sent back to back
    /// before it) and returns the reply bytes they cause with their arrival times, in time order.
    pub fn receive(&mut self, bytes: &[u8], at_ns: u64) -> Vec<WireByte> {
        self.receive_observed(bytes, at_ns, &mut |_, _| {})
    }

    /// As [`SimBus::receive`], calling `observe` after each frame is carried out, with the bus as
    /// that frame left it: a safety monitor sees every goal write on its own, in order, even when
    /// one burst carries several control ticks' packets.
    pub fn receive_observed(
        &mut self,
        bytes: &[u8],
        at_ns: u64,
        observe: &mut dyn FnMut(&SimBus, Frame),
    ) -> Vec<WireByte> {
        let first_ns = at_ns.saturating_sub(wire_time_ns(bytes.len(), self.baud));
        let mut pending = Vec::new();
        if first_ns.saturating_sub(self.last_rx_ns) > self.inter_byte_timeout_ns {
            self.expire_partial(&mut pending, observe);
        }
        self.last_rx_ns = at_ns;
        for (k, &sent) in bytes.iter().enumerate() {
            let Some(b) = self.faults.on_byte(sent) else {
                self.lost_before = true;
                continue;
            };
            if b != sent {
                self.last_flip_at = Some(self.fed);
            }
            if std::mem::take(&mut self.lost_before) {
                self.last_gap_at = Some(self.fed);
            }
            self.fed += 1;
            self.decoder.extend(&[b]);
            let t = first_ns + wire_time_ns(k + 1, self.baud);
            while let Some(frame) = self.decoder.next_frame() {
                let mut frame = frame.to_vec();
                // The frame ends at the byte just fed and began `wire_len` bytes before.
                let start = self.fed.saturating_sub(self.wire_len(&frame));
                self.corrupted =
                    self.last_flip_at.is_some_and(|at| at >= start) || self.last_gap_at.is_some_and(|at| at > start);
                self.advance_to(t);
                self.stats.instructions += 1;
                self.handle(&mut frame, t, &mut pending);
                observe(self, Frame { t_ns: t, reads_position: self.reads_position });
            }
        }
        self.stats.replies += pending.len() as u64;
        self.lay_on_wire(pending)
    }

    /// The line has been quiet since the last byte received: [`INTER_BYTE_TIMEOUT_NS`] after it,
    /// the servos drop whatever incomplete packet they hold (a packet cut short, a header-like
    /// pattern in noise) and carry out the complete packets that were held behind it. Returns the
    /// replies those cause. Call it when the line goes quiet (after a burst in memory, on a read
    /// timeout on a pty); it does nothing when no partial packet is held.
    pub fn line_idle(&mut self) -> Vec<WireByte> {
        self.line_idle_observed(&mut |_, _| {})
    }

    /// As [`SimBus::line_idle`], calling `observe` after each frame (see
    /// [`SimBus::receive_observed`]).
    pub fn line_idle_observed(&mut self, observe: &mut dyn FnMut(&SimBus, Frame)) -> Vec<WireByte> {
        let mut pending = Vec::new();
        self.expire_partial(&mut pending, observe);
        self.stats.replies += pending.len() as u64;
        self.lay_on_wire(pending)
    }

    fn expire_partial(&mut self, pending: &mut Vec<Pending>, observe: &mut dyn FnMut(&SimBus, Frame)) {
        if !self.decoder.holds_partial() {
            return;
        }
        // Without a gap timeout (a pty's), the packet died the servos' own timeout after its
        // last byte.
        let gap =
            if self.inter_byte_timeout_ns == u64::MAX { INTER_BYTE_TIMEOUT_NS } else { self.inter_byte_timeout_ns };
        let t = self.last_rx_ns.saturating_add(gap);
        self.decoder.expire();
        while let Some(frame) = self.decoder.next_frame() {
            let mut frame = frame.to_vec();
            self.advance_to(t);
            self.stats.instructions += 1;
            self.corrupted = false;
            self.handle(&mut frame, t, pending);
            observe(self, Frame { t_ns: t, reads_position: self.reads_position });
        }
        // Nothing held now is waiting for more bytes: the next burst starts afresh.
        self.last_rx_ns = t;
    }

    /// Bytes `frame` took on the wire: Dynamixel stuffs a 0xFD after every `FF FF FD` past the
    /// header, which the decoder has taken out again.
    fn wire_len(&self, frame: &[u8]) -> u64 {
        let stuffed = match self.protocol {
            Protocol::Dxl2 => {
                frame.get(4..).map_or(0, |body| body.windows(3).filter(|w| w == &[0xFF, 0xFF, 0xFD]).count())
            }
            Protocol::Feetech => 0,
        };
        (frame.len() + stuffed) as u64
    }

    /// Carries out one instruction frame, telling the servos whether the line corrupted it (for
    /// the safety monitor; frames released by [`SimBus::line_idle`] count as clean).
    fn handle(&mut self, frame: &mut [u8], t: u64, out: &mut Vec<Pending>) {
        let corrupted = std::mem::take(&mut self.corrupted);
        self.reads_position = false;
        for s in &mut self.servos {
            s.set_in_corrupted_packet(corrupted);
        }
        let protocol = self.protocol;
        let id_at = if protocol == Protocol::Dxl2 { 4 } else { 2 };
        let target = frame.get(id_at).copied().unwrap_or(BROADCAST);
        let packet = match protocol.parse_instruction(frame) {
            Ok(p) => p,
            Err(ParseError::UnknownInstruction { .. } | ParseError::BadParameters { .. })
                if protocol == Protocol::Dxl2 && target != BROADCAST =>
            {
                // A Dynamixel servo answers what it cannot carry out with an instruction error.
                for i in 0..self.servos.len() {
                    if self.servos[i].id() == target && self.servos[i].baud() == Some(self.baud) {
                        self.send(i, target, t, Err(error::INSTRUCTION), out);
                    }
                }
                return;
            }
            Err(_) => return,
        };
        let InstructionPacket { id, instruction } = packet;
        let position = self.model.items.present_position.address;
        let reads_position = match &instruction {
            Instruction::SyncRead { address, .. } | Instruction::FastSyncRead { address, .. } => {
                Some(*address == position)
            }
            Instruction::BulkRead { records } => {
                Some(bulk_read_records(records).into_iter().flatten().any(|r| r.address == position))
            }
            _ => None,
        };
        if let Some(reads_position) = reads_position {
            self.stats.group_reads += 1;
            self.reads_position = reads_position;
        }
        match instruction {
            Instruction::Ping if id == BROADCAST => {
                let mut order: Vec<usize> = (0..self.servos.len()).collect();
                order.sort_by_key(|&i| self.servos[i].id());
                let mut cursor = t;
                for i in order {
                    if let Some(end) = self.reply_from(i, cursor, Ok(self.servos[i].ping_params()), out) {
                        cursor = end;
                    }
                }
            }
            Instruction::SyncWrite { address, length, data } => {
                for record in sync_write_records(length, data).into_iter().flatten() {
                    self.each_listening(record.id, |s| {
                        let _ = s.write(address, record.data, t);
                    });
                }
            }
            Instruction::BulkWrite { records } => {
                for record in bulk_write_records(records).map_while(Result::ok) {
                    self.each_listening(record.id, |s| {
                        let _ = s.write(record.address, record.data, t);
                    });
                }
            }
            Instruction::SyncRead { address, length, ids } => {
                let asked: Vec<_> = ids.iter().map(|&id| (id, address, length)).collect();
                self.group_read(&asked, t, out);
            }
            Instruction::BulkRead { records } => {
                let asked: Vec<_> =
                    bulk_read_records(records).into_iter().flatten().map(|r| (r.id, r.address, r.length)).collect();
                self.group_read(&asked, t, out);
            }
            Instruction::FastSyncRead { address, length, ids } => self.fast_sync_read(address, length, ids, t, out),
            _ if id == BROADCAST => {
                for s in self.servos.iter_mut().filter(|s| s.baud() == Some(self.baud)) {
                    let _ = s.execute(&instruction, t);
                }
            }
            _ => self.unicast(id, &instruction, t, out),
        }
    }

    /// Runs `f` on every listening servo with `id`.
    fn each_listening(&mut self, id: u8, mut f: impl FnMut(&mut SimServo)) {
        let baud = self.baud;
        for s in self.servos.iter_mut().filter(|s| s.id() == id && s.baud() == Some(baud)) {
            f(s);
        }
    }

    /// A unicast instruction: every listening servo with `id` carries it out and answers after its
    /// return delay, if its status return level says so.
    fn unicast(&mut self, id: u8, instruction: &Instruction<'_>, t: u64, out: &mut Vec<Pending>) {
        for i in 0..self.servos.len() {
            let s = &self.servos[i];
            if s.id() != id || s.baud() != Some(self.baud) {
                continue;
            }
            // Decided before carrying it out: a write may change the return level itself, and the
            // reply of a factory reset still comes from the old id.
            let answers = s.answers(instruction);
            let result = self.servos[i].execute(instruction, t);
            if answers {
                self.send(i, id, t, result, out);
            }
        }
    }

    /// Sync or bulk read of `(id, address, length)` in turn: each servo answers its return delay
    /// after the previous reply ended.
    fn group_read(&mut self, asked: &[(u8, u16, u16)], t: u64, out: &mut Vec<Pending>) {
        let read = Instruction::Read { address: 0, length: 0 };
        let mut cursor = t;
        for &(id, address, length) in asked {
            let mut end = None;
            for i in 0..self.servos.len() {
                let s = &self.servos[i];
                if s.id() != id || s.baud() != Some(self.baud) || !s.answers(&read) {
                    continue;
                }
                let result = s.read(address, length);
                self.servos[i].note_read(address, length, cursor);
                // Two servos with one id both take the turn: their replies overlap.
                end = end.max(self.send(i, id, cursor, result, out));
            }
            if let Some(end) = end {
                cursor = end;
            }
        }
    }

    /// Dynamixel fast sync read: one packet, the servos' parts chained in the order asked.
    fn fast_sync_read(&mut self, address: u16, length: u16, ids: &[u8], t: u64, out: &mut Vec<Pending>) {
        let read = Instruction::Read { address: 0, length: 0 };
        let zeros = vec![0u8; usize::from(length)];
        let mut data: Vec<(u8, u8, Vec<u8>)> = Vec::new();
        let mut present = 0;
        let mut first = None;
        for &id in ids {
            let found = self.servos.iter().position(|s| s.id() == id && s.baud() == Some(self.baud));
            let part = match found {
                Some(i) if present == data.len() && self.servos[i].answers(&read) && !self.faults.is_silent(id) => {
                    present += 1;
                    first.get_or_insert(i);
                    self.servos[i].note_read(address, length, t);
                    let s = &self.servos[i];
                    match s.read(address, length) {
                        Ok(d) => (s.status_error(0), id, d),
                        Err(n) => (s.status_error(n), id, zeros.clone()),
                    }
                }
                _ => (0, id, zeros.clone()),
            };
            data.push(part);
        }
        let Some(first) = first else { return };
        let parts: Vec<(u8, u8, &[u8])> = data.iter().map(|(e, id, d)| (*e, *id, d.as_slice())).collect();
        let mut buf = vec![0u8; 8 + parts.len() * (usize::from(length) + 4)];
        let Ok(n) = encode_fast_sync_read_status(&parts, &mut buf) else { return };
        // A servo missing from the chain cuts the packet after the parts before it.
        buf.truncate(n.min(8 + present * (usize::from(length) + 4)));
        self.faults.on_reply(BROADCAST, &mut buf, 7);
        out.push(Pending { start_ns: t + self.servos[first].return_delay_ns(), bytes: buf });
    }

    /// Servo `i` answers with `result` its return delay after `t`; returns when its reply ends.
    fn reply_from(&mut self, i: usize, t: u64, result: Result<Vec<u8>, u8>, out: &mut Vec<Pending>) -> Option<u64> {
        let s = &self.servos[i];
        if s.baud() != Some(self.baud) {
            return None;
        }
        let id = s.id();
        self.send(i, id, t, result, out)
    }

    fn send(&mut self, i: usize, id: u8, t: u64, result: Result<Vec<u8>, u8>, out: &mut Vec<Pending>) -> Option<u64> {
        if self.faults.is_silent(id) {
            return None;
        }
        let s = &self.servos[i];
        let (error, params) = match result {
            Ok(data) => (s.status_error(0), data),
            Err(n) => (s.status_error(n), Vec::new()),
        };
        let mut buf = vec![0u8; params.len() * 2 + 16];
        let n = self.protocol.encode_status(&Status { id, error, params: &params }, &mut buf).ok()?;
        buf.truncate(n);
        let body = if self.protocol == Protocol::Dxl2 { 7 } else { 4 };
        self.faults.on_reply(id, &mut buf, body);
        let start_ns = t + s.return_delay_ns();
        let end = start_ns + wire_time_ns(buf.len(), self.baud);
        out.push(Pending { start_ns, bytes: buf });
        Some(end)
    }
}

impl SimBus {
    /// Lays replies on the wire: each byte arrives one byte time after the one before; bytes sent
    /// in the same byte time by two servos collide (bitwise AND, the open-drain line); then the
    /// per-byte faults.
    fn lay_on_wire(&mut self, pending: Vec<Pending>) -> Vec<WireByte> {
        let mut bytes: Vec<WireByte> = pending
            .iter()
            .flat_map(|p| p.bytes.iter().enumerate().map(|(k, &b)| (p.start_ns + wire_time_ns(k + 1, self.baud), b)))
            .collect();
        bytes.sort_by_key(|&(t, _)| t);
        let byte_ns = wire_time_ns(1, self.baud);
        let mut merged: Vec<WireByte> = Vec::with_capacity(bytes.len());
        for (t, b) in bytes {
            match merged.last_mut() {
                // Back-to-back bytes of one reply are a byte time apart give or take the 1 ns of
                // rounding (`wire_time_ns` rounds up, and 10 bits rarely take whole nanoseconds):
                // only bytes closer than that overlap.
                Some((last_t, last_b)) if t - *last_t + 1 < byte_ns => {
                    *last_b &= b;
                    self.stats.collisions += 1;
                }
                _ => merged.push((t, b)),
            }
        }
        merged.into_iter().filter_map(|(t, b)| self.faults.on_byte(b).map(|b| (t, b))).collect()
    }
}

/// Gives `servo` the drive of its model at the supply it reads (no drive for a model without one).
fn enable_drive(servo: &mut SimServo, t_ns: u64) {
    let volts = servo.get(super::drive_models::DriveRegisters::of(servo.model()).voltage()) as f64 / 10.0;
    if let Some(model) = drive_model(servo.model(), volts) {
        servo.enable_drive(model, t_ns);
    }
}
