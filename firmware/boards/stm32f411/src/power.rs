//! The supply side of start-up: the regulator's voltage scale (PWR_CR.VOS) the 84 MHz clock
//! needs, and the brown-out reset level (FLASH_OPTCR.BOR_LEV) the flash's wait states need.
//!
//! **The voltage scale.** 84 MHz is the most the F411 may run at in scale 2 (RM0383 §5.1.3), the
//! scale it comes out of reset in. The scale can be changed only while the PLL is off, and takes
//! effect when the PLL starts (PWR_CSR.VOSRDY then says it is in force). Start-up writes scale 2
//! before the PLL, so that 84 MHz never depends on a reset value, and logs what it reads back.
//!
//! **The brown-out level.** Out of the factory, BOR_LEV is 0b11: brown-out reset off, so only the
//! power-down reset (about 1.7 V) stops the chip on a sagging supply. The flash's 2 wait states at
//! 84 MHz are specified from 2.7 V (RM0383's table of wait states against the clock and the supply;
//! below 2.7 V 84 MHz needs 3), so between about 1.7 and 2.7 V the
//! core would run on with undefined reads from flash, saying nothing, while the servos, on their
//! own supply, keep whatever goal they were sent. BOR level 3 (0b00: reset below about 2.7 V)
//! closes that gap. It is an option byte, in flash, so writing it is done with care
//! ([`raise_bor_to_level_3`]).
//!
//! Note the encoding: BOR_LEV 0b00 is level 3 (the highest threshold) and 0b11 is off (RM0383,
//! FLASH_OPTCR; ST's HAL: `OB_BOR_LEVEL3` 0x00, `OB_BOR_OFF` 0x0C). The device crate's names for the
//! field's values come from an SVD that has them the other way round, so this file uses the bits.

use firmware::board::watchdog::Iwdg;
use stm32f4xx_hal::pac::{FLASH, PWR, RCC};

use crate::watchdog::Watchdog;

/// FLASH_OPTCR.BOR_LEV for level 3 (VBOR3, about 2.7 V).
const BOR_LEVEL_3: u8 = 0b00;
/// FLASH_OPTKEYR's unlock sequence (RM0383, option byte programming).
const OPT_KEYS: [u32; 2] = [0x0819_2A3B, 0x4C5D_6E7F];
/// PWR_CR.PLS for the highest PVD threshold (PVD level 7, about 2.9 V on a rising supply: DS10314,
/// "programmable voltage detector characteristics").
const PVD_HIGHEST: u8 = 0b111;
/// How long the PVD needs after it is enabled before PVDO can be trusted (a few microseconds;
/// a millisecond of the 16 MHz HSI start-up runs on, with margin).
const PVD_SETTLE_CYCLES: u32 = 16_000;
/// How many times FLASH_SR.BSY is polled while the option bytes are written. The bus stalls on
/// flash reads during the write, so the loop runs only as fast as the write lets it; the bound
/// keeps a write that never ends from hanging start-up (the watchdog's longest setting, below,
/// would reset it later anyway).
const OPTION_WRITE_POLLS: u32 = 50_000_000;
/// The watchdog's setting while the option bytes are written: its longest (22 s at the LSI's
/// fastest). Flash reads stall during the write, so nothing can feed the watchdog; a reset in the
/// middle of an option-byte write could leave them half-written.
const WATCHDOG_DURING_WRITE: Iwdg = Iwdg { pr: 6, rlr: 0xFFF };

/// The supply as start-up read it, for the first log line.
#[derive(Clone, Copy)]
pub struct Supply {
    /// PWR_CR.VOS: 1, 2 or 3 as the scale's number (3 is the lowest, up to 64 MHz).
    pub scale: u8,
    /// The brown-out reset level: 0 for off, else 1 to 3.
    pub bor_level: u8,
}

/// Switches the power controller's clock on and reads the voltage scale and the BOR level.
pub fn read(rcc: &RCC, pwr: &PWR, flash: &FLASH) -> Supply {
    rcc.apb1enr().modify(|_, w| w.pwren().set_bit());
    // Read back, so that the clock is on before the PWR registers are read.
    let _ = rcc.apb1enr().read();
    Supply { scale: scale_number(pwr.cr().read().vos().bits()), bor_level: bor_level(flash) }
}

