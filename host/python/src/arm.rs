//! An arm driven through the firmware core, for Python: opened as every drive command opens it
//! (`sim`, `port`, or `bus` + `protocol`, with `arm` and `calibration`: a
//! [`armctl::runtime::connection::Place`]), and driven by the same typed operations
//! ([`armctl::commands::drive`]): each method builds the operation's request from its arguments and returns
//! its report as a dict, with no command line, text or JSON in between. A stream of readings (a
//! policy's actions, a teleoperation) feeds the player through
//! [`armctl::motion::teleop::stream::Streamer`], as `armctl teleop` does.
//!
//! `sim` runs the core on this PC in real time against simulated servos on a pseudo-terminal (as
//! `armctl serve --sim`), so that a stream is paced by the clock it is sent on, and the
//! simulator's safety monitor judges every goal ([`Arm::monitor`]).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use armctl::arm::collision::edit::{geometry_json, geometry_of, obstacle_json, source_of};
use armctl::arm::collision::{CollisionSpec, ObstacleSpec, TABLE};
use armctl::commands::drive::gripper::{GripperGoal, GripperRequest};
use armctl::commands::drive::joints::JointsRequest;
use armctl::commands::drive::move_to::MoveRequest;
use armctl::commands::drive::play::Plan;
use armctl::commands::drive::{gripper, joints, move_to, play, state, DriveError, DriveResult};
use armctl::motion::teleop::leader::Reading;
use armctl::motion::teleop::stream::{refused, Settings, Streamer};
use armctl::runtime::connection::{protocol_named, Place};
use armctl::runtime::driver::Driver;
use armctl::sim::PtyServer;
use firmware::link::message::{CartesianTarget, MovePath};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde::Serialize;

use crate::errors::{interrupted, to_py, OrRaise};
use crate::obstacles;

/// Runs `f` with the GIL released, so that Python's other threads (a camera's reader) run while
/// the arm is waited for. `detach` runs `f` on this very thread and returns its value here; its
/// `Send` bound guards against Python objects crossing threads, and neither `f` nor its value
/// holds any: only this unsendable object's driver, which never leaves the thread that owns it.
fn released<T>(py: Python<'_>, f: impl FnOnce() -> T) -> T {
    struct OnThisThread<V>(V);
    // SAFETY: see above: the closure is called, and its value used, on the thread that made it.
    unsafe impl<V> Send for OnThisThread<V> {}
    impl<V> OnThisThread<V> {
        fn call<T>(self) -> OnThisThread<T>
        where
            V: FnOnce() -> T,
        {
            OnThisThread((self.0)())
        }
        fn into_inner(self) -> V {
            self.0
        }
    }
    let f = OnThisThread(f);
    py.detach(move || f.call()).into_inner()
}

/// A report as Python's own objects (dicts, lists, floats), converted from its serde form.
fn python<T: Serialize>(py: Python<'_>, report: &T) -> PyResult<Py<PyAny>> {
    Ok(pythonize::pythonize(py, report).map_err(|e| to_py(anyhow!("{e}")))?.unbind())
}

/// An operation's failure as Python's exception: Ctrl-C stopped the arm (`KeyboardInterrupt`,
/// Python's own if its handler raised one), anything else `ArmctlError` with the command line's
/// line.
fn raised(e: DriveError) -> PyErr {
    match e {
        DriveError::Interrupted { said } => {
            interrupted().unwrap_or_else(|| pyo3::exceptions::PyKeyboardInterrupt::new_err(said))
        }
        other => to_py(other.into()),
    }
}

/// Exactly `N` values, as the command line's parser would have read them (its words when not).
fn fixed<const N: usize>(values: &[f64], what: &str) -> PyResult<[f64; N]> {
    <[f64; N]>::try_from(values)
        .map_err(|_| to_py(anyhow!("{what}: expected {N} comma-separated numbers, got {}", values.len())))
}

/// The simulated servos' safety monitor, for Python.
#[derive(Serialize)]
struct MonitorSummary {
    goals: u64,
    violations: u64,
    max_step_ratio: f64,
    first_violations: Vec<String>,
}

/// A stream's settings before it opens: its rate, lead and step clamp as given.
struct StreamRequest {
    period: Duration,
    lead: Duration,
    /// One value for every joint, or one per joint.
    max_step: Option<Vec<f64>>,
}

