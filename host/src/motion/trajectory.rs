//! `armctl trajectory sample`: keyframes from a CSV file, interpolated by one of the kinematics
//! crate's methods, sampled at a fixed rate and written as CSV or JSON (optionally plotted).
//!
//! The keyframe file is CSV with the header `t,q1,...,qN` and optionally `v1,...,vN` (velocities
//! at the keyframes, used by `--method hermite`), then optionally `gripper` (the gripper's opening
//! at the keyframe, percent: 0 closed to 100 open, as LeRobot's `RANGE_0_100`; `armctl play`
//! sends it, interpolated by the firmware between keyframes). Blank lines and lines starting with
//! `#` are skipped. Every error names the file line it is about (the header is line 1).

use anyhow::{anyhow, bail, Context, Result};
use kinematics::nalgebra::SVector;
use kinematics::trajectory::{
    time_scale, Curve, EndCondition, Interpolation, JointLimits, Keyframe, KochanekBartels, LimitError, TrajectoryError,
};
use serde_json::{json, Value};
use std::io::Write;

/// The largest joint count `armctl trajectory` handles.
pub const MAX_JOINTS: usize = 12;
/// The largest keyframe count (the fixed capacity of the kinematics crate's curves).
pub const MAX_KEYFRAMES: usize = 1024;
/// The most sample rows one run writes.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Interpolation method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Straight lines (constant velocity between keyframes; velocity jumps at keyframes).
    Linear,
    /// Non-uniform Catmull-Rom (C1); ends per --ends.
    CatmullRom,
    /// Monotone cubic (Fritsch-Carlson): never overshoots between keyframes (C1).
    Monotone,
    /// Natural cubic spline (C2, zero acceleration at both ends).
    Natural,
    /// Cubic Hermite with the velocities of the file's v1..vN columns (C1).
    Hermite,
    /// Kochanek-Bartels (TCB): --tension, --continuity, --bias; ends per --ends.
    Kb,
}

// By their command-line names, with no parser's derive (this module is beneath the command line):
// `armctl::cli::values` offers these names to the parser, other front ends use `FromStr`.

impl Method {
    /// Every method with its name on the command line and what it is (its help there).
    pub const NAMES: [(&'static str, Method, &'static str); 6] = [
        ("linear", Method::Linear, "Straight lines (constant velocity between keyframes; velocity jumps at keyframes)"),
        ("catmull-rom", Method::CatmullRom, "Non-uniform Catmull-Rom (C1); ends per --ends"),
        ("monotone", Method::Monotone, "Monotone cubic (Fritsch-Carlson): never overshoots between keyframes (C1)"),
        ("natural", Method::Natural, "Natural cubic spline (C2, zero acceleration at both ends)"),
        ("hermite", Method::Hermite, "Cubic Hermite with the velocities of the file's v1..vN columns (C1)"),
        ("kb", Method::Kb, "Kochanek-Bartels (TCB): --tension, --continuity, --bias; ends per --ends"),
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        name_of(self, &Self::NAMES)
    }
}

impl std::str::FromStr for Method {
    type Err = anyhow::Error;

    /// A method by its name on the command line (any case), for front ends other than the command line.
    fn from_str(name: &str) -> Result<Self> {
        by_name(name, "method", &Self::NAMES)
    }
}

/// The name of `value` in its `NAMES` table.
fn name_of<T: Copy + PartialEq>(value: T, names: &[(&'static str, T, &'static str)]) -> &'static str {
    names.iter().find(|(_, v, _)| *v == value).map(|&(name, _, _)| name).expect("every variant is named")
}

/// The value whose name is `name` (any case), or the one-line error listing them.
fn by_name<T: Copy>(name: &str, what: &str, names: &[(&'static str, T, &'static str)]) -> Result<T> {
    names.iter().find(|(n, _, _)| n.eq_ignore_ascii_case(name)).map(|&(_, v, _)| v).ok_or_else(|| {
        let names: Vec<&str> = names.iter().map(|(n, _, _)| *n).collect();
        anyhow::anyhow!("{what} {name:?}: one of {}", names.join(", "))
    })
}

