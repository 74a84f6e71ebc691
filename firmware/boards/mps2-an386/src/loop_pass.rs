//! The main loop's longest pass, for `armctl bench loop-pass`: the time from one wake-up (the
//! return from the idle closure, after any `wfi`) to the next call of the idle closure, which is
//! one [`firmware::board::MainLoop::poll`] and all the STM32F411's loop does between two feeds of
//! its watchdog; and the bytes the pass sent on the host link (its replies) and on the servo bus
//! (which reads its tick made), which tell what kind of pass it was and how long the F411's
//! UARTs would take to send them. The board logs a pass when it is the longest so far of its kind:
//! one that answered the host, or one that did not (a tick alone). Both are kept apart because the
//! bench wants the flood's pass, and at `-icount shift=0` the bus master's reply timeouts come out
//! a few per cent short by how fast the host runs the emulated core: a tick that waited its
//! timeouts out in full could outlast every flood pass, which then were never logged.

use core::cell::Cell;

/// The pass under way and the longest so far of each kind.
#[derive(Debug, Default)]
pub struct Longest {
    started_us: u64,
    /// The longest pass that sent the host nothing, and the longest that answered it.
    longest_us: [u32; 2],
}

impl Longest {
    /// A pass starts (the core woke, or had no reason to sleep) at `now_us`.
    pub fn start(&mut self, now_us: u64) {
        self.started_us = now_us;
    }

    /// The pass ends at `now_us`, having `answered` the host or not: its length in microseconds if
    /// it is the longest so far of its kind.
    pub fn end(&mut self, now_us: u64, answered: bool) -> Option<u32> {
        let us = u32::try_from(now_us.saturating_sub(self.started_us)).unwrap_or(u32::MAX);
        let longest = &mut self.longest_us[usize::from(answered)];
        (us > *longest).then(|| {
            *longest = us;
            us
        })
    }
}

/// A writer that counts the bytes written through it into a cell the caller keeps.
pub struct Counted<'a, W> {
    inner: W,
    bytes: &'a Cell<u32>,
}

impl<'a, W> Counted<'a, W> {
    /// `inner`, counting into `bytes`.
    pub fn new(inner: W, bytes: &'a Cell<u32>) -> Self {
        Self { inner, bytes }
    }
}

impl<W: embedded_io::ErrorType> embedded_io::ErrorType for Counted<'_, W> {
    type Error = W::Error;
}

impl<W: embedded_io::Write> embedded_io::Write for Counted<'_, W> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        let n = self.inner.write(buf)?;
        self.bytes.set(self.bytes.get().wrapping_add(n as u32));
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        self.inner.flush()
    }
}
