//! The firmware for the MPS2 AN386 board under QEMU: UART0 is the host link (its bytes kept by the
//! receive interrupt, [`irq::LINK_RX`]), UART1 the servo bus (Feetech, 1 Mbps), SysTick the time
//! base; the built-in SO-101 arm. Everything else is the firmware core: the application
//! ([`firmware::app::Firmware`]), its start-up in static memory ([`firmware::board::Slots`]) and
//! the main loop every board runs ([`firmware::board::MainLoop`]); this file only wires the
//! hardware to them.
#![no_std]
#![no_main]

use core::cell::Cell;
use core::sync::atomic::Ordering;

use board_mps2_an386::clock::{self, SysTickClock};
use board_mps2_an386::uart::{self, Uart};
use board_mps2_an386::{halt, irq, loop_pass, reset, stack};
use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::app::{Board, Firmware};
use firmware::board::reset::{Note, ResetCause, TorqueAfterReset};
use firmware::board::{MainLoop, Slots, StartError};
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::STS3215;
use firmware::controller::Config;

/// Host link and servo bus baud rate.
const BAUD: u32 = 1_000_000;
/// The joints the firmware is built for: any arm of 1 to this many (the built-in SO-101 has 5).
const JOINTS: usize = firmware::board::JOINTS;
/// Keyframe queue slots.
const QUEUE: usize = 32;
/// How often the stack's high-water mark is checked and, when it grew, logged.
const STACK_CHECK_US: u64 = 1_000_000;

type App = Firmware<JOINTS, QUEUE>;
type BusMaster = Master<Uart, NoDirectionPin, SysTickClock>;
/// The main loop over the firmware, the bus master and the link's receive ring.
type Loop = MainLoop<'static, JOINTS, QUEUE, { irq::LINK_RX_BYTES }, Uart, NoDirectionPin, SysTickClock>;

/// The firmware state and the bus master, in static RAM (see [`Slots`]).
static SLOTS: Slots<JOINTS, QUEUE, BusMaster> = Slots::new();

#[entry]
fn main() -> ! {
    // The watchdog first, before anything else can stop: from here on every way the firmware can
    // stop (start-up, a panic, a fault, the control loop) ends in its reset, after which start-up
    // takes the servos' torque off. Started at the end of start-up instead, a start-up that
    // stopped would leave the servos holding their last goal for good, with nothing running
    // them. Its 100 ms cover start-up many times over (0.24 ms from here to the control loop
    // under QEMU: nothing is sent on the bus); the loop feeds it from its first pass.
    reset::start_watchdog();
    stack::paint();
    // Why the board was reset decides the servos' torque (firmware::board::reset): logged before
    // anything is set up.
    let cause = reset::take_cause();
    // Interned texts: defmt keeps them in the ELF's table on the host, none in flash.
    let what = match cause {
        ResetCause::PowerOn => defmt::intern!("power-on"),
        ResetCause::BrownOut => defmt::intern!("brown-out"),
        ResetCause::Watchdog => defmt::intern!("the watchdog"),
        ResetCause::Fault => defmt::intern!("a fault (then the watchdog)"),
        ResetCause::LowPower => defmt::intern!("low-power management"),
        ResetCause::Software => defmt::intern!("software (SYSRESETREQ)"),
        ResetCause::Pin => defmt::intern!("the reset pin"),
        ResetCause::Unknown => defmt::intern!("an unknown cause"),
    };
    let torque = match cause.torque() {
        TorqueAfterReset::Off => defmt::intern!("the servos' torque goes off"),
        TorqueAfterReset::Hold => defmt::intern!("servos found torqued are held where they stand"),
    };
    defmt::info!("mps2-an386: reset by {=istr}: {=istr}; starting", what, torque);
    let (main_loop, link) = match start(cause) {
        Ok(started) => started,
        // The host sees no handshake; the watchdog, unfed, resets the board, and the next
        // start-up (torque off) tries again: a start-up that always stops says so every 200 ms.
        Err(why) => {
            defmt::error!("start-up stopped: {=istr}", why);
            halt()
        }
    };
    defmt::info!(
        "static state: firmware {=usize} bytes, bus master {=usize} bytes; start-up stack {=usize} bytes",
        core::mem::size_of::<App>(),
        core::mem::size_of::<BusMaster>(),
        stack::high_water()
    );
    // From here on the high-water mark is the control loop's own (start-up's frames are gone).
    stack::paint();
    run(main_loop, link)
}

/// Brings up the hardware and the firmware core, the servos' torque as `cause` wants it; why not,
/// in a few words, if the built-in arm is refused or this ran before (the statics are written
/// once): interned, so that the words are in the ELF's defmt table and not in flash. Never
/// inlined, so that its frame is gone before the control loop starts (and so that the HIL tests
/// can stop the core at its first instruction).
#[inline(never)]
fn start(cause: ResetCause) -> Result<(Loop, Uart), defmt::Str> {
    let Some(core) = cortex_m::Peripherals::take() else { return Err(defmt::intern!("peripherals taken")) };
    clock::start(core.SYST);
    let mut link = Uart::new(uart::UART0, clock::SYSCLK_HZ, BAUD);
    irq::enable_link_receive(&mut link);
    let bus = BusConfig::new(STS3215.protocol, BAUD);
    let board =
        Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: Uart::max_baud(clock::SYSCLK_HZ) };
    let port = Uart::new(uart::UART1, clock::SYSCLK_HZ, BAUD);
    let main_loop = SLOTS
        .start(board, &firmware::builtin::SO101, cause, &irq::LINK_RX, || {
            BusMaster::new(port, NoDirectionPin, SysTickClock, bus)
        })
        .map_err(|e| match e {
            StartError::Twice => defmt::intern!("started twice"),
            StartError::Arm(_) => defmt::intern!("built-in arm refused"),
        })?;
    defmt::info!(
        "mps2-an386: so101 built in, up to {=usize} joints, {=usize} queue slots, {=u32} us period, link and bus at {=u32} baud",
        JOINTS,
        QUEUE,
        main_loop.firmware().period_us(),
        BAUD
    );
    Ok((main_loop, link))
}

