//! The Biovision hierarchy (BVH) file: a skeleton (`HIERARCHY`) and its motion (`MOTION`).
//!
//! Format as in `research.cs.wisc.edu/graphics/Courses/cs-838-1999/Jeff/BVH.html`: joints with an
//! `OFFSET` from their parent and `CHANNELS` in any order and count, `End Site`s, then `Frames:`,
//! `Frame Time:` and one line of numbers per frame, one per channel in hierarchy order. Spaces,
//! tabs and CRLF line endings are all whitespace here. Errors are `line L: ...`; the caller puts
//! the file name in front. A frame count that disagrees with the data lines is not an error (real
//! files are often one line off): the lines present are used and [`Bvh::warnings`] says so.

use anyhow::{anyhow, bail, Result};
use kinematics::nalgebra::Vector3;

/// One channel of a joint, as named in `CHANNELS`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Translation along an axis (0 = x, 1 = y, 2 = z), file units.
    Position(usize),
    /// Rotation about an axis (0 = x, 1 = y, 2 = z), degrees.
    Rotation(usize),
}

impl Channel {
    fn parse(name: &str) -> Option<Self> {
        let axis = match name.as_bytes().first()? {
            b'X' | b'x' => 0,
            b'Y' | b'y' => 1,
            b'Z' | b'z' => 2,
            _ => return None,
        };
        match name[1..].to_ascii_lowercase().as_str() {
            "position" => Some(Channel::Position(axis)),
            "rotation" => Some(Channel::Rotation(axis)),
            _ => None,
        }
    }
}

/// One joint of the hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name as in the file.
    pub name: String,
    /// Index of the parent joint; `None` for the root.
    pub parent: Option<usize>,
    /// Offset from the parent joint, in the parent's frame (file units).
    pub offset: Vector3<f64>,
    /// Channels in file order.
    pub channels: Vec<Channel>,
    /// Index of this joint's first value in a frame's line.
    pub first_value: usize,
    /// The `End Site` offset, for a joint that ends a branch.
    pub end_site: Option<Vector3<f64>>,
    /// The file line of the joint's name, for messages.
    pub line: usize,
}

/// A parsed file.
#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    /// Joints in file order: every parent comes before its children.
    pub joints: Vec<Joint>,
    /// Seconds per frame.
    pub frame_time: f64,
    /// One row of channel values per frame.
    pub frames: Vec<Vec<f64>>,
    /// Values per frame (the channels of every joint).
    pub channel_count: usize,
    /// What the caller should print: a frame count that disagrees with the data, for one.
    pub warnings: Vec<String>,
}

impl Bvh {
    /// The index of the joint called `name`.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// The values of joint `joint` in frame `frame`.
    pub fn values(&self, frame: usize, joint: usize) -> &[f64] {
        let j = &self.joints[joint];
        &self.frames[frame][j.first_value..j.first_value + j.channels.len()]
    }

    /// Seconds the motion lasts (first frame at 0).
    pub fn duration(&self) -> f64 {
        self.frames.len().saturating_sub(1) as f64 * self.frame_time
    }
}

/// Reads and parses a file; errors start with its name (`FILE: line L: ...`).
pub fn read(path: &std::path::Path) -> Result<Bvh> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("cannot read BVH file {}: {e}", path.display()))?;
    parse(&text).map_err(|e| anyhow!("{}: {e:#}", path.display()))
}

/// Words with the line they are on (1-based).
struct Words<'a> {
    words: Vec<(usize, &'a str)>,
    at: usize,
    /// The `MOTION` line, where the hierarchy's words end.
    motion_line: usize,
}

impl<'a> Words<'a> {
    fn next(&mut self, wanted: &str) -> Result<(usize, &'a str)> {
        let word = self.words.get(self.at).copied();
        self.at += 1;
        word.ok_or_else(|| {
            anyhow!("line {}: MOTION comes where {wanted} was expected (a `}}` missing?)", self.motion_line)
        })
    }

    fn peek(&self) -> Option<(usize, &'a str)> {
        self.words.get(self.at).copied()
    }

    fn expect(&mut self, keyword: &str) -> Result<usize> {
        let (line, word) = self.next(&format!("`{keyword}`"))?;
        if word != keyword {
            bail!("line {line}: expected `{keyword}`, found `{word}`");
        }
        Ok(line)
    }

    fn number(&mut self, what: &str) -> Result<f64> {
        let (line, word) = self.next(what)?;
        number(line, word, what)
    }
}

fn number(line: usize, word: &str, what: &str) -> Result<f64> {
    match word.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => bail!("line {line}: {what}: `{word}` is not a finite number"),
    }
}

