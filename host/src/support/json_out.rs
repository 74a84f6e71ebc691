//! One line of JSON on a command's output: every command's `--json` report and the first lines
//! that name a pty or a URL.

use std::io::Write;

use anyhow::Result;

/// Writes `value` as one line of JSON. The line is serialised in memory and written at once: into
/// `dyn Write` directly, every key, comma and number is a call of its own (a third of the
/// per-line cost of `ik --batch` went there). The buffer is kept from line to line.
pub fn print_json(out: &mut dyn Write, value: &impl serde::Serialize) -> Result<()> {
    thread_local! {
        static LINE: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    LINE.with_borrow_mut(|line| {
        line.clear();
        serde_json::to_writer(&mut *line, value)?;
        line.push(b'\n');
        out.write_all(line)?;
        Ok(())
    })
}
