//! A stream of readings to the follower's player: each reading made a keyframe the follower may
//! take and pushed through the link ([`Streamer`]). `armctl teleop` reads a leader at a fixed rate
//! ([`run`]); the Python package's `Arm.stream` and LeRobot's `armctl_follower` push whatever
//! comes, when it comes (a policy's actions), through the same [`Streamer`]. A reading that comes
//! after the player ran out (its source paused) starts a new playback from where the arm holds.
//!
//! Timing. A keyframe is due `lead` after the reading it carries, on the follower's playback clock
//! (`Status::play_time`, which the firmware reports at the status's own time, not only at ticks).
//! The host keeps that clock's offset from its own: each status tells it to within the request's
//! round trip (its middle stands for the time the status was made), and the largest of the recent
//! ones is kept, since a reply held up on its way only makes the offset look smaller; the window
//! also follows a board whose crystal drifts from the PC's. Each keyframe carries its velocity,
//! the step from the previous keyframe over the time, so the player never needs a later keyframe
//! to shape the current segment. It does need the next keyframe queued by the time it reaches
//! this one, so `lead` covers one period plus the leader's read, the link and the loop's jitter.
//!
//! Safety. A reading outside a follower joint's commanded range is clamped to it, and no joint
//! moves more than `max_step` from one keyframe to the next (LeRobot's `max_relative_target`; by
//! default the follower's speed limit over one period, so a leader that jumps is followed at the
//! speed limit). The follower's firmware then applies its own limits to whatever it is sent.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use firmware::link::message::{CartesianKeyframe, CartesianTarget, JointKeyframe, Joints, NakReason, RunState};

use super::leader::Reading;
use super::record::Recorder;
use crate::arm::servos::servos_of;
use crate::link::client::LinkError;
use crate::link::session::Keyframe;
use crate::runtime::driver::{Driver, Waited};

/// Statuses whose offsets are kept for the playback clock (about 1.6 s at one per 5 periods).
const OFFSET_WINDOW: usize = 32;
/// Consecutive failed leader reads after which the session ends (the follower is stopped).
const MAX_READ_FAILURES: u32 = 50;

/// How the loop runs.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The loop's period.
    pub period: Duration,
    /// How long after its reading a keyframe is due on the follower.
    pub lead: Duration,
    /// Largest change of each joint between consecutive keyframes (rad or m).
    pub max_step: Vec<f64>,
    /// The follower's commanded range per joint (rad or m).
    pub range: Vec<(f64, f64)>,
    /// The follower's speed limit per joint (rad/s or m/s), which keyframe velocities stay within.
    pub max_velocity: Vec<f64>,
    /// Whether keyframes carry the leader's trigger to the follower's gripper.
    pub gripper: bool,
    /// A status is asked for every this many periods (the playback clock and the tracking figure).
    pub status_every: u32,
}

impl Settings {
    /// The settings for `driver`'s follower at one keyframe a `period`, each due `lead` after its
    /// reading: the range each joint is commanded within, its speed limit, and the step clamp
    /// (`max_step` rad, by default the speed limit over one period). A status every 5 keyframes.
    pub fn for_follower(
        driver: &Driver,
        period: Duration,
        lead: Duration,
        max_step: Option<f64>,
        gripper: bool,
    ) -> Result<Self> {
        let servos = servos_of(driver.arm()).ok_or_else(|| anyhow!("the follower has no servo mapping"))?;
        // The range as the firmware holds it (f32), and within the arm's own limits (f64): a limit
        // rounded to f32 can lie just beyond the arm's (1.69 is 1.6900000572 as f32), and a value
        // there would be refused when the recording is played back.
        let range = (0..driver.joints())
            .map(|j| {
                let joint = &driver.arm().joints[j];
                servos
                    .commanded_range(driver.arm(), j)
                    .map(|(lo, hi)| (f64::from(lo).max(joint.lower), f64::from(hi).min(joint.upper)))
                    .ok_or_else(|| anyhow!("the follower's joint {} has no range within its servo", j + 1))
            })
            .collect::<Result<Vec<_>>>()?;
        // The limit as the firmware holds it (f32).
        let max_velocity = f64::from(servos.max_velocity as f32);
        let max_step = max_step.unwrap_or(max_velocity * period.as_secs_f64());
        Ok(Settings {
            period,
            lead,
            max_step: vec![max_step; driver.joints()],
            range,
            max_velocity: vec![max_velocity; driver.joints()],
            gripper: gripper && driver.gripper().is_some(),
            status_every: 5,
        })
    }
}

