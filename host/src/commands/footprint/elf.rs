//! Flash and static RAM of a board binary, from its ELF section headers.
//!
//! The section names are cortex-m-rt's linker script (`link.x`): `.vector_table`, `.text` and
//! `.rodata` live in flash; `.data` is initialised data, stored in flash (its load address) and
//! copied to RAM at reset, so it counts in both; `.bss` and `.uninit` are RAM only. The stack is not
//! a section: it takes the RAM left above these, so the static figure plus the stack depth must fit.

use anyhow::{anyhow, Result};
use object::{Object, ObjectSection};
use serde::Serialize;

/// The sizes of the sections that matter, in bytes (0 for a section the ELF lacks).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Sizes {
    /// The exception vectors at the start of flash.
    pub vector_table: u64,
    /// Code.
    pub text: u64,
    /// Constants.
    pub rodata: u64,
    /// Initialised statics (in flash and in RAM).
    pub data: u64,
    /// Zeroed statics.
    pub bss: u64,
    /// Statics left uninitialised at reset (cortex-m-rt's `#[link_section = ".uninit"]`).
    pub uninit: u64,
}

impl Sizes {
    /// Reads the section headers of the ELF in `bytes`.
    pub fn of_elf(bytes: &[u8]) -> Result<Sizes> {
        let file = object::File::parse(bytes).map_err(|e| anyhow!("not an ELF file: {e}"))?;
        let size = |name: &str| file.section_by_name(name).map_or(0, |s| s.size());
        let sizes = Sizes {
            vector_table: size(".vector_table"),
            text: size(".text"),
            rodata: size(".rodata"),
            data: size(".data"),
            bss: size(".bss"),
            uninit: size(".uninit"),
        };
        if sizes.text == 0 {
            return Err(anyhow!("the ELF has no .text section (not a linked firmware binary?)"));
        }
        Ok(sizes)
    }

    /// Bytes of flash the binary takes.
    pub fn flash(&self) -> u64 {
        self.vector_table + self.text + self.rodata + self.data
    }

    /// Bytes of RAM its statics take (the stack comes on top).
    pub fn static_ram(&self) -> u64 {
        self.data + self.bss + self.uninit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn initialised_data_counts_in_flash_and_in_ram() {
        let s = Sizes { vector_table: 0x400, text: 1000, rodata: 200, data: 16, bss: 300, uninit: 8 };
        assert_eq!(s.flash(), 0x400 + 1000 + 200 + 16);
        assert_eq!(s.static_ram(), 16 + 300 + 8);
    }

    #[test]
    fn a_file_that_is_not_an_elf_is_refused() {
        assert!(Sizes::of_elf(b"not an elf").is_err());
    }
}