/// An arm connected through the firmware core.
#[pyclass(unsendable, module = "armctl._armctl")]
pub struct Arm {
    /// `None` once closed.
    driver: Option<Driver>,
    /// The simulated servos of `sim`.
    servos: Option<PtyServer>,
    stream: Option<Streamer>,
    /// What connecting said (for `bus`: the bus timing measured).
    connected: String,
}

impl Arm {
    fn driver(&mut self) -> PyResult<&mut Driver> {
        self.driver.as_mut().ok_or_else(|| to_py(anyhow!("the arm is closed")))
    }

    /// Runs one operation with the GIL released, refused while a stream is open; returns its
    /// report as Python objects.
    fn run<T: Serialize>(
        &mut self,
        py: Python<'_>,
        operation: impl FnOnce(&mut Driver, &mut dyn std::io::Write) -> DriveResult<T>,
    ) -> PyResult<Py<PyAny>> {
        if self.stream.is_some() {
            return Err(to_py(anyhow!("a stream is open: close it before other commands (nothing was sent)")));
        }
        let driver = self.driver()?;
        // Notes (torque switched on, a progress bar) are the command line's; Python has the report.
        let report = released(py, || operation(driver, &mut std::io::sink())).map_err(raised)?;
        python(py, &report)
    }

    /// New collision geometry for the commands that follow (sent with the arm where the
    /// firmware's copy changes: only with the torque off); refused while a stream is open.
    fn set_geometry(&mut self, py: Python<'_>, spec: CollisionSpec) -> PyResult<()> {
        if self.stream.is_some() {
            return Err(to_py(anyhow!("a stream is open: close it before changing the obstacles (nothing changed)")));
        }
        let driver = self.driver()?;
        released(py, || driver.set_collision(Some(spec))).or_raise()?;
        Ok(())
    }

    fn open_stream(&mut self, py: Python<'_>, request: StreamRequest) -> PyResult<()> {
        if self.stream.is_some() {
            return Err(to_py(anyhow!("a stream is open already: close it before opening another")));
        }
        let driver = self.driver()?;
        let mut settings = Settings::for_follower(driver, request.period, request.lead, None, true).or_raise()?;
        match request.max_step.as_deref() {
            None => {}
            Some(&[step]) => settings.max_step.fill(step),
            Some(steps) if steps.len() == driver.joints() => settings.max_step = steps.to_vec(),
            Some(steps) => {
                let joints = driver.joints();
                return Err(to_py(anyhow!(
                    "max_step: {} values for {joints} joints: give one, or one per joint",
                    steps.len()
                )));
            }
        }
        let stream = released(py, || Streamer::begin(driver, settings)).or_raise()?;
        self.stream = Some(stream);
        Ok(())
    }

    fn streaming(&mut self) -> PyResult<(&mut Driver, &mut Streamer)> {
        match (self.driver.as_mut(), self.stream.as_mut()) {
            (Some(d), Some(s)) => Ok((d, s)),
            (None, _) => Err(to_py(anyhow!("the arm is closed"))),
            (_, None) => Err(to_py(anyhow!("no stream is open: call stream_begin first"))),
        }
    }

    /// After a stream's keyframe failed. One the firmware refused (an unreachable pose) changed
    /// nothing, and the stream goes on; otherwise (the link failed, the arm left playback) the
    /// stream is over, and the arm is stopped.
    fn failed_keyframe(&mut self, py: Python<'_>, e: anyhow::Error) -> PyErr {
        if !refused(&e) {
            self.stream = None;
            if let Some(driver) = self.driver.as_mut() {
                let _ = released(py, || driver.stop());
            }
        }
        to_py(e)
    }
}