/// What a session measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Figures {
    /// Keyframes pushed.
    pub keyframes: u64,
    /// Wall time of the loop, s.
    pub seconds: f64,
    /// Iterations that started more than a period late (their slots were skipped).
    pub late_iterations: u64,
    /// Leader reads that failed.
    pub read_failures: u64,
    /// Joint values moved back by the step clamp.
    pub clamped_steps: u64,
    /// Joint values moved back into the follower's range.
    pub limited_values: u64,
    /// Reading to keyframe acknowledged by the follower (in its queue), ms, one per keyframe.
    pub queued_ms: Vec<f64>,
    /// Reading to the keyframe due on the follower (its lead, or later if it was queued late), ms.
    pub goal_ms: Vec<f64>,
    /// Keyframes acknowledged after the previous one was due (when the player needed them).
    pub late_keyframes: u64,
    /// The follower's setpoint against the leader one lead earlier, largest over the joints, rad.
    pub tracking: Vec<f64>,
    /// Underruns the follower counted during the session.
    pub underruns: u32,
    /// Playbacks started again after the follower ran out of keyframes and held.
    pub restarts: u64,
    /// Pushes retimed later after an underrun shifted the follower's queue.
    pub retimed: u64,
    /// Times the follower's collision check stopped it short of a contact (it then holds there
    /// until the stream moves it away), and the last such stop in words.
    pub collision_stops: u64,
    /// The last collision stop, its pair named.
    pub last_collision: Option<String>,
}

impl Figures {
    /// Keyframes per second.
    pub fn rate_hz(&self) -> f64 {
        if self.seconds > 0.0 {
            self.keyframes as f64 / self.seconds
        } else {
            0.0
        }
    }
}

/// A stream's figures in summary, as a stream of actions reports them when it ends (Python's
/// `Stream.close`): counts, and the latencies and tracking by their quantiles.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Keyframes pushed.
    pub keyframes: u64,
    /// Wall time of the stream, s.
    pub seconds: f64,
    /// Keyframes per second.
    pub rate_hz: f64,
    /// Reading to keyframe queued and to keyframe due, ms: median and 99th percentile.
    pub latency_ms: Latency,
    /// Keyframes acknowledged after the previous one was due.
    pub late_keyframes: u64,
    /// Underruns the follower counted.
    pub underruns: u32,
    /// Playbacks started again after the follower ran dry.
    pub restarts: u64,
    /// Pushes retimed after an underrun.
    pub retimed: u64,
    /// Joint values moved back by the step clamp.
    pub clamped_steps: u64,
    /// Joint values moved back into the follower's range.
    pub limited_values: u64,
    /// The follower's setpoint against the reading one lead earlier, rad: median, 99th
    /// percentile, largest.
    pub tracking_rad: Tracking,
    /// Times the follower's collision check held it short of a contact.
    pub collision_stops: u64,
    /// The last of them, its pair named.
    pub last_collision: Option<String>,
}

/// Latencies of a stream, ms.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Latency {
    /// Reading to queued, median.
    pub queued_p50: f64,
    /// Reading to queued, 99th percentile.
    pub queued_p99: f64,
    /// Reading to due, median.
    pub goal_p50: f64,
    /// Reading to due, 99th percentile.
    pub goal_p99: f64,
}

