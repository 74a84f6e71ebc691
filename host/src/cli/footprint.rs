//! `armctl footprint`'s options, turned into the request [`crate::commands::footprint`] runs.

use std::path::PathBuf;

use clap::Args;

use crate::commands::footprint::{Board, FootprintRequest};

/// Arguments of `armctl footprint`.
#[derive(Args, Debug)]
pub struct FootprintArgs {
    /// The board binary to report on (default: both).
    #[arg(long, value_parser = crate::cli::values::board())]
    board: Option<Board>,
    /// Report on this firmware ELF instead of building the board binary (any Cortex-M ELF; with no
    /// --board the board is told by its start-up and loop functions, and an ELF without them, such
    /// as the `opcount` benchmark, is bounded from `main`).
    #[arg(long)]
    elf: Option<PathBuf>,
    /// Skip the stack measurement under QEMU.
    #[arg(long)]
    no_qemu: bool,
    /// One line of JSON instead of the text report.
    #[arg(long)]
    pub json: bool,
}

impl FootprintArgs {
    /// The request the options make.
    pub fn request(self) -> FootprintRequest {
        FootprintRequest { board: self.board, elf: self.elf, no_qemu: self.no_qemu, json: self.json }
    }
}
