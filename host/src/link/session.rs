//! [`Session`]: the one place on the host that speaks the link protocol's requests. Every host
//! message the product sends is built here (the handshake, the arm's configuration, torque,
//! moves, keyframes, start, stop, the gripper), and every wait on the firmware is written here
//! once: until a request it refused with `NotReady` is taken, until the arm is at rest, until a
//! stop has ended.
//!
//! A session runs on the clock of its transport: each pause is one read timeout of the link, which
//! is real time on a serial port or a pty and virtual time in SIL (the simulated board runs on
//! meanwhile), so the drive commands, the demo, a rig, teleoperation, the view and the tests wait
//! alike, however the core is run. Controller time (a status's `time`) measures every timeout; a
//! wall-clock backstop ends a wait on a controller whose clock stands still.
//!
//! The types say what a request is: [`Session::move_to`] takes a Cartesian target, a timing and
//! a path; [`Keyframe`] is a joint or a Cartesian keyframe. What a request answers is an ack
//! (`Ok(())`), a [`Status`] or an [`Info`]; a refusal is [`LinkError::Nak`] with its reason.

use std::time::Instant;

use firmware::link::message::{
    CartesianKeyframe, CartesianTarget, FirmwareMessage, HostMessage, Info, JointKeyframe, Joints, MovePath, NakReason,
    RunState, Status, Timing,
};

use super::client::{LinkClient, LinkConfig, LinkError, LinkStats};
use super::Transport;

/// Longest wait for the arm to come to rest after a stop (controller seconds).
pub const STOP_TIMEOUT: f64 = 30.0;
/// A joint this close to its setpoint (rad or m) has arrived.
pub const SETTLED: f32 = 1e-3;
/// A joint that moved less than this (rad or m) over [`STILL_SPAN`] stands still.
const STILL: f32 = 1e-4;
/// How long (controller seconds) the joints must stand still to be taken as held back: several
/// control periods, not two polls. The core run on a loaded PC can go without its CPU between two
/// polls and read no servo meanwhile; a teleop rig's follower was taken as at rest 0.2 rad short
/// of its setpoint that way.
const STILL_SPAN: f32 = 0.2;
/// Longest wait for the servos to catch up with a resting setpoint (controller seconds).
const SETTLE_TIMEOUT: f32 = 2.0;
/// Read timeouts a torque-on waits through `NotReady` (0.5 s at 20 ms): right after the board
/// starts or gets a new arm, the firmware has not read every servo yet for a tick or two.
pub const TORQUE_ON_WAITS: usize = 25;

/// A keyframe for the player's queue.
#[derive(Clone, Debug, PartialEq)]
pub enum Keyframe {
    /// Joint values (and velocities) at a time.
    Joints(JointKeyframe),
    /// A tool target at a time, solved by the firmware's IK as the player reaches it.
    Pose(CartesianKeyframe),
}

impl Keyframe {
    /// Its time on the playback clock (s).
    pub fn time(&self) -> f32 {
        match self {
            Keyframe::Joints(k) => k.time,
            Keyframe::Pose(k) => k.time,
        }
    }

    fn message(&self) -> HostMessage {
        match self {
            Keyframe::Joints(k) => HostMessage::PushKeyframe(k.clone()),
            Keyframe::Pose(k) => HostMessage::PushCartesianKeyframe(*k),
        }
    }
}

/// How a wait ended.
#[derive(Debug)]
pub enum Waited {
    /// At rest (holding), with this status (boxed: a status is over 200 bytes, and a wait's end
    /// is once per move).
    Done(Box<Status>),
    /// The caller's interrupt (Ctrl-C) was asked for; nothing was sent about it yet.
    Interrupted,
}

/// Why a wait failed.
#[derive(Debug)]
pub enum WaitError {
    /// The link failed, or the firmware refused a request.
    Link(LinkError),
    /// The arm went limp before it arrived.
    WentLimp,
    /// The arm was emergency-stopped before it arrived.
    EStopped,
    /// Still moving when the time was up; a stop was sent (acknowledged or not).
    TimedOut {
        /// Controller seconds waited.
        waited: f64,
        /// The state it was in.
        state: RunState,
        /// Whether the firmware acknowledged the stop.
        stopped: bool,
    },
    /// A stop that did not end within [`STOP_TIMEOUT`].
    StopTooLong {
        /// The state it was still in.
        state: RunState,
    },
}