/// Tracking of a stream, rad.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Tracking {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Figures {
    /// The figures in summary.
    pub fn summary(&self) -> Summary {
        Summary {
            keyframes: self.keyframes,
            seconds: self.seconds,
            rate_hz: self.rate_hz(),
            latency_ms: Latency {
                queued_p50: quantile(&self.queued_ms, 0.5),
                queued_p99: quantile(&self.queued_ms, 0.99),
                goal_p50: quantile(&self.goal_ms, 0.5),
                goal_p99: quantile(&self.goal_ms, 0.99),
            },
            late_keyframes: self.late_keyframes,
            underruns: self.underruns,
            restarts: self.restarts,
            retimed: self.retimed,
            clamped_steps: self.clamped_steps,
            limited_values: self.limited_values,
            tracking_rad: Tracking {
                p50: quantile(&self.tracking, 0.5),
                p99: quantile(&self.tracking, 0.99),
                max: quantile(&self.tracking, 1.0),
            },
            collision_stops: self.collision_stops,
            last_collision: self.last_collision.clone(),
        }
    }
}

/// The `q`-quantile (0..=1) of `values` (nearest rank); 0 for none.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The follower's playback clock as seen from this host.
struct PlayClock {
    origin: Instant,
    /// Recent `play_time - host time` (s); the largest is the estimate.
    offsets: VecDeque<f64>,
}

impl PlayClock {
    fn new(origin: Instant) -> Self {
        Self { origin, offsets: VecDeque::new() }
    }

    fn host(&self, at: Instant) -> f64 {
        at.duration_since(self.origin).as_secs_f64()
    }

    /// Takes a status's playback time, read between `sent` and `received`: the status was made in
    /// between, so the request's middle stands for its time.
    fn observe(&mut self, play_time: f32, sent: Instant, received: Instant) {
        let at = (self.host(sent) + self.host(received)) / 2.0;
        if self.offsets.len() == OFFSET_WINDOW {
            self.offsets.pop_front();
        }
        self.offsets.push_back(f64::from(play_time) - at);
    }

    /// The playback time at `at` (before any status: the time since the start).
    fn at(&self, at: Instant) -> f64 {
        let offset = self.offsets.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        self.host(at) + if offset.is_finite() { offset } else { 0.0 }
    }

    /// The host instant at which the playback clock reaches `play`.
    fn instant_of(&self, play: f64) -> Instant {
        let now = Instant::now();
        let ahead = play - self.at(now);
        if ahead >= 0.0 {
            now + Duration::from_secs_f64(ahead)
        } else {
            now.checked_sub(Duration::from_secs_f64(-ahead)).unwrap_or(now)
        }
    }
}

/// The keyframe for `reading` after `previous` (the last keyframe's joints, or the follower's
/// setpoint before the first), `dt` seconds later on the playback clock. Counts what it clamped.
fn shape(
    reading: &Reading,
    previous: &[f64],
    dt: f64,
    settings: &Settings,
    figures: &mut Figures,
) -> (Vec<f64>, Vec<f64>) {
    let mut q = Vec::with_capacity(previous.len());
    let mut v = Vec::with_capacity(previous.len());
    for (j, (&read, &before)) in reading.joints.iter().zip(previous).enumerate() {
        let (lo, hi) = settings.range[j];
        let inside = read.clamp(lo, hi);
        if inside != read {
            figures.limited_values += 1;
        }
        let step = settings.max_step[j];
        let value = inside.clamp(before - step, before + step);
        if value != inside {
            figures.clamped_steps += 1;
        }
        // The player takes no velocity beyond the limit; the step clamp keeps most within it.
        let limit = settings.max_velocity[j] * 0.999;
        v.push(((value - before) / dt).clamp(-limit, limit));
        q.push(value);
    }
    (q, v)
}

fn joints(values: &[f64]) -> Result<Joints> {
    Joints::from_slice(&values.iter().map(|&x| x as f32).collect::<Vec<_>>())
        .map_err(|_| anyhow::anyhow!("more joints than the link carries"))
}

/// After the player ran out of keyframes (one came too late) and braked, it shifts the keyframes
/// still queued later, so that the next segment starts from rest in the time it needs: a keyframe
/// timed by the playback clock may then come before the queue's last. It is pushed again
/// [`RETIME_STEP`] later each time until it fits (the latency grows by the shift until the
/// playback clock has caught up, which the figures show).
const RETIME_STEP: f64 = 0.01;
/// Retimed pushes of one keyframe before the session gives up (a shift of a second).
const MAX_RETIMES: u32 = 100;

