//! Parsing of the numbers people type on the command line and in CSV files.

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

/// Parses servo ids and ranges (`1-6`, `1,3,5`, `1-3,7`) into ids in the order given, without
/// repeats; every id at most `max`. `what` names the option in the error.
pub fn ids(text: &str, max: u8, what: &str) -> Result<Vec<u8>> {
    let mut ids = Vec::new();
    for part in text.split(',').map(str::trim) {
        let number = |s: &str| match s.trim().parse::<u8>() {
            Ok(id) if id <= max => Ok(id),
            _ => Err(anyhow::anyhow!("{what}: `{}` is not an id (0-{max})", s.trim())),
        };
        let (lo, hi) = match part.split_once('-') {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(part)?, number(part)?),
        };
        if lo > hi {
            bail!("{what}: range `{part}` runs backwards");
        }
        for id in lo..=hi {
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
    }
    Ok(ids)
}

/// Parses the fields of a CSV row (line `line` of a file whose header names the columns `names`)
/// as finite numbers; the error names the line and the column.
pub fn csv_row<S: std::fmt::Display>(line: usize, fields: &[&str], names: &[S]) -> Result<Vec<f64>> {
    let mut values = Vec::with_capacity(fields.len());
    for (field, name) in fields.iter().zip(names) {
        let Ok(value) = field.parse::<f64>() else {
            bail!("line {line}, column {name}: {field:?} is not a number");
        };
        if !value.is_finite() {
            bail!("line {line}, column {name}: {field} is not a finite number");
        }
        values.push(value);
    }
    Ok(values)
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
