//! Faults on demand, deterministic for a seed: the same seed and the same traffic give the same
//! lost and corrupted bytes, so a failing test replays exactly.

use std::collections::BTreeMap;

use kinematics::SplitMix64;

/// What goes wrong on the simulated bus. `Send` and `Clone`, so a pty server's thread can build
/// its bus from it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Faults {
    /// Seed of the random faults.
    pub seed: u64,
    /// Servos that carry out instructions but never answer.
    pub silent: Vec<u8>,
    /// Probability that a reply gets one bit flipped in its body (so its checksum fails).
    pub corrupt_rate: f64,
    /// Probability per byte, both directions, that the byte is lost.
    pub drop_rate: f64,
    /// Probability per byte, both directions, that one of its bits flips.
    pub bit_flip_rate: f64,
}

/// The faults of a running bus: the configuration, its random stream and the one-off requests.
#[derive(Clone, Debug)]
pub struct FaultState {
    config: Faults,
    rng: SplitMix64,
    /// Replies still to corrupt, by id.
    corrupt_next: BTreeMap<u8, u32>,
    stats: FaultStats,
}

/// What the faults did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultStats {
    /// Bytes lost (both directions).
    pub dropped: u64,
    /// Bits flipped (corrupted replies and random flips).
    pub flipped: u64,
    /// Replies suppressed because their servo is silent.
    pub silenced: u64,
}

impl FaultState {
    /// The state of a fresh run of `config`.
    pub fn new(config: Faults) -> Self {
        Self { rng: SplitMix64::new(config.seed), config, corrupt_next: BTreeMap::new(), stats: FaultStats::default() }
    }

    /// The configuration.
    pub fn config(&self) -> &Faults {
        &self.config
    }

    /// The configuration, to change faults mid-run.
    pub fn config_mut(&mut self) -> &mut Faults {
        &mut self.config
    }

    /// Counters so far.
    pub fn stats(&self) -> FaultStats {
        self.stats
    }

    /// Whether `id` never answers.
    pub fn is_silent(&mut self, id: u8) -> bool {
        let silent = self.config.silent.contains(&id);
        if silent {
            self.stats.silenced += 1;
        }
        silent
    }

    /// Corrupts the next `n` replies of `id`.
    pub fn corrupt_next(&mut self, id: u8, n: u32) {
        *self.corrupt_next.entry(id).or_default() += n;
    }

    fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.rng.unit_f64() < p
    }

    /// Applies reply faults to a reply of `id` whose body (after the length field, where a flip
    /// makes the checksum fail instead of breaking the framing) starts at `body`.
    pub fn on_reply(&mut self, id: u8, bytes: &mut [u8], body: usize) {
        let pending = self.corrupt_next.get_mut(&id).filter(|n| **n > 0);
        let forced = pending.map(|n| *n -= 1).is_some();
        if (forced || self.chance(self.config.corrupt_rate)) && bytes.len() > body {
            let at = body + (self.rng.next_u64() % (bytes.len() - body) as u64) as usize;
            bytes[at] ^= 1 << (self.rng.next_u64() % 8);
            self.stats.flipped += 1;
        }
    }

    /// Per-byte faults on bytes on the wire: `Some(byte)` (perhaps with a bit flipped), or `None`
    /// when it is lost.
    pub fn on_byte(&mut self, byte: u8) -> Option<u8> {
        if self.chance(self.config.drop_rate) {
            self.stats.dropped += 1;
            return None;
        }
        if self.chance(self.config.bit_flip_rate) {
            self.stats.flipped += 1;
            return Some(byte ^ (1 << (self.rng.next_u64() % 8)));
        }
        Some(byte)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_flips_change_one_bit_of_a_byte_at_their_rate() {
        let mut every = FaultState::new(Faults { bit_flip_rate: 1.0, ..Faults::default() });
        for b in 0..=255u8 {
            let flipped = every.on_byte(b).expect("flipped, not lost");
            assert_eq!((flipped ^ b).count_ones(), 1, "{b:#04x} -> {flipped:#04x}");
        }
        assert_eq!(every.stats().flipped, 256);
        let mut some = FaultState::new(Faults { seed: 7, bit_flip_rate: 0.1, ..Faults::default() });
        let flipped = (0..10_000).filter(|_| some.on_byte(0x55) != Some(0x55)).count();
        assert!((800..1200).contains(&flipped), "{flipped} of 10000 at 10 %");
        let mut none = FaultState::new(Faults::default());
        assert!((0..1000).all(|_| none.on_byte(0xA5) == Some(0xA5)));
    }
}