/// Pushes the keyframe `at(time)` (retimed after an underrun); returns the time it was queued at.
fn push(
    driver: &mut Driver,
    mut time: f64,
    at: &dyn Fn(f32) -> Keyframe,
    last_time: f64,
    figures: &mut Figures,
) -> Result<f64> {
    for _ in 0..MAX_RETIMES {
        match driver.session().push(&at(time as f32)) {
            Ok(()) => return Ok(time),
            Err(LinkError::Nak(NakReason::KeyframeTime)) => {
                figures.retimed += 1;
                time += RETIME_STEP;
            }
            // The link's error kept as the cause: a keyframe the firmware refused (a `Nak`) left
            // the stream as it was, which a caller may tell from a link that failed.
            Err(e) => {
                return Err(anyhow::Error::new(e)
                    .context(format!("keyframe at {time:.3} s (the previous at {last_time:.3} s)")))
            }
        }
    }
    bail!("the follower's queue kept refusing keyframes up to {time:.3} s (the previous at {last_time:.3} s)")
}

/// Whether `e` is a keyframe the follower's firmware refused (a `Nak`: a pose it cannot reach, a
/// value out of range), which changed nothing: the stream may go on with the next reading.
pub fn refused(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| matches!(cause.downcast_ref::<LinkError>(), Some(LinkError::Nak(_))))
}

/// A keyframe as it was sent.
#[derive(Clone, Debug, PartialEq)]
pub struct Sent {
    /// Its time on the follower's playback clock, s (since the stream began, across restarts).
    pub time: f64,
    /// The joints sent (after the range and step clamps); empty for a pose.
    pub joints: Vec<f64>,
    /// The gripper opening sent, percent.
    pub gripper: Option<f64>,
}

/// A stream of keyframes to the follower's player, each due `lead` after the reading it carries,
/// pushed one at a time as the readings come: by [`run`]'s fixed-rate loop (`armctl teleop`), or by
/// whoever has the next reading (a LeRobot policy's actions, through the Python package).
pub struct Streamer {
    settings: Settings,
    figures: Figures,
    clock: PlayClock,
    playing: bool,
    /// The last keyframe's joints (before the first: the follower's setpoint).
    previous: Vec<f64>,
    /// The last joint keyframe sent, which the stream ends on (even if a restart dropped it).
    last_sent: Option<Vec<f64>>,
    /// The last keyframe sent was at rest (every velocity zero: the reading had not changed).
    previous_at_rest: bool,
    last_time: f64,
    /// Recent readings with their host times, for the tracking figure.
    history: VecDeque<(f64, Vec<f64>)>,
    /// Statuses still to ask for every keyframe (after a start, while the clock's offset settles).
    statuses_left: u32,
    /// Keyframes since the last status.
    since_status: u32,
    /// The recording's time at the current playback's zero.
    recorded: f64,
    underruns_before: u32,
    started: Instant,
    /// The count of the follower's last collision stop, as last seen.
    collision_count: Option<u32>,
    /// A collision stop was seen and the follower has not yet come to rest after it.
    braking_short: bool,
}

impl Streamer {
    /// Makes the follower ready: idle (else an error, nothing sent), torque on, its queue empty.
    pub fn begin(driver: &mut Driver, settings: Settings) -> Result<Self> {
        let status = driver.status()?;
        if !matches!(status.state, RunState::Idle | RunState::TorqueOff) {
            bail!("the follower is busy ({:?}): wait, or `stop` it first; nothing was sent", status.state);
        }
        let (status, _) = driver.ready_to_move()?;
        if status.queued > 0 {
            driver.session().stop()?;
        }
        let started = Instant::now();
        Ok(Self {
            settings,
            figures: Figures::default(),
            clock: PlayClock::new(started),
            playing: false,
            previous: status.setpoints.iter().map(|&x| f64::from(x)).collect(),
            last_sent: None,
            previous_at_rest: false,
            last_time: 0.0,
            history: VecDeque::new(),
            statuses_left: 0,
            since_status: 0,
            recorded: 0.0,
            underruns_before: status.errors.underruns,
            started,
            collision_count: status.last_collision.map(|c| c.count),
            braking_short: false,
        })
    }

