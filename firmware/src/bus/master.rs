//! The bus master: one transaction at a time over an `embedded-io` serial port.
//!
//! A transaction sends one instruction packet and, where the protocol and the servos' status
//! return level say a reply comes, waits for it. The wait is bounded by a timeout computed for that
//! transaction: the wire time of the bytes expected at the baud rate, plus each replying servo's
//! return delay, plus a margin (the servo's processing time and, on a PC, the USB adapter's
//! latency). A timeout or a corrupt reply is retried; a sync read retries only the servos that did
//! not answer and reports those that still did not, instead of failing the whole read. A fast sync
//! read is retried whole; a bulk read makes one attempt and reports who answered.
//!
//! A quiet line ends a packet: when no byte has come for [`BusConfig::idle_gap_us`] while the
//! decoder holds an incomplete frame, that frame is dropped and the replies behind it are read.
//!
//! Half-duplex adapters have a direction pin: it is set high (transmit) before the first byte
//! and low (receive) after the port's `flush`, which must return only once the last byte has left
//! the UART (transmission complete, not just "buffer empty"). Adapters that echo what they send
//! are handled by [`BusConfig::echo`].

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};

use super::instruction::{BulkReadRecord, Instruction, InstructionPacket};
use super::protocol::ErrorText;
use super::stream::StreamDecoder;
use super::timing::wire_time_us;
use super::{EncodeError, Id, Protocol, Status, BROADCAST};

/// A monotonic time source in microseconds (a hardware timer on a board, a virtual clock in
/// simulation, `std::time::Instant` on a PC).
pub trait Clock {
    /// Microseconds since an arbitrary start; never decreases.
    fn now_us(&mut self) -> u64;
}

/// The direction pin of an adapter that needs none (full duplex, or one that switches by itself).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoDirectionPin;

impl embedded_hal::digital::ErrorType for NoDirectionPin {
    type Error = core::convert::Infallible;
}

impl OutputPin for NoDirectionPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Which instructions the servos answer: their status return level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Replies {
    /// Every instruction addressed to one servo (Dynamixel level 2, Feetech level 1; the factory
    /// setting of both).
    All,
    /// Ping and reads only (Dynamixel level 1, Feetech level 0).
    Reads,
    /// Ping only (Dynamixel level 0).
    PingOnly,
}

/// The return delay both protocols' servos leave the factory with: 250 units of 2 µs.
pub const FACTORY_RETURN_DELAY_US: u32 = 500;

/// How the bus is run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusConfig {
    /// The protocol spoken.
    pub protocol: Protocol,
    /// Baud rate of the port (for timeouts).
    pub baud: u32,
    /// The longest return delay of the servos on the bus, in microseconds.
    pub return_delay_us: u32,
    /// Added to every timeout: servo processing time, and on a PC the USB adapter's latency.
    pub margin_us: u32,
    /// How long the line may stay quiet in the middle of a packet before the bytes held are
    /// judged dead (see [`super::stream::StreamDecoder::expire`]): a few byte times on a
    /// microcontroller's UART, the adapter's latency on a PC, where a packet can arrive in two USB
    /// transfers.
    pub idle_gap_us: u32,
    /// Extra attempts after a timeout or a corrupt reply.
    pub retries: u8,
    /// Which instructions the servos answer.
    pub replies: Replies,
    /// The adapter hears its own transmission (one wire, receiver not gated): that many bytes are
    /// skipped after each send.
    pub echo: bool,
}

impl BusConfig {
    /// The factory settings of the protocol's servos (return delay 500 µs on both: Dynamixel X
    /// and Feetech STS3215 ship with 250 units of 2 µs, see the models' `DEFAULTS`; replies to
    /// everything), a 1 ms margin, 2 retries, and an idle gap of three byte times (at least
    /// 100 µs): the figures of a microcontroller's own UART, whose firmware writes no set-up to the
    /// servos. On a PC raise `margin_us` and `idle_gap_us` to the USB adapter's latency, and lower
    /// `return_delay_us` once the servos are set up.
    pub fn new(protocol: Protocol, baud: u32) -> Self {
        let return_delay_us = FACTORY_RETURN_DELAY_US;
        let idle_gap_us = wire_time_us(3, baud).max(100) as u32;
        Self {
            protocol,
            baud,
            return_delay_us,
            margin_us: 1000,
            idle_gap_us,
            retries: 2,
            replies: Replies::All,
            echo: false,
        }
    }
}

