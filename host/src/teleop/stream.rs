//! The teleoperation loop: at a fixed rate, read the leader, make the reading a keyframe the
//! follower may take, and push it to the follower's player through the link.
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

use anyhow::{bail, Result};
use firmware::link::message::{FirmwareMessage, HostMessage, JointKeyframe, Joints, NakReason, RunState};

use super::leader::Reading;
use super::record::Recorder;
use crate::drive::session::Driver;
use crate::link::client::LinkError;

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

/// Pushes `keyframe` (retimed after an underrun); returns the time it was queued at.
fn push(driver: &mut Driver, mut keyframe: JointKeyframe, last_time: f64, figures: &mut Figures) -> Result<f64> {
    let mut time = f64::from(keyframe.time);
    for _ in 0..MAX_RETIMES {
        keyframe.time = time as f32;
        match driver.push(&HostMessage::PushKeyframe(keyframe.clone())) {
            Ok(FirmwareMessage::Ack { .. }) => return Ok(time),
            Ok(other) => bail!("the follower answered {other:?} to a keyframe"),
            Err(LinkError::Nak(NakReason::KeyframeTime)) => {
                figures.retimed += 1;
                time += RETIME_STEP;
            }
            Err(e) => bail!("keyframe at {time:.3} s (the previous at {last_time:.3} s): {e}"),
        }
    }
    bail!("the follower's queue kept refusing keyframes up to {time:.3} s (the previous at {last_time:.3} s)")
}

/// Runs the loop until `done` says so; the follower is then brought to rest on the last reading.
/// `read` reads the leader.
pub fn run(
    driver: &mut Driver,
    read: &mut dyn FnMut() -> Result<Reading>,
    settings: &Settings,
    mut recorder: Option<&mut Recorder>,
    done: &mut dyn FnMut(Duration) -> bool,
) -> Result<Figures> {
    let mut figures = Figures::default();
    let status = driver.status()?;
    if !matches!(status.state, RunState::Idle | RunState::TorqueOff) {
        bail!("the follower is busy ({:?}): wait, or `stop` it first; nothing was sent", status.state);
    }
    let (status, _) = driver.ready_to_move()?;
    if status.queued > 0 {
        driver.request(&HostMessage::Stop)?;
    }
    let underruns_before = status.errors.underruns;
    let period = settings.period.as_secs_f64();
    let lead = settings.lead.as_secs_f64();
    let mut previous: Vec<f64> = status.setpoints.iter().map(|&x| f64::from(x)).collect();
    let mut last_time = 0.0f64;
    // Recent readings with their host times, for the tracking figure.
    let mut history: VecDeque<(f64, Vec<f64>)> = VecDeque::new();

    let started = Instant::now();
    let mut clock = PlayClock::new(started);
    let mut playing = false;
    let mut slot = started;
    let mut iteration: u64 = 0;
    let mut failures = 0u32;
    // Statuses still to ask for every period; the recording's time at the current playback's zero.
    let mut statuses_left = 0u32;
    let mut recorded = 0.0f64;
    loop {
        let now = Instant::now();
        if now < slot {
            std::thread::sleep(slot - now);
        } else if now > slot + settings.period {
            figures.late_iterations += 1;
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
                figures.read_failures += 1;
                failures += 1;
                if failures >= MAX_READ_FAILURES {
                    let _ = driver.stop();
                    bail!("the leader did not answer {MAX_READ_FAILURES} reads in a row (the follower was stopped): {e:#}");
                }
                continue;
            }
        };
        // Due one lead after the reading, and never before the previous keyframe.
        let time = (clock.at(read_at) + lead).max(last_time + 1e-3);
        let dt = if playing { time - last_time } else { time.max(period) };
        let (q, v) = shape(&reading, &previous, dt, settings, &mut figures);
        let gripper = reading.gripper.filter(|_| settings.gripper).map(|g| g as f32);
        let keyframe =
            JointKeyframe { time: time as f32, positions: joints(&q)?, velocities: Some(joints(&v)?), gripper };
        let time = push(driver, keyframe, last_time, &mut figures)?;
        let queued_at = Instant::now();
        if !playing {
            // The first keyframe starts the playback clock at zero; statuses tell where it stands.
            driver.request(&HostMessage::Start)?;
            playing = true;
            clock = PlayClock::new(Instant::now());
            statuses_left = 20;
        }
        let due = clock.instant_of(time);
        let queued_ms = queued_at.duration_since(read_at).as_secs_f64() * 1e3;
        figures.queued_ms.push(queued_ms);
        figures.goal_ms.push(due.max(queued_at).saturating_duration_since(read_at).as_secs_f64() * 1e3);
        // The player heads for a keyframe from the one before it, so it needs this one queued by
        // the time the previous one is due; otherwise it runs out (an underrun) and brakes.
        if playing && last_time > 0.0 && queued_at > clock.instant_of(last_time) {
            figures.late_keyframes += 1;
        }
        if let Some(r) = recorder.as_deref_mut() {
            r.row(recorded + time, &q, gripper.map(f64::from))?;
        }
        figures.keyframes += 1;
        history.push_back((clock.host(read_at), q.clone()));
        while history.len() > 400 {
            history.pop_front();
        }
        previous = q;
        last_time = time;
        // Statuses: every period after a start (the clock's offset settles), then sparser.
        if statuses_left > 0 || iteration.is_multiple_of(u64::from(settings.status_every.max(1))) {
            statuses_left = statuses_left.saturating_sub(1);
            let sent = Instant::now();
            let status = driver.status()?;
            match status.state {
                RunState::Moving => clock.observe(status.play_time, sent, Instant::now()),
                // The player ran out of keyframes (they came too late), braked and holds: the
                // next keyframe starts a new playback from where it stands.
                RunState::Idle => {
                    figures.restarts += 1;
                    playing = false;
                    recorded += last_time + period;
                    last_time = 0.0;
                    previous = status.setpoints.iter().map(|&x| f64::from(x)).collect();
                    clock = PlayClock::new(Instant::now());
                    iteration += 1;
                    continue;
                }
                other => bail!("the follower left playback ({other:?}): nothing more was sent"),
            }
            // The setpoint now is what the leader read one lead ago (the host's time of the status).
            let then = clock.host(sent) - lead;
            if let Some((_, q_then)) = history.iter().rev().find(|(t, _)| *t <= then) {
                let error =
                    status.setpoints.iter().zip(q_then).map(|(s, q)| (f64::from(*s) - q).abs()).fold(0.0, f64::max);
                figures.tracking.push(error);
            }
        }
        iteration += 1;
    }
    figures.seconds = started.elapsed().as_secs_f64();
    // A last keyframe at rest where the leader was, so the player ends there without braking.
    if playing {
        let time = clock.at(Instant::now()).max(last_time) + lead.max(period);
        let keyframe = JointKeyframe {
            time: time as f32,
            positions: joints(&previous)?,
            velocities: Some(joints(&vec![0.0; previous.len()])?),
            gripper: None,
        };
        driver.push(&HostMessage::PushKeyframe(keyframe))?;
        if let Some(r) = recorder {
            r.row(recorded + time, &previous, None)?;
        }
    }
    let status = driver.status()?;
    figures.underruns = status.errors.underruns.wrapping_sub(underruns_before);
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