    /// The settings it streams with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// What it measured so far.
    pub fn figures(&self) -> &Figures {
        &self.figures
    }

    /// The last joints sent (before the first: the follower's setpoint).
    pub fn last_joints(&self) -> &[f64] {
        &self.previous
    }

    /// Counts a reading that could not be taken (the figures' `read_failures`).
    pub fn missed_reading(&mut self) {
        self.figures.read_failures += 1;
    }

    /// The playback time a reading made at `read_at` is due at: one lead later, never before the
    /// previous keyframe. A reading that comes after the previous keyframe was due (its source
    /// paused) first asks for a status: the player has then run out and holds, and the keyframe
    /// starts a new playback.
    fn due(&mut self, driver: &mut Driver, read_at: Instant) -> Result<f64> {
        // A full queue while playing is a player that stopped taking keyframes (it ran dry under
        // a late host and holds): pushing would wait for a slot forever. Look first.
        let full = driver.free_slots() == 0;
        if self.playing && (full || self.clock.at(read_at) > self.last_time + self.settings.period.as_secs_f64()) {
            self.look(driver)?;
        }
        Ok((self.clock.at(read_at) + self.settings.lead.as_secs_f64()).max(self.last_time + 1e-3))
    }

    /// Refuses a reading that cannot be a keyframe (another joint count, a value not finite); a
    /// refused reading changes nothing, and the stream goes on with the next.
    pub fn check(&self, reading: &Reading) -> Result<()> {
        if reading.joints.len() != self.previous.len() {
            bail!(
                "{} joint values, but the follower has {} joints: nothing was sent",
                reading.joints.len(),
                self.previous.len()
            );
        }
        if let Some(bad) = reading.joints.iter().chain(&reading.gripper).find(|x| !x.is_finite()) {
            bail!("a reading holds {bad}: nothing was sent");
        }
        Ok(())
    }

    /// Sends `reading`, made at `read_at`, as a joint keyframe: clamped into the follower's range
    /// and to one step from the last keyframe, with the velocity that reaches it. Returns what was
    /// sent.
    pub fn send(&mut self, driver: &mut Driver, reading: &Reading, read_at: Instant) -> Result<Sent> {
        self.check(reading)?;
        let time = self.due(driver, read_at)?;
        let period = self.settings.period.as_secs_f64();
        let dt = if self.playing { time - self.last_time } else { time.max(period) };
        let (q, v) = shape(reading, &self.previous, dt, &self.settings, &mut self.figures);
        let gripper = reading.gripper.filter(|_| self.settings.gripper).map(|g| g.clamp(0.0, 100.0) as f32);
        let (positions, velocities) = (joints(&q)?, joints(&v)?);
        let at = |time: f32| {
            Keyframe::Joints(JointKeyframe {
                time,
                positions: positions.clone(),
                velocities: Some(velocities.clone()),
                gripper,
            })
        };
        let recorded = self.pushed(driver, time, &at, read_at, Some(&q))?;
        self.previous = q.clone();
        self.last_sent = Some(q.clone());
        self.previous_at_rest = v.iter().all(|&x| x == 0.0);
        Ok(Sent { time: recorded, joints: q, gripper: gripper.map(f64::from) })
    }

    /// Sends the tool pose `target`, read at `read_at`, as a Cartesian keyframe: the follower's
    /// firmware solves it (warm started, within the joint limits) as its player reaches it.
    pub fn send_pose(
        &mut self,
        driver: &mut Driver,
        target: CartesianTarget,
        gripper: Option<f64>,
        read_at: Instant,
    ) -> Result<Sent> {
        let values = target.position.iter().chain(target.orientation.iter().flatten());
        if let Some(bad) = values.map(|&x| f64::from(x)).chain(gripper).find(|x| !x.is_finite()) {
            bail!("a pose holds {bad}: nothing was sent");
        }
        let time = self.due(driver, read_at)?;
        let gripper = gripper.filter(|_| self.settings.gripper).map(|g| g.clamp(0.0, 100.0) as f32);
        let at = |time: f32| Keyframe::Pose(CartesianKeyframe { time, target, gripper });
        let recorded = self.pushed(driver, time, &at, read_at, None)?;
        // A pose stream ends where the firmware's solve of its last pose is, not on joints; the
        // firmware chooses the pose's velocity.
        self.last_sent = None;
        self.previous_at_rest = false;
        Ok(Sent { time: recorded, joints: Vec::new(), gripper: gripper.map(f64::from) })
    }

