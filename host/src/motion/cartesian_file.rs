//! Cartesian keyframe files for `armctl play`: CSV with the header `t,x,y,z` (position only, the
//! orientation left to IK) or `t,x,y,z,qw,qx,qy,qz` (a full pose, unit quaternion w first), either
//! optionally followed by `gripper` (the gripper's opening, percent: 0 closed to 100 open).
//!
//! Times are seconds on the playback clock (>= 0, strictly increasing), positions metres in the
//! arm's base frame. As in the joint keyframe files of `armctl trajectory`, blank lines and lines
//! starting with `#` are skipped, and every error names the file line (the header is line 1).

use anyhow::{bail, Result};
use firmware::link::message::{MAX_REACH, MAX_TIME, QUATERNION_TOLERANCE};

/// Keyframes as read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct CartesianKeyframes {
    /// Times (s), strictly increasing, from 0.
    pub times: Vec<f64>,
    /// Tool positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Tool orientations (unit quaternions, w first), if the file has the `qw..qz` columns.
    pub orientations: Option<Vec<[f64; 4]>>,
    /// The gripper's opening per keyframe (percent), if the file has the `gripper` column.
    pub gripper: Option<Vec<f64>>,
    /// The file line of each keyframe (1-based, the header is line 1).
    pub lines: Vec<usize>,
}

const POSITION_HEADER: [&str; 4] = ["t", "x", "y", "z"];
const POSE_HEADER: [&str; 8] = ["t", "x", "y", "z", "qw", "qx", "qy", "qz"];

/// The first line that is not blank or a comment, with its line number.
pub(crate) fn header(text: &str) -> Option<(usize, &str)> {
    rows(text).next()
}

/// Whether a header line is a Cartesian one (`t,x,...`), as opposed to a joint one (`t,q1,...`).
pub(crate) fn is_cartesian_header(header: &str) -> bool {
    header.split(',').nth(1).is_some_and(|name| name.trim() == "x")
}

pub(crate) fn rows(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.split('\n')
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim_end_matches('\r')))
        .filter(|(_, line)| !line.trim().is_empty() && !line.trim_start().starts_with('#'))
}

