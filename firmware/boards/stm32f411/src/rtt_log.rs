//! The defmt global logger over RTT, without a panic path.
//!
//! It follows defmt-rtt 1.3.1 (MIT OR Apache-2.0) in everything the host sees: the `_SEGGER_RTT`
//! control block with one up channel named `defmt` over a 1 KiB buffer, starting in non-blocking
//! mode, blocking only once the host (probe-rs) switches the channel to blocking; rzcobs frames
//! from `defmt::Encoder`. It differs where defmt-rtt panics, which put two panic call sites in
//! this firmware:
//!
//! - a frame started while another is being written ("taken reentrantly"): `acquire` masks
//!   interrupts, so only a fault or NMI handler that logs can get here. The nested frame is
//!   dropped (its writes ignored), and the frame it interrupted goes on;
//! - `release` without `acquire`, which defmt's contract rules out, is ignored.
//!
//! Cursor arithmetic is reduced modulo the buffer size and done with wrapping operations, so a
//! host writing nonsense into the read cursor cannot make it panic either.

use core::cell::UnsafeCell;
use core::ptr;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// The RTT buffer's size (defmt-rtt's default).
const BUF_SIZE: usize = 1024;
/// The mode bits of the channel's flags.
const MODE_MASK: u32 = 0b11;
/// The host reads as fast as the target writes: wait for room instead of dropping.
const MODE_BLOCK_IF_FULL: u32 = 2;
/// Drop what does not fit (the mode at start, with no host attached).
const MODE_NON_BLOCKING_TRIM: u32 = 1;

/// An RTT up channel, laid out as the host expects.
#[repr(C)]
struct Channel {
    name: *const u8,
    buffer: *mut u8,
    size: u32,
    /// Written by the target.
    write: AtomicU32,
    /// Written by the host.
    read: AtomicU32,
    flags: AtomicU32,
}

/// The RTT control block the host finds by its id.
#[repr(C)]
struct Header {
    id: [u8; 16],
    max_up_channels: u32,
    max_down_channels: u32,
    up_channel: Channel,
}

// SAFETY: the raw pointers point at statics that live for ever; the target writes the buffer and
// the write cursor only inside the logger's critical section, and the other fields are atomics
// shared with the host as the RTT protocol lays down.
unsafe impl Sync for Header {}

struct Buffer(UnsafeCell<[u8; BUF_SIZE]>);

// SAFETY: written only inside the logger's critical section (and read by the host over the debug
// port, which the RTT cursors order).
unsafe impl Sync for Buffer {}

#[link_section = ".uninit.defmt-rtt.BUFFER"]
static BUFFER: Buffer = Buffer(UnsafeCell::new([0; BUF_SIZE]));

/// In RAM, so that the whole control block can be read from RAM.
#[link_section = ".data.defmt-rtt.NAME"]
static NAME: [u8; 6] = *b"defmt\0";

#[no_mangle]
static _SEGGER_RTT: Header = Header {
    id: *b"SEGGER RTT\0\0\0\0\0\0",
    max_up_channels: 1,
    max_down_channels: 0,
    up_channel: Channel {
        name: NAME.as_ptr(),
        buffer: BUFFER.0.get() as *mut u8,
        size: BUF_SIZE as u32,
        write: AtomicU32::new(0),
        read: AtomicU32::new(0),
        flags: AtomicU32::new(MODE_NON_BLOCKING_TRIM),
    },
};

/// Free bytes between the write and the read cursor (one slot tells full from empty).
fn available(read: usize, write: usize) -> usize {
    let (read, write) = (read % BUF_SIZE, write % BUF_SIZE);
    if read > write {
        read.wrapping_sub(write).wrapping_sub(1)
    } else {
        BUF_SIZE.wrapping_sub(write).wrapping_sub(1).wrapping_add(read)
    }
}

impl Channel {
    fn host_is_connected(&self) -> bool {
        // probe-rs switches the channel to blocking when it attaches.
        self.flags.load(Ordering::Relaxed) & MODE_MASK == MODE_BLOCK_IF_FULL
    }

