//! The error byte of a status packet (e-manual, Protocol 2.0, "Status Packet" / "Error"): bit 7 is
//! the alert bit (the servo has a hardware error; read its Hardware Error Status, address 70 on the
//! X series), bits 0-6 the error number of the instruction just processed.

use crate::bus::protocol::ErrorText;

/// A decoded status error byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StatusError {
    byte: u8,
}

/// The e-manual's names of error numbers 1 to 7.
const NAMES: [&str; 7] = [
    "result fail",
    "instruction error",
    "CRC error",
    "data range error",
    "data length error",
    "data limit error",
    "access error",
];

/// "unknown error N" for every number, built at compile time so that [`StatusError::describe`]
/// can return a `&'static str` without allocating.
const UNKNOWN_LEN: usize = 17;
static UNKNOWN: [[u8; UNKNOWN_LEN]; 128] = unknown_texts();

const fn unknown_texts() -> [[u8; UNKNOWN_LEN]; 128] {
    let prefix = b"unknown error ";
    let mut texts = [[b' '; UNKNOWN_LEN]; 128];
    let mut n = 0;
    while n < 128 {
        let mut i = 0;
        while i < prefix.len() {
            texts[n][i] = prefix[i];
            i += 1;
        }
        // n < 128: at most three digits; unused trailing bytes are trimmed by `unknown_text`.
        let digits = [(n / 100) as u8, (n / 10 % 10) as u8, (n % 10) as u8];
        let mut at = prefix.len();
        let mut d = if n >= 100 {
            0
        } else if n >= 10 {
            1
        } else {
            2
        };
        while d < 3 {
            texts[n][at] = b'0' + digits[d];
            at += 1;
            d += 1;
        }
        n += 1;
    }
    texts
}

fn unknown_text(number: u8) -> &'static str {
    let text = UNKNOWN.get(usize::from(number)).map_or(&[][..], |t| &t[..]);
    core::str::from_utf8(text).map_or("unknown error", str::trim_end)
}

impl StatusError {
    /// The alert bit.
    pub const ALERT: u8 = 0x80;

    /// Decodes a raw error byte.
    pub fn from_byte(byte: u8) -> Self {
        Self { byte }
    }

    /// The raw byte.
    pub fn byte(&self) -> u8 {
        self.byte
    }

    /// The alert bit: the servo reports a hardware error (overload, overheating, voltage...) in
    /// its Hardware Error Status; the instruction itself may still have succeeded.
    pub fn alert(&self) -> bool {
        self.byte & Self::ALERT != 0
    }

    /// The error number (bits 0-6): 0 when the instruction was processed, 1 result fail,
    /// 2 instruction error, 3 CRC error, 4 data range, 5 data length, 6 data limit, 7 access error.
    pub fn number(&self) -> u8 {
        self.byte & !Self::ALERT
    }

    /// Whether the byte is 0: no error and no alert.
    pub fn is_ok(&self) -> bool {
        self.byte == 0
    }

    /// A one-line description, or `None` when the byte is 0.
    pub fn describe(&self) -> Option<ErrorText> {
        if self.is_ok() {
            return None;
        }
        let number = self.number();
        let what = match number {
            0 => "instruction processed",
            n => NAMES.get(usize::from(n) - 1).copied().unwrap_or_else(|| unknown_text(n)),
        };
        Some(ErrorText { what, alert: self.alert() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn describes_every_number() {
        assert_eq!(StatusError::from_byte(0).describe(), None);
        assert_eq!(StatusError::from_byte(3).describe(), Some(ErrorText { what: "CRC error", alert: false }));
        assert_eq!(StatusError::from_byte(0x87).describe(), Some(ErrorText { what: "access error", alert: true }));
        assert_eq!(StatusError::from_byte(8).describe().map(|t| t.what), Some("unknown error 8"));
        assert_eq!(StatusError::from_byte(42).describe().map(|t| t.what), Some("unknown error 42"));
        assert_eq!(StatusError::from_byte(0xFF).describe().map(|t| t.what), Some("unknown error 127"));
        assert_eq!(StatusError::from_byte(0x80).describe().map(|t| t.alert), Some(true));
    }
}