/// Parses Cartesian keyframe CSV text; errors are `line L: ...` (or `line L, column C: ...`).
pub fn parse_cartesian_keyframes(text: &str) -> Result<CartesianKeyframes> {
    let mut rows = rows(text);
    let Some((header_line, header)) = rows.next() else {
        bail!("empty file: expected the header t,x,y,z or t,x,y,z,qw,qx,qy,qz");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let (columns, with_gripper) = super::trajectory::split_gripper(&names);
    let with_orientation = columns == POSE_HEADER;
    if !(with_orientation || columns == POSITION_HEADER) {
        bail!(
            "line {header_line}: the header must be t,x,y,z or t,x,y,z,qw,qx,qy,qz, optionally then gripper; found {:?}",
            header.trim()
        );
    }
    let mut k = CartesianKeyframes {
        times: Vec::new(),
        positions: Vec::new(),
        orientations: with_orientation.then(Vec::new),
        gripper: with_gripper.then(Vec::new),
        lines: Vec::new(),
    };
    for (line, row) in rows {
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            bail!("line {line}: {} fields, but the header has {}", fields.len(), names.len());
        }
        let values = crate::support::numbers::csv_row(line, &fields, &names)?;
        let t = values[0];
        if !(0.0..=f64::from(MAX_TIME)).contains(&t) {
            bail!("line {line}: time {t} s is outside 0..={MAX_TIME} s");
        }
        if let (Some(&previous), Some(&previous_line)) = (k.times.last(), k.lines.last()) {
            if t <= previous {
                bail!("line {line}: time {t} is not later than the previous keyframe's ({previous}, line {previous_line})");
            }
        }
        for (value, name) in values[1..4].iter().zip(&names[1..4]) {
            if value.abs() > f64::from(MAX_REACH) {
                bail!("line {line}, column {name}: {value} m is more than {MAX_REACH} m from the base");
            }
        }
        if let Some(orientations) = &mut k.orientations {
            let q = [values[4], values[5], values[6], values[7]];
            let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            if (norm - 1.0).abs() > f64::from(QUATERNION_TOLERANCE) {
                bail!("line {line}: the quaternion qw,qx,qy,qz has norm {norm:.6}, not 1");
            }
            orientations.push(q);
        }
        if let Some(g) = &mut k.gripper {
            g.push(super::trajectory::gripper_value(line, values[names.len() - 1])?);
        }
        k.times.push(t);
        k.positions.push([values[1], values[2], values[3]]);
        k.lines.push(line);
    }
    if k.times.is_empty() {
        bail!("no keyframes after the header");
    }
    Ok(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_position_and_pose_files() {
        let k = parse_cartesian_keyframes("# tool path\nt,x,y,z\n0,0.2,0,0.1\n\n1.5, 0.2,0.05,0.1\r\n").unwrap();
        assert_eq!(k.times, vec![0.0, 1.5]);
        assert_eq!(k.positions[1], [0.2, 0.05, 0.1]);
        assert_eq!(k.lines, vec![3, 5]);
        assert!(k.orientations.is_none());
        let k = parse_cartesian_keyframes("t,x,y,z,qw,qx,qy,qz\n0.5,0.1,0,0.2,1,0,0,0\n").unwrap();
        assert_eq!(k.orientations.unwrap(), vec![[1.0, 0.0, 0.0, 0.0]]);
        assert!(k.gripper.is_none());
        let k = parse_cartesian_keyframes("t,x,y,z,gripper\n0,0.2,0,0.1,100\n1,0.2,0,0.1,12.5\n").unwrap();
        assert_eq!(k.gripper.unwrap(), vec![100.0, 12.5]);
        let e = parse_cartesian_keyframes("t,x,y,z,gripper\n0,0.2,0,0.1,100\n1,0.2,0,0.1,101\n").unwrap_err();
        assert!(format!("{e:#}").contains("line 3, column gripper: 101 is not an opening"), "{e:#}");
        let e = parse_cartesian_keyframes("t,x,y,z,gripper\n0,0.2,0,0.1,nan\n").unwrap_err();
        assert!(format!("{e:#}").starts_with("line 2"), "{e:#}");
    }

    #[test]
    fn errors_name_the_line() {
        let cases = [
            ("", "empty file"),
            ("t,q1,q2\n0,1,2\n", "line 1: the header must be"),
            ("t,x,y\n0,1,2\n", "line 1: the header must be"),
            ("t,x,y,z\n", "no keyframes"),
            ("t,x,y,z\n0,1,2\n", "line 2: 3 fields"),
            ("t,x,y,z\n0,0.1,0,0\n1,0.1,zz,0\n", "line 3, column y: \"zz\" is not a number"),
            ("t,x,y,z\n0,0.1,0,NaN\n", "line 2, column z: NaN is not a finite number"),
            ("t,x,y,z\n1,0.1,0,0\n1,0.1,0,0\n", "line 3: time 1 is not later"),
            ("t,x,y,z\n-1,0.1,0,0\n", "line 2: time -1 s is outside"),
            ("t,x,y,z\n0,11,0,0\n", "line 2, column x: 11 m is more than"),
            ("t,x,y,z,qw,qx,qy,qz\n0,0.1,0,0,1,1,0,0\n", "line 2: the quaternion"),
        ];
        for (text, needle) in cases {
            let e = parse_cartesian_keyframes(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn detects_the_format_by_header() {
        assert!(is_cartesian_header("t,x,y,z"));
        assert!(is_cartesian_header("t, x ,y,z,qw,qx,qy,qz"));
        assert!(!is_cartesian_header("t,q1,q2"));
        assert_eq!(header("\u{feff}# c\n\nt,x,y,z\n"), Some((3, "t,x,y,z")));
    }
}
