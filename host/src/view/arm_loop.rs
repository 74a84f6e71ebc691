//! The arm loop: one thread owns the connection to the firmware. It polls the status once per
//! control period, publishes it as telemetry, carries out the API's requests between polls, and
//! streams a keyframe file as the firmware's queue frees slots. Nothing else touches the link, so
//! the page, scripts and the stop button all go through the same queue of requests, where a stop
//! goes first ([`super::jobs`]).
//!
//! On Ctrl-C ([`ArmLoop::begin_stop`]) it stops the arm as its first act, keeps publishing the
//! status until the arm holds, and only then closes the link; [`ArmLoop::torque_off`] (a second
//! Ctrl-C) switches the torque off instead of waiting.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::Result;
use firmware::link::message::{CartesianTarget, MovePath, RunState, Status, Timing, MAX_SPEED};
use serde_json::{json, Value};

use super::api::{ApiError, Request};
use super::jobs::{Answer, JobQueue};
use super::telemetry::{self, Extras, LastSecond, Latest, Placement};
use crate::arm::collision::edit::{geometry_json, geometry_of, source_of};
use crate::arm::dof::DynArm;
use crate::arm::ArmSpec;
use crate::commands::drive::path::{self, RefusedBy};
use crate::commands::drive::play::Plan;
use crate::link::client::LinkError;
use crate::link::session::Keyframe;
use crate::runtime::connection::Target;
use crate::runtime::driver::{check_joints, Driver};

/// The poll period: the firmware's control period, so the telemetry shows every setpoint.
pub const PERIOD: Duration = Duration::from_millis(10);
/// The tool speed of a target sent with "go" (m/s): brisk enough to follow a dragged target.
const TARGET_SPEED: f32 = 0.2;
/// How long a file may run past its last keyframe before it counts as stuck (s).
const PLAY_MARGIN: f64 = 30.0;
/// How long the arm may take to come to rest after the stop of Ctrl-C: a braking arm takes
/// about a second; past this the loop says so and closes the link (the firmware's watchdog then
/// brakes it).
const EXIT_STOP_TIME: Duration = Duration::from_secs(10);

/// A file being streamed to the firmware's queue.
struct Playing {
    name: String,
    plan_seconds: f64,
    messages: Vec<(usize, Keyframe)>,
    /// Line numbers' owner, for messages.
    plan: Plan,
    pushed: usize,
    started: bool,
    done: bool,
    error: Option<String>,
    play_time: f32,
}

impl Playing {
    fn json(&self) -> Value {
        json!({
            "name": self.name, "keyframes": self.messages.len(), "pushed": self.pushed, "seconds": self.plan_seconds,
            "play_time": self.play_time, "done": self.done, "error": self.error,
        })
    }
}

/// Where a loop's arm sits in the view: the slot of [`Latest`] its telemetry goes to, its name in a
/// rig (added to its telemetry as `"arm"`), and the frame the API speaks for it.
pub struct Seat {
    /// Where the telemetry goes.
    pub latest: Arc<Latest>,
    /// The arm's slot in `latest`.
    pub slot: usize,
    /// The arm's name in a rig; `None` in the one-arm view.
    pub name: Option<String>,
    /// The frame of the positions the API takes and gives for this arm.
    pub placement: Placement,
}

impl Seat {
    /// The one arm of the one-arm view: slot 0, no name, its base frame.
    pub fn alone(latest: Arc<Latest>) -> Self {
        Self { latest, slot: 0, name: None, placement: Placement::default() }
    }
}

/// The running loop; dropping it ends the thread after it has stopped the arm.
pub struct ArmLoop {
    jobs: Arc<JobQueue>,
    quit: Arc<AtomicBool>,
    torque_off: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<String>>>,
}

impl ArmLoop {
    /// Connects to `target` (configuring `arm` on it when given) on the loop's own thread, which
    /// then owns the link, and starts polling; returns once connected, with the arm the firmware
    /// runs and its queue capacity. What connecting says is written on `err`.
    pub fn spawn(
        target: Target,
        arm: Option<String>,
        latest: Arc<Latest>,
        err: &mut dyn std::io::Write,
    ) -> Result<(Self, ArmSpec, usize)> {
        Self::spawn_seated(target, arm, Seat::alone(latest), err)
    }

