//! The firmware for the MPS2 AN386 board under QEMU: UART0 is the host link, UART1 the servo bus
//! (Feetech, 1 Mbps), SysTick the time base; the built-in SO-101 arm. Everything else is the
//! firmware core ([`firmware::app::Firmware`]): this file only wires the hardware to it.
#![no_std]
#![no_main]

mod clock;
mod uart;

use cortex_m_rt::entry;
use embedded_io::{Read, ReadReady};
use firmware::app::{Board, Firmware};
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::STS3215;
use firmware::controller::Config;

use clock::SysTickClock;
use uart::Uart;

/// Host link and servo bus baud rate.
const BAUD: u32 = 1_000_000;

#[entry]
fn main() -> ! {
    let Some(core) = cortex_m::Peripherals::take() else { halt() };
    clock::start(core.SYST);
    let clock = SysTickClock;
    let mut link = Uart::new(uart::UART0, clock::SYSCLK_HZ, BAUD);
    let bus_port = Uart::new(uart::UART1, clock::SYSCLK_HZ, BAUD);
    let bus = BusConfig::new(STS3215.protocol, BAUD);
    let board = Board { bus, model: &STS3215, control: Config::default() };
    let Ok(setup) = firmware::builtin::setup() else { halt() };
    let Ok(mut app) = Firmware::<{ firmware::builtin::JOINTS }, 32>::new(board, Some(setup)) else { halt() };
    let mut master: Master<Uart, NoDirectionPin, SysTickClock> = Master::new(bus_port, NoDirectionPin, clock, bus);
    let period = u64::from(app.period_us());
    let mut next_tick = clock.now();
    let mut received = [0u8; 64];
    loop {
        while link.read_ready().unwrap_or(false) {
            let n = link.read(&mut received).unwrap_or(0);
            let _ = app.receive(&received[..n], clock.now(), &mut link);
        }
        let now = clock.now();
        if now >= next_tick {
            let _ = app.tick(&mut master, now, &mut link);
            // The next slot on the fixed schedule; missed slots are skipped, not made up.
            next_tick = (next_tick + period).max(clock.now());
        }
    }
}

/// Stops the core for good (a broken start-up; the host sees no handshake).
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    halt()
}