#[pymethods]
impl Arm {
    #[new]
    #[pyo3(signature = (*, sim = false, port = None, bus = None, protocol = None, arm = None, calibration = None, baud = None, obstacles = None, table = true, servos = None, payload_kg = None, gravity_compensation = None, hidden_obstacles = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        sim: bool,
        port: Option<String>,
        bus: Option<String>,
        protocol: Option<&str>,
        arm: Option<String>,
        calibration: Option<PathBuf>,
        baud: Option<u32>,
        obstacles: Option<Vec<Bound<'_, PyAny>>>,
        table: bool,
        servos: Option<&str>,
        payload_kg: Option<f64>,
        gravity_compensation: Option<bool>,
        hidden_obstacles: Option<Vec<Bound<'_, PyAny>>>,
    ) -> PyResult<Self> {
        let protocol = protocol.map(protocol_named).transpose().or_raise()?;
        // Every obstacle read before anything opens: a bad one moves nothing.
        let given = obstacles.unwrap_or_default().iter().map(obstacles::obstacle).collect::<PyResult<Vec<_>>>()?;
        let hidden = hidden_obstacles
            .unwrap_or_default()
            .iter()
            .map(|o| {
                let (name, shape) = obstacles::obstacle(o)?;
                Ok(ObstacleSpec { name: name.unwrap_or_else(|| "hidden".into()), shape })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let place = Place {
            port,
            bus,
            protocol,
            baud,
            sim,
            arm,
            calibration,
            object_mm: None,
            // Given only with the simulated arm (the place refuses them otherwise).
            servos: (servos.is_some() || payload_kg.is_some())
                .then(|| armctl::sim::physics::servo_kind(servos, payload_kg))
                .transpose()
                .or_raise()?,
            surroundings: Default::default(),
            hidden_obstacles: hidden,
            no_collision_check: false,
            gravity: gravity_compensation,
        };
        let mut said = Vec::new();
        let (mut driver, servos) = released(py, || -> Result<(Driver, Option<PtyServer>)> {
            let (target, servos) = place.target()?.in_real_time()?;
            Ok((Driver::open(target, place.arm_name(), &mut said)?, servos))
        })
        .or_raise()?;
        if !given.is_empty() || !table {
            let spec = obstacles::edited(geometry_of(driver.arm()), table, &[], given)?;
            released(py, || driver.set_collision(Some(spec))).or_raise()?;
        }
        let connected = String::from_utf8_lossy(&said).trim().to_string();
        Ok(Self { driver: Some(driver), servos, stream: None, connected })
    }

    /// The obstacles every command is checked against, each a dict as `add_obstacle` takes one
    /// (the table's too), in the base frame.
    #[getter]
    fn obstacles(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let spec = geometry_of(self.driver()?.arm());
        let list: Vec<serde_json::Value> = spec.obstacles.iter().map(obstacle_json).collect();
        python(py, &list)
    }

    /// The whole collision geometry: `margin`, `bodies` (each on its joint's frame, `link`, or the
    /// base's, None), `obstacles`, `allowed` pairs, and where it comes from (`source`).
    #[getter]
    fn collision(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let arm = self.driver()?.arm();
        let mut value = geometry_json(&geometry_of(arm));
        value["source"] = serde_json::json!(source_of(arm));
        python(py, &value)
    }

    /// Adds an obstacle (a dict or a tuple, see the module `obstacles`) for the commands that
    /// follow; returns its name. A bad one raises `ValueError` and changes nothing.
    fn add_obstacle(&mut self, py: Python<'_>, obstacle: Bound<'_, PyAny>) -> PyResult<String> {
        let (name, shape) = obstacles::obstacle(&obstacle)?;
        let mut spec = geometry_of(self.driver()?.arm());
        let added = spec.add_obstacle(name.as_deref(), shape).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
        self.set_geometry(py, spec)?;
        Ok(added)
    }

    /// Removes the obstacle named `name` (`"table"` for the table).
    fn remove_obstacle(&mut self, py: Python<'_>, name: &str) -> PyResult<()> {
        let spec = obstacles::edited(geometry_of(self.driver()?.arm()), true, &[name.to_string()], Vec::new())?;
        self.set_geometry(py, spec)
    }

    /// Removes every obstacle but the table (`remove_obstacle("table")` removes that).
    fn clear_obstacles(&mut self, py: Python<'_>) -> PyResult<()> {
        let spec = geometry_of(self.driver()?.arm());
        let names: Vec<String> = spec.obstacles.iter().map(|o| o.name.clone()).filter(|n| n != TABLE).collect();
        let spec = obstacles::edited(spec, true, &names, Vec::new())?;
        self.set_geometry(py, spec)
    }

    /// The arm's name.
    #[getter]
    fn name(&mut self) -> PyResult<String> {
        Ok(self.driver()?.arm().name.clone())
    }

    /// Joint names, base first.
    #[getter]
    fn joint_names(&mut self) -> PyResult<Vec<String>> {
        Ok(self.driver()?.arm().joints.iter().map(|j| j.name.clone()).collect())
    }

    /// (lower, upper) per joint: the range the firmware commands it within, rad or m.
    #[getter]
    fn limits(&mut self) -> PyResult<Vec<(f64, f64)>> {
        let driver = self.driver()?;
        let servos = armctl::arm::servos::servos_of(driver.arm());
        (0..driver.joints())
            .map(|j| {
                servos
                    .as_ref()
                    .and_then(|s| s.commanded_range(driver.arm(), j))
                    .map(|(lo, hi)| (f64::from(lo), f64::from(hi)))
                    .ok_or_else(|| to_py(anyhow!("joint {} has no range within its servo", j + 1)))
            })
            .collect()
    }

    /// Whether the arm has a gripper.
    #[getter]
    fn has_gripper(&mut self) -> PyResult<bool> {
        Ok(self.driver()?.gripper().is_some())
    }

    /// What connecting said (for `bus`: the bus timing it measured), or "".
    #[getter]
    fn connected(&self) -> String {
        self.connected.clone()
    }

    /// The servo ids of the joints, base first, then the gripper's.
    #[getter]
    fn servo_ids(&mut self) -> PyResult<Vec<u16>> {
        let servos = armctl::arm::servos::servos_of(self.driver()?.arm());
        Ok(servos.map(|s| s.bus_ids().into_iter().map(u16::from).collect()).unwrap_or_default())
    }

    /// `armctl status --json`: the controller's state, measured joints, setpoints, tool, gripper,
    /// queue and error counts. Read between a stream's keyframes too (a LeRobot observation).
    fn status(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let driver = self.driver()?;
        let report = released(py, || state::status(driver)).map_err(raised)?;
        python(py, &report)
    }

    /// `armctl move`: the tool to `position` (m), with `quaternion_wxyz` if given; waits until the
    /// arm is at rest.
    #[pyo3(signature = (position, quaternion_wxyz = None, speed = None, duration = None, path = "auto", timeout = 60.0))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments, each a command-line option.
    fn move_to(
        &mut self,
        py: Python<'_>,
        position: Vec<f64>,
        quaternion_wxyz: Option<Vec<f64>>,
        speed: Option<f64>,
        duration: Option<f64>,
        path: &str,
        timeout: f64,
    ) -> PyResult<Py<PyAny>> {
        let path = match path.to_ascii_lowercase().as_str() {
            "auto" => MovePath::Auto,
            "line" => MovePath::Line,
            "joint" => MovePath::Joint,
            _ => return Err(to_py(anyhow!("path {path:?}: auto, line or joint"))),
        };
        let position = fixed::<3>(&position, "--to")?;
        let orientation = quaternion_wxyz.as_deref().map(|q| fixed::<4>(q, "--quat")).transpose()?;
        let request = MoveRequest::new(position, orientation, speed, duration, path, timeout).map_err(raised)?;
        self.run(py, |driver, notes| move_to::move_to(driver, &request, notes))
    }

    /// `armctl joints`: every joint to `q` (rad or m), arriving together; waits until at rest.
    #[pyo3(signature = (q, speed = None, duration = None, timeout = 60.0))]
    fn move_joints(
        &mut self,
        py: Python<'_>,
        q: Vec<f64>,
        speed: Option<f64>,
        duration: Option<f64>,
        timeout: f64,
    ) -> PyResult<Py<PyAny>> {
        let request = JointsRequest::new(q, speed, duration, timeout).map_err(raised)?;
        self.run(py, |driver, notes| joints::joints(driver, &request, notes))
    }

    /// `armctl play`: a keyframe file (joint `t,q1,...,qN[,v1,...,vN][,gripper]` or Cartesian)
    /// given by its `path`, or joint keyframes given as values (`times`, `positions` one row per
    /// keyframe, the `gripper`'s opening per keyframe), named `name` in messages; streamed with
    /// flow control and waited for.
    #[pyo3(signature = (path = None, times = None, positions = None, gripper = None, name = "keyframes", timeout = 30.0))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments.
    fn play(
        &mut self,
        py: Python<'_>,
        path: Option<PathBuf>,
        times: Option<Vec<f64>>,
        positions: Option<Vec<Vec<f64>>>,
        gripper: Option<Vec<f64>>,
        name: &str,
        timeout: f64,
    ) -> PyResult<Py<PyAny>> {
        let plan = match (path, times, positions) {
            (Some(file), None, None) if gripper.is_none() => Plan::read(&file, timeout),
            (None, Some(times), Some(positions)) => {
                Plan::from_joint_rows(&times, &positions, gripper.as_deref(), std::path::Path::new(name), timeout)
            }
            _ => Err(anyhow!("play takes a keyframe file, or times and positions (and the gripper's openings)")),
        }
        .or_raise()?;
        self.run(py, |driver, notes| play::play(driver, &plan, notes))
    }

    /// `armctl stop`: decelerates within the limits and holds; waits until at rest. Closes an
    /// open stream first.
    fn stop(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.stream = None;
        self.run(py, |driver, _| state::stop(driver))
    }

    /// `armctl torque on|off`.
    fn torque(&mut self, py: Python<'_>, on: bool) -> PyResult<Py<PyAny>> {
        self.run(py, |driver, _| state::torque(driver, on))
    }

    /// `armctl gripper open|close|set PERCENT [--effort E]`; waits until the jaws stop.
    #[pyo3(signature = (action, percent = None, effort = None, timeout = 10.0))]
    fn gripper(
        &mut self,
        py: Python<'_>,
        action: &str,
        percent: Option<f64>,
        effort: Option<f64>,
        timeout: f64,
    ) -> PyResult<Py<PyAny>> {
        let goal = match (action.to_ascii_lowercase().as_str(), percent) {
            ("open", None) => GripperGoal::Open,
            ("close", None) => GripperGoal::Close,
            ("set", Some(p)) => GripperGoal::Set(p),
            ("set", None) => {
                return Err(to_py(anyhow!("gripper set: give the opening in percent, 0 closed to 100 open")))
            }
            (action @ ("open" | "close"), Some(_)) => {
                return Err(to_py(anyhow!("gripper {action}: takes no percent (use `gripper set PERCENT`)")))
            }
            _ => return Err(to_py(anyhow!("gripper action {action:?}: open, close or set"))),
        };
        let request = GripperRequest::new(goal, effort, timeout).map_err(raised)?;
        self.run(py, |driver, notes| gripper::gripper(driver, &request, notes))
    }

    /// Opens a stream at `rate` readings a second: each reading is a keyframe due `lead_ms` after
    /// it is sent (default: one period plus 8 ms), no joint moving more than `max_step` rad from
    /// one keyframe to the next (one value, or one per joint; default: the speed limit over one
    /// period, LeRobot's `max_relative_target`). Switches torque on.
    #[pyo3(signature = (rate, lead_ms = None, max_step = None))]
    fn stream_begin(
        &mut self,
        py: Python<'_>,
        rate: f64,
        lead_ms: Option<f64>,
        max_step: Option<Vec<f64>>,
    ) -> PyResult<()> {
        let check = || -> Result<StreamRequest> {
            if !(rate.is_finite() && (1.0..=1000.0).contains(&rate)) {
                bail!("rate: {rate} must be between 1 and 1000 readings per second");
            }
            let period = Duration::from_secs_f64(1.0 / rate);
            let lead = match lead_ms {
                Some(ms) if ms.is_finite() && ms > 0.0 && ms <= 1000.0 => Duration::from_secs_f64(ms * 1e-3),
                Some(ms) => bail!("lead_ms: {ms} must be above 0 and at most 1000"),
                None => period + armctl::commands::teleop::LEAD_MARGIN,
            };
            if let Some(step) = max_step.iter().flatten().find(|step| !(step.is_finite() && **step > 0.0)) {
                bail!("max_step: {step} must be a positive number of radians");
            }
            Ok(StreamRequest { period, lead, max_step })
        };
        let request = check().or_raise()?;
        self.open_stream(py, request)
    }

    /// Sends joint values `q` (rad or m) and the gripper's opening (percent) as the stream's next
    /// keyframe; returns `(time, q, gripper)` as sent, after the range and step clamps.
    #[pyo3(signature = (q, gripper = None))]
    fn stream_joints(
        &mut self,
        py: Python<'_>,
        q: Vec<f64>,
        gripper: Option<f64>,
    ) -> PyResult<(f64, Vec<f64>, Option<f64>)> {
        let read_at = Instant::now();
        let reading = Reading { joints: q, gripper };
        let (driver, stream) = self.streaming()?;
        // Bad input ends nothing: the stream goes on with the next good reading.
        stream.check(&reading).or_raise()?;
        match released(py, || stream.send(driver, &reading, read_at)) {
            Ok(sent) => Ok((sent.time, sent.joints, sent.gripper)),
            Err(e) => Err(self.failed_keyframe(py, e)),
        }
    }

    /// Sends the tool pose (`position` m, `quaternion_wxyz` or None for a position only) and the
    /// gripper's opening as the stream's next keyframe, solved by the firmware's IK as the player
    /// reaches it; returns `(time, gripper)` as sent.
    #[pyo3(signature = (position, quaternion_wxyz = None, gripper = None))]
    fn stream_pose(
        &mut self,
        py: Python<'_>,
        position: [f64; 3],
        quaternion_wxyz: Option<[f64; 4]>,
        gripper: Option<f64>,
    ) -> PyResult<(f64, Option<f64>)> {
        let read_at = Instant::now();
        let values = position.iter().chain(quaternion_wxyz.iter().flatten()).chain(&gripper);
        if let Some(bad) = values.copied().find(|x| !x.is_finite()) {
            return Err(to_py(anyhow!("a pose holds {bad}: nothing was sent")));
        }
        let orientation = match quaternion_wxyz {
            Some(q) => {
                let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                if (norm - 1.0).abs() > f64::from(firmware::link::message::QUATERNION_TOLERANCE) {
                    return Err(to_py(anyhow!("quaternion_wxyz must be a unit quaternion; its norm is {norm:.6}")));
                }
                Some(q.map(|x| x as f32))
            }
            None => None,
        };
        let target = CartesianTarget { position: position.map(|x| x as f32), orientation };
        let (driver, stream) = self.streaming()?;
        match released(py, || stream.send_pose(driver, target, gripper, read_at)) {
            Ok(sent) => Ok((sent.time, sent.gripper)),
            Err(e) => Err(self.failed_keyframe(py, e)),
        }
    }

    /// Whether a stream is open.
    #[getter]
    fn streaming_now(&self) -> bool {
        self.stream.is_some()
    }

    /// Ends the stream: a last keyframe at rest where it was, then waits until the arm holds.
    /// Returns the stream's figures (keyframes, latency, underruns, clamps, tracking).
    fn stream_end(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let Some(stream) = self.stream.take() else {
            return Err(to_py(anyhow!("no stream is open")));
        };
        let driver = self.driver()?;
        let (figures, _) = released(py, || stream.finish(driver)).or_raise()?;
        released(py, || driver.wait_until_rest(10.0)).or_raise()?;
        python(py, &figures.summary())
    }

    /// The simulated servos' safety monitor (for `sim`): goals checked, violations (the first 100
    /// in words), the largest step against the limit; None for a real arm.
    fn monitor(&self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        let Some(report) = self.servos.as_ref().and_then(PtyServer::monitor) else { return Ok(None) };
        let summary = MonitorSummary {
            goals: report.checked,
            violations: report.violation_count,
            max_step_ratio: report.max_step_ratio,
            first_violations: report.violations.iter().map(ToString::to_string).collect(),
        };
        python(py, &summary).map(Some)
    }

    /// The simulated servos' pseudo-terminal (for `sim`), or None.
    #[getter]
    fn sim_port(&self) -> Option<String> {
        self.servos.as_ref().map(|s| s.path().to_string())
    }

    /// Ends an open stream (the arm comes to rest where it was), then the connection. With
    /// `torque_off`, the servos go limp last. Closing twice does nothing.
    #[pyo3(signature = (torque_off = false))]
    fn close(&mut self, py: Python<'_>, torque_off: bool) -> PyResult<()> {
        if self.driver.is_none() {
            return Ok(());
        }
        let mut first_error = None;
        if self.stream.is_some() {
            first_error = self.stream_end(py).err();
        }
        if torque_off {
            if let Err(e) = self.torque(py, false) {
                first_error.get_or_insert(e);
            }
        }
        if let Some(driver) = self.driver.take() {
            let mut said = Vec::new();
            if let Err(e) = released(py, || driver.close(&mut said)) {
                first_error.get_or_insert(to_py(e));
            }
        }
        self.servos = None;
        first_error.map_or(Ok(()), Err)
    }
}
