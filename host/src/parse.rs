//! Parsing of the numbers people type on the command line.

use anyhow::{bail, Result};

/// Parses a comma-separated list of finite numbers (`"0.1,-2,3e-1"`; empty string for none).
/// `what` names the option in the error, which quotes the offending item.
pub fn numbers(text: &str, what: &str) -> Result<Vec<f64>> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    text.split(',')
        .enumerate()
        .map(|(i, item)| {
            let item = item.trim();
            match item.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                Ok(_) => bail!("{what}: value {} ({item:?}) is not a finite number", i + 1),
                Err(_) => bail!("{what}: value {} ({item:?}) is not a number", i + 1),
            }
        })
        .collect()
}

/// Parses exactly `K` comma-separated finite numbers.
pub fn fixed<const K: usize>(text: &str, what: &str) -> Result<[f64; K]> {
    let v = numbers(text, what)?;
    match <[f64; K]>::try_from(v.as_slice()) {
        Ok(a) => Ok(a),
        Err(_) => bail!("{what}: expected {K} comma-separated numbers, got {}", v.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_lists_and_rejects_bad_items() {
        assert_eq!(numbers("1, -2.5,3e-1", "q").unwrap(), vec![1.0, -2.5, 0.3]);
        assert_eq!(numbers("", "q").unwrap(), Vec::<f64>::new());
        let e = numbers("1,x,3", "--q").unwrap_err().to_string();
        assert!(e.contains("--q") && e.contains("value 2") && e.contains("\"x\""), "{e}");
        let e = numbers("1,NaN", "--q").unwrap_err().to_string();
        assert!(e.contains("not a finite number"), "{e}");
        assert!(numbers("1,,2", "q").is_err());
        assert_eq!(fixed::<3>("1,2,3", "t").unwrap(), [1.0, 2.0, 3.0]);
        let e = fixed::<3>("1,2", "--target").unwrap_err().to_string();
        assert!(e.contains("expected 3") && e.contains("got 2"), "{e}");
    }
}
