//! The MPS2 AN386 board support shared by the firmware binary (`main.rs`) and the instruction-count
//! benchmark (`bin/opcount.rs`): the UARTs, the SysTick time base, defmt logging over semihosting,
//! stack painting, the main loop's longest pass, and the reset note with the watchdog. `unsafe`
//! lives only in this crate, each block with a SAFETY line.
#![no_std]

pub mod clock;
pub mod irq;
pub mod log;
pub mod loop_pass;
pub mod reset;
pub mod stack;
pub mod uart;

/// Stops the core (a start-up that stopped, or a panic in a build with debug assertions); the
/// watchdog, running since `main`'s first line and no longer fed, then resets the board.
pub fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