impl From<LinkError> for WaitError {
    fn from(e: LinkError) -> Self {
        WaitError::Link(e)
    }
}

impl std::fmt::Display for WaitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WaitError::Link(e) => write!(f, "{e}"),
            WaitError::WentLimp => write!(f, "the arm went limp (torque off) before reaching the target"),
            WaitError::EStopped => write!(f, "the arm was emergency-stopped before reaching the target"),
            WaitError::TimedOut { waited, state, stopped } => write!(
                f,
                "timed out after {} s with the arm still {state:?}; {}",
                seconds_waited(*waited),
                if *stopped { "sent stop" } else { "stop was not acknowledged" }
            ),
            WaitError::StopTooLong { state } => {
                write!(f, "sent stop, but the arm was still {state:?} after {STOP_TIMEOUT} s")
            }
        }
    }
}

impl std::error::Error for WaitError {}

/// Seconds waited, as a person reads them against the timeout they gave: a tenth of a second
/// would show a 0.05 s timeout as "0.1 s", so below one second to the hundredth.
pub fn seconds_waited(s: f64) -> String {
    if s < 1.0 {
        format!("{s:.2}")
    } else {
        format!("{s:.1}")
    }
}

/// The session over one link to a firmware core.
pub struct Session<T: Transport> {
    client: LinkClient<T>,
    /// Whether an arm it sends has its goals checked against its collision geometry.
    collision_check: super::arm_config::CollisionCheck,
}

impl<T: Transport> Session<T> {
    /// A session over a link client.
    pub fn new(client: LinkClient<T>) -> Self {
        Self { client, collision_check: super::arm_config::CollisionCheck::On }
    }

    /// Sends the arms of [`Session::configure_arm`] with the collision check on (the default) or
    /// off (`--no-collision-check`, for a test that must see the arm reach a contact).
    pub fn set_collision_check(&mut self, check: super::arm_config::CollisionCheck) {
        self.collision_check = check;
    }

    /// Whether the arms this session sends are checked.
    pub fn collision_check(&self) -> super::arm_config::CollisionCheck {
        self.collision_check
    }

    /// A session over `io` with the default retransmission settings; `io`'s reads must time out
    /// ([`LinkClient::new`]).
    pub fn over(io: T) -> Self {
        Self::new(LinkClient::new(io, LinkConfig::default()))
    }

    /// The link client under the session, for tests of the link protocol itself (they send the
    /// firmware what the product never would). The product's requests all go through the
    /// session's methods.
    pub fn client(&mut self) -> &mut LinkClient<T> {
        &mut self.client
    }

    /// The link client back, for tests of the link protocol itself (see [`Session::client`]).
    pub fn into_client(self) -> LinkClient<T> {
        self.client
    }

    /// The transport back, once the session is done with it (`armctl serve` hands the core's
    /// link, its arm configured, to a pty).
    pub fn into_transport(self) -> T {
        self.client.into_transport()
    }

    /// The transport (a simulated board's clock and trace, a pty).
    pub fn transport(&mut self) -> &mut T {
        self.client.transport()
    }

    /// The link's counters since it opened.
    pub fn stats(&self) -> LinkStats {
        self.client.stats()
    }

    /// Free keyframe slots by the firmware's last report (0 when unknown).
    pub fn free_slots(&self) -> u16 {
        self.client.free_slots()
    }

    /// The last telemetry received.
    pub fn telemetry(&self) -> Option<&Status> {
        self.client.telemetry()
    }

    /// Handshake: checks the protocol version and returns the firmware's info.
    pub fn hello(&mut self) -> Result<Info, LinkError> {
        self.client.hello()
    }

