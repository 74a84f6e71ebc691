//! `armctl play FILE`: streams a keyframe file to the firmware's queue and waits until it has
//! played.
//!
//! The whole file is read and checked first (joint count and limits against the connected arm),
//! so a bad file sends nothing. Then the queue is filled up to its capacity before `Start`, and
//! the rest is pushed as slots free up (the firmware reports its free slots with every ack and
//! status). Every keyframe must be acknowledged: the count is reported. A Cartesian keyframe the
//! firmware cannot reach is refused at its push; before `Start` the queue is then dropped and
//! nothing moves, after it the arm is stopped.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use firmware::link::message::{
    CartesianKeyframe, CartesianTarget, JointKeyframe, Joints, RunState, Status, MAX_JOINT_VELOCITY, MAX_TIME,
};
use serde::Serialize;

use super::avoid;
use super::error::{interrupted, DriveError, DriveResult};
use super::progress::Progress;
use crate::link::session::seconds_waited;
use crate::link::session::Keyframe;
use crate::motion::cartesian_file::{self, parse_cartesian_keyframes, CartesianKeyframes};
use crate::motion::mocap::retarget::timebase::limits_of;
use crate::motion::plan::{as_played, check_keyframes};
use crate::motion::trajectory::{self, Keyframes};
use crate::runtime::driver::{check_joints, fmt3, Driver};
use crate::support::interrupt;

/// The keyframes of a file, in either format.
pub enum Frames {
    /// Joint keyframes (`t,q1,...,qN[,v1,...,vN]`).
    Joint(Keyframes),
    /// Cartesian keyframes (`t,x,y,z[,qw,qx,qy,qz]`).
    Cartesian(CartesianKeyframes),
}

/// A keyframe file, read and checked on its own.
pub struct Plan {
    path: PathBuf,
    frames: Frames,
    timeout: f64,
}

impl Plan {
    /// Reads and parses `path`, telling the format by its header.
    pub fn read(path: &Path, timeout: f64) -> Result<Self> {
        if !(timeout.is_finite() && timeout > 0.0) {
            bail!("--timeout: {timeout} s must be a positive number");
        }
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read keyframe file {shown}"))?;
        Self::parse(&text, path, timeout)
    }

    /// Parses the text of a keyframe file (`path` names it in messages), telling the format by
    /// its header.
    pub fn parse(text: &str, path: &Path, timeout: f64) -> Result<Self> {
        let shown = path.display().to_string();
        let Some((line, header)) = cartesian_file::header(text) else {
            bail!(
                "{shown}: empty file: expected a header t,q1,...,qN (joint keyframes) or t,x,y,z (Cartesian keyframes)"
            );
        };
        let second = header.split(',').nth(1).map(str::trim).unwrap_or_default();
        let frames = if cartesian_file::is_cartesian_header(header) {
            Frames::Cartesian(parse_cartesian_keyframes(text).context(shown.clone())?)
        } else if second.starts_with('q') {
            Frames::Joint(trajectory::parse_keyframes(text).context(shown.clone())?)
        } else {
            bail!(
                "{shown}: line {line}: the header must be t,q1,...,qN[,v1,...,vN] (joint keyframes) or \
                 t,x,y,z[,qw,qx,qy,qz] (Cartesian keyframes); found {:?}",
                header.trim()
            );
        };
        let plan = Self { path: path.to_path_buf(), frames, timeout };
        plan.check_times()?;
        Ok(plan)
    }

    /// Joint keyframes given as values (the Python binding's arrays) instead of a file's text:
    /// checked as a file's are, `name` naming them in messages, and each keyframe's "line" its
    /// number from 1, as [`Keyframes::from_rows`] (and `sample`) count them. `gripper`: the
    /// opening per keyframe, percent.
    pub fn from_joint_rows(
        times: &[f64],
        positions: &[Vec<f64>],
        gripper: Option<&[f64]>,
        name: &Path,
        timeout: f64,
    ) -> Result<Self> {
        if !(timeout.is_finite() && timeout > 0.0) {
            bail!("timeout: {timeout} s must be a positive number");
        }
        let shown = name.display().to_string();
        let mut keyframes = Keyframes::from_rows(times, positions, None).context(shown.clone())?;
        if let Some(openings) = gripper {
            if openings.len() != times.len() {
                bail!("{shown}: gripper: {} openings for {} keyframes", openings.len(), times.len());
            }
            let checked: Result<Vec<f64>> =
                openings.iter().zip(&keyframes.lines).map(|(&g, &line)| trajectory::gripper_value(line, g)).collect();
            keyframes.gripper = Some(checked.context(shown.clone())?);
        }
        let plan = Self { path: name.to_path_buf(), frames: Frames::Joint(keyframes), timeout };
        plan.check_times()?;
        Ok(plan)
    }

