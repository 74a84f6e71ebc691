//! Why the board was reset, and the watchdog that resets it when the firmware stops: started as
//! the first thing `main` does, so that a start-up that stops, a panic (in a build with debug
//! assertions: the release build has none) and a fault end in its reset as a stopped control loop
//! does, and the servos' torque then goes off.
//!
//! The MPS2 has no reset-cause register (neither its SCC nor QEMU's model of it holds one), so the
//! firmware leaves a note ([`firmware::board::reset::Note`]) in the 16 bytes above the stack that
//! `memory.x` keeps out of every section: RAM keeps it through a reset (QEMU reloads only the ELF's
//! segments) and a new QEMU, like a power-on, starts with none. Start-up reads it and writes
//! "running"; the watchdog's warning writes "watchdog", the fault handler "fault", each just
//! before the reset that follows. So a reset finds "running" when it came from outside (QEMU's
//! `system_reset`, a debugger), "watchdog" or "fault" when the firmware stopped, and nothing after
//! a power-on.
//!
//! The watchdog is the CMSDK APB watchdog at 0x40008000 (ARM DDI 0479C, §4.7; QEMU models it on
//! the mps2 machines, clocked at the 25 MHz system clock, its interrupt wired to the NMI): it
//! counts down from WDOGLOAD; at zero it raises its interrupt and counts again, and at zero with
//! the interrupt still raised it resets the system (RESEN). Writing WDOGINTCLR clears the
//! interrupt and reloads the count: that is the loop's feed.

use core::ptr::{addr_of_mut, read_volatile, write_volatile};

use firmware::board::reset::{Note, ResetCause};

use crate::clock::SYSCLK_HZ;

extern "C" {
    /// The note's two words (memory.x).
    static mut _reset_note: [u32; 2];
}

/// The watchdog's registers (DDI 0479C, table 4-13).
const WDOGLOAD: *mut u32 = 0x4000_8000 as *mut u32;
const WDOGCONTROL: *mut u32 = 0x4000_8008 as *mut u32;
const WDOGINTCLR: *mut u32 = 0x4000_800C as *mut u32;
/// WDOGCONTROL: INTEN (count, and raise the interrupt at zero) and RESEN (reset at the next zero).
const INTEN_RESEN: u32 = 0b11;

/// The time from the last feed to the watchdog's warning (the NMI); its reset comes as long again
/// later. Ten control periods. Start-up, which it covers too (from `main`'s first line to the
/// control loop), takes 0.24 ms of it under QEMU: it sends nothing on the bus.
pub const WATCHDOG_MS: u32 = 100;

fn note_words() -> *mut [u32; 2] {
    // Only the symbol's address is taken (safe since Rust 1.82); memory.x puts it in RAM, aligned.
    addr_of_mut!(_reset_note)
}

/// The note left before this reset (`None`: a power-on), the cause it tells, and "running" noted
/// from now on.
pub fn take_cause() -> ResetCause {
    // SAFETY: the note's words are RAM no section uses (memory.x); only this core touches them.
    let note = Note::read(unsafe { read_volatile(note_words()) });
    note_that(Note::Running);
    Note::flags(note).cause()
}

/// Leaves `note` for the next start-up. A fault noted is kept: the watchdog's warning that
/// follows it does not overwrite it.
pub fn note_that(note: Note) {
    // SAFETY: as in `take_cause`.
    unsafe {
        if note == Note::Watchdog && Note::read(read_volatile(note_words())) == Some(Note::Fault) {
            return;
        }
        write_volatile(note_words(), note.words());
    }
}

/// Starts the watchdog, or restarts its count if it runs.
pub fn start_watchdog() {
    // SAFETY: the watchdog's own registers; nothing else on the board writes them.
    unsafe {
        write_volatile(WDOGLOAD, SYSCLK_HZ / 1000 * WATCHDOG_MS);
        write_volatile(WDOGCONTROL, INTEN_RESEN);
    }
}

/// Whether the watchdog counts.
pub fn watchdog_runs() -> bool {
    // SAFETY: a read of the watchdog's control register.
    unsafe { read_volatile(WDOGCONTROL) & INTEN_RESEN == INTEN_RESEN }
}

/// Feeds the watchdog: its interrupt cleared, its count back at WDOGLOAD.
pub fn feed() {
    // SAFETY: any write to WDOGINTCLR does only that.
    unsafe { write_volatile(WDOGINTCLR, 1) }
}
