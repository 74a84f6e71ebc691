//! An arm's kinematics for Python ([`Model`]) and trajectory sampling ([`sample`]): the host's
//! own ([`armctl::arm::dof::DynArm`], [`armctl::motion::trajectory`]), in f64.

use std::path::PathBuf;

use armctl::arm::dof::{self, DynArm, IkRequest, Scalar, SolverName};
use armctl::arm::ArmSpec;
use armctl::motion::trajectory::{self, Ends, Keyframes, Method, Options};
use kinematics::ik::IkConfig;
use pyo3::prelude::*;

use crate::errors::OrRaise;

/// 4 x 4 homogeneous matrix, row by row.
pub(crate) type Matrix4 = [[f64; 4]; 4];

pub(crate) fn homogeneous(p: &kinematics::Pose<f64>) -> Matrix4 {
    let mut m = [[0.0; 4]; 4];
    for (r, row) in m.iter_mut().enumerate().take(3) {
        for (c, value) in row.iter_mut().enumerate().take(3) {
            *value = p.rotation[(r, c)];
        }
        row[3] = p.translation[r];
    }
    m[3][3] = 1.0;
    m
}

/// `q` itself, or the error naming its first value that is not finite (NaN or infinite joint
/// values would give a pose of NaNs, not an error).
pub(crate) fn finite(q: Vec<f64>) -> PyResult<Vec<f64>> {
    match q.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(crate::errors::to_py(anyhow::anyhow!("q: value {} ({}) is not a finite number", i + 1, q[i]))),
        None => Ok(q),
    }
}

/// An arm's kinematics: a preset (`so101`, `ur5e`, `planar:3`, ...), a URDF file (with `tip`, the
/// link the chain ends at) or an arm file (`.toml`), optionally with a LeRobot calibration.
#[pyclass(frozen, module = "armctl._armctl")]
pub struct Model {
    arm: Box<dyn DynArm>,
}

#[pymethods]
impl Model {
    #[new]
    #[pyo3(signature = (arm, tip = None, calibration = None))]
    fn new(arm: &str, tip: Option<&str>, calibration: Option<PathBuf>) -> PyResult<Self> {
        Self::of(ArmSpec::load(arm, tip).or_raise()?, calibration.as_deref())
    }

    /// The arm's name.
    #[getter]
    fn name(&self) -> String {
        self.arm.spec().name.clone()
    }

    /// Joint names, base first.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.arm.spec().joints.iter().map(|j| j.name.clone()).collect()
    }

    /// (lower, upper) limit per joint, rad or m.
    #[getter]
    fn limits(&self) -> Vec<(f64, f64)> {
        self.arm.spec().joints.iter().map(|j| (j.lower, j.upper)).collect()
    }

    /// Whether the arm has a gripper (its servos' `[gripper]` table, or its preset's).
    #[getter]
    fn has_gripper(&self) -> bool {
        armctl::arm::servos::servos_of(self.arm.spec()).is_some_and(|s| s.gripper.is_some())
    }

    /// The closed-form IK shape its geometry has (`spherical_wrist`, `three_parallel`,
    /// `yaw_pitch`), or None.
    #[getter]
    fn closed_form(&self) -> Option<String> {
        self.arm.closed_form_shape().map(|s| s.as_str().to_string())
    }

    /// The tool pose at `q`, a 4 x 4 homogeneous matrix.
    fn fk(&self, q: Vec<f64>) -> PyResult<Matrix4> {
        Ok(homogeneous(&self.arm.tool_pose(&finite(q)?).or_raise()?))
    }

    /// Every joint frame (after its motion) at `q`, base first.
    fn frames(&self, q: Vec<f64>) -> PyResult<Vec<Matrix4>> {
        Ok(self.arm.joint_frames(&finite(q)?).or_raise()?.iter().map(homogeneous).collect())
    }

    /// The 6 x N geometric Jacobian at `q` (linear rows first), row by row.
    fn jacobian(&self, q: Vec<f64>) -> PyResult<Vec<Vec<f64>>> {
        self.arm.jacobian(&finite(q)?).or_raise()
    }

    /// Solves one target: `(q, status, position_error, orientation_error, method)`. The status is
    /// `converged`, `best_effort`, `iteration_limit` or the reason an input was refused.
    #[pyo3(signature = (position, quaternion_wxyz = None, seed = None, solver = "auto", position_tolerance = None, orientation_tolerance = None))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments, each an `armctl ik` option.
    fn ik(
        &self,
        py: Python<'_>,
        position: [f64; 3],
        quaternion_wxyz: Option<[f64; 4]>,
        seed: Option<Vec<f64>>,
        solver: &str,
        position_tolerance: Option<f64>,
        orientation_tolerance: Option<f64>,
    ) -> PyResult<(Vec<f64>, String, f64, f64, String)> {
        let request =
            self.request(position, quaternion_wxyz, seed, solver, position_tolerance, orientation_tolerance)?;
        let arm = &*self.arm;
        let outcome = py.detach(|| arm.solve(&request)).or_raise()?;
        Ok((
            outcome.q,
            outcome.status.as_str().to_string(),
            outcome.position_error,
            outcome.orientation_error,
            outcome.method.into(),
        ))
    }
}

