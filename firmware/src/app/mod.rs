//! The firmware application: the host link in front of the controller, as one sans-IO object.
//!
//! A board's main loop (and the SIL harness on the host) does two things, forever:
//! - hands every byte received from the host to [`Firmware::receive`], which decodes frames,
//!   answers each request once ([`crate::link::session`]) and writes the reply frames to the link;
//! - calls [`Firmware::tick`] every [`Firmware::period_us`], which runs one control tick on the servo
//!   bus and sends a telemetry frame when one is due.
//!
//! - [`arm`]: the arm the firmware drives (built in, or configured by the host) and its checks.
//! - [`requests`]: host messages turned into controller commands and replies.
//! - [`report`]: the status snapshot and loop statistics.
//!
//! # Panics
//! Nothing here panics, allocates or loops without a bound, on any bytes from the host.

pub mod arm;
mod report;
mod requests;

pub use arm::{ArmSetup, Staging};

use crate::builtin::BuiltinArm;

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};
use heapless::String;

use crate::bus::master::{BusConfig, Clock, Master};
use crate::bus::table::Model;
use crate::controller::{minimum_period_us, Config, ConfigError, Controller, TickReport};
use crate::link::frame::{FrameDecoder, MAX_ENCODED, MAX_FRAME};
use crate::link::message::{FirmwareMessage, MAX_NAME};
use crate::link::session::Session;
use report::LoopStats;

/// What the board is: its servo bus and how the control loop runs on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Board {
    /// The servo bus (protocol, baud rate, return delay, margins).
    pub bus: BusConfig,
    /// The servo model of the built-in arm, and of a configured arm that names none it knows.
    pub model: &'static Model,
    /// Control rate, watchdog and IK budget.
    pub control: Config,
    /// The fastest baud rate the servo bus's UART reaches: an arm on a faster bus is refused.
    pub max_bus_baud: u32,
}

/// What a board's link receive path lost before the firmware saw the bytes: the receive ring's
/// drops and the UART's overruns ([`crate::board::RxRing`]), as its counters read. The board's main
/// loop hands them over on every pass ([`Firmware::set_receive_loss`]); the status reports them
/// (`errors.link_dropped`, `errors.link_overruns`). Where the core runs without such a ring (SIL,
/// a PC) nothing sets them and they stay 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiveLoss {
    /// Bytes the ring dropped because it was full.
    pub dropped: u32,
    /// Receive overruns of the UART.
    pub overruns: u32,
}

/// The arm in use: its name and digest ([`ArmSetup::digest`]). Its controller is
/// [`Core::controller`], which stays in place from one arm to the next.
#[derive(Clone, Debug)]
struct ArmId {
    name: String<MAX_NAME>,
    digest: u32,
}

/// Everything but the link's framing: what a request may change.
#[derive(Clone, Debug)]
struct Core<const N: usize, const Q: usize> {
    board: Board,
    /// The built-in arm, if there is one: the messages that configure it, replayed at start and
    /// on [`crate::link::message::HostMessage::UseBuiltinArm`].
    builtin: Option<&'static BuiltinArm>,
    /// Where an arm the host sends is built when it is committed: in static memory, like the
    /// controller, because an arm's set-up (1.5 KB with six joints) would take a good part of
    /// the stack budget.
    incoming: ArmSetup<N>,
    /// The arm the controller drives; `None` before there is one (the controller is blank).
    arm: Option<ArmId>,
    /// The controller, built once and configured in place for each arm: a second one on the
    /// stack would cost more than a board's whole stack budget.
    controller: Controller<N, Q>,
    staging: Staging<N>,
    /// Telemetry period (µs) and when the next frame is due.
    telemetry: Option<(u64, u64)>,
    loops: LoopStats,
    /// The board's link receive losses, as its main loop last set them.
    receive_loss: ReceiveLoss,
}