/// Velocity at the first and last keyframe for `catmull-rom` and `kb`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ends {
    /// Start and end at rest.
    Zero,
    /// Zero acceleration at the first and last keyframe.
    Natural,
}

impl Ends {
    /// Both end conditions with their names on the command line and what they are.
    pub const NAMES: [(&'static str, Ends, &'static str); 2] = [
        ("zero", Ends::Zero, "Start and end at rest"),
        ("natural", Ends::Natural, "Zero acceleration at the first and last keyframe"),
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        name_of(self, &Self::NAMES)
    }
}

impl std::str::FromStr for Ends {
    type Err = anyhow::Error;

    /// Ends by their name on the command line (any case), for front ends other than the command line.
    fn from_str(name: &str) -> Result<Self> {
        by_name(name, "ends", &Self::NAMES)
    }
}

/// Keyframes as read from a file, before the joint count is fixed at compile time.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes {
    /// Joint count N.
    pub joints: usize,
    /// Times (s), strictly increasing.
    pub times: Vec<f64>,
    /// One row of N positions per keyframe.
    pub positions: Vec<Vec<f64>>,
    /// One row of N velocities per keyframe, if the file has `v` columns.
    pub velocities: Option<Vec<Vec<f64>>>,
    /// The gripper's opening per keyframe (percent), if the file has the `gripper` column.
    pub gripper: Option<Vec<f64>>,
    /// The file line of each keyframe (1-based, the header is line 1).
    pub lines: Vec<usize>,
}

/// The optional last column of keyframe files: the gripper's opening, percent.
pub const GRIPPER_COLUMN: &str = "gripper";

/// Splits a trailing `gripper` column off a header's names.
pub(crate) fn split_gripper<'a>(names: &[&'a str]) -> (Vec<&'a str>, bool) {
    match names.split_last() {
        Some((&GRIPPER_COLUMN, rest)) => (rest.to_vec(), true),
        _ => (names.to_vec(), false),
    }
}

/// A gripper opening read from a file: a percentage, or a line error.
pub(crate) fn gripper_value(line: usize, value: f64) -> Result<f64> {
    if !(0.0..=100.0).contains(&value) {
        bail!("line {line}, column {GRIPPER_COLUMN}: {value} is not an opening in percent (0 closed to 100 open)");
    }
    Ok(value)
}

/// Appends one row of a keyframe file to `text`: the time to the microsecond (the link's clock
/// counts microseconds), then `values` in full, each as the shortest text that reads back as the
/// same `f64`. Rounded to a few decimals, a value the sender left at a joint limit can land just
/// beyond it, and the file is then refused when read or played back (`teleop --record`,
/// `retarget` and its rig file write through this).
pub fn push_keyframe_row(text: &mut String, time: f64, values: impl IntoIterator<Item = f64>) {
    use std::fmt::Write as _;
    let _ = write!(text, "{time:.6}");
    for v in values {
        let _ = write!(text, ",{v}");
    }
    text.push('\n');
}

fn expected_header(joints: usize, velocities: bool) -> Vec<String> {
    let mut names = vec!["t".to_string()];
    names.extend((1..=joints).map(|j| format!("q{j}")));
    if velocities {
        names.extend((1..=joints).map(|j| format!("v{j}")));
    }
    names
}