    /// [`Self::spawn`] for an arm seated as `seat` says (an arm of a rig).
    pub fn spawn_seated(
        target: Target,
        arm: Option<String>,
        seat: Seat,
        err: &mut dyn std::io::Write,
    ) -> Result<(Self, ArmSpec, usize)> {
        let jobs = Arc::new(JobQueue::default());
        let (opened, connected) = mpsc::channel();
        let quit = Arc::new(AtomicBool::new(false));
        let torque_off = Arc::new(AtomicBool::new(false));
        let thread = {
            let (quit, torque_off, inbox) = (quit.clone(), torque_off.clone(), jobs.clone());
            std::thread::Builder::new().name("view-arm".into()).spawn(move || {
                // What connecting says is handed back to the caller, which holds the stderr lock.
                let mut said = Vec::new();
                let open = || -> Result<(Driver, Box<dyn DynArm>)> {
                    let driver = Driver::open(target, arm.as_deref(), &mut said)?;
                    let fk = crate::arm::dof::build(driver.arm().clone())?;
                    Ok((driver, fk))
                };
                let (driver, fk) = match open() {
                    Ok(both) => both,
                    Err(e) => {
                        let _ = opened.send((said, Err(e)));
                        return Ok(String::new());
                    }
                };
                let capacity = driver.queue_capacity();
                let _ = opened.send((said, Ok((driver.arm().clone(), capacity))));
                let extras = Extras { queue_capacity: capacity, ..Extras::default() };
                let state = LoopState { driver, fk, seat, extras, playing: None, seq: 0, rate: LastSecond::default() };
                state.run(&inbox, &quit, &torque_off)
            })?
        };
        let (said, answer) = connected.recv().map_err(|_| anyhow::anyhow!("the arm loop ended before connecting"))?;
        err.write_all(&said)?;
        let (spec, capacity) = answer?;
        Ok((Self { jobs, quit, torque_off, thread: Some(thread) }, spec, capacity))
    }

    /// The queue requests go to.
    pub fn jobs(&self) -> Arc<JobQueue> {
        self.jobs.clone()
    }

    /// Ctrl-C: refuses new requests and stops the arm before anything else; the loop ends once
    /// the arm holds ([`Self::is_finished`]).
    pub fn begin_stop(&self) {
        self.jobs.close();
        self.quit.store(true, Ordering::SeqCst);
    }

    /// A second Ctrl-C: torque off now, rather than waiting for the arm to hold.
    pub fn torque_off(&self) {
        self.torque_off.store(true, Ordering::SeqCst);
        self.begin_stop();
    }

    /// True once the loop has ended (the link failed for good).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Stops the arm (decelerating within its limits), waits until it holds, ends the loop and
    /// closes the connection; returns what closing said, or the loop's error.
    pub fn finish(mut self) -> Result<String> {
        self.begin_stop();
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| Err(anyhow::anyhow!("the arm loop panicked"))),
            None => Ok(String::new()),
        }
    }
}