    /// The recording's time of `time` on the current playback's clock.
    fn recorded_time(&self, time: f64) -> f64 {
        self.recorded + time
    }

    /// Pushes a keyframe due at `time`, starts the playback with the first, keeps the figures and,
    /// now and then, asks for a status (the playback clock, the tracking, a follower that ran out
    /// of keyframes). Returns the keyframe's time in the recording.
    fn pushed(
        &mut self,
        driver: &mut Driver,
        time: f64,
        at: &dyn Fn(f32) -> Keyframe,
        read_at: Instant,
        joints: Option<&[f64]>,
    ) -> Result<f64> {
        let time = push(driver, time, at, self.last_time, &mut self.figures)?;
        // On the clock of the playback it went into, taken now: the status read below can find
        // that playback ended and move the recording's offset on for the next one, which would
        // put this keyframe after the next ones in the file.
        let recorded = self.recorded_time(time);
        let queued_at = Instant::now();
        if !self.playing {
            // The first keyframe starts the playback clock at zero; statuses tell where it stands.
            driver.session().start()?;
            self.playing = true;
            self.clock = PlayClock::new(Instant::now());
            self.statuses_left = 20;
        }
        // The player heads for a keyframe from the one before it, so it needs this one queued by
        // the time the previous one is due; otherwise it runs out (an underrun) and brakes.
        let previous_due = self.clock.instant_of(self.last_time);
        if self.last_time > 0.0 && queued_at > previous_due {
            self.figures.late_keyframes += 1;
        }
        if self.previous_at_rest && self.last_time > 0.0 && queued_at + REST_RACE > previous_due {
            // The previous keyframe was at rest: a player that reached it before this one was
            // queued ended there and holds, and this one waits for a start. A status now tells
            // (after this push the player cannot come to rest there any more); if so this one
            // goes again, the first of a new playback. Else a stream that stops here would
            // leave the arm on the previous keyframe, not on the last one sent.
            self.look(driver)?;
            if !self.playing {
                let period = self.settings.period.as_secs_f64();
                return self.pushed(driver, period, at, read_at, joints);
            }
        }
        let due = self.clock.instant_of(time);
        self.figures.queued_ms.push(queued_at.duration_since(read_at).as_secs_f64() * 1e3);
        self.figures.goal_ms.push(due.max(queued_at).saturating_duration_since(read_at).as_secs_f64() * 1e3);
        self.figures.keyframes += 1;
        if let Some(q) = joints {
            self.history.push_back((self.clock.host(read_at), q.to_vec()));
            while self.history.len() > 400 {
                self.history.pop_front();
            }
        }
        self.last_time = time;
        self.since_status += 1;
        // Statuses: every keyframe after a start (the clock's offset settles), then sparser.
        if self.statuses_left > 0 || self.since_status >= self.settings.status_every.max(1) {
            self.statuses_left = self.statuses_left.saturating_sub(1);
            self.since_status = 0;
            self.look(driver)?;
        }
        Ok(recorded)
    }

