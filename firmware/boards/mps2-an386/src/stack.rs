//! Stack painting: the stack's unused part is filled with a pattern at start-up, and the deepest
//! word no longer holding it is the worst stack depth reached so far. This measures the depth the
//! firmware really reached under QEMU (every code path the test drove), where a static call-graph
//! bound would need to see through trait objects and LLVM's inlining.

use core::ptr::{addr_of, read_volatile, write_volatile};

/// The pattern (an unlikely value for data or addresses).
const PAINT: u32 = 0xC0DE_57AC;
/// How much of the stack is painted and watched: deeper use than this reads as this.
pub const WATCHED_BYTES: usize = 32 * 1024;
/// Words left unpainted just below the painting function's own frame.
const MARGIN_BYTES: usize = 256;

extern "C" {
    /// The initial stack pointer (top of RAM), from cortex-m-rt's linker script.
    static _stack_start: u32;
    /// The lowest address the stack may reach (end of static RAM), from cortex-m-rt.
    static _stack_end: u32;
}

fn top() -> usize {
    // Only the symbols' addresses are taken (safe since Rust 1.82); they are never read.
    addr_of!(_stack_start) as usize
}

fn watched_bottom() -> usize {
    let end = addr_of!(_stack_end) as usize;
    top().saturating_sub(WATCHED_BYTES).max(end)
}

/// Paints the watched stack below the caller's frame. Call first thing in `main`.
#[inline(never)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    let mut word = watched_bottom();
    while word + 4 <= sp.saturating_sub(MARGIN_BYTES) {
        // SAFETY: `word` lies between the end of static RAM and below this function's frame (less a
        // margin), word-aligned: stack memory no live frame uses yet.
        unsafe { write_volatile(word as *mut u32, PAINT) };
        word += 4;
    }
}

/// The deepest stack use so far, in bytes below the initial stack pointer.
pub fn high_water() -> usize {
    let mut word = watched_bottom();
    let top = top();
    // SAFETY: `word` stays within the stack region (watched bottom up to the top), word-aligned.
    while word < top && unsafe { read_volatile(word as *const u32) } == PAINT {
        word += 4;
    }
    top - word
}