/// What a servo's reply said besides its data.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Answer {
    /// A reply came (false when the status return level says none comes).
    pub replied: bool,
    /// The servo reports a hardware fault (Dynamixel alert bit; any Feetech error bit). The
    /// instruction was carried out; the fault's description is [`Protocol::describe_error`].
    pub alert: Option<u8>,
}

/// A ping's reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PingInfo {
    /// Model number (Dynamixel replies carry it; on Feetech read the model item).
    pub model: Option<u16>,
    /// Firmware version (Dynamixel).
    pub firmware: Option<u8>,
    /// The error byte, when it reports a hardware fault.
    pub alert: Option<u8>,
}

/// The most servos one sync read, fast sync read or bulk read may address here (bit masks of the
/// report are 32 bits wide). An arm has far fewer.
pub const MAX_GROUP: usize = 32;

/// The outcome of a sync or bulk read, servo by servo (bit `i` is the `i`-th id asked).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GroupReport {
    /// Servos asked.
    pub count: usize,
    /// Servos whose data arrived.
    pub answered: u32,
    /// Servos that replied with a hardware fault (their data did arrive).
    pub alerts: u32,
    /// Servos that refused the instruction (Dynamixel error number; no data).
    pub failed: u32,
    /// Attempts made (1 + retries used).
    pub attempts: u8,
}

impl GroupReport {
    /// Whether every servo's data arrived.
    pub fn complete(&self) -> bool {
        self.count <= 32 && self.answered == mask(self.count)
    }

    /// The ids, among `ids` (the ones asked, in order), whose data did not arrive.
    pub fn missing<'a>(&self, ids: &'a [Id]) -> impl Iterator<Item = Id> + 'a {
        let answered = self.answered;
        ids.iter()
            .enumerate()
            .filter(move |(i, _)| answered & 1u32.checked_shl(*i as u32).unwrap_or(0) == 0)
            .map(|(_, id)| *id)
    }
}

impl GroupReport {
    /// Books servo `i`'s reply (`error` byte and `data`) into the report and its `slot` of the
    /// output; false when it does not count (already booked, or data of the wrong size).
    fn book(&mut self, i: usize, protocol: Protocol, error: u8, data: &[u8], slot: &mut [u8]) -> bool {
        let bit = 1u32 << i;
        if (self.answered | self.failed) & bit != 0 {
            return false;
        }
        let (refused, alert) = classify(protocol, error);
        if refused {
            self.failed |= bit;
        } else if data.len() == slot.len() {
            slot.copy_from_slice(data);
            self.answered |= bit;
            if alert.is_some() {
                self.alerts |= bit;
            }
        } else {
            return false;
        }
        true
    }
}

/// Until `pending` reaches zero, more replies are awaited.
fn countdown(pending: &mut usize) -> Flow {
    *pending = pending.saturating_sub(1);
    if *pending == 0 {
        Flow::Done
    } else {
        Flow::More
    }
}

fn mask(count: usize) -> u32 {
    if count >= 32 {
        u32::MAX
    } else {
        (1u32 << count) - 1
    }
}

/// Counters of a master, for link statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MasterStats {
    /// Instruction packets sent, retries included.
    pub packets_sent: u32,
    /// Bytes sent.
    pub bytes_sent: u64,
    /// Bytes received.
    pub bytes_received: u64,
    /// Retries made.
    pub retries: u32,
    /// Waits that ended without the expected replies.
    pub timeouts: u32,
    /// Received frames with a bad checksum.
    pub bad_checksums: u32,
    /// Valid frames that were not an expected reply (another id, an echo, a stray packet).
    pub ignored: u32,
}