    /// Sends an arm to the firmware ([`super::arm_config::configure_messages`]), message by
    /// message, each again after a `NotReady` for up to `waits` read timeouts (a firmware takes a
    /// new arm only once the torque is off); the firmware switches to it at the last.
    pub fn configure_arm(
        &mut self,
        arm: &crate::arm::ArmSpec,
        servos: &crate::arm::servos::ServoSetup,
        waits: usize,
    ) -> anyhow::Result<()> {
        for message in super::arm_config::configure_messages_checked(arm, servos, self.collision_check)? {
            self.when_ready(&message, waits)?;
        }
        Ok(())
    }

    /// Gives the firmware gravity compensation: one [`HostMessage::SetGravity`] per joint, base
    /// first (`crate::runtime::gravity::gravity_parts`), each acked.
    pub fn gravity(&mut self, parts: &[firmware::controller::gravity::GravityJoint]) -> Result<(), LinkError> {
        parts.iter().enumerate().try_for_each(|(j, p)| {
            let joint = u8::try_from(j).unwrap_or(u8::MAX);
            self.ack(&HostMessage::SetGravity { joint, mass: p.mass, com: p.com, compliance: p.compliance })
        })
    }

    /// The controller's status.
    pub fn status(&mut self) -> Result<Status, LinkError> {
        self.client.status()
    }

    /// An ack, which carries the free keyframe slots and feeds the watchdog.
    pub fn ping(&mut self) -> Result<(), LinkError> {
        self.ack(&HostMessage::Ping)
    }

    /// Switches torque on (also leaving an emergency stop), asking again after each `NotReady`
    /// for up to `waits` read timeouts.
    pub fn torque_on(&mut self, waits: usize) -> Result<(), LinkError> {
        self.when_ready(&HostMessage::Torque { on: true }, waits)
    }

    /// Switches torque off: the servos go limp.
    pub fn torque_off(&mut self) -> Result<(), LinkError> {
        self.ack(&HostMessage::Torque { on: false })
    }

    /// Moves the tool to `target` by `path`, IK on the firmware.
    pub fn move_to(&mut self, target: CartesianTarget, timing: Timing, path: MovePath) -> Result<(), LinkError> {
        self.ack(&HostMessage::MoveTo { target, timing, path })
    }

    /// Moves every joint to `positions`, arriving together.
    pub fn move_joints(&mut self, positions: Joints, timing: Timing) -> Result<(), LinkError> {
        self.ack(&HostMessage::MoveJoints { positions, timing })
    }

    /// Drives the gripper to `opening` (percent), with a new effort limit if given.
    pub fn gripper(&mut self, opening: f32, effort: Option<f32>) -> Result<(), LinkError> {
        self.ack(&HostMessage::Gripper { opening, effort })
    }

    /// Appends a keyframe to the player's queue, first waiting for a free slot (the client's flow
    /// control).
    pub fn push(&mut self, keyframe: &Keyframe) -> Result<(), LinkError> {
        match self.client.push(&keyframe.message())? {
            FirmwareMessage::Ack { .. } => Ok(()),
            other => Err(LinkError::Unexpected(Box::new(other))),
        }
    }

    /// Starts (or resumes) playing the queue; the playback clock starts at zero.
    pub fn start(&mut self) -> Result<(), LinkError> {
        self.ack(&HostMessage::Start)
    }

    /// Stops: the arm decelerates within its limits, the queue is dropped, then it holds.
    pub fn stop(&mut self) -> Result<(), LinkError> {
        self.ack(&HostMessage::Stop)
    }

    /// Waits one read timeout of the link, taking in telemetry meanwhile: the pause between polls.
    pub fn pause(&mut self) -> Result<(), LinkError> {
        self.client.wait_once()
    }

    /// Polls status until the arm is at rest and holding, then until the servos have caught up
    /// ([`Session::settle`]). Gives up after `timeout` seconds of controller time (stopping the
    /// arm first); fails if the arm ends up limp or emergency-stopped. `interrupted` is asked
    /// before each poll (Ctrl-C): when it says so, the wait ends with nothing sent.
    pub fn wait_at_rest(&mut self, timeout: f64, interrupted: &mut dyn FnMut() -> bool) -> Result<Waited, WaitError> {
        let started = Instant::now();
        let mut first: Option<f32> = None;
        loop {
            if interrupted() {
                return Ok(Waited::Interrupted);
            }
            let status = self.status()?;
            match status.state {
                RunState::Idle => return Ok(Waited::Done(Box::new(self.settle(status)?))),
                RunState::TorqueOff => return Err(WaitError::WentLimp),
                RunState::EStopped => return Err(WaitError::EStopped),
                _ => {}
            }
            let t0 = *first.get_or_insert(status.time);
            let waited = f64::from(status.time - t0);
            // The wall clock is a backstop for a controller whose clock stands still.
            if waited > timeout || started.elapsed().as_secs_f64() > 4.0 * timeout + 10.0 {
                let stopped = self.stop().is_ok();
                return Err(WaitError::TimedOut { waited, state: status.state, stopped });
            }
            self.pause()?;
        }
    }

