//! A tree's kinematics for Python ([`TreeModel`]): a URDF with several leaves, several end
//! effectors on shared joints, over the host's own [`DynTree`] (the one `armctl fk`, `jacobian`
//! and `ik` use on a tree, and the rig's). [`model`] reads `--arm`'s name as the command line
//! does and gives a chain's [`Model`] or a [`TreeModel`].

use std::path::PathBuf;

use armctl::arm::body::Body;
use armctl::arm::dyn_tree::{DynTree, NamedGoal, TreeIkRequest, DEFAULT_MAX_ITERATIONS};
use kinematics::ik::IkConfig;
use pyo3::prelude::*;

use crate::errors::{to_py, OrRaise};
use crate::model::{finite, homogeneous, ik_config, Matrix4, Model};

/// A chain's [`Model`], or a [`TreeModel`] when `arm` is a URDF with several leaves and no `tip`
/// is named (as `armctl fk --arm` reads it).
#[pyfunction]
#[pyo3(signature = (arm, tip = None, calibration = None))]
pub fn model(py: Python<'_>, arm: &str, tip: Option<&str>, calibration: Option<PathBuf>) -> PyResult<Py<PyAny>> {
    match Body::load(arm, tip).or_raise()? {
        Body::Chain(spec) => Ok(Py::new(py, Model::of(spec, calibration.as_deref())?)?.into_any()),
        Body::Tree(spec) => {
            if calibration.is_some() {
                return Err(to_py(anyhow::anyhow!(
                    "{arm} is a tree (a URDF with several leaves): a calibration is for a chain's servos (name its tip)"
                )));
            }
            Ok(Py::new(py, TreeModel { tree: DynTree::build(spec).or_raise()? })?.into_any())
        }
    }
}

/// One end effector's outcome: `(link, reached, position_error, orientation_error or None,
/// priority)`, for the end effectors with a target.
type EffectorOutcome = (String, bool, f64, Option<f64>, u8);

/// A tree's kinematics: every end effector's pose and Jacobian, and the IK of several targets at
/// once.
#[pyclass(frozen, module = "armctl._armctl")]
pub struct TreeModel {
    tree: DynTree,
}

#[pymethods]
impl TreeModel {
    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.tree.spec().name.clone()
    }

    /// Joint names, parents first.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.tree.spec().joints.iter().map(|j| j.name.clone()).collect()
    }

    /// (lower, upper) limit per joint, rad or m.
    #[getter]
    fn limits(&self) -> Vec<(f64, f64)> {
        self.tree.spec().joints.iter().map(|j| (j.lower, j.upper)).collect()
    }

    /// The end effectors' links, in the order `fk` and `jacobian` give them.
    #[getter]
    fn effector_names(&self) -> Vec<String> {
        self.tree.effector_names().into_iter().map(str::to_string).collect()
    }

    /// Each end effector's pose at `q`, a 4 x 4 homogeneous matrix, in `effector_names`' order.
    fn fk(&self, q: Vec<f64>) -> PyResult<Vec<Matrix4>> {
        Ok(self.tree.forward(&finite(q)?).or_raise()?.effectors.iter().map(homogeneous).collect())
    }

    /// Every joint frame (after its motion) at `q`, parents first.
    fn frames(&self, q: Vec<f64>) -> PyResult<Vec<Matrix4>> {
        Ok(self.tree.forward(&finite(q)?).or_raise()?.joints.iter().map(homogeneous).collect())
    }

    /// Each end effector's 6 x N geometric Jacobian at `q` over every joint of the tree, in
    /// `effector_names`' order.
    fn jacobian(&self, q: Vec<f64>) -> PyResult<Vec<Vec<Vec<f64>>>> {
        self.tree.jacobians(&finite(q)?).or_raise()
    }

    /// Solves every target at once: `targets` as `(link, position, quaternion_wxyz or None)`;
    /// `priority` the links whose targets are met first (the rest in the null space those leave).
    /// Returns `(q, status, effectors, iterations)`, the status as a chain's (`converged`,
    /// `best_effort`, `iteration_limit`, `invalid_input`).
    #[pyo3(signature = (targets, seed = None, priority = None, position_tolerance = None, orientation_tolerance = None))]
    fn ik(
        &self,
        py: Python<'_>,
        targets: Vec<(String, [f64; 3], Option<[f64; 4]>)>,
        seed: Option<Vec<f64>>,
        priority: Option<Vec<String>>,
        position_tolerance: Option<f64>,
        orientation_tolerance: Option<f64>,
    ) -> PyResult<(Vec<f64>, String, Vec<EffectorOutcome>, u32)> {
        let named: Vec<NamedGoal> = targets
            .into_iter()
            .map(|(link, position, quaternion_wxyz)| NamedGoal { link, position, quaternion_wxyz })
            .collect();
        for goal in &named {
            let values = goal.position.iter().chain(goal.quaternion_wxyz.iter().flatten());
            if values.clone().any(|v| !v.is_finite()) {
                return Err(to_py(anyhow::anyhow!("targets[{:?}]: a value is not a finite number", goal.link)));
            }
        }
        let seed = seed.map(finite).transpose()?;
        let goals = self.tree.goals(&named, priority.as_deref()).or_raise()?;
        let config = IkConfig {
            max_iterations: DEFAULT_MAX_ITERATIONS,
            ..ik_config(position_tolerance, orientation_tolerance)?
        };
        let tree = &self.tree;
        let request = TreeIkRequest { goals: goals.clone(), seed, config };
        let outcome = py.detach(|| tree.solve(&request)).or_raise()?;
        let names = tree.effector_names();
        let effectors = goals
            .iter()
            .enumerate()
            .filter_map(|(e, goal)| {
                let goal = goal.as_ref()?;
                let o = &outcome.effectors[e];
                let orientation = goal.quaternion_wxyz.map(|_| o.orientation_error);
                Some((names[e].to_string(), o.reached, o.position_error, orientation, goal.priority))
            })
            .collect();
        Ok((outcome.q.clone(), outcome.status_name().to_string(), effectors, outcome.iterations))
    }
}