/// Parses keyframe CSV text; errors are `line L: ...` (or `line L, column C: ...`).
pub fn parse_keyframes(text: &str) -> Result<Keyframes> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut rows = text
        .split('\n')
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim_end_matches('\r')))
        .filter(|(_, line)| !line.trim().is_empty() && !line.trim_start().starts_with('#'));
    let Some((header_line, header)) = rows.next() else {
        bail!("empty file: expected the header t,q1,...,qN[,v1,...,vN][,gripper]");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let (columns, with_gripper) = split_gripper(&names);
    let joints = columns.iter().skip(1).filter(|n| n.starts_with('q')).count();
    let with_velocities = columns.len() == 1 + 2 * joints;
    if joints == 0 || columns != expected_header(joints, with_velocities) {
        bail!(
            "line {header_line}: the header must be t,q1,...,qN or t,q1,...,qN,v1,...,vN, optionally then gripper; found {:?}",
            header.trim()
        );
    }
    if joints > MAX_JOINTS {
        bail!("line {header_line}: {joints} joints: armctl trajectory handles at most {MAX_JOINTS}");
    }
    let mut k = Keyframes {
        joints,
        times: Vec::new(),
        positions: Vec::new(),
        velocities: with_velocities.then(Vec::new),
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
        if let (Some(&previous), Some(&previous_line)) = (k.times.last(), k.lines.last()) {
            if t <= previous {
                bail!("line {line}: time {t} is not later than the previous keyframe's ({previous}, line {previous_line})");
            }
        }
        k.times.push(t);
        k.positions.push(values[1..=joints].to_vec());
        if let Some(v) = &mut k.velocities {
            v.push(values[1 + joints..1 + 2 * joints].to_vec());
        }
        if let Some(g) = &mut k.gripper {
            g.push(gripper_value(line, values[names.len() - 1])?);
        }
        k.lines.push(line);
    }
    match k.times.len() {
        0 => bail!("no keyframes after the header"),
        1 => bail!("line {}: only one keyframe; a trajectory needs at least 2", k.lines[0]),
        _ => Ok(k),
    }
}

impl Keyframes {
    /// Keyframes given as values rather than a file (the Python package's arrays), with the
    /// checks [`parse_keyframes`] makes: at least 2, times finite and strictly increasing, every
    /// row of the same joint count, every value finite. The `lines` are the keyframes' numbers
    /// (from 1), which errors name as `line N`.
    pub fn from_rows(times: &[f64], positions: &[Vec<f64>], velocities: Option<&[Vec<f64>]>) -> Result<Self> {
        let joints = positions.first().map_or(0, Vec::len);
        if times.len() != positions.len() || velocities.is_some_and(|v| v.len() != times.len()) {
            bail!(
                "{} times but {} rows of positions{}",
                times.len(),
                positions.len(),
                velocities.map(|v| format!(" and {} of velocities", v.len())).unwrap_or_default()
            );
        }
        if times.len() < 2 {
            bail!("{} keyframes: a trajectory needs at least 2", times.len());
        }
        if joints == 0 || joints > MAX_JOINTS {
            bail!("{joints} joints: armctl trajectory handles 1 to {MAX_JOINTS}");
        }
        let rows = positions.iter().chain(velocities.into_iter().flatten());
        for (i, row) in rows.enumerate() {
            let k = i % times.len() + 1;
            if row.len() != joints {
                bail!("line {k}: {} values, but the first keyframe has {joints} joints", row.len());
            }
            if let Some(bad) = row.iter().find(|x| !x.is_finite()) {
                bail!("line {k}: {bad} is not a finite number");
            }
        }
        for (i, pair) in times.windows(2).enumerate() {
            if !(pair[0].is_finite() && pair[1].is_finite()) || pair[1] <= pair[0] {
                bail!("line {}: time {} is not later than the previous keyframe's ({})", i + 2, pair[1], pair[0]);
            }
        }
        Ok(Self {
            joints,
            times: times.to_vec(),
            positions: positions.to_vec(),
            velocities: velocities.map(<[Vec<f64>]>::to_vec),
            gripper: None,
            lines: (1..=times.len()).collect(),
        })
    }
}

/// Reads and parses a keyframe file; errors start with the file name.
pub fn read_keyframes(path: &std::path::Path) -> Result<Keyframes> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read keyframe file {}", path.display()))?;
    parse_keyframes(&text).with_context(|| path.display().to_string())
}

/// Joint limits as given on the command line; each list has one entry (every joint) or N.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LimitSpec {
    /// Max |velocity|.
    pub velocity: Vec<f64>,
    /// Max |acceleration|.
    pub acceleration: Vec<f64>,
    /// Lowest positions (unbounded if absent).
    pub lower: Option<Vec<f64>>,
    /// Highest positions (unbounded if absent).
    pub upper: Option<Vec<f64>>,
}

