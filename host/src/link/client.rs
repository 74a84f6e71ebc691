//! [`LinkClient`]: requests to the firmware over any `Read + Write` byte transport with a read
//! timeout (a serial port, a pty, an in-memory pipe).
//!
//! One request is in flight at a time (stop-and-wait): it is sent with the next seq and sent again,
//! same seq and bytes, until a reply with that seq comes. The wait before a retransmission doubles
//! each time, counted in read timeouts of the transport (1, 2, 4, ... up to
//! [`LinkConfig::max_backoff`]), so the client needs no clock of its own; a nak event for a broken
//! frame retransmits at once. The firmware applies a repeated request once, so a lost reply costs
//! time but never a duplicate. After [`LinkConfig::max_attempts`] sends the client gives up with
//! [`LinkError::GaveUp`].
//!
//! Telemetry frames arrive unasked; each one ends a wait slot like a read timeout (the firmware
//! sends at most one per control tick, so at the fastest rate, 100 Hz against a 20 ms timeout, the
//! waits are half as long as without telemetry, never endless).
//!
//! Flow control: every ack (and status) reports the free keyframe slots. A keyframe push is only
//! sent while the last report says a slot is free; otherwise the client polls with a ping, waiting one
//! read timeout between polls, until one is. The count is unknown (zero) at the start and after a
//! failed request, so the client then asks before pushing.

use std::io::{ErrorKind, Read, Write};

use firmware::link::frame::{
    decode_payload, encode_message, FrameDecoder, FrameError, FrameKind, MAX_ENCODED, MAX_FRAME,
};
use firmware::link::message::{FirmwareMessage, HostMessage, Info, NakReason, Status, ValueError, PROTOCOL_VERSION};

/// Retransmission settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkConfig {
    /// Sends of one request before giving up.
    pub max_attempts: u32,
    /// Longest wait for a reply, in read timeouts of the transport.
    pub max_backoff: u32,
    /// Status polls while the queue is full before giving up (each waits one read timeout).
    pub max_polls: u32,
}

impl Default for LinkConfig {
    /// 40 attempts and a wait of at most 8 timeouts: with a 20 ms timeout, about 6 s before giving
    /// up, which outlasts a noisy stretch of line but not a disconnected board. Many attempts with
    /// short waits rather than few long ones, because on a noisy line a long reply (a status is
    /// about 80 bytes) may need many tries: at 1% lost bytes and 0.1% flipped bits only one in
    /// four status replies arrives whole.
    fn default() -> Self {
        Self { max_attempts: 40, max_backoff: 8, max_polls: 100_000 }
    }
}

/// Counters of a client.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Requests completed (acked, answered or nak'ed).
    pub requests: u32,
    /// Sends beyond the first of a request.
    pub retransmissions: u32,
    /// Retransmissions caused by a nak event instead of a timeout.
    pub nak_retransmissions: u32,
    /// Read timeouts.
    pub timeouts: u32,
    /// Status polls because the queue was full.
    pub full_polls: u32,
    /// Received frames dropped as broken.
    pub broken_frames: u32,
    /// Replies with a seq not awaited (late replies to earlier sends).
    pub stale_replies: u32,
}

/// Why a request failed.
#[derive(Debug)]
pub enum LinkError {
    /// The transport failed.
    Io(std::io::Error),
    /// No reply after every attempt.
    GaveUp {
        /// The request's seq.
        seq: u8,
        /// Sends made.
        attempts: u32,
    },
    /// The firmware refused the request.
    Nak(NakReason),
    /// The message was refused before sending.
    Invalid(ValueError),
    /// The message does not fit a frame.
    Encode(FrameError),
    /// A reply that does not answer the request (e.g. info for a status request).
    Unexpected(Box<FirmwareMessage>),
    /// The queue stayed full for every poll.
    QueueStuck {
        /// Polls made.
        polls: u32,
    },
    /// The firmware speaks another protocol version.
    Version {
        /// The firmware's version.
        firmware: u16,
    },
}