impl Drop for ArmLoop {
    fn drop(&mut self) {
        self.begin_stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct LoopState {
    driver: Driver,
    fk: Box<dyn DynArm>,
    seat: Seat,
    extras: Extras,
    playing: Option<Playing>,
    seq: u64,
    rate: LastSecond,
}

/// A link error as an API error: a refusal is the firmware's word (422), anything else means the
/// firmware is not answering (503).
fn link_error(e: LinkError) -> ApiError {
    match e {
        LinkError::Nak(_) => ApiError::new(422, format!("{e}")),
        other => ApiError::new(503, format!("the firmware did not answer: {other}")),
    }
}

/// Says in `value` which path a Cartesian move took (`line` or `joint`) and why.
fn describe(value: &mut Value, taken: &str, how: &str) {
    value["path"] = json!(taken);
    value["how"] = json!(how);
}

fn ok() -> Result<Value, ApiError> {
    Ok(json!({"ok": true}))
}

impl LoopState {
    /// Returns what closing the connection said (for `--bus`, the control loop's counts).
    fn run(mut self, inbox: &JobQueue, quit: &AtomicBool, torque_off: &AtomicBool) -> Result<String> {
        let mut next = Instant::now();
        let mut last_status: Option<Status> = None;
        while !quit.load(Ordering::SeqCst) {
            // Requests first, a stop first of all (the queue's order): a stop must not wait
            // behind a poll.
            while let Some(job) = inbox.next() {
                let (request, reply) = job.split();
                let answer: Answer = self.handle(request, last_status.as_ref());
                if let Err(e) = &answer {
                    self.extras.last_error = Some(e.message.clone());
                }
                reply.send(answer);
                if quit.load(Ordering::SeqCst) {
                    break;
                }
            }
            self.feed();
            match self.driver.status() {
                Ok(status) => {
                    self.follow_play(&status);
                    self.publish(&status);
                    last_status = Some(status);
                }
                Err(e) => self.extras.last_error = Some(format!("status: {e:#}")),
            }
            next += PERIOD;
            let now = Instant::now();
            if next <= now {
                // Late (a slow request): start the next period from now rather than catch up.
                next = now;
            }
            // Until the next poll, or at once when a request comes.
            inbox.wait(next);
        }
        let stopped = self.stop_for_exit(torque_off);
        let mut said = Vec::new();
        let closed = self.driver.close(&mut said);
        let said = String::from_utf8_lossy(&said).into_owned();
        let how = stopped?;
        closed.map(|_| format!("{said}{how}\n"))
    }

    /// Ctrl-C: stop (the arm decelerates within its limits), publishing the status until it
    /// holds; torque off instead when `torque_off` is set. Returns what happened, in words.
    fn stop_for_exit(&mut self, torque_off: &AtomicBool) -> Result<String> {
        if let Some(p) = self.playing.as_mut().filter(|p| !p.done) {
            p.done = true;
            p.error =
                Some(format!("stopped by Ctrl-C after {} of {} keyframes were pushed", p.pushed, p.messages.len()));
        }
        let asked = Instant::now();
        let mut stop_sent = false;
        loop {
            if torque_off.load(Ordering::SeqCst) {
                self.driver.session().torque_off()?;
                // The last telemetry says so, for a page still connected.
                if let Ok(status) = self.driver.status() {
                    self.publish(&status);
                }
                return Ok("second signal: torque off".to_string());
            }
            if !stop_sent {
                self.driver.session().stop()?;
                stop_sent = true;
            }
            let status = self.driver.status()?;
            self.publish(&status);
            if !matches!(status.state, RunState::Moving | RunState::Stopping | RunState::Paused) {
                let joints: Vec<String> = status.measured.iter().map(|x| format!("{x:.3}")).collect();
                return Ok(format!(
                    "stopped: the arm holds ({:?}, joints {}) {:.2} s after the signal",
                    status.state,
                    joints.join(" "),
                    asked.elapsed().as_secs_f64()
                ));
            }
            if asked.elapsed() > EXIT_STOP_TIME {
                anyhow::bail!(
                    "sent stop, but the arm was still {:?} after {} s",
                    status.state,
                    EXIT_STOP_TIME.as_secs()
                );
            }
            std::thread::sleep(PERIOD);
        }
    }

    fn publish(&mut self, status: &Status) {
        self.seq += 1;
        let window = self.rate.push(status.timing.max_us);
        if let Some(p) = &self.playing {
            self.extras.play = p.json();
        }
        match telemetry::telemetry(self.fk.as_ref(), self.seq, status, &self.extras, window, &self.seat.placement) {
            Ok(mut t) => {
                if let Some(name) = &self.seat.name {
                    t["arm"] = json!(name);
                }
                self.seat.latest.publish_arm(self.seat.slot, self.seq, t.to_string())
            }
            Err(e) => self.extras.last_error = Some(format!("telemetry: {e:#}")),
        }
    }

    fn busy_playing(&self) -> Result<(), ApiError> {
        match &self.playing {
            Some(p) if !p.done => Err(ApiError::new(409, format!("{} is playing: stop it first", p.name))),
            _ => Ok(()),
        }
    }

    fn handle(&mut self, request: Request, last: Option<&Status>) -> Result<Value, ApiError> {
        match request {
            Request::Stop => {
                if let Some(p) = self.playing.as_mut().filter(|p| !p.done) {
                    p.done = true;
                    p.error = Some(format!("stopped after {} of {} keyframes were pushed", p.pushed, p.messages.len()));
                }
                self.driver.session().stop().map_err(link_error)?;
                ok()
            }
            Request::Torque(on) => {
                // As `armctl torque` does it.
                crate::commands::drive::state::torque(&mut self.driver, on)
                    .map_err(|e| ApiError::new(503, e.to_string()))?;
                ok()
            }
            Request::Gripper(percent) => {
                if self.driver.gripper().is_none() {
                    return Err(ApiError::bad(format!("the arm {} has no gripper", self.driver.arm().name)));
                }
                self.ready()?;
                self.driver.session().gripper(percent as f32, None).map_err(link_error)?;
                ok()
            }
            Request::Joints { q, speed } => {
                self.busy_playing()?;
                check_joints(&self.driver, &q, "q").map_err(|e| ApiError::bad(format!("{e:#}")))?;
                self.ready()?;
                let timing = Timing::MaxSpeed(speed.map_or(MAX_SPEED, |s| s as f32));
                // As `armctl joints` goes: a target in collision refused, a blocked path planned.
                let start = self.driver.status().map_err(|e| ApiError::new(503, format!("{e:#}")))?;
                let from: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
                match crate::commands::drive::avoid::send(&mut self.driver, &from, &q, timing) {
                    Ok(_) => {}
                    Err(crate::commands::drive::avoid::NotSent::Host(e)) => {
                        return Err(ApiError::bad(format!("{e:#}")))
                    }
                    Err(crate::commands::drive::avoid::NotSent::Link(e)) => return Err(link_error(e)),
                }
                self.extras.last_error = None;
                ok()
            }
            Request::Target { position, orientation, go } => {
                let seed = last.map(|s| s.measured.iter().map(|&x| f64::from(x)).collect());
                // The IK and the firmware know the base frame only (a rig's targets are in the world).
                let placement = self.seat.placement;
                let (local, local_orientation) = placement.to_base(position, orientation);
                let reach = f64::from(firmware::link::message::MAX_REACH);
                if let Some(x) = local.iter().find(|x| x.abs() > reach).filter(|_| placement.base().is_some()) {
                    return Err(ApiError::bad(format!("position: {x} m is more than {reach} m from the arm's base")));
                }
                let preview =
                    super::preview::solve(self.fk.as_ref(), local, local_orientation, seed, &self.seat.placement);
                self.extras.target = json!({
                    "position": position, "orientation": orientation,
                    "reachable": preview.is_ok(), "reason": preview.as_ref().err().map(|e| e.message.clone()),
                });
                let mut solution = preview?;
                if go {
                    self.busy_playing()?;
                    self.ready()?;
                    let target = CartesianTarget {
                        position: local.map(|x| x as f32),
                        orientation: local_orientation.map(|q| q.map(|x| x as f32)),
                    };
                    // As `armctl move` decides: the straight line checked first, and a blocked one
                    // gone by joints from the start, saying so, rather than tracked into a limit.
                    let start = self.driver.status().map_err(|e| ApiError::new(503, format!("{e:#}")))?;
                    match path::take(&mut self.driver, &start, target, Timing::MaxSpeed(TARGET_SPEED), MovePath::Auto) {
                        Ok(route) => {
                            // The last word on the way is the firmware's refusal, if the host's
                            // solution went instead.
                            let avoided = route.avoided.as_ref().map(|sent| {
                                let why = path::avoided_why(self.driver.arm(), &route, sent);
                                (sent.path, why.unwrap_or_else(|| "by joints".to_string()))
                            });
                            let (taken, how) = match (&route.blocked_ahead, route.solved_on_host) {
                                _ if avoided.is_some() => avoided.unwrap_or_default(),
                                (_, true) => ("joint", path::SOLVED_ON_HOST.to_string()),
                                (Some(b), false) => (
                                    "joint",
                                    format!("{}, so the arm goes by joints", path::where_blocked(self.driver.arm(), b)),
                                ),
                                (None, false) => ("line", "the straight line".to_string()),
                            };
                            describe(&mut self.extras.target, taken, &how);
                            describe(&mut solution, taken, &how);
                        }
                        Err(refused) => {
                            let e = match refused.by {
                                RefusedBy::Host => ApiError::bad(refused.reason),
                                RefusedBy::Firmware => ApiError::new(422, refused.reason),
                                RefusedBy::Link => {
                                    ApiError::new(503, format!("the firmware did not answer: {}", refused.reason))
                                }
                            };
                            self.extras.target["reachable"] = json!(false);
                            self.extras.target["reason"] = json!(e.message);
                            return Err(e);
                        }
                    }
                    self.extras.last_error = None;
                }
                Ok(solution)
            }
            Request::Collision => Ok(self.collision_json()),
            Request::Obstacles { remove, add } => {
                // A file's keyframes were checked against the obstacles there were.
                self.busy_playing()?;
                let mut spec = geometry_of(self.driver.arm());
                let bad = |e: anyhow::Error| ApiError::bad(format!("{e:#}"));
                for name in &remove {
                    spec.remove_obstacle(name).map_err(bad)?;
                }
                for (name, shape) in add {
                    spec.add_obstacle(name.as_deref(), shape).map_err(bad)?;
                }
                let sent = self.driver.set_collision(Some(spec)).map_err(|e| ApiError::new(409, format!("{e:#}")))?;
                self.extras.collision_version += 1;
                let mut answer = self.collision_json();
                answer["sent_to_firmware"] = json!(sent);
                Ok(answer)
            }
            Request::Play { name, csv } => {
                self.busy_playing()?;
                let plan = Plan::parse(&csv, std::path::Path::new(&name), PLAY_MARGIN)
                    .map_err(|e| ApiError::bad(format!("{e:#}")))?;
                let messages = plan.keyframes(&self.driver).map_err(|e| ApiError::bad(format!("{e:#}")))?;
                let path = plan.tool_path(&self.driver).map_err(|e| ApiError::bad(format!("{e:#}")))?;
                let path: Vec<[f64; 3]> = path.into_iter().map(|p| self.seat.placement.point(p)).collect();
                if messages.is_empty() {
                    return Err(ApiError::bad(format!("{name}: no keyframes")));
                }
                let status = self.driver.status().map_err(|e| ApiError::new(503, format!("{e:#}")))?;
                if !matches!(status.state, RunState::Idle | RunState::TorqueOff) {
                    return Err(ApiError::new(
                        409,
                        format!("the arm is busy ({:?}): wait, or stop it first", status.state),
                    ));
                }
                self.ready()?;
                if status.queued > 0 {
                    // Left over from an interrupted run: not what this file says.
                    self.driver.session().stop().map_err(link_error)?;
                }
                let seconds = plan.seconds();
                let answer = json!({"keyframes": messages.len(), "seconds": seconds, "path": path});
                self.playing = Some(Playing {
                    name,
                    plan_seconds: seconds,
                    messages,
                    plan,
                    pushed: 0,
                    started: false,
                    done: false,
                    error: None,
                    play_time: 0.0,
                });
                self.extras.last_error = None;
                self.feed();
                Ok(answer)
            }
        }
    }

    /// The collision geometry the arm's commands are checked against ([`geometry_of`]), for
    /// drawing: the bodies on their joints' frames (as the telemetry's `frames` place them), the
    /// obstacles in the base frame, and the base where the API's frame has it (a rig's world).
    fn collision_json(&self) -> Value {
        let arm = self.driver.arm();
        let mut value = geometry_json(&geometry_of(arm));
        value["source"] = json!(source_of(arm));
        value["base"] = match self.seat.placement.base() {
            Some(base) => telemetry::frame(base),
            None => Value::Null,
        };
        value["version"] = json!(self.extras.collision_version);
        value
    }

    /// Torque on if it is off; an emergency stop is left to the person.
    fn ready(&mut self) -> Result<(), ApiError> {
        self.driver.ready_to_move().map(drop).map_err(|e| ApiError::new(409, format!("{e:#}")))
    }

    /// Pushes keyframes while the firmware has free slots, and starts playing once the queue is
    /// full or the file is all queued.
    fn feed(&mut self) {
        let Some(p) = self.playing.as_mut().filter(|p| !p.done) else { return };
        while p.pushed < p.messages.len() && (p.pushed == 0 || self.driver.free_slots() > 0) {
            let (line, message) = &p.messages[p.pushed];
            match self.driver.session().push(message) {
                Ok(()) => p.pushed += 1,
                Err(e) => return fail(p, &mut self.driver, format!("{}: {e}", p.plan.at(*line))),
            }
        }
        if !p.started {
            match self.driver.session().start() {
                Ok(_) => p.started = true,
                Err(e) => fail(p, &mut self.driver, format!("start: {e}")),
            }
        }
    }

    /// Follows a playing file by the status: restarts after an underrun, ends when all is played.
    fn follow_play(&mut self, status: &Status) {
        let Some(p) = self.playing.as_mut().filter(|p| !p.done && p.started) else { return };
        p.play_time = status.play_time.max(p.play_time);
        match status.state {
            RunState::Idle if p.pushed == p.messages.len() && status.queued == 0 => p.done = true,
            RunState::Idle if status.queued > 0 => {
                // The player ran dry and went to hold: go on.
                if let Err(e) = self.driver.session().start() {
                    fail(p, &mut self.driver, format!("restart: {e}"));
                }
            }
            RunState::TorqueOff | RunState::EStopped => {
                p.done = true;
                p.error =
                    Some(format!("the arm stopped ({:?}) after {} keyframes were pushed", status.state, p.pushed));
            }
            _ if f64::from(p.play_time) > p.plan_seconds + PLAY_MARGIN => {
                fail(p, &mut self.driver, format!("still {:?} {PLAY_MARGIN} s after the last keyframe", status.state))
            }
            _ => {}
        }
        if let Some(e) = p.error.clone().filter(|_| p.done) {
            self.extras.last_error = Some(format!("{}: {e}", p.name));
        }
    }
}

/// Ends a file with an error, stopping the arm.
fn fail(p: &mut Playing, driver: &mut Driver, why: String) {
    let stopped = driver.session().stop().is_ok();
    p.done = true;
    p.error = Some(format!("{why}; {}", if stopped { "stopped the arm" } else { "could not stop the arm" }));
}
