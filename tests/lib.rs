//! Helpers for the workspace-level tests: run `armctl` in process, exactly as the binary does.

use serde_json::Value;

/// Runs `armctl` with `args`; returns the exit code, stdout and stderr.
pub fn armctl(args: &[&str]) -> (i32, String, String) {
    let mut out = Vec::new();
    let mut err = Vec::new();
    let argv = std::iter::once("armctl").chain(args.iter().copied());
    let code = armctl::cli::main(argv, &mut out, &mut err);
    (code, String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap())
}

/// Runs `armctl` and parses its stdout as one JSON value; panics with stderr if it failed.
pub fn armctl_json(args: &[&str]) -> Value {
    let (code, out, err) = armctl(args);
    assert_eq!(code, 0, "armctl {args:?} failed: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("armctl {args:?} printed invalid JSON ({e}): {out}"))
}

/// The numbers of a JSON array.
pub fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}