    fn write_all(&self, mut bytes: &[u8]) {
        let blocking = self.host_is_connected();
        while !bytes.is_empty() {
            let write = self.write.load(Ordering::Acquire) as usize % BUF_SIZE;
            let room = if blocking {
                available(self.read.load(Ordering::Relaxed) as usize, write)
            } else {
                // Without a host, overwrite: at most one wrap per call.
                BUF_SIZE
            };
            let len = bytes.len().min(room);
            let (now, rest) = bytes.split_at(len);
            self.copy_wrapping(now, write);
            self.write.store((write.wrapping_add(len) % BUF_SIZE) as u32, Ordering::Release);
            bytes = rest;
        }
    }

    /// Copies `bytes` (at most `BUF_SIZE`) into the buffer from `cursor` on, wrapping at its end.
    fn copy_wrapping(&self, bytes: &[u8], cursor: usize) {
        let cursor = cursor % BUF_SIZE;
        let len = bytes.len().min(BUF_SIZE);
        let first = len.min(BUF_SIZE - cursor);
        // SAFETY: `cursor < BUF_SIZE` and `first <= BUF_SIZE - cursor`, so the first copy stays in
        // the buffer; the second copies `len - first <= cursor` bytes to its start. Only the
        // logger's critical section writes the buffer.
        unsafe {
            ptr::copy_nonoverlapping(bytes.as_ptr(), self.buffer.add(cursor), first);
            ptr::copy_nonoverlapping(bytes.as_ptr().add(first), self.buffer, len - first);
        }
    }

    fn flush(&self) {
        if !self.host_is_connected() {
            return;
        }
        while self.read.load(Ordering::Relaxed) != self.write.load(Ordering::Relaxed) {}
    }
}

/// The encoder's state, used only inside the critical section that `acquire` opens.
struct Encoder {
    /// A frame is being written.
    taken: AtomicBool,
    /// Frames started while one was being written (dropped), not yet released.
    nested: AtomicU32,
    restore: UnsafeCell<critical_section::RestoreState>,
    encoder: UnsafeCell<defmt::Encoder>,
}

// SAFETY: every field but the atomics is touched only between `acquire` and `release`, with
// interrupts masked, by the one frame that holds `taken`.
unsafe impl Sync for Encoder {}

static ENCODER: Encoder = Encoder {
    taken: AtomicBool::new(false),
    nested: AtomicU32::new(0),
    restore: UnsafeCell::new(critical_section::RestoreState::invalid()),
    encoder: UnsafeCell::new(defmt::Encoder::new()),
};

fn emit(bytes: &[u8]) {
    _SEGGER_RTT.up_channel.write_all(bytes);
}

#[defmt::global_logger]
struct Logger;

// SAFETY: defmt calls acquire, then write and flush, then release, from one context at a time;
// acquire masks interrupts, and a nested frame (from a fault handler) is dropped, not interleaved.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the release below (or at once, for a nested frame).
        let restore = unsafe { critical_section::acquire() };
        if ENCODER.taken.load(Ordering::Relaxed) {
            ENCODER.nested.store(ENCODER.nested.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
            // SAFETY: the nested acquire's own state: interrupts were already masked, and stay so.
            unsafe { critical_section::release(restore) };
            return;
        }
        ENCODER.taken.store(true, Ordering::Relaxed);
        // SAFETY: inside the critical section, and `taken` is ours.
        unsafe {
            ENCODER.restore.get().write(restore);
            (*ENCODER.encoder.get()).start_frame(emit);
        }
    }

    unsafe fn write(bytes: &[u8]) {
        if ENCODER.nested.load(Ordering::Relaxed) == 0 && ENCODER.taken.load(Ordering::Relaxed) {
            // SAFETY: inside the critical section that `acquire` opened.
            unsafe { (*ENCODER.encoder.get()).write(bytes, emit) };
        }
    }

    unsafe fn flush() {
        _SEGGER_RTT.up_channel.flush();
    }

    unsafe fn release() {
        let nested = ENCODER.nested.load(Ordering::Relaxed);
        if nested > 0 {
            ENCODER.nested.store(nested - 1, Ordering::Relaxed);
            return;
        }
        if !ENCODER.taken.load(Ordering::Relaxed) {
            return;
        }
        // SAFETY: inside the critical section that `acquire` opened; released exactly once.
        unsafe {
            (*ENCODER.encoder.get()).end_frame(emit);
            let restore = ENCODER.restore.get().read();
            ENCODER.taken.store(false, Ordering::Relaxed);
            critical_section::release(restore);
        }
    }
}
