//! The firmware for an STM32F411 "Black Pill" (STM32F411CEU6, 25 MHz crystal): USART1 is the host
//! link to a USB-serial adapter (its bytes kept by the receive interrupt, `link_rx.rs`), USART2
//! the servo bus (Feetech, 1 Mbps, one wire), TIM2 the time base; the built-in SO-101 arm.
//! Everything else is the firmware core: the application ([`firmware::app::Firmware`]) and the
//! main loop every board runs ([`firmware::board::MainLoop`]); this file only wires the hardware
//! to them.
//!
//! | pin  | use                                                                   |
//! |------|-----------------------------------------------------------------------|
//! | PA9  | USART1 TX, host link (to the adapter's RX)                            |
//! | PA10 | USART1 RX, host link (from the adapter's TX)                          |
//! | PA2  | USART2 TX/RX, servo bus data, open drain, external pull-up to 3.3 V   |
//! | PA1  | bus direction, high while transmitting (for a tri-state buffer board) |
#![no_std]
#![no_main]

mod clock;
mod half_duplex;
mod link_rx;
mod rtt_log;
mod serial;

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_rt::entry;
use firmware::app::{Board, Firmware};
use firmware::board::MainLoop;
use firmware::bus::master::{BusConfig, Master};
use firmware::bus::table::STS3215;
use firmware::controller::Config;
use stm32f4xx_hal::gpio::{Output, PinState, PA1};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc;
use stm32f4xx_hal::serial::{config::Config as SerialConfig, Event as SerialEvent, Serial};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use clock::Tim2Clock;
use half_duplex::HalfDuplex;
use serial::Link;

/// Host link and servo bus baud rate.
const BAUD: u32 = 1_000_000;

/// The bus direction output: high while the board transmits on the bus.
///
/// Driving it costs one pin and makes both wirings work with the same binary: the servo data line
/// straight on PA2 (PA1 left unconnected; the USART's single-wire mode needs no direction signal),
/// or a 74HC126 + 74HC04 tri-state buffer adapter whose transmit buffer PA1 enables (and, inverted,
/// whose receive buffer it disables). The master raises it before the first byte and lowers it after
/// `flush`, which waits for transmission complete.
type DirectionPin = PA1<Output>;
/// Any arm of 1 to [`firmware::board::JOINTS`] joints (the built-in SO-101 has 5).
type App = Firmware<{ firmware::board::JOINTS }, 32>;
type BusMaster = Master<HalfDuplex, DirectionPin, Tim2Clock>;

/// The firmware state, in static RAM so that the stack holds only call frames. The constructor's
/// result is written straight into it (as on the MPS2 board): built on the stack and moved, it
/// would need its size in stack again at start-up.
static mut APP: MaybeUninit<App> = MaybeUninit::uninit();
static mut MASTER: MaybeUninit<BusMaster> = MaybeUninit::uninit();
static STARTED: AtomicBool = AtomicBool::new(false);

/// How long the main loop may go without feeding the independent watchdog before it resets the
/// chip: fifteen control periods, far above a tick's few milliseconds.
const WATCHDOG_MS: u32 = 150;

/// Logs why start-up stopped (the host then sees no handshake) and gives up.
fn refused<T>(what: &str) -> Option<T> {
    defmt::error!("start-up stopped: {=str}", what);
    None
}

#[entry]
fn main() -> ! {
    let Some((app, master, link, watchdog)) = start() else { halt() };
    run(app, master, link, watchdog)
}

