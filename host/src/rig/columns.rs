//! A rig's keyframe file: one timeline, every arm's columns side by side, each named after its arm:
//!
//! ```text
//! t,left.q1,left.q2,left.q3,left.q4,left.q5,left.gripper,right.q1,...,right.q5,right.gripper
//! t,left.x,left.y,left.z,right.q1,...          (an arm's Cartesian columns: the world frame)
//! ```
//!
//! Each arm's columns are those of `armctl play`'s files (`q1..qN[,v1..vN][,gripper]` or
//! `x,y,z[,qw,qx,qy,qz][,gripper]`), so the file is split into one such file per arm, with the line
//! numbers kept, and each part is read and checked by the one-arm reader
//! ([`crate::commands::drive::play::Plan`]). Cartesian columns are in the world frame and are moved into the
//! arm's base frame here. An arm without columns does not move.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use kinematics::Pose;

use crate::commands::drive::play::Plan;
use crate::motion::cartesian_file::rows;

/// One arm's part of a rig keyframe file.
pub struct ArmPart {
    /// The arm's index in the rig.
    pub arm: usize,
    /// Its keyframes, read and checked as `armctl play` reads a file.
    pub plan: Plan,
}

/// Reads the rig keyframe file at `path` for the arms `names` with bases `bases` (world frame).
pub fn read(path: &Path, names: &[&str], bases: &[Pose<f64>], timeout: f64) -> Result<Vec<ArmPart>> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read keyframe file {shown}"))?;
    split(&text, path, names, bases, timeout)
}

/// The arm's columns of a header: (index in the file's columns, name after `arm.`).
type Columns = Vec<(usize, String)>;

/// Splits the text of a rig keyframe file (`path` names it in messages) into one part per arm with
/// columns.
pub fn split(text: &str, path: &Path, names: &[&str], bases: &[Pose<f64>], timeout: f64) -> Result<Vec<ArmPart>> {
    let shown = path.display().to_string();
    let rows: Vec<(usize, &str)> = rows(text).collect();
    let Some(&(header_line, header)) = rows.first() else {
        bail!("{shown}: empty file: expected a header t,ARM.q1,... naming each arm's columns");
    };
    let fields: Vec<&str> = header.split(',').map(str::trim).collect();
    if fields.first() != Some(&"t") {
        bail!("{shown}: line {header_line}: the first column must be t; found {:?}", fields.first().unwrap_or(&""));
    }
    let mut columns: Vec<Columns> = vec![Vec::new(); names.len()];
    for (c, field) in fields.iter().enumerate().skip(1) {
        let Some((arm, column)) = field.split_once('.') else {
            bail!(
                "{shown}: line {header_line}: column {:?}: name each arm's columns ARM.COLUMN (e.g. {}.q1)",
                field,
                names.first().unwrap_or(&"left")
            );
        };
        let Some(a) = names.iter().position(|n| *n == arm) else {
            bail!(
                "{shown}: line {header_line}: column {field:?}: the rig has no arm {arm:?} (its arms: {})",
                names.join(", ")
            );
        };
        columns[a].push((c, column.to_string()));
    }
    let last_line = rows.last().map_or(0, |r| r.0);
    let mut parts = Vec::new();
    for (a, cols) in columns.iter().enumerate() {
        if cols.is_empty() {
            continue;
        }
        let cartesian = cols.first().is_some_and(|(_, name)| name == "x");
        // The arm's file, line for line: what is not a keyframe row stays blank.
        let mut lines = vec![String::new(); last_line];
        let names_of: Vec<&str> = cols.iter().map(|(_, n)| n.as_str()).collect();
        lines[header_line - 1] = format!("t,{}", names_of.join(","));
        for &(line, row) in &rows[1..] {
            let values: Vec<&str> = row.split(',').map(str::trim).collect();
            if values.len() != fields.len() {
                bail!("{shown}: line {line}: {} fields, but the header has {}", values.len(), fields.len());
            }
            let mut picked: Vec<String> = cols.iter().map(|&(c, _)| values[c].to_string()).collect();
            if cartesian {
                to_base(&mut picked, &names_of, &bases[a]).with_context(|| format!("{shown}: line {line}"))?;
            }
            lines[line - 1] = format!("{},{}", values[0], picked.join(","));
        }
        let part_path = PathBuf::from(format!("{shown} ({})", names[a]));
        let plan = Plan::parse(&lines.join("\n"), &part_path, timeout)?;
        parts.push(ArmPart { arm: a, plan });
    }
    if parts.is_empty() {
        bail!("{shown}: line {header_line}: no arm's columns: name them ARM.q1,... or ARM.x,ARM.y,ARM.z");
    }
    Ok(parts)
}

/// Moves a Cartesian row's position (and orientation) from the world frame into the arm's base
/// frame, in place; the other columns (the gripper) are left as they are.
fn to_base(values: &mut [String], names: &[&str], base: &Pose<f64>) -> Result<()> {
    let index = |name: &str| names.iter().position(|n| *n == name);
    let number = |values: &[String], i: usize| -> Result<f64> {
        let v: f64 = values[i].parse().map_err(|_| anyhow::anyhow!("{}: {:?} is not a number", names[i], values[i]))?;
        if !v.is_finite() {
            bail!("{}: {v} is not a finite number", names[i]);
        }
        Ok(v)
    };
    let (Some(x), Some(y), Some(z)) = (index("x"), index("y"), index("z")) else {
        // The one-arm reader says what the header lacks.
        return Ok(());
    };
    let p = [number(values, x)?, number(values, y)?, number(values, z)?];
    let quaternion = match (index("qw"), index("qx"), index("qy"), index("qz")) {
        (Some(w), Some(a), Some(b), Some(c)) => {
            Some([number(values, w)?, number(values, a)?, number(values, b)?, number(values, c)?])
        }
        _ => None,
    };
    let rotation = match quaternion {
        Some(q) => {
            let Some(r) = Pose::rotation_from_quaternion_wxyz(q) else {
                bail!("qw,qx,qy,qz {q:?} is not a unit quaternion");
            };
            r
        }
        None => kinematics::nalgebra::Matrix3::identity(),
    };
    let local = base.inverse().compose(&Pose { rotation, translation: p.into() });
    for (i, v) in [x, y, z].into_iter().zip(local.translation.iter()) {
        values[i] = format!("{v:.9}");
    }
    if let (Some(_), [w, a, b, c]) = (quaternion, [index("qw"), index("qx"), index("qy"), index("qz")]) {
        let q = local.quaternion_wxyz();
        for (i, v) in [w, a, b, c].into_iter().zip(q) {
            if let Some(i) = i {
                values[i] = format!("{v:.9}");
            }
        }
    }
    Ok(())
}