impl<const N: usize, const Q: usize> Core<N, Q> {
    /// The core of [`Firmware::blank`]; only ever built in place, or for the compiler's
    /// completeness check in [`Firmware::blank_in`].
    fn blank(board: Board) -> Self {
        let mut slot = core::mem::MaybeUninit::uninit();
        // SAFETY: the pointer is the local slot's; `blank_at` initialises it whole.
        #[allow(unsafe_code)]
        unsafe {
            Self::blank_at(slot.as_mut_ptr(), board);
            slot.assume_init()
        }
    }

    /// [`Core::blank`] written field by field at `at`.
    ///
    /// # Safety
    /// `at` must be valid for writes and aligned. Every field is written (see
    /// [`crate::place::place_fields`]); nothing is read or dropped.
    #[allow(unsafe_code)]
    unsafe fn blank_at(at: *mut Self, board: Board) {
        crate::place::place_fields!(at: Self {
            board: board,
            builtin: None,
            arm: None,
            staging: Staging::new(),
            telemetry: None,
            loops: LoopStats::default(),
            receive_loss: ReceiveLoss::default(),
        } in place {
            controller: Controller::blank(board.model, board.control)
                => |controller| Controller::blank_at(controller, board.model, board.control),
            incoming: ArmSetup::blank(board.model) => |incoming| ArmSetup::blank_at(incoming, board.model),
        });
    }

    /// Checks the board and drives `builtin`, if there is one.
    fn start(&mut self, builtin: Option<&'static BuiltinArm>) -> Result<(), ConfigError> {
        if N > crate::link::message::MAX_JOINTS {
            return Err(ConfigError::TooManyJoints);
        }
        let minimum_us = minimum_period_us(self.board.model, &self.board.bus, N);
        if self.board.control.period_us < minimum_us {
            return Err(ConfigError::PeriodTooShort { minimum_us });
        }
        self.builtin = builtin;
        if builtin.is_some() {
            self.use_builtin_arm().map_err(|_| ConfigError::BuiltinRefused)?;
        }
        Ok(())
    }

    /// The controller, once there is an arm.
    fn running(&self) -> Option<&Controller<N, Q>> {
        self.arm.as_ref().map(|_| &self.controller)
    }

    /// The controller, once there is an arm.
    fn running_mut(&mut self) -> Option<&mut Controller<N, Q>> {
        match self.arm {
            Some(_) => Some(&mut self.controller),
            None => None,
        }
    }
}

/// The firmware of an arm of `N` joints with a keyframe queue of `Q`.
#[derive(Clone, Debug)]
pub struct Firmware<const N: usize, const Q: usize> {
    decoder: FrameDecoder<MAX_ENCODED>,
    session: Session,
    core: Core<N, Q>,
}

impl<const N: usize, const Q: usize> Firmware<N, Q> {
    /// Firmware for `board`, driving `builtin` until the host configures another arm (with no
    /// built-in arm, motion requests are refused until the host sends one). Fails if the control
    /// period is shorter than one bus cycle for `N` servos, or the built-in arm is refused.
    pub fn new(board: Board, builtin: Option<&'static BuiltinArm>) -> Result<Self, ConfigError> {
        let mut firmware = Self::blank(board);
        firmware.start(builtin)?;
        Ok(firmware)
    }

    /// Firmware for `board` without an arm, not yet started: built without a check that could
    /// fail, so that a board can write it straight into static memory ([`Firmware::blank_in`]),
    /// then [`Firmware::start`] it there.
    pub fn blank(board: Board) -> Self {
        let mut slot = core::mem::MaybeUninit::uninit();
        Self::blank_in(&mut slot, board);
        // SAFETY: `blank_in` initialised the slot whole.
        #[allow(unsafe_code)]
        unsafe {
            slot.assume_init()
        }
    }

    /// Writes [`Firmware::blank`] into `slot`, field by field, and returns it there: a board's
    /// way to put its firmware in static memory without ever holding it whole on the stack,
    /// which it is larger than (see [`crate::place`]).
    #[allow(unsafe_code)]
    pub fn blank_in(slot: &mut core::mem::MaybeUninit<Self>, board: Board) -> &mut Self {
        let at = slot.as_mut_ptr();
        // SAFETY: `at` is the slot's, valid for writes and aligned. `place_fields!` writes every
        // field (its struct literal does not compile if one is missing), the core through
        // `Core::blank_at`, which does the same; so the slot is whole before `assume_init_mut`.
        unsafe {
            crate::place::place_fields!(at: Self {
                decoder: FrameDecoder::new(),
                session: Session::new(),
            } in place {
                core: Core::blank(board) => |core| Core::blank_at(core, board),
            });
            slot.assume_init_mut()
        }
    }

