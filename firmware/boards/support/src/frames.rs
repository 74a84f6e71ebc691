//! defmt's log frames, held one at a time over any byte sink: what a global logger does between
//! defmt's `acquire` and `release`, apart from where the bytes go.
//!
//! `acquire` enters a critical section (interrupts masked on these single-core boards) and
//! starts a frame; `write` encodes into it (rzcobs, `defmt::Encoder`); `release` ends it and
//! leaves the section. A frame started while another is being written, which only a fault or NMI
//! handler that logs can do, is dropped (its writes ignored) and the frame it interrupted goes
//! on: defmt-rtt and defmt-semihosting panic there instead, and the boards must reach no panic.
//! A `release` without `acquire`, which defmt's contract rules out, is ignored.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Where a logger's encoded bytes go.
pub trait Sink {
    /// Sends encoded bytes; a sink that cannot loses them (logging never fails or retries).
    fn write(&mut self, bytes: &[u8]);

    /// Waits until what was written has left, where the transport can tell.
    fn flush(&mut self) {}
}

/// One frame at a time over the sink `S`; a board's global logger forwards defmt's four calls to
/// a static of it.
pub struct Frames<S> {
    /// A frame is being written.
    taken: AtomicBool,
    /// Frames started while one was being written (dropped), not yet released.
    nested: AtomicU32,
    restore: UnsafeCell<critical_section::RestoreState>,
    encoder: UnsafeCell<defmt::Encoder>,
    sink: UnsafeCell<S>,
}

// SAFETY: every field but the atomics is touched only between `acquire` and `release`, inside the
// critical section, by the one frame that holds `taken`; the sink moves into the static once.
unsafe impl<S: Send> Sync for Frames<S> {}

impl<S: Sink> Frames<S> {
    /// No frame yet.
    pub const fn new(sink: S) -> Self {
        Self {
            taken: AtomicBool::new(false),
            nested: AtomicU32::new(0),
            restore: UnsafeCell::new(critical_section::RestoreState::invalid()),
            encoder: UnsafeCell::new(defmt::Encoder::new()),
            sink: UnsafeCell::new(sink),
        }
    }

    /// defmt's `acquire`: masks interrupts and starts a frame (or, inside another, counts a dropped
    /// one).
    pub fn acquire(&self) {
        // SAFETY: paired with the release in `release` (or at once, for a nested frame).
        let restore = unsafe { critical_section::acquire() };
        if self.taken.load(Ordering::Relaxed) {
            self.nested.store(self.nested.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
            // SAFETY: the nested acquire's own state: interrupts were already masked, and stay so.
            unsafe { critical_section::release(restore) };
            return;
        }
        self.taken.store(true, Ordering::Relaxed);
        // SAFETY: inside the critical section, and `taken` is ours: sole access.
        unsafe {
            self.restore.get().write(restore);
            let sink = &mut *self.sink.get();
            (*self.encoder.get()).start_frame(|bytes| sink.write(bytes));
        }
    }

    /// defmt's `write`: encodes `bytes` into the frame (nothing, for a dropped one).
    ///
    /// # Safety
    /// Only between [`Self::acquire`] and [`Self::release`], as defmt calls it.
    pub unsafe fn write(&self, bytes: &[u8]) {
        if self.nested.load(Ordering::Relaxed) == 0 && self.taken.load(Ordering::Relaxed) {
            // SAFETY: inside the critical section that `acquire` opened, the frame ours.
            unsafe {
                let sink = &mut *self.sink.get();
                (*self.encoder.get()).write(bytes, |out| sink.write(out));
            }
        }
    }

    /// defmt's `flush`: the sink's (nothing, for a dropped frame).
    ///
    /// # Safety
    /// Only between [`Self::acquire`] and [`Self::release`], as defmt calls it.
    pub unsafe fn flush(&self) {
        if self.nested.load(Ordering::Relaxed) == 0 && self.taken.load(Ordering::Relaxed) {
            // SAFETY: inside the critical section that `acquire` opened, the frame ours.
            unsafe { (*self.sink.get()).flush() };
        }
    }

    /// defmt's `release`: ends the frame and unmasks interrupts as they were (or ends a dropped
    /// frame).
    ///
    /// # Safety
    /// Once for each [`Self::acquire`], as defmt calls it.
    pub unsafe fn release(&self) {
        let nested = self.nested.load(Ordering::Relaxed);
        if nested > 0 {
            self.nested.store(nested - 1, Ordering::Relaxed);
            return;
        }
        if !self.taken.load(Ordering::Relaxed) {
            return;
        }
        // SAFETY: inside the critical section that `acquire` opened; left exactly once.
        unsafe {
            let sink = &mut *self.sink.get();
            (*self.encoder.get()).end_frame(|bytes| sink.write(bytes));
            let restore = self.restore.get().read();
            self.taken.store(false, Ordering::Relaxed);
            critical_section::release(restore);
        }
    }
}

/// Declares a board's defmt global logger over a static [`Frames`]:
/// `board_support::global_logger!(FRAMES);`.
#[macro_export]
macro_rules! global_logger {
    ($frames:path) => {
        #[defmt::global_logger]
        struct Logger;

        // SAFETY: defmt calls acquire, then write and flush, then release, from one context at a
        // time; `Frames` masks interrupts from acquire to release and drops a nested frame
        // instead of interleaving it.
        unsafe impl defmt::Logger for Logger {
            fn acquire() {
                $frames.acquire()
            }

            unsafe fn flush() {
                // SAFETY: defmt calls it between acquire and release.
                unsafe { $frames.flush() }
            }

            unsafe fn release() {
                // SAFETY: defmt calls it once for each acquire.
                unsafe { $frames.release() }
            }

            unsafe fn write(bytes: &[u8]) {
                // SAFETY: defmt calls it between acquire and release.
                unsafe { $frames.write(bytes) }
            }
        }
    };
}