/// Parses BVH text; errors are `line L: ...`.
pub fn parse(text: &str) -> Result<Bvh> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let lines: Vec<&str> = text.split('\n').collect();
    // The hierarchy is read as words; the motion's data as lines, since a line is a frame.
    let motion_line = lines
        .iter()
        .position(|l| l.split_whitespace().next() == Some("MOTION"))
        .ok_or_else(|| anyhow!("line {}: no MOTION section", lines.len()))?;
    let words = lines[..motion_line]
        .iter()
        .enumerate()
        .flat_map(|(i, l)| l.split_whitespace().map(move |w| (i + 1, w)))
        .collect();
    let mut w = Words { words, at: 0, motion_line: motion_line + 1 };
    w.expect("HIERARCHY")?;
    let mut joints = Vec::new();
    let line = w.expect("ROOT")?;
    joint(&mut w, &mut joints, None, line)?;
    if let Some((line, word)) = w.peek() {
        bail!("line {line}: `{word}` after the root joint's closing brace (one ROOT per file)");
    }
    let channel_count = joints.iter().map(|j: &Joint| j.channels.len()).sum();
    let (frame_time, frames, warnings) = motion(&lines, motion_line, channel_count)?;
    Ok(Bvh { joints, frame_time, frames, channel_count, warnings })
}

/// A joint after its `ROOT` or `JOINT` keyword (on line `line`), with everything inside its braces.
fn joint(w: &mut Words, joints: &mut Vec<Joint>, parent: Option<usize>, line: usize) -> Result<()> {
    let (_, name) = w.next("a joint name")?;
    if name == "{" {
        bail!("line {line}: a joint needs a name before its `{{`");
    }
    if joints.iter().any(|j| j.name == name) {
        bail!("line {line}: a second joint named {name}");
    }
    w.expect("{")?;
    let origin = offset(w)?;
    let first_value = joints.iter().map(|j| j.channels.len()).sum();
    let channels = channels(w)?;
    let index = joints.len();
    joints.push(Joint { name: name.to_string(), parent, offset: origin, channels, first_value, end_site: None, line });
    loop {
        let (line, word) = w.next("`JOINT`, `End Site` or `}`")?;
        match word {
            "JOINT" => joint(w, joints, Some(index), line)?,
            "End" => {
                w.expect("Site")?;
                w.expect("{")?;
                let end = offset(w)?;
                let (close, word) = w.next("`}` closing the End Site")?;
                if word != "}" {
                    bail!("line {close}: expected `}}` closing the End Site, found `{word}`");
                }
                joints[index].end_site = Some(end);
            }
            "}" => return Ok(()),
            other => bail!("line {line}: expected `JOINT`, `End Site` or `}}` in joint {name}, found `{other}`"),
        }
    }
}

fn offset(w: &mut Words) -> Result<Vector3<f64>> {
    w.expect("OFFSET")?;
    let x = w.number("OFFSET x")?;
    let y = w.number("OFFSET y")?;
    let z = w.number("OFFSET z")?;
    Ok(Vector3::new(x, y, z))
}

fn channels(w: &mut Words) -> Result<Vec<Channel>> {
    let line = w.expect("CHANNELS")?;
    let (at, count) = w.next("the channel count")?;
    let count: usize =
        count.parse().map_err(|_| anyhow!("line {at}: the channel count `{count}` is not a whole number"))?;
    if count > 6 {
        bail!("line {line}: {count} channels: a joint has at most 6 (3 positions, 3 rotations)");
    }
    let mut out: Vec<Channel> = Vec::with_capacity(count);
    for _ in 0..count {
        let (at, name) = w.next("a channel name")?;
        let channel = Channel::parse(name).ok_or_else(|| {
            anyhow!("line {at}: unknown channel `{name}` (Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation)")
        })?;
        if out.contains(&channel) {
            bail!("line {at}: channel {name} twice");
        }
        out.push(channel);
    }
    Ok(out)
}