impl std::fmt::Display for LinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "link transport: {e}"),
            Self::GaveUp { seq, attempts } => {
                write!(f, "no reply from the firmware to request {seq} after {attempts} attempts")
            }
            Self::Nak(reason) => write!(f, "the firmware refused the request: {}", Reason(reason)),
            Self::Invalid(e) => write!(f, "refused before sending: {}", Value(e)),
            Self::Encode(e) => write!(f, "{e}"),
            Self::Unexpected(m) => write!(f, "unexpected reply {m:?}"),
            Self::QueueStuck { polls } => write!(f, "keyframe queue still full after {polls} status polls"),
            Self::Version { firmware } => {
                write!(f, "firmware speaks link protocol {firmware}, this host {PROTOCOL_VERSION}")
            }
        }
    }
}

impl std::error::Error for LinkError {}

/// A [`NakReason`] in words, for messages to people.
pub struct Reason<'a>(pub &'a NakReason);

impl std::fmt::Display for Reason<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            NakReason::Corrupt => write!(f, "the request arrived corrupted"),
            NakReason::Oversized => write!(f, "the request frame is too long"),
            NakReason::UnknownMessage => write!(f, "the firmware does not know this request"),
            NakReason::BadValue(e) => write!(f, "{}", Value(e)),
            NakReason::QueueFull => write!(f, "the keyframe queue is full"),
            NakReason::NotReady => write!(f, "not possible in the controller's state now"),
            NakReason::Unreachable => {
                write!(f, "IK found no solution for the target within the joint limits (unreachable)")
            }
            NakReason::JointLimit { joint } => write!(f, "joint {} would leave its limits", u16::from(*joint) + 1),
            NakReason::KeyframeTime => write!(f, "the keyframe's time is not later than the previous keyframe's"),
            NakReason::TorqueOff => write!(f, "the torque is off (`torque on` first)"),
            NakReason::EStopped => write!(f, "the arm is emergency-stopped (`torque on` leaves the emergency stop)"),
            NakReason::NoGripper => write!(f, "the arm has no gripper (name one in the arm file's [gripper] table)"),
            NakReason::Collision { body, other, distance } => write!(
                f,
                "the target brings collision body {body} {:.1} mm from {} (closer than the margin)",
                f64::from(*distance) * 1e3,
                match other {
                    firmware::link::message::CollisionPart::Body(i) => format!("body {i}"),
                    firmware::link::message::CollisionPart::Obstacle(o) => format!("obstacle {o}"),
                }
            ),
            NakReason::BadCollision => {
                write!(f, "the arm's collision geometry was refused (a body on a joint the arm lacks, or too many)")
            }
        }
    }
}

/// A [`ValueError`] in words.
pub struct Value<'a>(pub &'a ValueError);

impl std::fmt::Display for Value<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use firmware::link::message::{Field, Problem};
        let field = match self.0.field {
            Field::Position => "position",
            Field::Orientation => "orientation",
            Field::Duration => "duration",
            Field::Speed => "speed",
            Field::Time => "keyframe time",
            Field::Joints => "joint values",
            Field::Velocities => "joint velocities",
            Field::JointCount => "joint count",
            Field::JointIndex => "joint index",
            Field::Origin => "joint origin",
            Field::Axis => "joint axis",
            Field::Limits => "joint limits",
            Field::Servo => "servo mapping",
            Field::Rate => "telemetry rate",
            Field::Name => "arm name",
            Field::Gripper => "gripper opening, effort or configuration",
            Field::Bus => "servo bus (its baud rate, or a cycle too long for the control period)",
            Field::Margin => "collision margin",
            Field::Body => "collision body (its index, joint, ends or radius)",
            Field::Obstacle => "obstacle (its index, place, rotation or size)",
            Field::Gravity => "gravity compensation (a link's mass or centre, or its servo's compliance)",
            Field::Allowed => "allowed collision pair",
        };
        let problem = match self.0.problem {
            Problem::NotFinite => "not a finite number",
            Problem::OutOfRange => "out of range",
            Problem::NotUnit => "not of unit length",
            Problem::Count => "the wrong number of values",
        };
        write!(f, "{field}: {problem}")
    }
}