/// Parses `--limits` (`v=1.5,a=4,lo=-3,hi=3`, a value being `x` or `x1:x2:...:xN`).
pub fn parse_limits(text: &str) -> Result<LimitSpec> {
    let mut spec = LimitSpec::default();
    let (mut v, mut a) = (None, None);
    for item in text.split(',').map(str::trim) {
        let Some((key, value)) = item.split_once('=') else {
            bail!("--limits: {item:?} is not KEY=VALUE (keys v, a, lo, hi)");
        };
        let key = key.trim();
        let numbers = crate::support::numbers::numbers(&value.replace(':', ","), &format!("--limits {key}"))?;
        if numbers.is_empty() {
            bail!("--limits: {key} has no value");
        }
        let slot = match key {
            "v" => &mut v,
            "a" => &mut a,
            "lo" => &mut spec.lower,
            "hi" => &mut spec.upper,
            _ => bail!("--limits: unknown key {key:?} (keys v, a, lo, hi)"),
        };
        if slot.replace(numbers).is_some() {
            bail!("--limits: {key} given twice");
        }
    }
    spec.velocity = v.ok_or_else(|| anyhow!("--limits needs v=MAX_VELOCITY"))?;
    spec.acceleration = a.ok_or_else(|| anyhow!("--limits needs a=MAX_ACCELERATION"))?;
    Ok(spec)
}

/// One sampled instant.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Time (s).
    pub t: f64,
    /// Positions.
    pub q: Vec<f64>,
    /// Velocities.
    pub v: Vec<f64>,
    /// Accelerations.
    pub a: Vec<f64>,
}

/// What time scaling under `--limits` did.
#[derive(Clone, Debug, PartialEq)]
pub struct Retiming {
    /// Duration before (s).
    pub old_duration: f64,
    /// Duration after (s).
    pub new_duration: f64,
    /// The largest factor a segment was stretched by.
    pub max_stretch: f64,
    /// True if velocities were reduced to keep a segment inside the position range.
    pub range_clamped: bool,
}

/// A sampled trajectory.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    /// Method used.
    pub method: Method,
    /// Joint count.
    pub joints: usize,
    /// Keyframe times of the sampled curve (after any time scaling).
    pub keyframe_times: Vec<f64>,
    /// Keyframe positions.
    pub keyframe_positions: Vec<Vec<f64>>,
    /// The samples.
    pub rows: Vec<Row>,
    /// Set when `--limits` changed the timing.
    pub retiming: Option<Retiming>,
}

/// Sampling options.
#[derive(Clone, Debug)]
pub struct Options {
    /// Method.
    pub method: Method,
    /// Kochanek-Bartels tension, continuity, bias.
    pub tcb: [f64; 3],
    /// End condition of catmull-rom and kb.
    pub ends: Ends,
    /// Samples per second.
    pub rate: f64,
    /// Joint limits.
    pub limits: Option<LimitSpec>,
}

/// Sample times from `start` to `end` inclusive at `rate` (the last one is exactly `end`).
pub fn sample_times(start: f64, end: f64, rate: f64) -> Result<Vec<f64>> {
    if !(rate.is_finite() && rate > 0.0) {
        bail!("--rate must be a positive finite number of samples per second");
    }
    let span = (end - start) * rate;
    let steps = (span + 1e-9 * span.max(1.0)).floor();
    if !(steps.is_finite() && steps < MAX_SAMPLES as f64) {
        bail!("--rate {rate} over {} s gives more than {MAX_SAMPLES} samples", end - start);
    }
    let steps = steps as usize;
    let mut times: Vec<f64> = (0..=steps).map(|i| start + i as f64 / rate).collect();
    let last = times.last_mut().expect("at least one sample");
    if (end - *last).abs() <= 1e-9 * (end - start).abs().max(1.0) {
        *last = end;
    } else {
        times.push(end);
    }
    Ok(times)
}

/// Builds the curve of `options` from `keyframes` and samples it.
///
/// The curves have a fixed capacity of [`MAX_KEYFRAMES`]; `armctl play` streams a file of any
/// length (the firmware's queue holds a window of it), so the cap is checked here, not when parsing.
pub fn sample(keyframes: &Keyframes, options: &Options) -> Result<Sampled> {
    if keyframes.times.len() > MAX_KEYFRAMES {
        let line = keyframes.lines.get(MAX_KEYFRAMES).copied().unwrap_or_default();
        bail!("line {line}: more than {MAX_KEYFRAMES} keyframes (the capacity of armctl trajectory's curves)");
    }
    macro_rules! by_joints {
        ($($n:literal)*) => {
            match keyframes.joints {
                $($n => sample_n::<$n>(keyframes, options),)*
                n => bail!("{n} joints: armctl trajectory handles 1 to {MAX_JOINTS}"),
            }
        };
    }
    by_joints!(1 2 3 4 5 6 7 8 9 10 11 12)
}

