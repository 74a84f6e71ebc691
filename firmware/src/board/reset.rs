//! What a reset does to the servos' torque: each board reads why it was reset (the STM32's
//! RCC_CSR flags, the MPS2's note in retained RAM) into [`ResetFlags`], and [`ResetCause::torque`]
//! decides. The servos are powered apart from the board, so a reset of the board alone leaves them
//! with the torque and the goal they had; both ways out of that are hazards:
//!
//! - torque off: the arm drops (an arm without brakes falls under its own weight);
//! - torque kept: the arm holds, and during the reset nothing runs it. After start-up the
//!   controller adopts servos it finds torqued: they hold where they stand, the goal set to the
//!   present position (see `adopt_torque` in the controller), with the firmware running them again.
//!
//! The rule: the torque stays (held where the arm stands) only after a reset that someone at the
//! board asked for and that says nothing bad about the firmware or the power: the reset button.
//! Every other cause takes the torque off:
//!
//! | cause | torque | why |
//! |-------|--------|-----|
//! | power-on | off | servos powered with the board start limp anyway; if only the board lost power, the servos held for as long as it was off with nothing running them, and the host's plan is gone: the arm starts as a power-on of everything leaves it |
//! | brown-out | off | the supply sagged, often under the servos' own current; holding draws that current again and can reset the board again, in a loop |
//! | watchdog | off | the control loop stopped (or faulted: the fault handlers wait for the watchdog); the same input can stop it again, and limp is the one state that does not depend on it |
//! | fault | off | as the watchdog's (a board that notes its faults: the MPS2) |
//! | software | off | on the STM32 only a debugger asks for one (after flashing): new code, perhaps another arm or calibration, should not inherit a hold it did not make |
//! | low-power | off | this firmware never enters standby: unexpected |
//! | button (pin) | hold | someone at the board asked; the firmware did not fail; the arm stops where it is instead of falling onto the person who pressed it |
//! | unknown | off | nothing says it is safe to hold |
//!
//! # Panics
//! Nothing here panics.

/// Why the board was reset, the most telling cause first when several flags are set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// The supply came up (STM32 PORRSTF; the MPS2 under QEMU: RAM without a note, a new QEMU).
    PowerOn,
    /// The supply dropped below the brown-out level and came back (STM32 BORRSTF without PORRSTF).
    BrownOut,
    /// A watchdog reset the chip: the control loop stopped feeding it (STM32 IWDGRSTF or
    /// WWDGRSTF; the MPS2's CMSDK watchdog, noted by its NMI).
    Watchdog,
    /// A fault handler ran, and the watchdog then reset the chip (the MPS2 notes it).
    Fault,
    /// The low-power management reset (STM32 LPWRRSTF: standby or stop with nRST_STDBY/STOP).
    LowPower,
    /// A software reset (SYSRESETREQ): on the STM32, a debugger's (this firmware never asks).
    Software,
    /// The reset pin alone: the board's reset button (the MPS2 under QEMU: `system_reset`, its
    /// board's button, or any reset of a firmware that was running and noted nothing else).
    Pin,
    /// No flag at all.
    Unknown,
}

/// What start-up does to the servos' torque.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TorqueAfterReset {
    /// Torque off on the first tick: the arm goes limp.
    Off,
    /// Left as the servos have it: torqued servos are held where they stand (the controller's
    /// adoption at start), limp ones stay limp.
    Hold,
}

impl ResetCause {
    /// What this reset does to the servos' torque (the table in the module's documentation).
    pub fn torque(self) -> TorqueAfterReset {
        match self {
            ResetCause::Pin => TorqueAfterReset::Hold,
            ResetCause::PowerOn
            | ResetCause::BrownOut
            | ResetCause::Watchdog
            | ResetCause::Fault
            | ResetCause::LowPower
            | ResetCause::Software
            | ResetCause::Unknown => TorqueAfterReset::Off,
        }
    }
}

/// The reset flags a board read, as booleans (a board sets those it has).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ResetFlags {
    /// Power-on/power-down reset (STM32 PORRSTF).
    pub power_on: bool,
    /// Brown-out reset (STM32 BORRSTF: also set by a power-on).
    pub brown_out: bool,
    /// Independent or window watchdog (STM32 IWDGRSTF, WWDGRSTF).
    pub watchdog: bool,
    /// A fault handler ran before the reset.
    pub fault: bool,
    /// Low-power management (STM32 LPWRRSTF).
    pub low_power: bool,
    /// Software reset (STM32 SFTRSTF).
    pub software: bool,
    /// The reset pin (STM32 PINRSTF: also set by every internal reset, which drives NRST low).
    pub pin: bool,
}

impl ResetFlags {
    /// The cause these flags tell. On the STM32 one reset sets several flags (RM0383 §6.3.19,
    /// RCC_CSR): a power-on sets PORRSTF, BORRSTF and PINRSTF; every internal reset also sets
    /// PINRSTF. So the most specific flag wins: power-on, then brown-out, fault, watchdog,
    /// low-power, software, and the pin only when nothing else is set.
    pub fn cause(self) -> ResetCause {
        if self.power_on {
            ResetCause::PowerOn
        } else if self.brown_out {
            ResetCause::BrownOut
        } else if self.fault {
            ResetCause::Fault
        } else if self.watchdog {
            ResetCause::Watchdog
        } else if self.low_power {
            ResetCause::LowPower
        } else if self.software {
            ResetCause::Software
        } else if self.pin {
            ResetCause::Pin
        } else {
            ResetCause::Unknown
        }
    }
}