/// Why a transaction failed. `E` is the serial port's error type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterError<E> {
    /// The serial port failed.
    Io(E),
    /// The direction pin could not be switched.
    DirectionPin,
    /// The instruction could not be encoded (nothing was sent).
    Encode(EncodeError),
    /// No valid reply within the timeout, on every attempt.
    NoReply {
        /// The servo.
        id: Id,
        /// The instruction.
        instruction: &'static str,
        /// The timeout of one attempt, in microseconds.
        timeout_us: u64,
        /// Attempts made.
        attempts: u8,
        /// Replies that arrived with a bad checksum in the meantime.
        corrupt: u32,
    },
    /// The servo refused the instruction (Dynamixel error number in its status).
    Refused {
        /// The servo.
        id: Id,
        /// The raw error byte.
        error: u8,
        /// Its description.
        text: ErrorText,
    },
    /// A reply of the wrong size.
    BadReply {
        /// The servo.
        id: Id,
        /// Data bytes expected.
        expected: usize,
        /// Data bytes received.
        received: usize,
    },
    /// More servos in one group read than [`MAX_GROUP`], or a group's output buffer too small.
    BadRequest {
        /// What is wrong.
        reason: &'static str,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for MasterError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "serial port error: {e:?}"),
            Self::DirectionPin => write!(f, "the bus direction pin could not be switched"),
            Self::Encode(e) => write!(f, "{e}"),
            Self::NoReply { id, instruction, timeout_us, attempts, corrupt } if *corrupt > 0 => write!(
                f,
                "servo {id}: reply to {instruction} had a bad checksum ({corrupt} corrupt replies in {attempts} attempts)"
            ),
            Self::NoReply { id, instruction, timeout_us, attempts, .. } => write!(
                f,
                "servo {id}: no reply to {instruction} ({attempts} attempts, {}.{:03} ms each)",
                timeout_us / 1000,
                timeout_us % 1000
            ),
            Self::Refused { id, text, .. } => write!(f, "servo {id}: {text}"),
            Self::BadReply { id, expected, received } => {
                write!(f, "servo {id}: reply carries {received} data bytes, expected {expected}")
            }
            Self::BadRequest { reason } => write!(f, "{reason}"),
        }
    }
}

/// What to do after a status packet arrives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Flow {
    Done,
    More,
}

/// Splits an error byte: whether the instruction was refused, and the hardware-fault byte if any.
fn classify(protocol: Protocol, error: u8) -> (bool, Option<u8>) {
    match protocol {
        // Bits 0-6 are an error number (the instruction failed); bit 7 is the alert bit.
        Protocol::Dxl2 => (error & 0x7F != 0, (error & 0x80 != 0).then_some(error)),
        // Every Feetech bit is a hardware condition; the instruction was still carried out.
        Protocol::Feetech => (false, (error != 0).then_some(error)),
    }
}

/// A master's packet buffers unless its type says otherwise (bytes).
pub const PACKET_BUF: usize = 256;

/// A bus master over serial port `P`, direction pin `D` and clock `C`, with `BUF`-byte packet
/// buffers (the longest packet sent or received).
#[derive(Debug)]
pub struct Master<P, D, C, const BUF: usize = PACKET_BUF> {
    port: P,
    direction: D,
    clock: C,
    config: BusConfig,
    decoder: StreamDecoder<BUF>,
    tx: [u8; BUF],
    echo_left: usize,
    stats: MasterStats,
}

/// The error type of a master's port.
pub type PortError<P> = MasterError<<P as embedded_io::ErrorType>::Error>;