type Curve64<const J: usize> = Curve<f64, J, MAX_KEYFRAMES>;

/// The keyframe named by a kinematics error, as a file line.
fn explain(e: impl std::fmt::Display, index: Option<usize>, keyframes: &Keyframes) -> anyhow::Error {
    match index.and_then(|i| keyframes.lines.get(i)) {
        Some(line) => anyhow!("line {line}: {e}"),
        None => anyhow!("{e}"),
    }
}

fn trajectory_error(e: TrajectoryError, keyframes: &Keyframes) -> anyhow::Error {
    let index = match e {
        TrajectoryError::TimesNotIncreasing { index } | TrajectoryError::NonFinite { index } => Some(index),
        _ => None,
    };
    explain(e, index, keyframes)
}

fn vector<const J: usize>(values: &[f64], what: &str) -> Result<SVector<f64, J>> {
    match values.len() {
        1 => Ok(SVector::repeat(values[0])),
        n if n == J => Ok(SVector::from_column_slice(values)),
        n => bail!("--limits {what}: {n} values for {J} joints (give 1 or {J})"),
    }
}

/// Refuses options the chosen method would ignore, so nothing the user gave is dropped silently
/// (velocity columns are only noted, see `super::sample::run`: one file is often sampled by several methods).
fn check_unused(options: &Options) -> Result<()> {
    if options.tcb != [0.0; 3] && options.method != Method::Kb {
        bail!("--tension, --continuity and --bias apply only to --method kb");
    }
    if options.ends != Ends::Zero && !matches!(options.method, Method::CatmullRom | Method::Kb) {
        bail!("--ends applies only to --method catmull-rom and kb");
    }
    Ok(())
}

fn build<const J: usize>(k: &Keyframes, options: &Options, frames: &[Keyframe<f64, J>]) -> Result<Box<Curve64<J>>> {
    check_unused(options)?;
    let ends = match options.ends {
        Ends::Zero => EndCondition::ZeroVelocity,
        Ends::Natural => EndCondition::Natural,
    };
    let curve = match options.method {
        Method::Linear => Curve64::<J>::linear(frames),
        Method::CatmullRom => Curve64::<J>::catmull_rom(frames, ends),
        Method::Monotone => Curve64::<J>::monotone(frames),
        Method::Natural => Curve64::<J>::natural_spline(frames),
        Method::Hermite => {
            let Some(velocities) = &k.velocities else {
                bail!("--method hermite needs velocity columns v1,...,v{} in the keyframe file", k.joints);
            };
            let velocities: Vec<SVector<f64, J>> = velocities.iter().map(|v| SVector::from_column_slice(v)).collect();
            Curve64::<J>::with_velocities(frames, &velocities)
        }
        Method::Kb => {
            let [tension, continuity, bias] = options.tcb;
            if !options.tcb.iter().all(|x| x.is_finite()) {
                bail!("--tension, --continuity and --bias must be finite numbers");
            }
            Curve64::<J>::kochanek_bartels(frames, KochanekBartels { tension, continuity, bias }, ends)
        }
    };
    curve.map(Box::new).map_err(|e| trajectory_error(e, k))
}