/// A link client over transport `T`.
pub struct LinkClient<T: Read + Write> {
    io: T,
    config: LinkConfig,
    decoder: FrameDecoder<MAX_ENCODED>,
    seq: u8,
    free_slots: u16,
    telemetry: Option<Status>,
    stats: LinkStats,
}

/// What came in while waiting for a reply.
// A reply is a status at its largest (228 bytes since protocol 9's collision report), held for one
// call on the stack: boxing it would allocate for every reply, to save nothing worth having.
#[allow(clippy::large_enum_variant)]
enum Heard {
    Reply(FirmwareMessage),
    /// The firmware received a broken frame: retransmit now.
    Broken,
    Nothing,
}

impl<T: Read + Write> LinkClient<T> {
    /// A client over `io`, whose reads must return `TimedOut` or `WouldBlock` (or 0 bytes) when
    /// nothing came within its timeout.
    pub fn new(io: T, config: LinkConfig) -> Self {
        Self {
            io,
            config,
            decoder: FrameDecoder::new(),
            seq: 0,
            free_slots: 0,
            telemetry: None,
            stats: LinkStats::default(),
        }
    }

    /// Counters since creation.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Free keyframe slots by the last report (0 when unknown).
    pub fn free_slots(&self) -> u16 {
        self.free_slots
    }

    /// The last telemetry received.
    pub fn telemetry(&self) -> Option<&Status> {
        self.telemetry.as_ref()
    }

    /// The transport.
    pub fn transport(&mut self) -> &mut T {
        &mut self.io
    }

    /// The transport back, once the client is done with it.
    pub fn into_transport(self) -> T {
        self.io
    }

    /// Handshake: checks the protocol version and returns the firmware's info.
    pub fn hello(&mut self) -> Result<Info, LinkError> {
        match self.request(&HostMessage::Hello { protocol_version: PROTOCOL_VERSION })? {
            FirmwareMessage::Info(info) if info.protocol_version == PROTOCOL_VERSION => Ok(info),
            FirmwareMessage::Info(info) => Err(LinkError::Version { firmware: info.protocol_version }),
            other => Err(LinkError::Unexpected(Box::new(other))),
        }
    }

    /// The firmware's status.
    pub fn status(&mut self) -> Result<Status, LinkError> {
        match self.request(&HostMessage::GetStatus)? {
            FirmwareMessage::Status(s) => Ok(s),
            other => Err(LinkError::Unexpected(Box::new(other))),
        }
    }

    /// Pushes a keyframe ([`HostMessage::PushKeyframe`] or [`HostMessage::PushCartesianKeyframe`];
    /// other messages are sent as they are), first waiting for a free slot.
    pub fn push(&mut self, message: &HostMessage) -> Result<FirmwareMessage, LinkError> {
        if message.is_keyframe_push() {
            let mut polls = 0;
            while self.free_slots == 0 {
                if polls == self.config.max_polls {
                    return Err(LinkError::QueueStuck { polls });
                }
                if polls > 0 {
                    // Let the firmware play a keyframe before asking again.
                    self.listen_once()?;
                }
                polls += 1;
                self.stats.full_polls += 1;
                // A ping's ack is short, so it gets through a noisy line more often than a status.
                self.request(&HostMessage::Ping)?;
            }
        }
        self.request(message)
    }

