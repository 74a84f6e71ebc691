//! Start-up as every board does it: the firmware state and the bus master in static memory,
//! written once; the firmware placed there field by field and started on the built-in arm; the
//! servos' torque as the reset's cause wants it ([`super::reset`]); and the [`MainLoop`] over
//! them. A board brings up its clocks and UARTs, then hands them to [`Slots::start`].
//!
//! Why static memory, written in place: the firmware state is larger than a board's whole stack
//! budget would comfortably hold twice (over 7 KB with a 6-joint arm, against 8 KiB), so it is
//! never built on the stack and moved ([`crate::place`]); the stack holds only call frames.
//!
//! # Panics
//! Nothing here panics.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};

use super::main_loop::MainLoop;
use super::reset::{ResetCause, TorqueAfterReset};
use super::rx_ring::RxRing;
use super::BusPort;
use crate::app::{Board, Firmware};
use crate::builtin::BuiltinArm;
use crate::bus::master::{Clock, Master};
use crate::controller::ConfigError;

/// Why start-up stopped; the board logs it, and the host then sees no handshake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartError {
    /// Start-up ran before: the slots are written once.
    Twice,
    /// The built-in arm is refused (its control period is shorter than one bus cycle).
    Arm(ConfigError),
}

/// The static home of a board's firmware (`N` joints, `Q` keyframe slots) and its bus master `M`:
/// a board declares one `static`, and [`Slots::start`] fills it once.
pub struct Slots<const N: usize, const Q: usize, M> {
    taken: AtomicBool,
    app: UnsafeCell<MaybeUninit<Firmware<N, Q>>>,
    master: UnsafeCell<MaybeUninit<M>>,
}

// SAFETY: the cells are reached only by the one call of `start` that wins `taken` (an atomic
// swap), which hands out the only references to them; no other context ever touches them.
#[allow(unsafe_code)]
unsafe impl<const N: usize, const Q: usize, M> Sync for Slots<N, Q, M> {}

impl<const N: usize, const Q: usize, M> Slots<N, Q, M> {
    /// Empty slots, for a `static`.
    pub const fn new() -> Self {
        Self {
            taken: AtomicBool::new(false),
            app: UnsafeCell::new(MaybeUninit::uninit()),
            master: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }
}

impl<const N: usize, const Q: usize, M> Default for Slots<N, Q, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const Q: usize, P, D, C, const BUF: usize> Slots<N, Q, Master<P, D, C, BUF>>
where
    P: Read + Write + ReadReady + BusPort,
    D: OutputPin,
    C: Clock,
{
    /// Places the firmware for `board` in its slot and starts it on `arm`, then places the bus
    /// master `master()` builds; after any reset but the button (`cause`), the servos' torque
    /// goes off on the first tick. Returns the main loop over them and the link's ring `rx`,
    /// its first tick due at once.
    ///
    /// The master is built only once the firmware has started, so that it is not held in the
    /// caller's frame while the arm is taken (which solves IK: start-up's deepest stack).
    pub fn start<const R: usize>(
        &'static self,
        board: Board,
        arm: &'static BuiltinArm,
        cause: ResetCause,
        rx: &'static RxRing<R>,
        master: impl FnOnce() -> Master<P, D, C, BUF>,
    ) -> Result<MainLoop<'static, N, Q, R, P, D, C, BUF>, StartError> {
        if self.taken.swap(true, Ordering::Relaxed) {
            return Err(StartError::Twice);
        }
        // SAFETY: `taken` was false and is now set for good, so this is the one call that gets
        // here: these are the only references to the cells, for ever.
        #[allow(unsafe_code)]
        let (app_slot, master_slot) = unsafe { (&mut *self.app.get(), &mut *self.master.get()) };
        let app = Firmware::blank_in(app_slot, board);
        app.start(Some(arm)).map_err(StartError::Arm)?;
        let master = master_slot.write(master());
        // The servos may still hold torque toward the goal they had: limp, until the host switches
        // torque on again (or, after the reset button, held where they stand).
        if cause.torque() == TorqueAfterReset::Off {
            let now = master.clock().now_us();
            app.torque_off(now);
        }
        Ok(MainLoop::new(app, master, rx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::master::{BusConfig, NoDirectionPin};
    use crate::bus::table::STS3215;
    use crate::controller::Config;

    /// A servo bus where nothing answers: start-up sends nothing on it.
    struct Silent;

    impl embedded_io::ErrorType for Silent {
        type Error = core::convert::Infallible;
    }
    impl Read for Silent {
        fn read(&mut self, _: &mut [u8]) -> Result<usize, Self::Error> {
            Ok(0)
        }
    }
    impl ReadReady for Silent {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            Ok(false)
        }
    }
    impl Write for Silent {
        fn write(&mut self, bytes: &[u8]) -> Result<usize, Self::Error> {
            Ok(bytes.len())
        }
        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }
    impl BusPort for Silent {
        fn set_baud(&mut self, _: u32) {}
    }

    struct Zero;

    impl Clock for Zero {
        fn now_us(&mut self) -> u64 {
            0
        }
    }

    type TestSlots = Slots<6, 8, Master<Silent, NoDirectionPin, Zero>>;

    fn start(slots: &'static TestSlots, cause: ResetCause) -> Result<bool, StartError> {
        let bus = BusConfig::new(STS3215.protocol, 1_000_000);
        let board = Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: u32::MAX };
        let rx: &'static RxRing<16> = Box::leak(Box::new(RxRing::new()));
        let main_loop =
            slots.start(board, &crate::builtin::SO101, cause, rx, || Master::new(Silent, NoDirectionPin, Zero, bus))?;
        let controller = main_loop.firmware().controller().expect("the built-in arm runs");
        Ok(controller.torque_pending())
    }

    #[test]
    fn the_slots_are_filled_once_and_the_reset_decides_the_torque() {
        let slots: &'static TestSlots = Box::leak(Box::new(Slots::new()));
        assert_eq!(start(slots, ResetCause::PowerOn), Ok(true), "torque off after a power-on");
        assert_eq!(start(slots, ResetCause::PowerOn), Err(StartError::Twice));
        let button: &'static TestSlots = Box::leak(Box::new(Slots::new()));
        assert_eq!(start(button, ResetCause::Pin), Ok(false), "the button leaves the torque as it is");
    }
}
