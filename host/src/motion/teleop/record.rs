//! A teleoperation session written as a joint keyframe file, `t,q1,...,qN[,gripper]`, the format
//! `armctl play` and `armctl trajectory sample` read ([`crate::motion::trajectory`]): the keyframes
//! exactly as they were sent, at their playback times, so a replay moves the follower the same way.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::motion::trajectory::push_keyframe_row;

/// Writes the rows of one session.
pub struct Recorder {
    path: PathBuf,
    out: BufWriter<File>,
    gripper: bool,
    last_gripper: f64,
}

impl Recorder {
    /// Creates `path` with the header for `joints` joints (and the gripper column).
    pub fn create(path: &Path, joints: usize, gripper: bool) -> Result<Self> {
        let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let mut out = BufWriter::new(file);
        let mut header = vec!["t".to_string()];
        header.extend((1..=joints).map(|j| format!("q{j}")));
        if gripper {
            header.push("gripper".into());
        }
        writeln!(out, "{}", header.join(",")).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Self { path: path.to_path_buf(), out, gripper, last_gripper: 50.0 })
    }

    /// One keyframe; a row without a gripper value repeats the last one. The values are written
    /// in full, as `retarget` writes them ([`push_keyframe_row`]): each reads back as the `f64`
    /// that was sent, so one the stream left at a joint limit is not rounded past it.
    pub fn row(&mut self, time: f64, q: &[f64], gripper: Option<f64>) -> Result<()> {
        let mut text = String::new();
        let gripper = if self.gripper {
            self.last_gripper = gripper.unwrap_or(self.last_gripper);
            Some(self.last_gripper)
        } else {
            None
        };
        push_keyframe_row(&mut text, time, q.iter().copied().chain(gripper));
        self.out.write_all(text.as_bytes()).with_context(|| format!("cannot write {}", self.path.display()))
    }

    /// Flushes the file.
    pub fn finish(mut self) -> Result<PathBuf> {
        self.out.flush().with_context(|| format!("cannot write {}", self.path.display()))?;
        Ok(self.path)
    }
}