    /// Asks for a status: where the playback clock stands, how well the setpoint tracks, and
    /// whether the player ran out of keyframes and holds (the next keyframe then starts anew).
    fn look(&mut self, driver: &mut Driver) -> Result<()> {
        let sent = Instant::now();
        let status = driver.status()?;
        let count = status.last_collision.map(|c| c.count);
        if count.is_some() && count != self.collision_count {
            // Stopped short of a contact: the follower holds there, and the stream goes on from
            // there (a new playback once it has run dry), held short as long as it pushes on.
            self.collision_count = count;
            self.braking_short = true;
            self.figures.collision_stops += 1;
            self.figures.last_collision =
                status.last_collision.as_ref().map(|c| crate::link::collision::stop(driver.arm(), c));
        }
        match status.state {
            RunState::Moving => self.clock.observe(status.play_time, sent, Instant::now()),
            // Braking short of the contact: the follower comes to rest, then holds (Idle).
            RunState::Stopping if self.braking_short => {}
            RunState::Idle => {
                self.braking_short = false;
                if status.queued > 0 {
                    // Keyframes left from the playback that ran dry are timed on its clock; the
                    // new playback starts its own at zero, so they go (the arm holds where it is).
                    driver.session().stop()?;
                }
                self.figures.restarts += 1;
                self.playing = false;
                self.recorded += self.last_time + self.settings.period.as_secs_f64();
                self.last_time = 0.0;
                self.previous = status.setpoints.iter().map(|&x| f64::from(x)).collect();
                self.clock = PlayClock::new(Instant::now());
                return Ok(());
            }
            other => bail!("the follower left playback ({other:?}): nothing more was sent"),
        }
        // The setpoint now is what the reading one lead ago asked for (the host's time of the status).
        let then = self.clock.host(sent) - self.settings.lead.as_secs_f64();
        if let Some((_, q_then)) = self.history.iter().rev().find(|(t, _)| *t <= then) {
            let error = status.setpoints.iter().zip(q_then).map(|(s, q)| (f64::from(*s) - q).abs()).fold(0.0, f64::max);
            self.figures.tracking.push(error);
        }
        Ok(())
    }

    /// Ends the stream: a last keyframe at rest on the last joints sent, so that the player ends
    /// there without braking (after joint keyframes), and the follower brought to rest on it.
    /// Returns the figures and that keyframe.
    ///
    /// A player that came to rest on a keyframe at rest (the leader held still for a reading)
    /// before the next one was queued holds there, and what was queued after it waits for a
    /// start: mid-stream a status finds that and the stream starts anew, but after the last
    /// status nothing would. So the last keyframe goes again, as a playback of its own from where
    /// the follower holds.
    pub fn finish(mut self, driver: &mut Driver) -> Result<(Figures, Option<Sent>)> {
        self.figures.seconds = self.started.elapsed().as_secs_f64();
        let mut last = None;
        if let Some(q) = self.last_sent.clone() {
            let period = self.settings.period.as_secs_f64();
            let at_rest = |time: f64| -> Result<Keyframe> {
                Ok(Keyframe::Joints(JointKeyframe {
                    time: time as f32,
                    positions: joints(&q)?,
                    velocities: Some(joints(&vec![0.0; q.len()])?),
                    gripper: None,
                }))
            };
            // After a restart the last keyframe was dropped with the queue: a playback of its own.
            let time = if self.playing {
                self.clock.at(Instant::now()).max(self.last_time) + self.settings.lead.as_secs_f64().max(period)
            } else {
                period
            };
            driver.session().push(&at_rest(time)?)?;
            if !self.playing {
                driver.session().start()?;
            }
            last = Some(Sent { time: self.recorded_time(time), joints: q.clone(), gripper: None });
            if let Waited::Done(status) = driver.wait_until_rest(FINISH_TIMEOUT)? {
                if status.queued > 0 {
                    // At rest short of it, the rest of the stream queued: that goes, this plays.
                    driver.stop()?;
                    driver.session().push(&at_rest(period)?)?;
                    driver.session().start()?;
                    self.figures.restarts += 1;
                }
            }
        }
        let status = driver.status()?;
        self.figures.underruns = status.errors.underruns.wrapping_sub(self.underruns_before);
        Ok((self.figures, last))
    }
}

/// How far ahead of a keyframe at rest being due (by the host's estimate of the playback clock)
/// the next one is taken as possibly too late for it: the estimate's error, with room.
const REST_RACE: Duration = Duration::from_millis(10);

/// How long [`Streamer::finish`] waits for the follower to come to rest (controller time, s):
/// the queue's worth of keyframes and the brake, with room.
const FINISH_TIMEOUT: f64 = 10.0;

