//! Flash and static RAM of a board binary, from its ELF section headers; and where a function is,
//! from its symbol table ([`function_address`], for the HIL tests' debugger).
//!
//! The section names are cortex-m-rt's linker script (`link.x`): `.vector_table`, `.text` and
//! `.rodata` live in flash; `.data` is initialised data, stored in flash (its load address) and
//! copied to RAM at reset, so it counts in both; `.bss` and `.uninit` are RAM only. The stack is not
//! a section: it takes the RAM left above these, so the static figure plus the stack depth must fit.

use anyhow::{anyhow, Result};
use object::{Object, ObjectSection, ObjectSymbol};
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

/// The address of the function `path` in the ELF in `bytes`, its Thumb bit cleared: `path` is a
/// symbol's own name (`injected_panic`, a `#[no_mangle]` function) or the Rust path of a mangled
/// one without its hash (`board_mps2_an386::start`). Fails if no function or more than one has it.
pub fn function_address(bytes: &[u8], path: &str) -> Result<u64> {
    let file = object::File::parse(bytes).map_err(|e| anyhow!("not an ELF file: {e}"))?;
    let mut found = file
        .symbols()
        .filter(|s| s.kind() == object::SymbolKind::Text)
        .filter(|s| s.name().is_ok_and(|name| name == path || legacy_path(name).as_deref() == Some(path)))
        .map(|s| s.address() & !1);
    match (found.next(), found.next()) {
        (Some(address), None) => Ok(address),
        (None, _) => Err(anyhow!("no function {path} in the ELF")),
        (Some(_), Some(_)) => Err(anyhow!("more than one function {path} in the ELF")),
    }
}

/// The Rust path of a legacy-mangled symbol (`_ZN16board_mps2_an3865start17h0123456789abcdefE`
/// is `board_mps2_an386::start`), its hash dropped and its escapes decoded as
/// [`super::disasm::pretty`] decodes llvm-objdump's; `None` for any other name.
fn legacy_path(symbol: &str) -> Option<String> {
    let mut rest = symbol.strip_prefix("_ZN")?.strip_suffix('E')?;
    let mut parts = Vec::new();
    while !rest.is_empty() {
        let digits = rest.find(|c: char| !c.is_ascii_digit())?;
        let len: usize = rest[..digits].parse().ok()?;
        let part = rest.get(digits..digits + len)?;
        parts.push(part);
        rest = &rest[digits + len..];
    }
    Some(super::disasm::pretty(&parts.join("::")))
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
        assert!(function_address(b"not an elf", "main").is_err());
    }

    #[test]
    fn a_legacy_mangled_symbol_reads_as_its_rust_path() {
        assert_eq!(
            legacy_path("_ZN16board_mps2_an3865start17h0123456789abcdefE").as_deref(),
            Some("board_mps2_an386::start")
        );
        assert_eq!(
            legacy_path("_ZN8firmware5board9main_loop17MainLoop$LT$T$GT$3run17h0123456789abcdefE").as_deref(),
            Some("firmware::board::main_loop::MainLoop<T>::run")
        );
        assert_eq!(legacy_path("injected_panic"), None);
        assert_eq!(legacy_path("_ZN99shortE"), None, "a length past the end");
    }
}