fn sample_n<const J: usize>(k: &Keyframes, options: &Options) -> Result<Sampled> {
    let frames: Vec<Keyframe<f64, J>> = k
        .times
        .iter()
        .zip(&k.positions)
        .map(|(&time, p)| Keyframe { time, position: SVector::from_column_slice(p) })
        .collect();
    let mut curve = build::<J>(k, options, &frames)?;
    let mut retiming = None;
    if let Some(spec) = &options.limits {
        let unbounded = |sign: f64| vec![sign * 1e12];
        let limits = JointLimits::new(
            vector::<J>(spec.lower.as_ref().unwrap_or(&unbounded(-1.0)), "lo")?,
            vector::<J>(spec.upper.as_ref().unwrap_or(&unbounded(1.0)), "hi")?,
            vector::<J>(&spec.velocity, "v")?,
            vector::<J>(&spec.acceleration, "a")?,
        )
        .map_err(|e| match e {
            LimitError::InvalidLimits { joint } => anyhow!(
                "--limits: joint {} has unusable limits (need finite values, lo <= hi, v > 0, a > 0)",
                joint + 1
            ),
            e => anyhow!("--limits: {e}"),
        })?;
        if let Err(violation) = limits.check(curve.as_ref()) {
            let cubic = curve.interpolation() == Interpolation::Hermite && curve.arriving() == curve.leaving();
            if !cubic {
                bail!(
                    "the {} trajectory breaks --limits (joint {}: {:?} limit at t = {}) and only a C1 cubic \
                     (not linear, not kb with --continuity) can be time-scaled",
                    options.method.name(),
                    violation.joint + 1,
                    violation.limit,
                    violation.time
                );
            }
            let retimed =
                time_scale::<f64, J, MAX_KEYFRAMES>(&frames, curve.leaving(), &limits).map_err(|e| match e {
                    LimitError::KeyframeOutOfRange { keyframe, joint, value } => explain(
                        format_args!("q{} = {value} is outside the --limits position range", joint + 1),
                        Some(keyframe),
                        k,
                    ),
                    LimitError::Trajectory(e) => trajectory_error(e, k),
                    e => anyhow!("--limits: {e}"),
                })?;
            let old_duration = curve.end() - curve.start();
            *curve = retimed.curve().map_err(|e| trajectory_error(e, k))?;
            retiming = Some(Retiming {
                old_duration,
                new_duration: curve.end() - curve.start(),
                max_stretch: retimed.stretch.iter().copied().fold(1.0, f64::max),
                range_clamped: retimed.range_clamped(),
            });
        }
    }
    let rows = sample_times(curve.start(), curve.end(), options.rate)?
        .into_iter()
        .map(|t| {
            let s = sample_inside(&curve, t);
            Row {
                t,
                q: s.position.iter().copied().collect(),
                v: s.velocity.iter().copied().collect(),
                a: s.acceleration.iter().copied().collect(),
            }
        })
        .collect();
    Ok(Sampled {
        method: options.method,
        joints: J,
        keyframe_times: curve.times().to_vec(),
        keyframe_positions: curve.positions().iter().map(|p| p.iter().copied().collect()).collect(),
        rows,
        retiming,
    })
}

/// `curve.sample(t)`, except at the first and last keyframe, where the curve's own sample is the
/// hold outside it (zero velocity and acceleration): there the first or last segment's one-sided
/// values are given, so the rows show the velocity a Hermite curve starts and ends with.
fn sample_inside<const J: usize>(curve: &Curve64<J>, t: f64) -> kinematics::trajectory::Sample<f64, J> {
    let n = curve.times().len();
    let segment = if n < 2 {
        return curve.sample(t);
    } else if t <= curve.start() {
        0
    } else if t >= curve.end() {
        n - 2
    } else {
        return curve.sample(t);
    };
    let s = curve.segment(segment);
    match curve.interpolation() {
        Interpolation::Hermite => s.sample(t),
        _ => {
            let mut out = curve.sample(t);
            if curve.interpolation() == Interpolation::Linear {
                out.velocity = (s.p1 - s.p0) / (s.t1 - s.t0);
            }
            out
        }
    }
}

/// Writes `t,q1..qN,v1..vN,a1..aN` and one line per sample.
pub fn write_csv(out: &mut dyn Write, s: &Sampled) -> Result<()> {
    let mut header = vec!["t".to_string()];
    for prefix in ["q", "v", "a"] {
        header.extend((1..=s.joints).map(|j| format!("{prefix}{j}")));
    }
    let mut text = header.join(",");
    text.push('\n');
    for row in &s.rows {
        text.push_str(&row.t.to_string());
        for x in row.q.iter().chain(&row.v).chain(&row.a) {
            text.push(',');
            text.push_str(&x.to_string());
        }
        text.push('\n');
    }
    out.write_all(text.as_bytes())?;
    Ok(())
}