/// Runs the loop until `done` says so; the follower is then brought to rest on the last reading.
/// `read` reads the leader.
pub fn run(
    driver: &mut Driver,
    read: &mut dyn FnMut() -> Result<Reading>,
    settings: &Settings,
    mut recorder: Option<&mut Recorder>,
    done: &mut dyn FnMut(Duration) -> bool,
) -> Result<Figures> {
    let mut stream = Streamer::begin(driver, settings.clone())?;
    let started = Instant::now();
    let mut slot = started;
    let mut failures = 0u32;
    loop {
        let now = Instant::now();
        if now < slot {
            std::thread::sleep(slot - now);
        } else if now > slot + settings.period {
            stream.figures.late_iterations += 1;
            slot = now;
        }
        slot += settings.period;
        if done(started.elapsed()) {
            break;
        }
        let read_at = Instant::now();
        let reading = match read() {
            Ok(r) => {
                failures = 0;
                r
            }
            Err(e) => {
                stream.missed_reading();
                failures += 1;
                if failures >= MAX_READ_FAILURES {
                    let _ = driver.stop();
                    bail!("the leader did not answer {MAX_READ_FAILURES} reads in a row (the follower was stopped): {e:#}");
                }
                continue;
            }
        };
        let sent = stream.send(driver, &reading, read_at)?;
        if let Some(r) = recorder.as_deref_mut() {
            r.row(sent.time, &sent.joints, sent.gripper)?;
        }
    }
    let (figures, last) = stream.finish(driver)?;
    if let (Some(r), Some(last)) = (recorder, last) {
        r.row(last.time, &last.joints, None)?;
    }
    Ok(figures)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> Settings {
        Settings {
            period: Duration::from_millis(10),
            lead: Duration::from_millis(15),
            max_step: vec![0.02, 0.02],
            range: vec![(-1.0, 1.0), (-0.5, 0.5)],
            max_velocity: vec![2.0, 2.0],
            gripper: false,
            status_every: 5,
        }
    }

    /// A reading is clamped into the range first, then to one step from the previous keyframe;
    /// the velocity is the step over the time and within the limit.
    #[test]
    fn readings_are_clamped_to_the_range_and_the_step() {
        let mut figures = Figures::default();
        let reading = Reading { joints: vec![0.005, 0.9], gripper: None };
        let (q, v) = shape(&reading, &[0.0, 0.49], 0.01, &settings(), &mut figures);
        assert_eq!(q, vec![0.005, 0.5]);
        assert!((v[0] - 0.5).abs() < 1e-9 && (v[1] - 1.0).abs() < 1e-9, "{v:?}");
        assert_eq!((figures.limited_values, figures.clamped_steps), (1, 0));
        let jump = Reading { joints: vec![0.8, -0.5], gripper: None };
        let (q, v) = shape(&jump, &[0.0, 0.0], 0.005, &settings(), &mut figures);
        assert_eq!(q, vec![0.02, -0.02]);
        assert!(v.iter().all(|x| x.abs() <= 2.0 * 0.999 + 1e-12), "{v:?}");
        assert_eq!((figures.limited_values, figures.clamped_steps), (1, 2));
    }

    /// The playback clock is the host's plus the largest recent offset: a status whose reply was
    /// held up on its way (its request's middle later than when it was made) tells less.
    #[test]
    fn the_playback_clock_keeps_the_largest_offset() {
        let origin = Instant::now();
        let mut clock = PlayClock::new(origin);
        let at = |ms: u64| origin + Duration::from_millis(ms);
        assert!((clock.at(at(100)) - 0.1).abs() < 1e-9);
        // The playback clock is 7 ms ahead of the host's.
        clock.observe(0.015, at(7), at(9)); // made at 8 ms
        clock.observe(0.020, at(12), at(18)); // made at 13 ms, its reply 4 ms late: middle 15 ms
        clock.observe(0.030, at(22), at(24));
        assert!((clock.at(at(100)) - (0.1 + 0.007)).abs() < 1e-9, "{}", clock.at(at(100)));
    }

    #[test]
    fn quantiles_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 50.0);
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(quantile(&[], 0.5), 0.0);
    }
}
