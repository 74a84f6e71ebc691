//! `armctl fk`, `jacobian` and `ik` on a tree (a URDF with several leaves and no `--tip`): each
//! end effector answered under its link's name with the fields a chain's tool has, and the IK of
//! every target as one problem over the whole tree ([`DynTree::solve`]).

use std::collections::BTreeMap;
use std::io::Write;

use anyhow::{bail, Result};
use kinematics::ik::IkConfig;
use kinematics::tree::TreeStatus;
use kinematics::Pose;
use serde::Serialize;
use serde_json::{json, Value};

use super::{print_json, vec3};
use crate::arm::dyn_tree::{DynTree, NamedGoal, TreeIkRequest};
use crate::support::numbers as parse;

/// A pose as a chain's `fk` prints its tool.
fn pose_json(p: &Pose<f64>) -> Value {
    let rotation: Vec<[f64; 3]> =
        (0..3).map(|r| [p.rotation[(r, 0)], p.rotation[(r, 1)], p.rotation[(r, 2)]]).collect();
    json!({"position": vec3(p), "quaternion_wxyz": p.quaternion_wxyz(), "rotation": rotation})
}

/// `armctl fk` of a tree: every end effector's pose, keyed by its link, and every joint's frame.
pub(super) fn fk(tree: &DynTree, q: &str, out: &mut dyn Write) -> Result<i32> {
    let q = parse::numbers(q, "--q")?;
    let poses = tree.forward(&q)?;
    let effectors: BTreeMap<&str, Value> =
        tree.effector_names().into_iter().zip(&poses.effectors).map(|(name, p)| (name, pose_json(p))).collect();
    let frames: Vec<Value> = poses
        .joints
        .iter()
        .zip(&tree.spec().joints)
        .map(|(p, j)| json!({"joint": j.name, "position": vec3(p), "quaternion_wxyz": p.quaternion_wxyz()}))
        .collect();
    print_json(out, &json!({"arm": tree.spec().name, "effectors": effectors, "frames": frames}))?;
    Ok(0)
}

/// `armctl jacobian` of a tree: each end effector's 6 x N Jacobian over every joint of the tree,
/// the columns in the order of `joints`.
pub(super) fn jacobian(tree: &DynTree, q: &str, out: &mut dyn Write) -> Result<i32> {
    let q = parse::numbers(q, "--q")?;
    let jacobians = tree.jacobians(&q)?;
    let effectors: BTreeMap<&str, Value> = tree
        .effector_names()
        .into_iter()
        .zip(jacobians)
        .map(|(name, jacobian)| (name, json!({"jacobian": jacobian})))
        .collect();
    let joints: Vec<&str> = tree.spec().joints.iter().map(|j| j.name.as_str()).collect();
    print_json(out, &json!({"arm": tree.spec().name, "effectors": effectors, "joints": joints}))?;
    Ok(0)
}

/// `armctl ik` of a tree, as typed: one `--target NAME=x,y,z[,qw,qx,qy,qz]` per end effector.
pub(super) struct TreeIk<'a> {
    /// The `--target` values.
    pub targets: &'a [String],
    /// `--seed`.
    pub seed: Option<&'a str>,
    /// `--priority`: the end effectors whose targets come first.
    pub priority: Option<&'a str>,
    /// Tolerances, orientation weight, iteration budget.
    pub config: IkConfig<f64>,
}

/// One `--target NAME=x,y,z[,qw,qx,qy,qz]`.
fn named_goal(tree: &DynTree, text: &str) -> Result<NamedGoal> {
    let Some((link, values)) = text.split_once('=') else {
        bail!(
            "--target {text}: a tree's target is NAME=x,y,z or NAME=x,y,z,qw,qx,qy,qz, NAME one of its end effectors ({})",
            tree.effector_names().join(", ")
        );
    };
    let link = link.trim();
    let what = format!("--target {link}");
    let v = parse::numbers(values, &what)?;
    let (position, quaternion_wxyz) = match *v.as_slice() {
        [x, y, z] => ([x, y, z], None),
        [x, y, z, w, i, j, k] => ([x, y, z], Some([w, i, j, k])),
        _ => bail!("{what}: expected 3 numbers (x,y,z) or 7 (x,y,z,qw,qx,qy,qz), got {}", v.len()),
    };
    Ok(NamedGoal { link: link.to_string(), position, quaternion_wxyz })
}

/// One end effector's line of the answer: the chain's error fields, whether it reached its
/// target, and the priority it had.
#[derive(Serialize)]
struct PrintedEffector {
    orientation_error: Option<f64>,
    position_error: Option<f64>,
    priority: u8,
    reached: bool,
}

/// The answer as printed: a chain's fields (alphabetical, as `serde_json`'s maps print them),
/// the errors per end effector with a target. `reason` only for a refused input.
#[derive(Serialize)]
struct Printed<'a> {
    effectors: BTreeMap<&'a str, PrintedEffector>,
    iterations: u32,
    q: &'a [f64],
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<&'static str>,
    restarts: u32,
    /// The tree has one method: damped least squares over every target.
    solver: &'static str,
    status: &'static str,
}

/// Solves every target at once and prints the answer; returns the exit code (1 if the solver
/// refused the input, as a chain's `ik`).
pub(super) fn ik(tree: &DynTree, request: TreeIk<'_>, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let targets = request.targets.iter().map(|t| named_goal(tree, t)).collect::<Result<Vec<_>>>()?;
    let first: Option<Vec<String>> =
        request.priority.map(|p| p.split(',').map(|name| name.trim().to_string()).collect());
    // The error names the option it is about: `--priority` for the ranking, else `--target`.
    let goals = tree.goals(&targets, first.as_deref()).map_err(|e| {
        let text = format!("{e:#}");
        match text.strip_prefix("priority: ") {
            Some(rest) => anyhow::anyhow!("--priority: {rest}"),
            None => anyhow::anyhow!("--target: {text}"),
        }
    })?;
    let seed = request.seed.map(|s| parse::numbers(s, "--seed")).transpose()?;
    let outcome = tree.solve(&TreeIkRequest { goals: goals.clone(), seed, config: request.config })?;
    let refused = outcome.status == TreeStatus::InvalidInput;
    let names = tree.effector_names();
    let effectors = goals
        .iter()
        .enumerate()
        .filter_map(|(e, goal)| {
            let goal = goal.as_ref()?;
            let o = &outcome.effectors[e];
            Some((
                names[e],
                PrintedEffector {
                    orientation_error: (!refused && goal.quaternion_wxyz.is_some()).then_some(o.orientation_error),
                    position_error: (!refused).then_some(o.position_error),
                    priority: goal.priority,
                    reached: o.reached,
                },
            ))
        })
        .collect();
    print_json(
        out,
        &Printed {
            effectors,
            iterations: outcome.iterations,
            q: &outcome.q,
            reason: refused.then_some("a target, the seed or a tolerance is not finite"),
            restarts: outcome.restarts,
            solver: "dls",
            status: outcome.status_name(),
        },
    )?;
    if refused {
        writeln!(err, "error: the tree's solver refused the input: a target, the seed or a tolerance is not finite")?;
        return Ok(1);
    }
    Ok(0)
}