    fn times_and_lines(&self) -> (&[f64], &[usize]) {
        match &self.frames {
            Frames::Joint(k) => (&k.times, &k.lines),
            Frames::Cartesian(k) => (&k.times, &k.lines),
        }
    }

    /// Times the firmware accepts, still strictly increasing in its f32.
    fn check_times(&self) -> Result<()> {
        let (times, lines) = self.times_and_lines();
        let mut previous: Option<f32> = None;
        for (&t, line) in times.iter().zip(lines) {
            let at = self.at(*line);
            if !(0.0..=f64::from(MAX_TIME)).contains(&t) {
                bail!("{at}: time {t} s is outside 0..={MAX_TIME} s");
            }
            if previous.is_some_and(|p| t as f32 <= p) {
                bail!("{at}: time {t} s is too close to the previous keyframe's to tell apart in the firmware's f32");
            }
            previous = Some(t as f32);
        }
        Ok(())
    }

    /// Where line `line` of the file is, for messages.
    pub(crate) fn at(&self, line: usize) -> String {
        format!("{}: line {line}", self.path.display())
    }

    /// The last keyframe's time (s).
    pub fn seconds(&self) -> f64 {
        self.times_and_lines().0.last().copied().unwrap_or(0.0)
    }

    /// Whether the keyframes are Cartesian (tool positions) rather than joint values.
    pub fn is_cartesian(&self) -> bool {
        matches!(self.frames, Frames::Cartesian(_))
    }

    /// The longest the player may take beyond the last keyframe's time (controller seconds).
    pub fn timeout(&self) -> f64 {
        self.timeout
    }

    /// How far the arm at `measured` ended from the last keyframe, and the unit: the largest
    /// joint difference (rad) for joint keyframes, the tool's distance (m) for Cartesian ones. The
    /// firmware keeps within the joint limits, so a file that asks for more can end elsewhere.
    pub fn end_error(&self, driver: &Driver, measured: &[f32]) -> Result<(f64, &'static str)> {
        Ok(match &self.frames {
            Frames::Joint(k) => {
                let goal = k.positions.last().map(Vec::as_slice).unwrap_or_default();
                let error = goal.iter().zip(measured).map(|(g, m)| (g - f64::from(*m)).abs()).fold(0.0, f64::max);
                (error, "rad")
            }
            Frames::Cartesian(k) => {
                let goal = k.positions.last().copied().unwrap_or_default();
                let tool = driver.tool_position(measured)?;
                ((0..3).map(|i| (goal[i] - tool[i]).powi(2)).sum::<f64>().sqrt(), "m")
            }
        })
    }

    /// The planned tool path, one point per keyframe (m): the keyframes' positions, or the forward
    /// kinematics of joint keyframes.
    pub fn tool_path(&self, driver: &Driver) -> Result<Vec<[f64; 3]>> {
        match &self.frames {
            Frames::Cartesian(k) => Ok(k.positions.clone()),
            Frames::Joint(k) => k
                .positions
                .iter()
                .map(|q| driver.tool_position(&q.iter().map(|&x| x as f32).collect::<Vec<_>>()))
                .collect(),
        }
    }

    /// Checks every segment the player will play, from where the arm stands (`start`) through
    /// every keyframe, against the arm's collision geometry (nothing to check without one): fails
    /// naming the first keyframe pair whose segment collides, the pair of bodies and their
    /// distance. Cartesian keyframes are checked at the host's IK solutions of them.
    pub fn check_collisions(&self, driver: &Driver, start: &[f64]) -> Result<()> {
        let Some(mut checker) = avoid::host_checker(driver)? else { return Ok(()) };
        let (times, lines, positions, velocities) = match &self.frames {
            Frames::Joint(k) => (&k.times, &k.lines, k.positions.clone(), k.velocities.as_deref()),
            Frames::Cartesian(k) => {
                (&k.times, &k.lines, crate::motion::reach::check(driver.model(), k, &|line| self.at(line))?, None)
            }
        };
        let (max_velocity, max_acceleration) = limits_of(driver.model());
        let played = as_played(start, times, &positions, velocities, max_velocity, max_acceleration);
        let Some((k, found)) = check_keyframes(&mut checker, start, &played)? else { return Ok(()) };
        let pair = match k {
            0 => format!("from where the arm stands to keyframe 1 (line {})", lines[0]),
            k => format!("between keyframes {k} and {} (lines {} and {})", k + 1, lines[k - 1], lines[k]),
        };
        bail!("{}: {pair}: {}; nothing was sent, nothing moved", self.path.display(), checker.describe_along(&found))
    }