impl<P, D, C, const BUF: usize> Master<P, D, C, BUF>
where
    P: Read + Write + ReadReady,
    D: OutputPin,
    C: Clock,
{
    /// A master on `port`, switching `direction` (use [`NoDirectionPin`] when there is none).
    pub fn new(port: P, direction: D, clock: C, config: BusConfig) -> Self {
        Self {
            port,
            direction,
            clock,
            config,
            decoder: StreamDecoder::new(config.protocol),
            tx: [0; BUF],
            echo_left: 0,
            stats: MasterStats::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &BusConfig {
        &self.config
    }

    /// Changes the configuration (e.g. after changing the servos' baud rate or return delay).
    pub fn set_config(&mut self, config: BusConfig) {
        self.decoder = StreamDecoder::new(config.protocol);
        self.config = config;
    }

    /// The port, to change what the master does not (its baud rate).
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// Counters so far.
    pub fn stats(&self) -> MasterStats {
        self.stats
    }

    /// The port, clock and direction pin back.
    pub fn release(self) -> (P, D, C) {
        (self.port, self.direction, self.clock)
    }

    /// The clock (the control loop shares the master's time source).
    pub fn clock(&mut self) -> &mut C {
        &mut self.clock
    }

    /// The timeout of a wait for `replies` status packets of `data` bytes each, in microseconds.
    pub fn reply_timeout_us(&self, replies: usize, data: usize) -> u64 {
        let protocol = self.config.protocol;
        let mut bytes = replies * protocol.status_len(data);
        if protocol == Protocol::Dxl2 {
            // Byte stuffing can add one byte per three of data.
            bytes += replies * data.div_ceil(3);
        }
        wire_time_us(bytes, self.config.baud)
            + replies as u64 * u64::from(self.config.return_delay_us)
            + u64::from(self.config.margin_us)
    }

    /// Sends one instruction packet: stale input dropped, direction to transmit, bytes out, wait
    /// for the last byte to leave, direction to receive.
    fn send(&mut self, packet: &InstructionPacket<'_>) -> Result<(), PortError<P>> {
        let n = self.config.protocol.encode_instruction(packet, &mut self.tx).map_err(MasterError::Encode)?;
        // Whatever arrived before this instruction (a late reply to a timed-out one) is not its reply.
        let mut stale = [0u8; 32];
        while self.port.read_ready().map_err(MasterError::Io)? {
            let got = self.port.read(&mut stale).map_err(MasterError::Io)?;
            if got == 0 {
                break;
            }
            self.stats.bytes_received = self.stats.bytes_received.wrapping_add(got as u64);
        }
        self.decoder.clear();
        self.direction.set_high().map_err(|_| MasterError::DirectionPin)?;
        let packet = self.tx.get(..n).ok_or(MasterError::BadRequest { reason: "packet longer than the buffer" })?;
        let sent = self.port.write_all(packet).and_then(|()| self.port.flush());
        // Back to receive even when the write failed, so the bus is not left driven.
        let released = self.direction.set_low();
        sent.map_err(MasterError::Io)?;
        released.map_err(|_| MasterError::DirectionPin)?;
        self.echo_left = if self.config.echo { n } else { 0 };
        self.stats.packets_sent = self.stats.packets_sent.wrapping_add(1);
        self.stats.bytes_sent = self.stats.bytes_sent.wrapping_add(n as u64);
        Ok(())
    }

    /// Feeds received status packets to `on_status` until it says done (`Ok(true)`) or `timeout_us`
    /// passes (`Ok(false)`).
    fn receive(
        &mut self,
        timeout_us: u64,
        mut on_status: impl FnMut(&Status<'_>) -> Flow,
    ) -> Result<bool, PortError<P>> {
        let deadline = self.clock.now_us().saturating_add(timeout_us);
        let checksums_before = self.decoder.stats().bad_checksums;
        let mut chunk = [0u8; 32];
        let mut last_byte = self.clock.now_us();
        let done = 'wait: loop {
            if self.drain(&mut on_status) {
                break 'wait true;
            }
            let now = self.clock.now_us();
            if now >= deadline {
                break 'wait false;
            }
            if !self.port.read_ready().map_err(MasterError::Io)? {
                // A quiet line ends any packet in progress: what is held but incomplete (a cut
                // reply, or a header-like pattern in noise) is dead, and frames behind it are freed.
                if now.saturating_sub(last_byte) >= u64::from(self.config.idle_gap_us) && self.decoder.holds_partial() {
                    self.decoder.expire();
                }
                continue;
            }
            let got = self.port.read(&mut chunk).map_err(MasterError::Io)?;
            last_byte = self.clock.now_us();
            self.stats.bytes_received = self.stats.bytes_received.wrapping_add(got as u64);
            let skip = self.echo_left.min(got);
            self.echo_left -= skip;
            let mut rest = chunk.get(skip..got).unwrap_or_default();
            while !rest.is_empty() {
                let taken = self.decoder.extend(rest);
                rest = rest.get(taken..).unwrap_or_default();
                if !rest.is_empty() && self.drain(&mut on_status) {
                    break 'wait true;
                }
            }
        };
        self.stats.bad_checksums =
            self.stats.bad_checksums.wrapping_add(self.decoder.stats().bad_checksums.wrapping_sub(checksums_before));
        if !done {
            self.stats.timeouts = self.stats.timeouts.wrapping_add(1);
        }
        Ok(done)
    }

    /// Hands every complete frame to `on_status`; true when it says done.
    fn drain(&mut self, on_status: &mut impl FnMut(&Status<'_>) -> Flow) -> bool {
        let protocol = self.config.protocol;
        while let Some(frame) = self.decoder.next_frame() {
            match protocol.parse_status(frame) {
                Ok(status) => {
                    if on_status(&status) == Flow::Done {
                        return true;
                    }
                }
                Err(_) => self.stats.ignored = self.stats.ignored.wrapping_add(1),
            }
        }
        false
    }

    /// Whether a unicast instruction gets a status reply under the configured return level.
    fn expects_reply(&self, id: Id, instruction: &Instruction<'_>) -> bool {
        if id == BROADCAST {
            return false;
        }
        match (self.config.replies, instruction) {
            (_, Instruction::Ping) => true,
            (Replies::PingOnly, _) => false,
            (Replies::Reads, Instruction::Read { .. }) => true,
            (Replies::Reads, _) => false,
            (Replies::All, _) => true,
        }
    }

    /// One instruction to one servo with its single reply, retried; `on_data` takes the reply's
    /// data once it arrives.
    fn unicast(
        &mut self,
        id: Id,
        instruction: Instruction<'_>,
        reply_len: usize,
        mut on_data: impl FnMut(&[u8]) -> Result<(), (usize, usize)>,
    ) -> Result<Answer, PortError<P>> {
        let packet = InstructionPacket { id, instruction };
        if !self.expects_reply(id, &instruction) {
            self.send(&packet)?;
            return Ok(Answer { replied: false, alert: None });
        }
        let timeout_us = self.reply_timeout_us(1, reply_len);
        let checksums_before = self.stats.bad_checksums;
        let protocol = self.config.protocol;
        // A reply of the wrong size: (expected, received) data bytes.
        let mut wrong_size = None;
        for attempt in 0..=self.config.retries {
            if attempt > 0 {
                self.stats.retries = self.stats.retries.wrapping_add(1);
            }
            self.send(&packet)?;
            let mut outcome: Option<Result<Answer, PortError<P>>> = None;
            let replied = self.receive(timeout_us, |status| {
                if status.id != id {
                    return Flow::More;
                }
                let (refused, alert) = classify(protocol, status.error);
                if refused {
                    let text =
                        protocol.describe_error(status.error).unwrap_or(ErrorText { what: "error", alert: false });
                    outcome = Some(Err(MasterError::Refused { id, error: status.error, text }));
                    return Flow::Done;
                }
                match on_data(status.params) {
                    Ok(()) => {
                        outcome = Some(Ok(Answer { replied: true, alert }));
                        Flow::Done
                    }
                    // Most likely a late reply to an earlier instruction (a retried ping's, on
                    // a busy line): this one's may still come, else the next attempt's.
                    Err(sizes) => {
                        wrong_size = Some(sizes);
                        Flow::More
                    }
                }
            })?;
            if let (true, Some(outcome)) = (replied, outcome) {
                return outcome;
            }
        }
        if let Some((expected, received)) = wrong_size {
            return Err(MasterError::BadReply { id, expected, received });
        }
        Err(MasterError::NoReply {
            id,
            instruction: instruction.name(),
            timeout_us,
            attempts: self.config.retries + 1,
            corrupt: self.stats.bad_checksums.wrapping_sub(checksums_before),
        })
    }

    /// Pings one servo.
    pub fn ping(&mut self, id: Id) -> Result<PingInfo, PortError<P>> {
        let mut info = PingInfo { model: None, firmware: None, alert: None };
        let reply_len = match self.config.protocol {
            Protocol::Dxl2 => 3,
            Protocol::Feetech => 0,
        };
        let answer = self.unicast(id, Instruction::Ping, reply_len, |data| {
            if let [m0, m1, fw] = data {
                info.model = Some(u16::from_le_bytes([*m0, *m1]));
                info.firmware = Some(*fw);
            }
            Ok(())
        })?;
        info.alert = answer.alert;
        Ok(info)
    }

    /// Reads `out.len()` bytes of one servo's control table from `address`.
    pub fn read(&mut self, id: Id, address: u16, out: &mut [u8]) -> Result<Answer, PortError<P>> {
        let length = u16::try_from(out.len()).map_err(|_| MasterError::BadRequest { reason: "read too long" })?;
        let want = out.len();
        self.unicast(id, Instruction::Read { address, length }, want, |data| {
            if data.len() != want {
                return Err((want, data.len()));
            }
            // Byte by byte rather than `copy_from_slice`, whose length check the compiler cannot
            // see is the one above (the firmware has no panic path).
            for (o, d) in out.iter_mut().zip(data) {
                *o = *d;
            }
            Ok(())
        })
    }

    /// Writes `data` to one servo's control table from `address` (broadcast: no reply).
    pub fn write(&mut self, id: Id, address: u16, data: &[u8]) -> Result<Answer, PortError<P>> {
        self.command(id, Instruction::Write { address, data })
    }

    /// Registers a write, carried out at the next [`Master::action`].
    pub fn reg_write(&mut self, id: Id, address: u16, data: &[u8]) -> Result<Answer, PortError<P>> {
        self.command(id, Instruction::RegWrite { address, data })
    }

    /// Sends an instruction that carries no data back (action, reboot, factory reset, clear,
    /// reset, write) and waits for its status where one comes.
    pub fn command(&mut self, id: Id, instruction: Instruction<'_>) -> Result<Answer, PortError<P>> {
        self.unicast(id, instruction, 0, |_| Ok(()))
    }

    /// Carries out the registered writes (usually broadcast, which gets no reply).
    pub fn action(&mut self, id: Id) -> Result<Answer, PortError<P>> {
        self.command(id, Instruction::Action)
    }

    /// Writes `length` bytes at `address` of several servos: `records` is `id, data[length]` per
    /// servo (build it with [`super::instruction::RecordWriter`]). Sync writes get no reply.
    pub fn sync_write(&mut self, address: u16, length: u16, records: &[u8]) -> Result<(), PortError<P>> {
        self.send(&InstructionPacket {
            id: BROADCAST,
            instruction: Instruction::SyncWrite { address, length, data: records },
        })
    }

    /// Writes different items of several servos (Dynamixel); no reply.
    pub fn bulk_write(&mut self, records: &[u8]) -> Result<(), PortError<P>> {
        self.send(&InstructionPacket { id: BROADCAST, instruction: Instruction::BulkWrite { records } })
    }

    /// Reads `length` bytes at `address` of each servo in `ids` into `out` (`length` bytes per id,
    /// in the order of `ids`). Servos that do not answer are retried with a sync read of just
    /// them; the report says which never did. Their part of `out` is left as it was.
    pub fn sync_read(
        &mut self,
        address: u16,
        length: u16,
        ids: &[Id],
        out: &mut [u8],
    ) -> Result<GroupReport, PortError<P>> {
        let len = usize::from(length);
        check_group(ids.len(), out.len(), ids.len() * len)?;
        let mut report = GroupReport { count: ids.len(), ..GroupReport::default() };
        let protocol = self.config.protocol;
        let mut asked = [0u8; MAX_GROUP];
        for attempt in 0..=self.config.retries {
            // The servos still missing (all of them on the first attempt), in their order.
            let mut n = 0;
            for (slot, id) in asked.iter_mut().zip(report.missing(ids)) {
                *slot = id;
                n += 1;
            }
            let asked = asked.get(..n).unwrap_or_default();
            if n == 0 {
                break;
            }
            if attempt > 0 {
                self.stats.retries = self.stats.retries.wrapping_add(1);
            }
            report.attempts = attempt + 1;
            let instruction = Instruction::SyncRead { address, length, ids: asked };
            self.send(&InstructionPacket { id: BROADCAST, instruction })?;
            let timeout_us = self.reply_timeout_us(n, len);
            let mut pending = n;
            self.receive(timeout_us, |status| {
                let Some(i) = ids.iter().position(|&id| id == status.id) else { return Flow::More };
                let Some(slot) = out.get_mut(i * len..(i + 1) * len) else { return Flow::More };
                if !asked.contains(&status.id) || !report.book(i, protocol, status.error, status.params, slot) {
                    return Flow::More;
                }
                countdown(&mut pending)
            })?;
            // A refusal is an answer: asking again would get the same.
            if report.answered | report.failed == mask(ids.len()) {
                break;
            }
        }
        Ok(report)
    }

    /// Reads `length` bytes at `address` of each servo in `ids` with a Dynamixel fast sync read:
    /// one combined reply instead of one per servo, which saves each reply's header. The servos
    /// chain their parts, so one silent servo spoils the whole reply: it is retried whole, and the
    /// report then says none answered (fall back to [`Master::sync_read`] to find which).
    pub fn fast_sync_read(
        &mut self,
        address: u16,
        length: u16,
        ids: &[Id],
        out: &mut [u8],
    ) -> Result<GroupReport, PortError<P>> {
        let len = usize::from(length);
        check_group(ids.len(), out.len(), ids.len() * len)?;
        let mut report = GroupReport { count: ids.len(), ..GroupReport::default() };
        // Header, id, length, instruction (8 bytes), then error, id, data and CRC per servo; the
        // status length formula with `data` covering all parts but one part's fixed bytes.
        let reply_data = (ids.len() * (len + 4)).saturating_sub(3);
        let timeout_us = self.reply_timeout_us(1, reply_data)
            + u64::from(self.config.return_delay_us) * ids.len().saturating_sub(1) as u64;
        let packet =
            InstructionPacket { id: BROADCAST, instruction: Instruction::FastSyncRead { address, length, ids } };
        let protocol = self.config.protocol;
        for attempt in 0..=self.config.retries {
            if attempt > 0 {
                self.stats.retries = self.stats.retries.wrapping_add(1);
            }
            report.attempts = attempt + 1;
            self.send(&packet)?;
            let replied = self.receive(timeout_us, |status| {
                if status.id != BROADCAST {
                    return Flow::More;
                }
                let Some(parts) = super::dxl2::fast_sync_read_parts(status, len) else { return Flow::More };
                for part in parts {
                    // The same id twice in one reply: the first part counts.
                    if let Some(i) = ids.iter().position(|&id| id == part.id) {
                        report.book(i, protocol, part.error, part.data, &mut out[i * len..(i + 1) * len]);
                    }
                }
                Flow::Done
            })?;
            if replied {
                break;
            }
        }
        Ok(report)
    }

    /// Reads a different item of each servo (Dynamixel bulk read): the data of record `i` goes to
    /// `out` at the sum of the lengths before it. One attempt per call; the report says who answered.
    pub fn bulk_read(&mut self, records: &[BulkReadRecord], out: &mut [u8]) -> Result<GroupReport, PortError<P>> {
        let total: usize = records.iter().map(|r| usize::from(r.length)).sum();
        check_group(records.len(), out.len(), total)?;
        let mut raw = [0u8; MAX_GROUP * 5];
        let mut writer = super::instruction::RecordWriter::new(&mut raw);
        for r in records {
            writer.bulk_read(r.id, r.address, r.length).map_err(MasterError::Encode)?;
        }
        let records_len = writer.records().len();
        self.send(&InstructionPacket {
            id: BROADCAST,
            instruction: Instruction::BulkRead { records: &raw[..records_len] },
        })?;
        let longest = records.iter().map(|r| usize::from(r.length)).max().unwrap_or(0);
        let timeout_us = self.reply_timeout_us(records.len(), longest);
        let protocol = self.config.protocol;
        let mut report = GroupReport { count: records.len(), attempts: 1, ..GroupReport::default() };
        let mut pending = records.len();
        self.receive(timeout_us, |status| {
            let Some(i) = records.iter().position(|r| r.id == status.id) else { return Flow::More };
            let start: usize = records[..i].iter().map(|r| usize::from(r.length)).sum();
            let slot = &mut out[start..start + usize::from(records[i].length)];
            if !report.book(i, protocol, status.error, status.params, slot) {
                return Flow::More;
            }
            countdown(&mut pending)
        })?;
        Ok(report)
    }
}

/// Checks a group read's size against [`MAX_GROUP`] and its output buffer.
fn check_group<E>(count: usize, out_len: usize, needed: usize) -> Result<(), MasterError<E>> {
    if count > MAX_GROUP {
        return Err(MasterError::BadRequest { reason: "more servos in one group read than MAX_GROUP (32)" });
    }
    if out_len < needed {
        return Err(MasterError::BadRequest { reason: "group read output buffer too small" });
    }
    Ok(())
}
