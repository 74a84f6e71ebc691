//! A JSON-lines input (a file or standard input) read and parsed on a thread of its own, so that a
//! command's work on one line overlaps the reading and parsing of the next (`ik --batch`).
//!
//! Lines go over in chunks, so that the two threads hand over, and wake each other, once per
//! chunk rather than once per line; a few chunks at most are in flight, so the memory is bounded
//! whatever the input's length. A chunk goes over early when the input has nothing more buffered:
//! a program that writes one line and waits for its answer gets it.

use std::io::{BufRead, BufReader, Read};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::Scope;

use serde::de::DeserializeOwned;

/// Lines per chunk.
const CHUNK: usize = 256;
/// Chunks in flight between the threads (and between the stages after them).
pub const IN_FLIGHT: usize = 4;

/// One non-blank line of the input.
#[derive(Debug)]
pub struct Line<T> {
    /// Its number in the input, from 1 (blank lines count).
    pub number: usize,
    /// What it held.
    pub parsed: Parsed<T>,
}

/// What a line held.
#[derive(Debug)]
pub enum Parsed<T> {
    /// A value.
    Value(T),
    /// Not JSON of the expected shape (or not UTF-8): an error of this line alone.
    Invalid(serde_json::Error),
    /// The input could not be read at this line; nothing follows it.
    Unreadable(std::io::Error),
}

/// Reads `source` on a thread of `scope`; the chunks of lines arrive on the receiver, in order, and
/// it disconnects after the last. Dropping the receiver stops the reader at its next chunk.
pub fn spawn<'scope, T, R>(scope: &'scope Scope<'scope, '_>, source: R) -> Receiver<Vec<Line<T>>>
where
    T: DeserializeOwned + Send + 'scope,
    R: Read + Send + 'scope,
{
    let (chunks, received) = sync_channel(IN_FLIGHT);
    scope.spawn(move || read(source, &chunks));
    received
}

fn read<T: DeserializeOwned, R: Read>(source: R, chunks: &SyncSender<Vec<Line<T>>>) {
    let mut reader = BufReader::with_capacity(1 << 16, source);
    let mut chunk = Vec::with_capacity(CHUNK);
    // Bytes, not a String: serde_json checks the UTF-8 of what it parses, so checking the whole
    // line first would be done twice.
    let mut line = Vec::new();
    for number in 1.. {
        if (chunk.len() == CHUNK || (reader.buffer().is_empty() && !chunk.is_empty()))
            && chunks.send(std::mem::replace(&mut chunk, Vec::with_capacity(CHUNK))).is_err()
        {
            return;
        }
        line.clear();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => break,
            Ok(_) if line.trim_ascii().is_empty() => {}
            Ok(_) => {
                let parsed = match serde_json::from_slice(&line) {
                    Ok(value) => Parsed::Value(value),
                    Err(e) => Parsed::Invalid(e),
                };
                chunk.push(Line { number, parsed });
            }
            Err(e) => {
                chunk.push(Line { number, parsed: Parsed::Unreadable(e) });
                break;
            }
        }
    }
    if !chunk.is_empty() {
        let _ = chunks.send(chunk);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &[u8]) -> Vec<Line<Vec<u32>>> {
        std::thread::scope(|scope| spawn(scope, input).into_iter().flatten().collect())
    }

    #[test]
    fn every_line_once_in_order_blank_lines_counted_but_not_sent() {
        let mut input = String::new();
        for i in 0..1000 {
            input.push_str(&format!("[{i}]\n"));
            if i % 7 == 0 {
                input.push_str("  \n");
            }
        }
        input.push_str("[1000]"); // no newline at the end
        let got = lines(input.as_bytes());
        assert_eq!(got.len(), 1001);
        let mut expected_number = 1;
        for (i, line) in got.iter().enumerate() {
            assert_eq!(line.number, expected_number, "line {i}");
            assert!(matches!(&line.parsed, Parsed::Value(v) if v == &[i as u32]), "{line:?}");
            expected_number += if i % 7 == 0 { 2 } else { 1 };
        }
    }

    #[test]
    fn a_bad_line_is_its_own_error() {
        let got = lines(b"[1]\n[2,\n\xff\xfe\n[3]\n");
        assert_eq!(got.len(), 4);
        assert!(matches!(got[1].parsed, Parsed::Invalid(_)));
        assert!(matches!(got[2].parsed, Parsed::Invalid(_)));
        assert!(matches!(&got[3].parsed, Parsed::Value(v) if v == &[3]));
        assert_eq!(got[3].number, 4);
    }

    /// A source that fails on its second read.
    struct Failing(bool);

    impl Read for Failing {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if std::mem::replace(&mut self.0, true) {
                return Err(std::io::Error::other("disk on fire"));
            }
            let text = b"[1]\n[2]\n[3";
            buf[..text.len()].copy_from_slice(text);
            Ok(text.len())
        }
    }

    #[test]
    fn a_read_error_ends_the_input_after_the_lines_before_it() {
        let got: Vec<Line<Vec<u32>>> =
            std::thread::scope(|scope| spawn(scope, Failing(false)).into_iter().flatten().collect());
        assert_eq!(got.len(), 3, "{got:?}");
        assert!(matches!(&got[1].parsed, Parsed::Value(v) if v == &[2]));
        assert!(matches!(&got[2].parsed, Parsed::Unreadable(e) if e.to_string() == "disk on fire"));
        assert_eq!(got[2].number, 3);
    }
}
