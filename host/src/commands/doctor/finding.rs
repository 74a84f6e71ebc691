//! What `armctl doctor` says: findings, each OK, WARN or FAIL with the fix in words, and the
//! report that prints them as lines or as JSON.

use std::io::Write;

use serde::Serialize;

/// How bad a finding is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// Checked, and as it should be.
    Ok,
    /// Works, but costs something or will bite later (a slow reply, a stale goal).
    Warn,
    /// The arm will not run right until it is fixed.
    Fail,
}

impl Level {
    /// `OK`, `WARN`, `FAIL`.
    pub fn tag(self) -> &'static str {
        match self {
            Self::Ok => "OK",
            Self::Warn => "WARN",
            Self::Fail => "FAIL",
        }
    }
}

/// One finding: a check's verdict on one thing, in one line, and what to do about it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// OK, WARN or FAIL.
    pub level: Level,
    /// The check that found it (`ids`, `power`, `line`, ...), stable for scripts.
    pub check: &'static str,
    /// What was found, one line.
    pub message: String,
    /// What to do, in words (none for an OK).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix: Option<String>,
}

impl Finding {
    /// An OK finding.
    pub fn ok(check: &'static str, message: impl Into<String>) -> Self {
        Self { level: Level::Ok, check, message: message.into(), fix: None }
    }

    /// A WARN finding with its fix.
    pub fn warn(check: &'static str, message: impl Into<String>, fix: impl Into<String>) -> Self {
        Self { level: Level::Warn, check, message: message.into(), fix: Some(fix.into()) }
    }

    /// A FAIL finding with its fix.
    pub fn fail(check: &'static str, message: impl Into<String>, fix: impl Into<String>) -> Self {
        Self { level: Level::Fail, check, message: message.into(), fix: Some(fix.into()) }
    }
}

/// How many findings of each level.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Counts {
    /// OK findings.
    pub ok: usize,
    /// WARN findings.
    pub warn: usize,
    /// FAIL findings.
    pub fail: usize,
}

/// Counts `findings` by level.
pub fn counts(findings: &[Finding]) -> Counts {
    let mut c = Counts::default();
    for f in findings {
        match f.level {
            Level::Ok => c.ok += 1,
            Level::Warn => c.warn += 1,
            Level::Fail => c.fail += 1,
        }
    }
    c
}

/// The findings as text: `OK    ids       6 servos answer ...`, the fix indented under it, and a
/// last line with the counts.
pub fn print(findings: &[Finding], out: &mut dyn Write) -> std::io::Result<()> {
    for f in findings {
        writeln!(out, "{:<5} {:<12} {}", f.level.tag(), f.check, f.message)?;
        if let Some(fix) = &f.fix {
            writeln!(out, "{:<18} fix: {fix}", "")?;
        }
    }
    let c = counts(findings);
    writeln!(out, "{} OK, {} WARN, {} FAIL", c.ok, c.warn, c.fail)
}

/// `1-5,7`: ids as ranges.
pub fn id_list(ids: &[u8]) -> String {
    let mut sorted = ids.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut parts = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let start = sorted[i];
        let mut end = start;
        while i + 1 < sorted.len() && sorted[i + 1] == end + 1 {
            i += 1;
            end = sorted[i];
        }
        parts.push(if end > start { format!("{start}-{end}") } else { start.to_string() });
        i += 1;
    }
    parts.join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_print_as_ranges() {
        assert_eq!(id_list(&[3, 1, 2, 5, 7, 6, 9]), "1-3,5-7,9");
        assert_eq!(id_list(&[4]), "4");
        assert_eq!(id_list(&[]), "");
    }

    #[test]
    fn text_puts_the_fix_under_its_finding_and_counts_at_the_end() {
        let findings = [
            Finding::ok("ids", "6 servos answer"),
            Finding::warn("settings", "servo 1: return delay 500 µs", "write 0"),
            Finding::fail("power", "servo 2: 12.0 V", "use the 7.4 V supply"),
        ];
        let mut out = Vec::new();
        print(&findings, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "OK    ids          6 servos answer");
        assert_eq!(lines[1], "WARN  settings     servo 1: return delay 500 µs");
        assert_eq!(lines[2].trim_start(), "fix: write 0");
        assert_eq!(lines.last(), Some(&"1 OK, 1 WARN, 1 FAIL"));
        let json = serde_json::to_value(&findings[0]).unwrap();
        assert_eq!(json, serde_json::json!({"level": "ok", "check": "ids", "message": "6 servos answer"}));
    }
}
