//! How long a board's independent watchdog waits, chosen from the worst case of the clock that
//! drives it rather than from its nominal rate.
//!
//! The STM32F411's IWDG counts on the LSI, an RC oscillator DS10314 (Table 40, LSI oscillator
//! characteristics) gives as 17 to 47 kHz, 32 kHz typical. A timeout written for 32 kHz is
//! therefore anywhere from 0.68 to 1.88 times itself on a given chip. What matters for the arm:
//!
//! - the **shortest** real timeout (the LSI at 47 kHz) must be well above the longest pass of the
//!   main loop, or a board that is merely busy (a host flooding the link while every servo is
//!   silent) resets itself, and the torque goes off, in a loop;
//! - the **longest** (17 kHz) is how long a hung chip can leave the servos holding their last goal
//!   with nothing running them.
//!
//! [`Iwdg::covering`] picks the shortest setting whose shortest real timeout covers a given time,
//! at compile time; the board passes it twice [`WORST_PASS_US`], the longest loop pass measured
//! (see that constant for how), so that the margin is a factor of two on the worst chip.
//!
//! The IWDG's arithmetic (RM0383 §17.3, IWDG_PR and IWDG_RLR): the LSI is divided by
//! `4 << PR` (PR 0 to 6: 4 to 256), and the counter runs down from RLR (0 to 4095) and resets the
//! chip one count past zero, so a timeout is `(4 << PR) * (RLR + 1)` LSI periods.

/// The LSI's slowest rate (DS10314, Table 40).
pub const LSI_MIN_HZ: u32 = 17_000;
/// The LSI's fastest rate (DS10314, Table 40).
pub const LSI_MAX_HZ: u32 = 47_000;
/// The LSI's typical rate, which the HAL's timeouts assume.
pub const LSI_TYPICAL_HZ: u32 = 32_000;

/// The longest pass of the main loop on an STM32F411 at 84 MHz, in microseconds: a host flooding
/// the link with status requests (the most work a pass takes from the ring: 512 bytes of 7-byte
/// requests, each answered by a full status) while every servo on the bus is silent (the tick
/// waits out every reply).
///
/// Measured on the MPS2 under QEMU and scaled to 84 MHz: `cargo run --release -p armctl
/// --features board-tools -- bench loop-pass` (docs/firmware.md, "The watchdog's margin"), which
/// fails where a measurement exceeds this figure. Twelve runs gave 124.2 ms (123.6 to 124.7):
/// 9 ms of instructions at one a cycle, 31.4 ms of reply timeouts, 82.5 ms sending 74 statuses to
/// the host and 1 ms of instruction packets to the servos. Rounded up to the next 5 ms past what the
/// measurement leaves out (the few requests of a full pass that QEMU's pty did not deliver in
/// time, 0.5 ms; a status that reports a last move, 116 bytes instead of 112, 3 ms): 130 ms.
pub const WORST_PASS_US: u32 = 130_000;

/// An IWDG setting: the prescaler register's value and the reload value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Iwdg {
    /// IWDG_PR: the LSI is divided by `4 << pr` (0 to 6).
    pub pr: u8,
    /// IWDG_RLR: the count the watchdog restarts from at every feed (0 to 4095).
    pub rlr: u16,
}

impl Iwdg {
    /// The largest prescaler register value (a divider of 256).
    const PR_MAX: u8 = 6;
    /// The largest reload value.
    const RLR_MAX: u32 = 0xFFF;

    /// LSI periods from a feed to the reset.
    pub const fn lsi_periods(&self) -> u64 {
        (4u64 << self.pr) * (self.rlr as u64 + 1)
    }

    /// The timeout in microseconds with the LSI at `lsi_hz`.
    pub const fn timeout_us(&self, lsi_hz: u32) -> u64 {
        self.lsi_periods() * 1_000_000 / lsi_hz as u64
    }

    /// The shortest real timeout (the LSI at its fastest).
    pub const fn shortest_us(&self) -> u64 {
        self.timeout_us(LSI_MAX_HZ)
    }

