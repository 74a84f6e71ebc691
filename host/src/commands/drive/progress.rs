//! The progress line of `armctl play` on stderr: a bar redrawn in place when stderr is a terminal,
//! and only the final line otherwise (so logs and pipes get no carriage returns).

use std::io::Write;
use std::time::{Duration, Instant};

/// Redraws at most this often.
const REDRAW: Duration = Duration::from_millis(100);
const WIDTH: usize = 30;

/// Keyframes played of a total, and trajectory seconds.
pub struct Progress {
    total: usize,
    seconds: f64,
    live: bool,
    last: Option<Instant>,
    drawn: bool,
}

impl Progress {
    /// A bar over `total` keyframes spanning `seconds` of trajectory; drawn live if `live`.
    pub fn new(total: usize, seconds: f64, live: bool) -> Self {
        Self { total, seconds, live, last: None, drawn: false }
    }

    /// The line for `played` keyframes at trajectory time `t` (s).
    pub fn line(&self, played: usize, t: f64) -> String {
        let fraction = if self.total == 0 { 1.0 } else { played.min(self.total) as f64 / self.total as f64 };
        let filled = ((fraction * WIDTH as f64).round() as usize).min(WIDTH);
        format!(
            "[{}{}] {played}/{} keyframes, {:.1}/{:.1} s",
            "#".repeat(filled),
            "-".repeat(WIDTH - filled),
            self.total,
            t.clamp(0.0, self.seconds),
            self.seconds
        )
    }

    /// Redraws the bar if live and due.
    pub fn update(&mut self, err: &mut dyn Write, played: usize, t: f64) {
        if !self.live || self.last.is_some_and(|l| l.elapsed() < REDRAW) {
            return;
        }
        self.last = Some(Instant::now());
        self.drawn = true;
        let _ = write!(err, "\r{}", self.line(played, t));
        let _ = err.flush();
    }

    /// Ends the bar: the final state on a line of its own (replacing the live bar).
    pub fn finish(&mut self, err: &mut dyn Write, played: usize, t: f64) {
        let start = if self.drawn { "\r" } else { "" };
        let _ = writeln!(err, "{start}{}", self.line(played, t));
        self.drawn = false;
    }

    /// Ends a live bar without a final line (before an error or a Ctrl-C message).
    pub fn clear(&mut self, err: &mut dyn Write) {
        if self.drawn {
            let _ = writeln!(err);
            self.drawn = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_the_fraction_played() {
        let p = Progress::new(40, 10.0, false);
        assert_eq!(p.line(20, 5.04), format!("[{}{}] 20/40 keyframes, 5.0/10.0 s", "#".repeat(15), "-".repeat(15)));
        assert!(p.line(40, 12.0).ends_with("40/40 keyframes, 10.0/10.0 s"));
        let mut out = Vec::new();
        let mut quiet = Progress::new(2, 1.0, false);
        quiet.update(&mut out, 1, 0.5);
        assert!(out.is_empty());
        quiet.finish(&mut out, 2, 1.0);
        assert_eq!(String::from_utf8(out).unwrap().matches('\n').count(), 1);
    }
}