    /// The keyframes with their file lines, checked against the connected arm.
    pub fn keyframes(&self, driver: &Driver) -> Result<Vec<(usize, Keyframe)>> {
        let column = match &self.frames {
            Frames::Joint(k) => k.gripper.as_ref(),
            Frames::Cartesian(k) => k.gripper.as_ref(),
        };
        if column.is_some() && driver.gripper().is_none() {
            bail!(
                "{}: the file has a gripper column, but the arm {} has no gripper",
                self.path.display(),
                driver.arm().name
            );
        }
        let gripper = |i: usize| column.map(|g| g[i] as f32);
        match &self.frames {
            Frames::Joint(k) => (0..k.times.len())
                .map(|i| {
                    let at = self.at(k.lines[i]);
                    let positions = check_joints(driver, &k.positions[i], &at)?;
                    let velocities = match &k.velocities {
                        None => None,
                        Some(v) => {
                            if let Some(bad) = v[i].iter().find(|x| x.abs() > f64::from(MAX_JOINT_VELOCITY)) {
                                bail!("{at}: velocity {bad} is beyond the largest the link carries ({MAX_JOINT_VELOCITY})");
                            }
                            let v: Vec<f32> = v[i].iter().map(|&x| x as f32).collect();
                            Some(Joints::from_slice(&v).map_err(|_| anyhow!("{at}: too many velocities"))?)
                        }
                    };
                    let keyframe = JointKeyframe { time: k.times[i] as f32, positions, velocities, gripper: gripper(i) };
                    Ok((k.lines[i], Keyframe::Joints(keyframe)))
                })
                .collect(),
            Frames::Cartesian(k) => {
                crate::motion::reach::check(driver.model(), k, &|line| self.at(line))?;
                Ok((0..k.times.len())
                .map(|i| {
                    let target = CartesianTarget {
                        position: k.positions[i].map(|x| x as f32),
                        orientation: k.orientations.as_ref().map(|o| o[i].map(|x| x as f32)),
                    };
                    let keyframe = CartesianKeyframe { time: k.times[i] as f32, target, gripper: gripper(i) };
                    (k.lines[i], Keyframe::Pose(keyframe))
                })
                .collect())
            }
        }
    }
}

/// Where the arm stands, for messages.
fn failed_at(driver: &mut Driver) -> String {
    match driver.status() {
        Ok(s) => driver.tool_position(&s.measured).map(|p| format!("the arm is at {} m", fmt3(&p))).unwrap_or_default(),
        Err(e) => format!("status unknown: {e}"),
    }
}

/// What `play` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlayReport {
    /// Always "play".
    pub command: &'static str,
    /// The file (or the name the keyframes were given).
    pub file: String,
    /// "joint" or "cartesian".
    pub format: &'static str,
    /// Keyframes in the file.
    pub keyframes: usize,
    /// Keyframes pushed and acknowledged.
    pub pushed: usize,
    /// The last keyframe's time (s).
    pub trajectory_s: f64,
    /// Controller seconds from the start to rest.
    pub time_s: f64,
    /// Times the queue ran dry.
    pub underruns: u32,
    /// How far the arm ended from the last keyframe: rad (joint) or m (Cartesian).
    pub end_error: f64,
    /// The tool position at rest (m).
    #[serde(serialize_with = "super::as_list")]
    pub tool: [f64; 3],
    /// The measured joints at rest.
    pub joints: Vec<f32>,
}

impl PlayReport {
    /// The report as `armctl play` prints it.
    pub fn text(&self) -> String {
        format!(
            "play {}: {} of {} {} keyframes pushed and acknowledged, {:.2} s of trajectory in {:.2} s; the arm is at {} m",
            self.file,
            self.pushed,
            self.keyframes,
            self.format,
            self.trajectory_s,
            self.time_s,
            fmt3(&self.tool)
        )
    }
}