    /// The longest real timeout (the LSI at its slowest), rounded up.
    pub const fn longest_us(&self) -> u64 {
        (self.lsi_periods() * 1_000_000).div_ceil(LSI_MIN_HZ as u64)
    }

    /// The shortest setting whose shortest real timeout is at least `us` microseconds: the
    /// smallest prescaler that reaches it, with the smallest reload; `None` beyond the IWDG's
    /// reach (about 22 s at 47 kHz).
    pub const fn covering(us: u64) -> Option<Iwdg> {
        // LSI periods needed at the fastest LSI, rounded up.
        let periods = (us * LSI_MAX_HZ as u64).div_ceil(1_000_000);
        let mut pr = 0;
        while pr <= Self::PR_MAX {
            let divider = 4u64 << pr;
            let reload = periods.div_ceil(divider);
            if reload >= 1 && reload - 1 <= Self::RLR_MAX as u64 {
                return Some(Iwdg { pr, rlr: (reload - 1) as u16 });
            }
            if reload == 0 {
                return Some(Iwdg { pr, rlr: 0 });
            }
            pr += 1;
        }
        None
    }
}

/// The F411's setting: its shortest real timeout is twice [`WORST_PASS_US`].
pub const STM32F411: Iwdg = match Iwdg::covering(2 * WORST_PASS_US as u64) {
    Some(setting) => setting,
    None => panic!("the watchdog cannot wait that long"),
};

#[cfg(test)]
mod tests {
    use super::*;

    /// RM0383's Table 80 (min/max timeout at 32 kHz): a divider of 4 gives 0.125 ms at a reload
    /// of 0 and 512 ms at 0xFFF; a divider of 256 (PR 6), 8 ms and 32,768 ms.
    #[test]
    fn timeouts_match_the_reference_manual() {
        assert_eq!(Iwdg { pr: 0, rlr: 0 }.timeout_us(LSI_TYPICAL_HZ), 125);
        assert_eq!(Iwdg { pr: 0, rlr: 0xFFF }.timeout_us(LSI_TYPICAL_HZ), 512_000);
        assert_eq!(Iwdg { pr: 6, rlr: 0 }.timeout_us(LSI_TYPICAL_HZ), 8_000);
        assert_eq!(Iwdg { pr: 6, rlr: 0xFFF }.timeout_us(LSI_TYPICAL_HZ), 32_768_000);
    }

    /// The chosen setting covers the time asked for on the fastest LSI, and the next smaller
    /// reload (or prescaler) would not: it is the shortest that does.
    #[test]
    fn covering_is_the_shortest_setting_that_covers() {
        for us in [1u64, 125, 1_000, 99_999, 150_000, 260_000, 1_000_000, 5_000_000, 20_000_000] {
            let s = Iwdg::covering(us).unwrap();
            assert!(s.shortest_us() >= us, "{us}: {s:?} gives {}", s.shortest_us());
            assert!(s.pr <= 6 && s.rlr <= 0xFFF);
            if s.rlr > 0 {
                let shorter = Iwdg { rlr: s.rlr - 1, ..s };
                assert!(shorter.shortest_us() < us, "{us}: {shorter:?} covers too");
            }
            if s.pr > 0 {
                let finer = Iwdg { pr: s.pr - 1, rlr: 0xFFF };
                assert!(finer.shortest_us() < us, "{us}: the smaller prescaler reaches it");
            }
        }
        assert_eq!(Iwdg::covering(23_000_000), None);
    }

    /// The F411's setting keeps its margin on the worst chip, and says how long a hung chip may
    /// hold the arm on the slowest one.
    #[test]
    fn the_f411_setting_covers_twice_the_worst_pass() {
        assert!(STM32F411.shortest_us() >= 2 * u64::from(WORST_PASS_US));
        assert!(STM32F411.longest_us() < 1_000_000, "a hung chip holds the arm {} us", STM32F411.longest_us());
        // The longest is the shortest times 47/17.
        let ratio = STM32F411.longest_us() as f64 / STM32F411.shortest_us() as f64;
        assert!((ratio - 47.0 / 17.0).abs() < 1e-3, "{ratio}");
    }
}