/// The control loop ([`MainLoop`]): host bytes as the receive interrupt kept them, a tick on the
/// fixed schedule, and sleep in between (SysTick wakes the core every millisecond, a host byte at
/// once); once a second, the stack's high-water mark, logged when it grew. Each pass (from a
/// wake-up to the next idle call, the time asleep left out: [`loop_pass`]) is timed, and logged
/// with the bytes it sent the host and the servos when it is the longest so far of its kind,
/// answering the host or not (`armctl bench loop-pass`).
#[inline(never)]
fn run(main_loop: Loop, link: Uart) -> ! {
    let clock = SysTickClock;
    let mut next_stack_check = clock.now() + STACK_CHECK_US;
    let mut stack_logged = 0;
    let sent = Cell::new(0);
    let mut sent_before = 0;
    let mut link = loop_pass::Counted::new(link, &sent);
    let mut pass = loop_pass::Longest::default();
    pass.start(clock.now());
    main_loop.run(&mut link, |next_tick, rx| {
        let now = clock.now();
        let link = sent.get();
        if let Some(us) = pass.end(now, link > 0) {
            let bus = uart::SENT.load(Ordering::Relaxed).wrapping_sub(sent_before).wrapping_sub(link);
            defmt::info!("longest loop pass: {=u32} us, {=u32} bytes sent, {=u32} on the bus", us, link, bus);
        }
        if now >= next_stack_check {
            next_stack_check = now + STACK_CHECK_US;
            let depth = stack::high_water();
            if depth > stack_logged {
                stack_logged = depth;
                defmt::info!("control loop stack high-water: {=usize} bytes", depth);
            }
        }
        reset::feed();
        // Interrupts off between the last check and `wfi`, so a byte that comes in between wakes
        // it (a pending interrupt ends `wfi` even while masked) instead of waiting for SysTick.
        cortex_m::interrupt::free(|_| {
            if rx.is_empty() && clock.now() < next_tick {
                cortex_m::asm::wfi();
            }
        });
        sent.set(0);
        sent_before = uart::SENT.load(Ordering::Relaxed);
        pass.start(clock.now());
    })
}

/// The watchdog's warning: nothing has fed it for `reset::WATCHDOG_MS` (the control loop stopped,
/// or start-up did: it runs from `main`'s first line). Noted and logged; the watchdog's reset
/// follows as long again later, and nothing runs until then (the servos hold their last goal).
/// Start-up then takes their torque off.
#[exception]
unsafe fn NonMaskableInt() {
    reset::note_that(Note::Watchdog);
    defmt::error!("watchdog: the firmware stopped; the board resets");
    loop {
        cortex_m::asm::nop();
    }
}

/// A fault: noted and logged (where), then the watchdog resets the board (started here in case
/// the fault came before `main` started it). The servo bus is left alone: the fault may have come
/// from the bus code or left its state half-written, so no packet sent from here could be
/// trusted. The servos hold their last goal until the reset, after which start-up takes their
/// torque off.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    reset::note_that(Note::Fault);
    defmt::error!(
        "HardFault: pc {=u32:#010x}, lr {=u32:#010x}, xpsr {=u32:#010x}; the watchdog resets the board",
        frame.pc(),
        frame.lr(),
        frame.xpsr()
    );
    if !reset::watchdog_runs() {
        reset::start_watchdog();
    }
    loop {
        cortex_m::asm::nop();
    }
}

/// The release firmware has no panic path: every index, slice and clamp in the code it runs is
/// written so that the compiler can prove it in bounds. This handler keeps it that way: it calls a
/// function that exists nowhere, so a change that makes any panic reachable again fails to link
/// ("undefined symbol: firmware_reaches_a_panic"). `armctl footprint` then lists the call sites.
#[cfg(not(debug_assertions))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "C" {
        fn firmware_reaches_a_panic() -> !;
    }
    // SAFETY: never runs: the symbol is undefined, so a binary that could reach this does not link.
    unsafe { firmware_reaches_a_panic() }
}

/// Builds with debug assertions (a debug build, or the `panic-test` profile the HIL tests inject a
/// panic into) keep their checks: a panic logs where, and the core stops; the watchdog, unfed,
/// then resets the board (its NMI notes "watchdog"), and start-up takes the servos' torque off,
/// as after any stop.
#[cfg(debug_assertions)]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let (file, line) = info.location().map_or(("?", 0), |l| (l.file(), l.line()));
    defmt::error!("panic at {=str}:{=u32}; the watchdog resets the board", file, line);
    halt()
}

/// A panic for the HIL tests to inject (`tests/hil_qemu.rs` points the core here through QEMU's
/// gdb stub), in builds with debug assertions only: the release firmware has no panic path.
#[cfg(debug_assertions)]
#[no_mangle]
#[inline(never)]
extern "C" fn injected_panic() -> ! {
    panic!("injected by a test")
}

/// Keeps [`injected_panic`] in the ELF: nothing calls it.
#[cfg(debug_assertions)]
#[used]
static INJECTED_PANIC: extern "C" fn() -> ! = injected_panic;