/// Plays a checked plan, streaming its keyframes with flow control, and waits until the arm is
/// at rest. Notes (keyframes left from before dropped, torque switched on, the progress bar,
/// warnings) go to `notes`.
pub fn play(driver: &mut Driver, plan: &Plan, notes: &mut dyn Write) -> DriveResult<PlayReport> {
    // Caught from the start: checking a long file against the arm's geometry takes seconds on a
    // busy machine, and a Ctrl-C then would otherwise end the process unhandled (CI once saw it).
    // One pressed before anything moves is seen as the first keyframe is about to go.
    interrupt::catch();
    let keyframes = plan.keyframes(driver).map_err(DriveError::Input)?;
    let total = keyframes.len();
    let status = driver.status()?;
    let measured: Vec<f64> = status.measured.iter().map(|&x| f64::from(x)).collect();
    plan.check_collisions(driver, &measured).map_err(DriveError::Input)?;
    if !matches!(status.state, RunState::Idle | RunState::TorqueOff) {
        return Err(DriveError::failed(format!(
            "the arm is busy ({:?}): wait, or `stop` it first; nothing was sent",
            status.state
        )));
    }
    let (status, switched) = driver.ready_to_move()?;
    if status.queued > 0 {
        // Left over from an interrupted run: playing them first would not be what the file says.
        driver.session().stop()?;
        writeln!(notes, "dropped {} keyframes left in the queue from before", status.queued)?;
    }
    let underruns_before = status.errors.underruns;
    let mut progress = Progress::new(total, plan.seconds(), std::io::stderr().is_terminal());
    let mut pushed = 0usize;

    // Fill the queue before starting, so the start does not wait on the link: as far as the
    // firmware reports free slots (with a gripper column, its track holds one keyframe fewer than
    // the joints' queue).
    while pushed < total.min(driver.queue_capacity().max(1)) && (pushed == 0 || driver.free_slots() > 0) {
        if interrupt::requested() {
            driver.session().stop()?;
            let undone = driver.undo_torque(switched);
            return Err(DriveError::Interrupted {
                said: format!(
                    "stopped by Ctrl-C before the start: nothing moved; {pushed} of {total} keyframes were queued \
                     and dropped{undone}"
                ),
            });
        }
        let (line, keyframe) = &keyframes[pushed];
        if let Err(e) = driver.session().push(keyframe) {
            let dropped = driver.session().stop().is_ok();
            let undone = driver.undo_torque(switched);
            return Err(DriveError::failed(format!(
                "{}: {e:#}; nothing moved{}{undone}",
                plan.at(*line),
                if dropped { ", the queued keyframes were dropped" } else { "" },
            )));
        }
        pushed += 1;
    }
    let start = driver.status()?;
    driver.session().start()?;
    Driver::note_torque(switched, notes)?;
    let played = |s: &Status, pushed: usize| pushed.saturating_sub(usize::from(s.queued));
    let clock = |s: &Status| f64::from(s.time - start.time);

    // Keep pushing as slots free up, then wait until the arm is at rest.
    let deadline = plan.seconds() + plan.timeout;
    let started = std::time::Instant::now();
    let mut restarts = 0u32;
    let last = loop {
        if interrupt::requested() {
            progress.clear(notes);
            return Err(interrupted(driver, &format!("play: {pushed} of {total} keyframes had been pushed\n")));
        }
        if pushed < total && driver.free_slots() > 0 {
            let (line, keyframe) = &keyframes[pushed];
            if let Err(e) = driver.session().push(keyframe) {
                progress.clear(notes);
                let stopped = driver.session().stop().is_ok();
                return Err(DriveError::failed(format!(
                    "{}: {e:#}; {} after {pushed} of {total} keyframes, {}",
                    plan.at(*line),
                    if stopped { "stopped the arm" } else { "could not stop the arm" },
                    failed_at(driver)
                )));
            }
            pushed += 1;
            continue;
        }
        let status = driver.status()?;
        progress.update(notes, played(&status, pushed), clock(&status));
        // A collision stop ends the playback: the firmware braked short of the contact, dropped
        // the queue and holds there; playing on would only run into it again.
        if status.last_collision.map(|c| c.count) != start.last_collision.map(|c| c.count) {
            progress.clear(notes);
            let pair = status.last_collision.as_ref().map(|c| super::collision::stop(driver.arm(), c));
            return Err(DriveError::failed(format!(
                "the firmware stopped the arm short of a collision after {} of {total} keyframes: {} where it was                  going; it holds there, the rest of the file dropped",
                played(&status, pushed),
                pair.unwrap_or_default()
            )));
        }
        match status.state {
            RunState::Idle if pushed == total && status.queued == 0 => {
                let settled = driver.settle(status)?;
                break super::blocked::check_at_rest(driver, settled).map_err(DriveError::Failed)?;
            }
            RunState::Idle if status.queued > 0 => {
                // The player ran dry (an underrun) and the controller went to hold: go on.
                restarts += 1;
                driver.session().start()?;
            }
            RunState::TorqueOff | RunState::EStopped => {
                progress.clear(notes);
                return Err(DriveError::failed(format!(
                    "the arm stopped ({:?}) after {} of {total} keyframes; {pushed} had been pushed",
                    status.state,
                    played(&status, pushed)
                )));
            }
            _ => {}
        }
        let waited = clock(&status);
        if waited > deadline || started.elapsed().as_secs_f64() > 4.0 * deadline + 10.0 {
            progress.clear(notes);
            let stopped = driver.session().stop().is_ok();
            return Err(DriveError::failed(format!(
                "timed out after {} s with the arm still {:?}; {}",
                seconds_waited(waited),
                status.state,
                if stopped { "sent stop" } else { "stop was not acknowledged" }
            )));
        }
        if status.free_slots == 0 || pushed == total {
            driver.pause()?;
        }
    };
    let took = clock(&last);
    progress.finish(notes, total, plan.seconds());
    let underruns = last.errors.underruns.saturating_sub(underruns_before);
    if underruns > 0 || restarts > 0 {
        writeln!(
            notes,
            "warning: the queue ran dry {underruns} times (restarted {restarts} times): keyframes came too slowly"
        )?;
    }
    let tool = driver.tool_position(&last.measured)?;
    let (end_error, unit) = plan.end_error(driver, &last.measured)?;
    let (format, tolerance) = match &plan.frames {
        Frames::Joint(_) => ("joint", 0.01),
        Frames::Cartesian(_) => ("cartesian", 0.002),
    };
    if end_error > tolerance {
        writeln!(
            notes,
            "warning: the arm ended {end_error:.4} {unit} from the last keyframe (beyond {tolerance} {unit})"
        )?;
    }
    Ok(PlayReport {
        command: "play",
        file: plan.path.display().to_string(),
        format,
        keyframes: total,
        pushed,
        trajectory_s: plan.seconds(),
        time_s: took,
        underruns,
        end_error,
        tool,
        joints: last.measured.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows() -> (Vec<f64>, Vec<Vec<f64>>) {
        (vec![0.0, 0.5, 1.25], vec![vec![0.0, 0.1], vec![0.2, 0.1], vec![0.3, -0.2]])
    }

    #[test]
    fn joint_rows_make_the_plan_a_file_with_the_same_rows_makes() {
        let (t, q) = rows();
        let given = Plan::from_joint_rows(&t, &q, Some(&[50.0, 20.0, 70.0]), Path::new("keyframes"), 30.0).unwrap();
        let text = "t,q1,q2,gripper\n0,0,0.1,50\n0.5,0.2,0.1,20\n1.25,0.3,-0.2,70\n";
        let read = Plan::parse(text, Path::new("keyframes"), 30.0).unwrap();
        let (Frames::Joint(a), Frames::Joint(b)) = (&given.frames, &read.frames) else { panic!("joint keyframes") };
        assert_eq!((&a.times, &a.positions, &a.gripper), (&b.times, &b.positions, &b.gripper));
        assert_eq!((given.seconds(), given.timeout(), given.is_cartesian()), (1.25, 30.0, false));
    }

    #[test]
    fn bad_rows_are_refused_in_one_line_naming_the_keyframe() {
        let (t, q) = rows();
        let name = Path::new("keyframes");
        let error = |r: Result<Plan>| {
            let e = format!("{:#}", r.err().expect("refused"));
            assert!(!e.contains('\n'), "{e}");
            e
        };
        let e = error(Plan::from_joint_rows(&t, &q, Some(&[50.0, 101.0, 0.0]), name, 30.0));
        assert!(e.contains("keyframes") && e.contains("line 2, column gripper: 101"), "{e}");
        let e = error(Plan::from_joint_rows(&t, &q, Some(&[50.0]), name, 30.0));
        assert!(e.contains("1 openings for 3 keyframes"), "{e}");
        let e = error(Plan::from_joint_rows(&[0.0, 0.5, 0.5], &q, None, name, 30.0));
        assert!(e.contains("line 3: time 0.5 is not later"), "{e}");
        let mut nan = q.clone();
        nan[1][0] = f64::NAN;
        let e = error(Plan::from_joint_rows(&t, &nan, None, name, 30.0));
        assert!(e.contains("line 2: NaN is not a finite number"), "{e}");
        let e = error(Plan::from_joint_rows(&t, &q, None, name, 0.0));
        assert!(e.contains("timeout: 0 s must be a positive number"), "{e}");
    }
}