/// Brings up the clocks, the two USARTs, the timer, the watchdog and the firmware core; `None`
/// (with an error line in the log) if anything is refused or this ran before (the statics are
/// written once). Never inlined, so that its frame is gone before the control loop starts.
#[inline(never)]
fn start() -> Option<(&'static mut App, &'static mut BusMaster, Link, IndependentWatchdog)> {
    if STARTED.swap(true, Ordering::Relaxed) {
        return refused("started twice");
    }
    let Some(dp) = pac::Peripherals::take() else { return refused("peripherals taken") };
    // Was the last reset the watchdog's? Read before anything else, then clear the flags
    // (RCC_CSR: IWDGRSTF is `wdgrstf` in the device crate; RMVF clears them all).
    let watchdog_reset = dp.RCC.csr().read().wdgrstf().bit_is_set();
    dp.RCC.csr().modify(|_, w| w.rmvf().set_bit());
    // 25 MHz crystal, PLL to 84 MHz: the most the F411 runs at in power scale 2 (RM0383 §5.1.3,
    // PWR_CR.VOS), where it comes out of reset and where the HAL leaves it (96 MHz would need
    // scale 1 set before the PLL starts). USART1 (APB2, 84 MHz: USARTDIV 5.25) and USART2 (APB1,
    // 42 MHz: USARTDIV 2.625) both divide exactly to 1 Mbps, and TIM2's 84 MHz to microseconds.
    let mut rcc = dp.RCC.freeze(rcc::Config::hse(25.MHz()).sysclk(84.MHz()));
    let Some(clock) = Tim2Clock::start(dp.TIM2, &mut rcc) else { return refused("TIM2 clock") };
    let gpioa = dp.GPIOA.split(&mut rcc);

    let link_config = SerialConfig::default().baudrate(BAUD.bps());
    // The pull-up holds RX idle (high) with the adapter unplugged, instead of reading noise as bytes.
    let rx_pin = gpioa.pa10.internal_pull_up(true);
    let Ok(mut usart1) = Serial::new(dp.USART1, (gpioa.pa9, rx_pin), link_config, &mut rcc) else {
        return refused("USART1 (host link)");
    };
    usart1.listen(SerialEvent::RxNotEmpty);
    link_rx::enable();
    let link = Link::new(usart1);

    // The internal pull-up (~40 kΩ) only keeps the line defined with nothing attached; the bus
    // needs the external ~1 kΩ one for 1 Mbps edges.
    let _bus_pin = gpioa.pa2.into_alternate_open_drain::<7>().internal_pull_up(true);
    let direction: DirectionPin = gpioa.pa1.into_push_pull_output_in_state(PinState::Low);
    let Some(bus_port) = HalfDuplex::new(dp.USART2, BAUD, &mut rcc) else { return refused("USART2 (servo bus)") };
    // The receiver is off while the board transmits (see half_duplex.rs): no echo to skip.
    let bus = BusConfig { echo: false, ..BusConfig::new(STS3215.protocol, BAUD) };

    defmt::info!(
        "stm32f411: link USART1 {=u32} bps (PA9/PA10), bus USART2 {=u32} bps one-wire PA2, sysclk {=u32} Hz",
        BAUD,
        BAUD,
        rcc.clocks.sysclk().raw()
    );

    let board = Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: bus_port.max_baud() };
    // SAFETY: STARTED guarantees this runs once, so these are the only references to the statics.
    let (app_slot, master_slot) = unsafe { (&mut *addr_of_mut!(APP), &mut *addr_of_mut!(MASTER)) };
    let app = App::blank_in(app_slot, board);
    if app.start(Some(&firmware::builtin::SO101)).is_err() {
        return refused("built-in arm");
    }
    let master = master_slot.write(BusMaster::new(bus_port, direction, clock, bus));
    if watchdog_reset {
        // The loop hung and the watchdog reset the chip: the servos may still hold torque toward
        // the goal they had. Limp, until the host switches torque on again.
        defmt::error!("reset by the watchdog: the servos' torque goes off");
        app.torque_off(clock.now());
    }
    // Started last, once start-up's own long steps are done; paused while a debugger halts the core.
    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.stop_on_debug(&dp.DBGMCU, true);
    watchdog.start(WATCHDOG_MS.millis());
    Some((app, master, link, watchdog))
}

/// The control loop ([`MainLoop`]): host bytes as the receive interrupt kept them, a tick on the
/// fixed schedule, the watchdog fed on every pass. It does not sleep: TIM2 counts time but raises
/// no interrupt to wake it.
#[inline(never)]
fn run(app: &'static mut App, master: &'static mut BusMaster, mut link: Link, mut watchdog: IndependentWatchdog) -> ! {
    MainLoop::new(app, master, &link_rx::LINK_RX).run(&mut link, |_, _| watchdog.feed())
}

/// Stops the core for good (a broken start-up; the host sees no handshake).
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// The release firmware has no panic site (`armctl footprint` checks); should one come back, the
/// panic says so in the log before the core stops, and the watchdog then resets the chip.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic");
    halt()
}