    /// Sends one request and returns its reply; a nak is [`LinkError::Nak`]. Keyframe pushes are
    /// sent whatever the free slots: use [`LinkClient::push`] for flow control.
    pub fn request(&mut self, message: &HostMessage) -> Result<FirmwareMessage, LinkError> {
        message.validate().map_err(LinkError::Invalid)?;
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let mut frame = [0u8; MAX_FRAME];
        let n = encode_message(seq, FrameKind::Request, message, &mut frame).map_err(LinkError::Encode)?;
        let result = self.exchange(seq, &frame[..n]);
        match &result {
            Ok(reply) => {
                self.stats.requests += 1;
                if let Some(free) = reply.free_slots() {
                    self.free_slots = free;
                }
            }
            // Whether it was applied is unknown: ask before the next push.
            Err(_) => self.free_slots = 0,
        }
        match result? {
            FirmwareMessage::Nak { reason } => Err(LinkError::Nak(reason)),
            reply => Ok(reply),
        }
    }

    fn exchange(&mut self, seq: u8, frame: &[u8]) -> Result<FirmwareMessage, LinkError> {
        for attempt in 0..self.config.max_attempts {
            if attempt > 0 {
                self.stats.retransmissions += 1;
            }
            self.io.write_all(frame).map_err(LinkError::Io)?;
            self.io.flush().map_err(LinkError::Io)?;
            let wait = 1u32.checked_shl(attempt).unwrap_or(u32::MAX).min(self.config.max_backoff.max(1));
            let mut timeouts = 0;
            while timeouts < wait {
                match self.receive(Some(seq))? {
                    Heard::Reply(reply) => return Ok(reply),
                    Heard::Broken => {
                        self.stats.nak_retransmissions += 1;
                        break;
                    }
                    Heard::Nothing => timeouts += 1,
                }
            }
        }
        Err(LinkError::GaveUp { seq, attempts: self.config.max_attempts })
    }

    /// Waits one read timeout of the transport, taking in events (telemetry) meanwhile: the pause
    /// between status polls, in the transport's own time (a simulated board runs on meanwhile).
    pub fn wait_once(&mut self) -> Result<(), LinkError> {
        self.listen_once()
    }

    /// One read timeout's worth of listening, for events only.
    fn listen_once(&mut self) -> Result<(), LinkError> {
        while !matches!(self.receive(None)?, Heard::Nothing) {}
        Ok(())
    }

    /// Reads once; returns the reply to `seq` if the bytes complete it, `Broken` for a nak event,
    /// or `Nothing` after a timeout. Bytes after a reply stay in the transport for the next read:
    /// the client reads one byte at a time so that nothing after a reply is lost.
    fn receive(&mut self, seq: Option<u8>) -> Result<Heard, LinkError> {
        let mut byte = [0u8; 1];
        loop {
            match self.io.read(&mut byte) {
                Ok(0) => return Ok(Heard::Nothing),
                Ok(_) => {}
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {
                    self.stats.timeouts += 1;
                    return Ok(Heard::Nothing);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(LinkError::Io(e)),
            }
            let heard = match self.decoder.push(byte[0]) {
                None => continue,
                Some(Err(_)) => {
                    self.stats.broken_frames += 1;
                    continue;
                }
                Some(Ok(frame)) => {
                    let Ok(message) = decode_payload::<FirmwareMessage>(frame.payload) else {
                        self.stats.broken_frames += 1;
                        continue;
                    };
                    match frame.kind {
                        FrameKind::Reply if Some(frame.seq) == seq => Heard::Reply(message),
                        FrameKind::Reply => {
                            self.stats.stale_replies += 1;
                            continue;
                        }
                        FrameKind::Event => match message {
                            FirmwareMessage::Telemetry(status) => {
                                // A telemetry frame ends this wait slot as a timeout would: with
                                // telemetry at least as fast as the read timeout, reads never
                                // time out, and the client would wait for ever.
                                self.telemetry = Some(status);
                                Heard::Nothing
                            }
                            FirmwareMessage::Nak { .. } if seq.is_some() => Heard::Broken,
                            _ => continue,
                        },
                        FrameKind::Request => continue,
                    }
                }
            };
            return Ok(heard);
        }
    }
}