/// `Frames:`, `Frame Time:` and the data lines after the `MOTION` line.
fn motion(lines: &[&str], motion_line: usize, channels: usize) -> Result<(f64, Vec<Vec<f64>>, Vec<String>)> {
    let mut rest = lines.iter().enumerate().skip(motion_line + 1).filter(|(_, l)| !l.trim().is_empty());
    let mut header = |label: &str| -> Result<(usize, String)> {
        let (i, l) = rest.next().ok_or_else(|| anyhow!("line {}: the file ends before `{label}`", lines.len()))?;
        let value = l.trim().strip_prefix(label).ok_or_else(|| anyhow!("line {}: expected `{label}`", i + 1))?;
        Ok((i + 1, value.trim().to_string()))
    };
    let (line, count) = header("Frames:")?;
    let declared: usize = count.parse().map_err(|_| anyhow!("line {line}: Frames: `{count}` is not a whole number"))?;
    let (line, time) = header("Frame Time:")?;
    let frame_time = number(line, &time, "Frame Time")?;
    if frame_time <= 0.0 {
        bail!("line {line}: Frame Time {frame_time} s must be positive");
    }
    let mut frames = Vec::with_capacity(declared);
    for (i, l) in rest {
        let values =
            l.split_whitespace().map(|word| number(i + 1, word, "frame value")).collect::<Result<Vec<f64>>>()?;
        if values.len() != channels {
            bail!("line {}: {} values, but the hierarchy has {channels} channels", i + 1, values.len());
        }
        frames.push(values);
    }
    if frames.is_empty() {
        bail!("line {}: no frames after Frame Time", lines.len());
    }
    let mut warnings = Vec::new();
    if frames.len() != declared {
        warnings.push(format!(
            "Frames: says {declared}, but {} frame lines follow: using the {} present",
            frames.len(),
            frames.len()
        ));
    }
    Ok((frame_time, frames, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO: &str = "HIERARCHY\nROOT Hips\n{\n  OFFSET 1 2 3\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n  JOINT Arm\n  {\n    OFFSET -1.5 .25 0\n    CHANNELS 3 Yrotation Xrotation Zrotation\n    End Site\n    {\n      OFFSET 0 -2 0\n    }\n  }\n}\nMOTION\nFrames: 2\nFrame Time: .0083333\n0 1 2 10 20 30 40 50 60\n-1 -2 -3 0 0 0 0 0 .5\n";

    #[test]
    fn reads_joints_offsets_channels_and_frames_exactly() {
        let b = parse(TWO).unwrap();
        assert_eq!(b.joints.len(), 2);
        assert_eq!(b.joints[0].name, "Hips");
        assert_eq!(b.joints[0].parent, None);
        assert_eq!(b.joints[0].offset, Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(
            b.joints[0].channels,
            vec![
                Channel::Position(0),
                Channel::Position(1),
                Channel::Position(2),
                Channel::Rotation(2),
                Channel::Rotation(0),
                Channel::Rotation(1)
            ]
        );
        assert_eq!(b.joints[1].parent, Some(0));
        assert_eq!(b.joints[1].offset, Vector3::new(-1.5, 0.25, 0.0));
        assert_eq!(b.joints[1].channels, vec![Channel::Rotation(1), Channel::Rotation(0), Channel::Rotation(2)]);
        assert_eq!(b.joints[1].first_value, 6);
        assert_eq!(b.joints[1].end_site, Some(Vector3::new(0.0, -2.0, 0.0)));
        assert_eq!(b.joints[1].line, 6);
        assert_eq!(b.frame_time, 0.0083333);
        assert_eq!(b.channel_count, 9);
        assert_eq!(b.frames.len(), 2);
        assert_eq!(b.values(0, 1), &[40.0, 50.0, 60.0]);
        assert_eq!(b.values(1, 1), &[0.0, 0.0, 0.5]);
        assert!(b.warnings.is_empty());
    }

    #[test]
    fn crlf_and_tabs_read_the_same() {
        let crlf = TWO.replace('\n', "\r\n").replace("  ", "\t");
        assert_eq!(parse(&crlf).unwrap(), parse(TWO).unwrap());
    }

    #[test]
    fn a_frame_count_off_by_one_is_a_warning_and_the_lines_present_are_used() {
        let b = parse(&TWO.replace("Frames: 2", "Frames: 3")).unwrap();
        assert_eq!(b.frames.len(), 2);
        assert_eq!(b.warnings, vec!["Frames: says 3, but 2 frame lines follow: using the 2 present".to_string()]);
    }

    #[test]
    fn errors_name_the_line() {
        let e = |text: String| format!("{:#}", parse(&text).unwrap_err());
        assert_eq!(
            e(TWO.replace("Yrotation Xrotation Zrotation", "Yrotation Xrotation Wrotation")),
            "line 9: unknown channel `Wrotation` (Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation)"
        );
        assert_eq!(e(TWO.replace("-1.5 .25", "-1.5 .2.5")), "line 8: OFFSET y: `.2.5` is not a finite number");
        assert_eq!(e(TWO.replace("-1 -2 -3 0", "-1 -2 -3")), "line 20: 8 values, but the hierarchy has 9 channels");
        assert_eq!(e(TWO.replace("60\n", "6x0\n")), "line 19: frame value: `6x0` is not a finite number");
        assert_eq!(
            e(TWO.replace("  }\n}\n", "  }\n")),
            "line 15: MOTION comes where `JOINT`, `End Site` or `}` was expected (a `}` missing?)"
        );
        assert_eq!(e(TWO.replace("Frame Time: .0083333", "Frame Time: 0")), "line 18: Frame Time 0 s must be positive");
    }
}