/// A note a board keeps in RAM that survives a reset but not a power-on (the MPS2 under QEMU,
/// which has no reset-cause register): what the firmware was doing when the reset came. Stored as
/// a word and its complement, so that RAM's power-on contents read as no note.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Note {
    /// Running: a reset now came from outside (the button, QEMU's `system_reset`).
    Running,
    /// The watchdog's warning (its first expiry) came: its reset follows.
    Watchdog,
    /// A fault handler ran: the watchdog's reset follows.
    Fault,
}

impl Note {
    const RUNNING: u32 = 0x5255_4E21;
    const WATCHDOG: u32 = 0x5744_4F47;
    const FAULT: u32 = 0x4641_554C;

    /// The two words to store.
    pub fn words(self) -> [u32; 2] {
        let word = match self {
            Note::Running => Self::RUNNING,
            Note::Watchdog => Self::WATCHDOG,
            Note::Fault => Self::FAULT,
        };
        [word, !word]
    }

    /// The note two stored words hold; `None` for anything else (a power-on's RAM).
    pub fn read(words: [u32; 2]) -> Option<Note> {
        let [word, check] = words;
        if check != !word {
            return None;
        }
        match word {
            Self::RUNNING => Some(Note::Running),
            Self::WATCHDOG => Some(Note::Watchdog),
            Self::FAULT => Some(Note::Fault),
            _ => None,
        }
    }

    /// The flags a note found at start-up stands for: none is a power-on.
    pub fn flags(note: Option<Note>) -> ResetFlags {
        match note {
            None => ResetFlags { power_on: true, ..ResetFlags::default() },
            Some(Note::Running) => ResetFlags { pin: true, ..ResetFlags::default() },
            Some(Note::Watchdog) => ResetFlags { watchdog: true, pin: true, ..ResetFlags::default() },
            Some(Note::Fault) => ResetFlags { fault: true, watchdog: true, pin: true, ..ResetFlags::default() },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flags(f: impl FnOnce(&mut ResetFlags)) -> ResetFlags {
        let mut flags = ResetFlags::default();
        f(&mut flags);
        flags
    }

    #[test]
    fn what_the_stm32_sets_for_each_reset_is_told_apart() {
        // RM0383 §6.3.19: internal resets also drive NRST low, so PINRSTF comes with each.
        let power_on = flags(|f| (f.power_on, f.brown_out, f.pin) = (true, true, true));
        assert_eq!(power_on.cause(), ResetCause::PowerOn);
        let brown_out = flags(|f| (f.brown_out, f.pin) = (true, true));
        assert_eq!(brown_out.cause(), ResetCause::BrownOut);
        let watchdog = flags(|f| (f.watchdog, f.pin) = (true, true));
        assert_eq!(watchdog.cause(), ResetCause::Watchdog);
        let software = flags(|f| (f.software, f.pin) = (true, true));
        assert_eq!(software.cause(), ResetCause::Software);
        let low_power = flags(|f| (f.low_power, f.pin) = (true, true));
        assert_eq!(low_power.cause(), ResetCause::LowPower);
        assert_eq!(flags(|f| f.pin = true).cause(), ResetCause::Pin);
        assert_eq!(ResetFlags::default().cause(), ResetCause::Unknown);
    }

    #[test]
    fn only_the_reset_button_leaves_the_torque_on() {
        use ResetCause::*;
        for cause in [PowerOn, BrownOut, Watchdog, Fault, LowPower, Software, Unknown] {
            assert_eq!(cause.torque(), TorqueAfterReset::Off, "{cause:?}");
        }
        assert_eq!(Pin.torque(), TorqueAfterReset::Hold);
    }

    #[test]
    fn a_power_on_with_a_watchdog_flag_left_over_is_a_power_on() {
        // Flags stay set until RMVF clears them; a power-on still says power-on.
        let stale = flags(|f| (f.power_on, f.watchdog, f.pin) = (true, true, true));
        assert_eq!(stale.cause(), ResetCause::PowerOn);
        assert_eq!(stale.cause().torque(), TorqueAfterReset::Off);
    }

    #[test]
    fn a_note_survives_only_whole() {
        for note in [Note::Running, Note::Watchdog, Note::Fault] {
            assert_eq!(Note::read(note.words()), Some(note));
            let [word, check] = note.words();
            assert_eq!(Note::read([word, check ^ 1]), None);
            assert_eq!(Note::read([word ^ 0x100, check]), None);
        }
        // Zeroed RAM, all-ones RAM and a word whose complement matches but means nothing.
        assert_eq!(Note::read([0, 0]), None);
        assert_eq!(Note::read([u32::MAX, u32::MAX]), None);
        assert_eq!(Note::read([0x1234_5678, !0x1234_5678]), None);
    }

    #[test]
    fn each_note_stands_for_its_cause() {
        assert_eq!(Note::flags(None).cause(), ResetCause::PowerOn);
        assert_eq!(Note::flags(Some(Note::Running)).cause(), ResetCause::Pin);
        assert_eq!(Note::flags(Some(Note::Watchdog)).cause(), ResetCause::Watchdog);
        assert_eq!(Note::flags(Some(Note::Fault)).cause(), ResetCause::Fault);
        assert_eq!(Note::flags(Some(Note::Running)).cause().torque(), TorqueAfterReset::Hold);
        assert_eq!(Note::flags(Some(Note::Fault)).cause().torque(), TorqueAfterReset::Off);
    }
}