/// The JSON form: method, joints, keyframes and the samples as `{t, q, v, a}` objects.
pub fn to_json(s: &Sampled) -> Value {
    let samples: Vec<Value> = s.rows.iter().map(|r| json!({"t": r.t, "q": r.q, "v": r.v, "a": r.a})).collect();
    let keyframes: Vec<Value> =
        s.keyframe_times.iter().zip(&s.keyframe_positions).map(|(t, q)| json!({"t": t, "q": q})).collect();
    json!({
        "method": s.method.name(),
        "joints": s.joints,
        "duration": s.keyframe_times.last().unwrap_or(&0.0) - s.keyframe_times.first().unwrap_or(&0.0),
        "time_scaled": s.retiming.is_some(),
        "keyframes": keyframes,
        "samples": samples,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A keyframe row reads back as the values written, bit for bit: ±π (a continuous joint's
    /// limits), which six decimals round past (3.141593 > π); a limit the firmware holds as f32;
    /// a value with more digits than any rounding keeps.
    #[test]
    fn a_keyframe_row_reads_back_exactly_even_at_a_limit() {
        let pi = core::f64::consts::PI;
        assert!(format!("{pi:.6}").parse::<f64>().unwrap() > pi, "the case rounding gets wrong");
        let rows = [
            [-pi, pi, f64::from(1.919_862_2_f32), 0.1 + 0.2, 1e-9, -0.0],
            [pi, -pi, f64::from(-1.745_329_3_f32), -2.0 / 3.0, 12.5, 100.0],
        ];
        let mut text = String::from("t,q1,q2,q3,q4,q5,q6\n");
        for (k, row) in rows.iter().enumerate() {
            push_keyframe_row(&mut text, 0.01 * k as f64, row.iter().copied());
        }
        let back = parse_keyframes(&text).unwrap();
        for (read, written) in back.positions.iter().zip(&rows) {
            assert_eq!(read.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), written.map(f64::to_bits), "{text}");
        }
        assert_eq!(back.times, [0.0, 0.01]);
    }

    #[test]
    fn parses_and_names_lines() {
        let k = parse_keyframes("t,q1,q2\n# c\n0,1,2\n\n1,3,4\n").unwrap();
        assert_eq!(k.joints, 2);
        assert_eq!(k.lines, vec![3, 5]);
        assert!(k.velocities.is_none());
        let k = parse_keyframes("t,q1,v1\r\n0,1,0\r\n1,2,0\r\n").unwrap();
        assert_eq!(k.velocities.unwrap(), vec![vec![0.0], vec![0.0]]);
        let e = parse_keyframes("t,q1\n0,1\n1\n").unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("1 fields"), "{e}");
        let e = parse_keyframes("t,q1\n0,1\n0,2\n").unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("not later"), "{e}");
        let e = parse_keyframes("t,q1\n0,1\n1,nan\n").unwrap_err().to_string();
        assert!(e.contains("line 3, column q1"), "{e}");
        assert!(parse_keyframes("t,q2\n0,1\n1,1\n").is_err());
        assert!(parse_keyframes("t,q1,v2\n0,1,1\n1,1,1\n").is_err());
    }

    #[test]
    fn sample_times_include_both_ends() {
        assert_eq!(sample_times(0.0, 1.0, 4.0).unwrap(), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(sample_times(0.0, 0.3, 10.0).unwrap().len(), 4);
        assert_eq!(sample_times(0.0, 1.05, 10.0).unwrap().last(), Some(&1.05));
    }

    #[test]
    fn limits_syntax() {
        let l = parse_limits("v=1.5,a=4:5,lo=-1").unwrap();
        assert_eq!(l.velocity, vec![1.5]);
        assert_eq!(l.acceleration, vec![4.0, 5.0]);
        assert_eq!(l.lower, Some(vec![-1.0]));
        assert!(parse_limits("v=1").is_err());
        assert!(parse_limits("v=1,a=2,x=3").is_err());
    }
}