    /// Once the setpoint rests: waits until the servos have caught up with it (every measured
    /// joint within [`SETTLED`] of its setpoint) or stand still (a servo held back by a load) for
    /// [`STILL_SPAN`], at most [`SETTLE_TIMEOUT`]. Returns the last status.
    pub fn settle(&mut self, mut status: Status) -> Result<Status, LinkError> {
        let t0 = status.time;
        // Where the joints stood when they last moved, and when.
        let mut still_since = (status.time, status.measured.clone());
        loop {
            let lag = status.measured.iter().zip(&status.setpoints).map(|(m, s)| (m - s).abs()).fold(0.0, f32::max);
            if lag <= SETTLED || status.state != RunState::Idle || status.time - t0 > SETTLE_TIMEOUT {
                return Ok(status);
            }
            self.pause()?;
            status = self.status()?;
            let moved = status.measured.iter().zip(&still_since.1).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            if moved > STILL {
                still_since = (status.time, status.measured.clone());
            } else if status.time - still_since.0 >= STILL_SPAN {
                return Ok(status);
            }
        }
    }

    /// Sends stop and waits until the arm no longer moves (holding, limp or emergency-stopped),
    /// then until the servos have caught up.
    pub fn stop_and_wait(&mut self) -> Result<Status, WaitError> {
        self.stop()?;
        let mut first = None;
        let started = Instant::now();
        loop {
            let status = self.status()?;
            let t0 = *first.get_or_insert(status.time);
            if !matches!(status.state, RunState::Moving | RunState::Stopping | RunState::Paused) {
                return Ok(self.settle(status)?);
            }
            if f64::from(status.time - t0) > STOP_TIMEOUT || started.elapsed().as_secs_f64() > 4.0 * STOP_TIMEOUT {
                return Err(WaitError::StopTooLong { state: status.state });
            }
            self.pause()?;
        }
    }

    /// Polls status until the arm is idle, at most `polls` times (a pause between polls); for a
    /// board whose moves end by themselves (the QEMU measurements).
    pub fn wait_idle(&mut self, polls: usize) -> anyhow::Result<Status> {
        let mut status = self.status()?;
        for _ in 0..polls {
            if status.state == RunState::Idle {
                return Ok(status);
            }
            self.pause()?;
            status = self.status()?;
        }
        if status.state != RunState::Idle {
            anyhow::bail!("the arm did not come to rest after {polls} status polls");
        }
        Ok(status)
    }

    /// Sends `message`, again after each `NotReady` for up to `waits` read timeouts.
    fn when_ready(&mut self, message: &HostMessage, waits: usize) -> Result<(), LinkError> {
        let mut waited = 0;
        loop {
            match self.ack(message) {
                Err(LinkError::Nak(NakReason::NotReady)) if waited < waits => {
                    waited += 1;
                    self.pause()?;
                }
                other => return other,
            }
        }
    }