/// The scale's number from PWR_CR.VOS (0b01 scale 3, 0b10 scale 2, 0b11 scale 1; 0b00 reads as
/// scale 3, as RM0383 has it).
fn scale_number(vos: u8) -> u8 {
    match vos {
        0b11 => 1,
        0b10 => 2,
        _ => 3,
    }
}

/// The BOR level (0 off, 1 to 3) from FLASH_OPTCR.BOR_LEV.
fn bor_level(flash: &FLASH) -> u8 {
    3 - flash.optcr().read().bor_lev().bits()
}

/// Puts the regulator in scale 2 while the PLL is still off (a no-op on a chip just out of
/// reset; it makes 84 MHz independent of what ran before).
pub fn select_scale_2(pwr: &PWR) {
    pwr.cr().modify(|_, w| w.vos().scale2());
}

/// The scale in force once the PLL runs: its number and whether PWR_CSR.VOSRDY says it is ready.
pub fn scale_in_force(pwr: &PWR) -> (u8, bool) {
    (scale_number(pwr.cr().read().vos().bits()), pwr.csr().read().vosrdy().bit_is_set())
}

/// What [`raise_bor_to_level_3`] did.
pub enum BorWrite {
    /// The option bytes already had it (or higher: there is none higher).
    AlreadySet,
    /// Written and read back as level 3.
    Written,
    /// Not written: the reset was not a power-on (a board resetting in a loop must not write its
    /// option bytes on every pass).
    NotAfterThisReset,
    /// Not written: the supply is below the PVD's highest threshold, too low to write flash safely.
    SupplyLow,
    /// Written, but the option bytes read back another level (or the write did not end): the
    /// write is not tried again until the next power-on.
    Failed,
}

/// Raises the BOR level to 3 in the option bytes when it is lower, once, and only when it is safe:
/// after a power-on (never after a watchdog, brown-out or other reset, which a loop could repeat:
/// option bytes last some ten thousand writes), with the supply above the PVD's highest threshold,
/// and with the watchdog at its longest setting for the duration (flash reads stall during the
/// write, so nothing could feed it), then back at `normal`. Only BOR_LEV changes: OPTCR is
/// read, modified and written, so the read protection and write protection bytes are written
/// with the values they had.
pub fn raise_bor_to_level_3(
    flash: &FLASH,
    pwr: &PWR,
    watchdog: &mut Watchdog,
    normal: Iwdg,
    power_on: bool,
) -> BorWrite {
    if bor_level(flash) == 3 {
        return BorWrite::AlreadySet;
    }
    if !power_on {
        return BorWrite::NotAfterThisReset;
    }
    if !supply_above_pvd_highest(pwr) {
        return BorWrite::SupplyLow;
    }
    watchdog.set(WATCHDOG_DURING_WRITE);
    for key in OPT_KEYS {
        flash.optkeyr().write(|w| w.optkeyr().set(key));
    }
    let mut ended = wait_not_busy(flash);
    if ended {
        flash.optcr().modify(|_, w| w.bor_lev().set(BOR_LEVEL_3));
        flash.optcr().modify(|_, w| w.optstrt().set_bit());
        ended = wait_not_busy(flash);
    }
    flash.optcr().modify(|_, w| w.optlock().set_bit());
    watchdog.set(normal);
    if ended && bor_level(flash) == 3 {
        BorWrite::Written
    } else {
        BorWrite::Failed
    }
}

/// Waits (bounded) for FLASH_SR.BSY to clear; false if it did not.
fn wait_not_busy(flash: &FLASH) -> bool {
    (0..OPTION_WRITE_POLLS).any(|_| flash.sr().read().bsy().bit_is_clear())
}

/// Whether VDD is above the PVD's highest threshold (PWR_CSR.PVDO clear). The PVD is switched
/// off again afterwards.
fn supply_above_pvd_highest(pwr: &PWR) -> bool {
    pwr.cr().modify(|_, w| w.pls().set(PVD_HIGHEST).pvde().set_bit());
    cortex_m::asm::delay(PVD_SETTLE_CYCLES);
    let low = pwr.csr().read().pvdo().bit_is_set();
    pwr.cr().modify(|_, w| w.pvde().clear_bit());
    !low
}