    /// Starts driving `builtin` (or nothing until the host sends an arm), taking it as it takes an
    /// arm from the host. Fails if the control period is shorter than one bus cycle for `N`
    /// servos, or the built-in arm is refused; the firmware then stays without an arm.
    pub fn start(&mut self, builtin: Option<&'static BuiltinArm>) -> Result<(), ConfigError> {
        self.core.start(builtin)
    }

    /// The control period (µs): call [`Firmware::tick`] this often.
    pub fn period_us(&self) -> u32 {
        self.core.board.control.period_us
    }

    /// The bus the firmware expects.
    pub fn bus(&self) -> &BusConfig {
        &self.core.board.bus
    }

    /// The controller, once there is an arm.
    pub fn controller(&self) -> Option<&Controller<N, Q>> {
        self.core.running()
    }

    /// The name of the arm in use (empty before there is one).
    pub fn arm_name(&self) -> &str {
        self.core.arm.as_ref().map_or("", |a| a.name.as_str())
    }

    /// The link session's counters.
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The frame decoder's counters.
    pub fn frame_stats(&self) -> crate::link::frame::FrameStats {
        self.decoder.stats()
    }

    /// What the board's link receive path has lost so far (its counters, which wrap), for the
    /// status to report; the board's main loop sets it before handing over received bytes.
    pub fn set_receive_loss(&mut self, loss: ReceiveLoss) {
        self.core.receive_loss = loss;
    }

    /// A stop from the board itself rather than the host (a stop button; on a PC, the signal that
    /// ends the process hosting the core): as the host's `Stop`, the arm decelerates within its
    /// limits, drops its queue and holds. Does nothing before there is an arm.
    pub fn stop(&mut self, now_us: u64) {
        if let Some(c) = self.core.running_mut() {
            let _ = c.command(crate::controller::Command::Stop, now_us);
        }
    }

    /// Torque off from the board itself (a second signal to the process hosting the core): the
    /// arm goes limp on the next tick.
    pub fn torque_off(&mut self, now_us: u64) {
        if let Some(c) = self.core.running_mut() {
            let _ = c.command(crate::controller::Command::TorqueOff, now_us);
        }
    }

    /// Takes bytes received from the host at `now_us`; every complete frame is answered on `tx`
    /// (replies to requests, nak events for broken frames). Returns the first write error, after
    /// which the remaining bytes are still decoded but their replies are lost like a broken line's.
    pub fn receive<W: Write>(&mut self, bytes: &[u8], now_us: u64, tx: &mut W) -> Result<(), W::Error> {
        let mut result = Ok(());
        let mut out = [0u8; MAX_FRAME];
        // The link's error counts as the status reports them; they change only when a frame ends.
        let mut link = report::LinkCounts::of(&self.decoder.stats(), &self.session.stats());
        for &byte in bytes {
            let written = match self.decoder.push(byte) {
                None => continue,
                Some(Ok(frame)) => {
                    let core = &mut self.core;
                    // Any whole frame proves the host alive, a repeat included: on a noisy line
                    // the host may retransmit for a while before a reply gets through.
                    if let Some(c) = core.running_mut() {
                        let _ = c.command(crate::controller::Command::HostAlive, now_us);
                    }
                    self.session.handle(&frame, &mut out, |message| core.apply(message, now_us, link))
                }
                Some(Err(error)) => self.session.nak_broken(&error, &mut out),
            };
            link = report::LinkCounts::of(&self.decoder.stats(), &self.session.stats());
            // A reply always fits a frame (every message's bound is below MAX_FRAME); should one
            // not, the host times out and retransmits.
            if let Some(frame) = written.ok().and_then(|n| out.get(..n)) {
                if result.is_ok() {
                    result = tx.write_all(frame);
                }
            }
        }
        result
    }