    /// Sends a request answered by an ack.
    fn ack(&mut self, message: &HostMessage) -> Result<(), LinkError> {
        match self.client.request(message)? {
            FirmwareMessage::Ack { .. } => Ok(()),
            other => Err(LinkError::Unexpected(Box::new(other))),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    //! The session against a scripted firmware: every method sends exactly the request it names
    //! (decoded from the bytes on the wire), waits where it should, and reads the answer as its
    //! type says.

    use std::collections::VecDeque;
    use std::io::{ErrorKind, Read, Write};

    use firmware::link::frame::{decode_payload, encode_message, FrameDecoder, FrameKind, MAX_ENCODED, MAX_FRAME};
    use firmware::link::message::{GripperStatus, IkStatus, Joints, LoopTiming};

    use super::*;

    /// A firmware that answers each request with the next scripted reply (an ack once the script
    /// runs out), and keeps every request it was sent.
    #[derive(Default)]
    struct Scripted {
        decoder: Option<Box<FrameDecoder<MAX_ENCODED>>>,
        replies: VecDeque<FirmwareMessage>,
        sent: Vec<HostMessage>,
        outgoing: VecDeque<u8>,
    }

    impl Write for Scripted {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            let decoder = self.decoder.get_or_insert_with(|| Box::new(FrameDecoder::new()));
            for &byte in bytes {
                let Some(Ok(frame)) = decoder.push(byte) else { continue };
                let (seq, message) = (frame.seq, decode_payload::<HostMessage>(frame.payload).unwrap());
                self.sent.push(message);
                let reply = self.replies.pop_front().unwrap_or(FirmwareMessage::Ack { free_slots: 4 });
                let mut out = [0u8; MAX_FRAME];
                let n = encode_message(seq, FrameKind::Reply, &reply, &mut out).unwrap();
                self.outgoing.extend(&out[..n]);
            }
            Ok(bytes.len())
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Read for Scripted {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            match self.outgoing.pop_front() {
                Some(byte) => {
                    buf[0] = byte;
                    Ok(1)
                }
                None => Err(std::io::Error::from(ErrorKind::TimedOut)),
            }
        }
    }

    fn session(replies: Vec<FirmwareMessage>) -> Session<Scripted> {
        Session::over(Scripted { replies: replies.into(), ..Scripted::default() })
    }

    /// A status at `time` in `state` (other fields of an idle arm).
    pub(crate) fn status(time: f32, state: RunState, measured: &[f32], setpoints: &[f32]) -> Status {
        let FirmwareMessage::Status(mut s) = firmware_status() else { unreachable!() };
        s.time = time;
        s.state = state;
        s.measured = Joints::from_slice(measured).unwrap();
        s.setpoints = Joints::from_slice(setpoints).unwrap();
        s
    }

    /// A status of an idle arm with no joints: the fields the tests set are set by [`status`].
    fn firmware_status() -> FirmwareMessage {
        FirmwareMessage::Status(Status {
            time: 0.0,
            play_time: 0.0,
            state: RunState::Idle,
            measured: Joints::new(),
            setpoints: Joints::new(),
            queued: 0,
            free_slots: 4,
            ik: IkStatus { converged: true, iterations: 0, position_error: 0.0, orientation_error: 0.0 },
            timing: LoopTiming { mean_us: 0, max_us: 0, overruns: 0 },
            errors: Default::default(),
            lost_servos: 0,
            gripper: None::<GripperStatus>,
            last_move: None,
            largest_pass: 0.0,
            collision_check: firmware::link::message::CollisionCheck::NoGeometry,
            last_collision: None,
        })
    }

    #[test]
    fn each_request_is_the_message_it_names() {
        let mut s = session(Vec::new());
        let target = CartesianTarget { position: [0.2, 0.0, 0.1], orientation: None };
        let joints = Joints::from_slice(&[0.1, -0.2]).unwrap();
        let keyframe = JointKeyframe { time: 0.5, positions: joints.clone(), velocities: None, gripper: Some(40.0) };
        s.torque_on(0).unwrap();
        s.torque_off().unwrap();
        s.move_to(target, Timing::MaxSpeed(0.1), MovePath::Line).unwrap();
        s.move_joints(joints.clone(), Timing::Duration(2.0)).unwrap();
        s.gripper(30.0, Some(50.0)).unwrap();
        s.push(&Keyframe::Joints(keyframe.clone())).unwrap();
        s.start().unwrap();
        s.stop().unwrap();
        s.ping().unwrap();
        assert_eq!(
            s.transport().sent,
            [
                HostMessage::Torque { on: true },
                HostMessage::Torque { on: false },
                HostMessage::MoveTo { target, timing: Timing::MaxSpeed(0.1), path: MovePath::Line },
                HostMessage::MoveJoints { positions: joints, timing: Timing::Duration(2.0) },
                HostMessage::Gripper { opening: 30.0, effort: Some(50.0) },
                // The free slots were known from the acks before: no poll before the push.
                HostMessage::PushKeyframe(keyframe),
                HostMessage::Start,
                HostMessage::Stop,
                HostMessage::Ping,
            ]
        );
    }

    #[test]
    fn a_refusal_is_its_reason_and_a_wrong_answer_is_unexpected() {
        let mut s = session(vec![
            FirmwareMessage::Nak { reason: NakReason::Unreachable },
            firmware_status(),
            FirmwareMessage::Nak { reason: NakReason::NotReady },
            FirmwareMessage::Nak { reason: NakReason::NotReady },
            FirmwareMessage::Nak { reason: NakReason::NotReady },
        ]);
        let target = CartesianTarget { position: [0.2, 0.0, 0.1], orientation: None };
        let refused = s.move_to(target, Timing::MaxSpeed(0.1), MovePath::Auto);
        assert!(matches!(refused, Err(LinkError::Nak(NakReason::Unreachable))), "{refused:?}");
        assert!(matches!(s.start(), Err(LinkError::Unexpected(_))), "a status does not answer a start");
        // Torque on through two NotReady, not through three.
        assert!(matches!(s.torque_on(2), Err(LinkError::Nak(NakReason::NotReady))));
        assert_eq!(s.transport().sent.len(), 2 + 3);
        let mut s = session(vec![FirmwareMessage::Nak { reason: NakReason::NotReady }; 2]);
        s.torque_on(2).unwrap();
        assert_eq!(s.transport().sent, vec![HostMessage::Torque { on: true }; 3]);
    }

    #[test]
    fn a_wait_ends_at_rest_once_the_servos_caught_up_and_times_out_on_the_controller_clock() {
        let (q, goal) = ([0.0, 0.0], [0.5, 0.5]);
        let mut s = session(vec![
            FirmwareMessage::Status(status(0.0, RunState::Moving, &q, &goal)),
            FirmwareMessage::Status(status(0.1, RunState::Moving, &[0.3, 0.3], &goal)),
            // At rest, but the servos lag: settle waits until they are within SETTLED.
            FirmwareMessage::Status(status(0.2, RunState::Idle, &[0.49, 0.49], &goal)),
            FirmwareMessage::Status(status(0.3, RunState::Idle, &[0.4995, 0.4995], &goal)),
        ]);
        let Waited::Done(end) = s.wait_at_rest(5.0, &mut || false).unwrap() else { panic!("interrupted") };
        assert_eq!(end.time, 0.3);
        let polls = s.transport().sent.iter().filter(|m| **m == HostMessage::GetStatus).count();
        assert_eq!(polls, 4);

        // Still moving past 2 s of controller time (at the 22nd poll): a stop is sent, and the
        // wait says so.
        let moving: Vec<_> =
            (0..22).map(|k| FirmwareMessage::Status(status(k as f32 * 0.1, RunState::Moving, &q, &goal))).collect();
        let mut s = session(moving);
        let e = s.wait_at_rest(2.0, &mut || false).unwrap_err();
        assert!(matches!(e, WaitError::TimedOut { stopped: true, .. }), "{e}");
        assert_eq!(s.transport().sent.last(), Some(&HostMessage::Stop));
        assert!(e.to_string().starts_with("timed out after 2.1 s with the arm still Moving; sent stop"), "{e}");
        let short = WaitError::TimedOut { waited: 0.06, state: RunState::Moving, stopped: true };
        assert_eq!(short.to_string(), "timed out after 0.06 s with the arm still Moving; sent stop");

        // Limp, or interrupted before the first poll: nothing else is sent.
        let mut s = session(vec![FirmwareMessage::Status(status(0.0, RunState::TorqueOff, &q, &q))]);
        assert!(matches!(s.wait_at_rest(2.0, &mut || false), Err(WaitError::WentLimp)));
        let mut s = session(Vec::new());
        assert!(matches!(s.wait_at_rest(2.0, &mut || true), Ok(Waited::Interrupted)));
        assert!(s.transport().sent.is_empty());
    }
}