impl Model {
    /// The chain of `spec`, with the LeRobot `calibration` file if given.
    pub(crate) fn of(spec: ArmSpec, calibration: Option<&std::path::Path>) -> PyResult<Self> {
        let spec = armctl::runtime::connection::calibrated(spec, calibration);
        Ok(Self { arm: spec.and_then(dof::build).or_raise()? })
    }

    fn request(
        &self,
        position: [f64; 3],
        quaternion_wxyz: Option<[f64; 4]>,
        seed: Option<Vec<f64>>,
        solver: &str,
        position_tolerance: Option<f64>,
        orientation_tolerance: Option<f64>,
    ) -> PyResult<IkRequest> {
        let solver: SolverName = solver.parse::<SolverName>().or_raise()?;
        let config = ik_config(position_tolerance, orientation_tolerance)?;
        Ok(IkRequest { position, quaternion_wxyz, seed, solver, config, scalar: Scalar::F64, tilt_only: false })
    }
}

/// The IK's tolerances (f64's defaults where not given), refused unless positive and finite; a
/// chain's and a tree's IK take the same.
pub(crate) fn ik_config(
    position_tolerance: Option<f64>,
    orientation_tolerance: Option<f64>,
) -> PyResult<IkConfig<f64>> {
    let (p, o) = Scalar::F64.default_tolerances();
    let config = IkConfig {
        position_tolerance: position_tolerance.unwrap_or(p),
        orientation_tolerance: orientation_tolerance.unwrap_or(o),
        ..IkConfig::default()
    };
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(config.position_tolerance) && positive(config.orientation_tolerance)) {
        return Err(crate::errors::to_py(anyhow::anyhow!("tolerances must be positive finite numbers")));
    }
    Ok(config)
}

/// Sampled times, and positions, velocities and accelerations, one row per sample.
type Samples = (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// Samples the curve through timed keyframes (`armctl trajectory sample`): `(t, q, v, a)`, one
/// row per sample, at `rate` samples per second.
#[pyfunction]
#[pyo3(signature = (times, positions, rate, method = "catmull-rom", velocities = None, ends = "zero"))]
pub fn sample(
    times: Vec<f64>,
    positions: Vec<Vec<f64>>,
    rate: f64,
    method: &str,
    velocities: Option<Vec<Vec<f64>>>,
    ends: &str,
) -> PyResult<Samples> {
    let method: Method = method.parse().or_raise()?;
    let ends: Ends = ends.parse().or_raise()?;
    let keyframes: Keyframes = Keyframes::from_rows(&times, &positions, velocities.as_deref()).or_raise()?;
    let options = Options { method, tcb: [0.0; 3], ends, rate, limits: None };
    let sampled = trajectory::sample(&keyframes, &options).or_raise()?;
    let mut out = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for row in sampled.rows {
        out.0.push(row.t);
        out.1.push(row.q);
        out.2.push(row.v);
        out.3.push(row.a);
    }
    Ok(out)
}