    /// Runs one control tick at `now_us` on `master`'s bus and, if due, writes a telemetry frame to
    /// `tx`. Returns the tick's report, or `None` while there is no arm.
    pub fn tick<P, D, C, W, const BUF: usize>(
        &mut self,
        master: &mut Master<P, D, C, BUF>,
        now_us: u64,
        tx: &mut W,
    ) -> Result<Option<TickReport>, W::Error>
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
        W: Write,
    {
        let Some(controller) = self.core.running_mut() else { return Ok(None) };
        let report = controller.tick(master, now_us);
        self.core.loops.record(report.loop_us);
        if let Some((period, next)) = self.core.telemetry {
            if now_us >= next {
                // The next frame is due a period after this one, or now if ticks fell behind.
                self.core.telemetry = Some((period, (next + period).max(now_us)));
                let link = report::LinkCounts::of(&self.decoder.stats(), &self.session.stats());
                let status = self.core.status(now_us, link);
                let mut out = [0u8; MAX_FRAME];
                let written = self.session.event(&FirmwareMessage::Telemetry(status), &mut out);
                if let Some(frame) = written.ok().and_then(|n| out.get(..n)) {
                    tx.write_all(frame)?;
                }
            }
        }
        Ok(Some(report))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::table::STS3215;

    fn board() -> Board {
        let bus = BusConfig::new(STS3215.protocol, 1_000_000);
        Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: 2_000_000 }
    }

    /// The firmware written field by field into a slot full of junk is the blank firmware, every
    /// field of it (Debug shows them all, the controller's and the arm slots' included), and it
    /// starts its built-in arm as one built whole does.
    #[test]
    fn a_firmware_placed_in_a_slot_of_junk_is_the_blank_one() {
        let mut slot = core::mem::MaybeUninit::<Firmware<6, 32>>::uninit();
        // SAFETY: writing bytes into the slot's own memory; nothing reads it as a value before
        // `blank_in` has written every field.
        #[allow(unsafe_code)]
        unsafe {
            slot.as_mut_ptr().cast::<u8>().write_bytes(0xa5, core::mem::size_of::<Firmware<6, 32>>());
        }
        let placed = Firmware::blank_in(&mut slot, board());
        let whole = Firmware::<6, 32>::blank(board());
        assert_eq!(format!("{placed:?}"), format!("{whole:?}"));
        placed.start(Some(&crate::builtin::SO101)).unwrap();
        let started = Firmware::<6, 32>::new(board(), Some(&crate::builtin::SO101)).unwrap();
        assert_eq!(format!("{placed:?}"), format!("{started:?}"));
        assert_eq!(placed.arm_name(), crate::builtin::NAME);
    }

    /// Another arm on another bus, then `UseBuiltinArm`: the built-in SO-101 runs again, with its
    /// digest, on its own bus.
    #[test]
    fn the_built_in_arm_comes_back_on_its_own_bus() {
        use crate::bus::table::XM430_W350;
        use crate::link::message::{BusProtocol, FirmwareMessage, HostMessage};
        let mut firmware = Firmware::<6, 32>::new(board(), Some(&crate::builtin::SO101)).unwrap();
        let link = report::LinkCounts::of(&firmware.decoder.stats(), &firmware.session.stats());
        let apply = |firmware: &mut Firmware<6, 32>, message: HostMessage| firmware.core.apply(&message, 0, link);
        // The SO-101's joints as another arm, on Dynamixel servos at 2 Mbps.
        for message in crate::builtin::SO101.messages() {
            let message = match message {
                HostMessage::ConfigureBegin { joints, tool_xyz, tool_rpy, .. } => HostMessage::ConfigureBegin {
                    name: String::try_from("other").unwrap(),
                    joints,
                    tool_xyz,
                    tool_rpy,
                    model: XM430_W350.number,
                },
                HostMessage::ConfigureBus { .. } => {
                    HostMessage::ConfigureBus { protocol: BusProtocol::Dynamixel2, baud: 2_000_000 }
                }
                HostMessage::ConfigureDigest { .. } => HostMessage::ConfigureDigest { digest: 7 },
                other => other,
            };
            assert!(matches!(apply(&mut firmware, message), FirmwareMessage::Ack { .. }));
        }
        assert_eq!((firmware.arm_name(), firmware.bus().baud), ("other", 2_000_000));
        assert_eq!(firmware.bus().protocol, crate::bus::Protocol::Dxl2);

        assert!(matches!(apply(&mut firmware, HostMessage::UseBuiltinArm), FirmwareMessage::Ack { .. }));
        assert_eq!(firmware.arm_name(), crate::builtin::NAME);
        assert_eq!(firmware.core.arm.as_ref().map(|a| a.digest), Some(crate::builtin::DIGEST));
        assert_eq!(*firmware.bus(), board().bus);
    }

