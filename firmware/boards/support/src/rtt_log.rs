//! The defmt global logger over RTT, without a panic path: for a board whose log a debug probe
//! reads (probe-rs).
//!
//! It follows defmt-rtt 1.3.1 (MIT OR Apache-2.0) in everything the host sees: the `_SEGGER_RTT`
//! control block with one up channel named `defmt` over a 1 KiB buffer, starting in non-blocking
//! mode, blocking only once the host (probe-rs) switches the channel to blocking; rzcobs frames
//! from `defmt::Encoder`. It differs where defmt-rtt panics: a frame started inside another is
//! dropped, and a release without acquire ignored ([`crate::frames`]).
//!
//! Cursor arithmetic is reduced modulo the buffer size and done with wrapping operations, so a
//! host writing nonsense into the read cursor cannot make it panic either.

use core::cell::UnsafeCell;
use core::ptr;
use core::sync::atomic::{AtomicU32, Ordering};

use crate::frames::{Frames, Sink};

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

/// The up channel as the frames' sink.
struct Rtt;

impl Sink for Rtt {
    fn write(&mut self, bytes: &[u8]) {
        _SEGGER_RTT.up_channel.write_all(bytes);
    }

    fn flush(&mut self) {
        _SEGGER_RTT.up_channel.flush();
    }
}

static FRAMES: Frames<Rtt> = Frames::new(Rtt);

crate::global_logger!(FRAMES);