    /// Collision geometry goes with the arm: sent between begin and commit it is the running
    /// arm's; one refused message (a body on a joint the arm lacks) refuses the whole arm at
    /// commit, and the arm before stays.
    #[test]
    fn collision_geometry_is_committed_with_the_arm_or_refused_with_it() {
        use crate::link::message::{
            BodyConfig, CollisionPart, Field, FirmwareMessage, HostMessage, NakReason, ObstacleShape, Problem,
            ValueError,
        };
        let mut firmware = Firmware::<6, 32>::new(board(), Some(&crate::builtin::SO101)).unwrap();
        let link = report::LinkCounts::of(&firmware.decoder.stats(), &firmware.session.stats());
        let apply = |firmware: &mut Firmware<6, 32>, message: &HostMessage| firmware.core.apply(message, 0, link);
        let body = |frame| BodyConfig { frame, a: [0.0; 3], b: [0.1, 0.0, 0.0], radius: 0.02 };
        let geometry = |last_frame| {
            [
                HostMessage::ConfigureCollision { margin: 0.01, check: true },
                HostMessage::ConfigureBody { index: 0, body: body(None) },
                HostMessage::ConfigureBody { index: 1, body: body(Some(last_frame)) },
                HostMessage::ConfigureObstacle {
                    index: 0,
                    shape: ObstacleShape::HalfSpace { normal: [0.0, 0.0, 1.0], offset: 0.0 },
                },
                HostMessage::ConfigureAllowed { body: 0, other: CollisionPart::Obstacle(0) },
            ]
        };
        let send = |firmware: &mut Firmware<6, 32>, last_frame: u8| {
            let mut replies = std::vec::Vec::new();
            for message in crate::builtin::SO101.messages() {
                if message == HostMessage::ConfigureCommit {
                    replies.extend(geometry(last_frame).iter().map(|m| apply(firmware, m)));
                }
                replies.push(apply(firmware, &message));
            }
            replies
        };
        let replies = send(&mut firmware, 4);
        assert!(replies.iter().all(|r| matches!(r, FirmwareMessage::Ack { .. })), "{replies:?}");
        let scene = firmware.controller().unwrap().collision().scene();
        assert_eq!((scene.bodies().len(), scene.obstacles().len(), scene.margin()), (2, 1, 0.01));
        assert!(firmware.controller().unwrap().collision().active());

        // The SO-101 has five joints: a body on a sixth is refused, and the arm with it.
        let replies = send(&mut firmware, 5);
        let bad = NakReason::BadValue(ValueError { field: Field::Body, problem: Problem::Count });
        assert!(replies.contains(&FirmwareMessage::Nak { reason: bad }), "{replies:?}");
        assert_eq!(replies.last(), Some(&FirmwareMessage::Nak { reason: NakReason::BadCollision }));
        // The arm before runs on, its geometry unchanged.
        assert_eq!(firmware.controller().unwrap().collision().scene().bodies().len(), 2);

        // The built-in arm carries none: nothing is checked.
        assert!(matches!(apply(&mut firmware, &HostMessage::UseBuiltinArm), FirmwareMessage::Ack { .. }));
        assert!(!firmware.controller().unwrap().collision().active());
    }
}
