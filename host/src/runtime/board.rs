//! Building a board binary, and the toolchain pieces that needs.
//!
//! Each board crate under `firmware/boards/` is its own cargo workspace that builds only for
//! [`TARGET`]. `rust-toolchain.toml` lists that target and the `llvm-tools` component, but rustup
//! adds a toolchain file's targets and components only when it installs the toolchain: a machine
//! that already had the pinned Rust has neither. So every board build ([`build`], shared by
//! `armctl sim --qemu`, `armctl bench mcu`, `armctl bench loop-pass`, `armctl footprint` and the
//! HIL tests) first makes sure they are there ([`ensure_toolchain`]), installing what is missing
//! through rustup once per process, with one line on stderr saying so.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use anyhow::{anyhow, bail, Context, Result};

/// The board binaries' target: Cortex-M4F with its single-precision FPU.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// The rustup component that ships `llvm-objdump`, which `armctl footprint` reads the ELFs with.
pub const LLVM_TOOLS: &str = "llvm-tools";

/// The error of `armctl COMMAND` in an armctl built without the `board-tools` feature, which the
/// commands that run a board binary need (`sim --qemu`, `bench mcu`, `bench loop-pass`,
/// `footprint`: they decode its defmt log and read its ELF). One line, with the build that has it.
pub fn without_tools(command: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "armctl {command} needs the board-tools feature, which this armctl was built without: \
         cargo run --release -p armctl --features board-tools -- {command}"
    )
}

/// The folder holding one cargo workspace per board.
pub fn boards_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/boards")
}

/// Builds the binary `bin` (release) of the board crate at `dir` (its own cargo workspace, with
/// its target in `.cargo/config.toml`); returns the ELF's path. The target and `llvm-tools` are
/// installed first where they are missing.
pub fn build(dir: &Path, bin: &str) -> Result<PathBuf> {
    build_with_profile(dir, bin, "release")
}

/// As [`build`], with the cargo profile `profile` of the board crate (`release`, `dev`, or one of
/// its own such as the MPS2's `panic-test`); the ELF is in the profile's folder of the shared
/// target folder, so builds of different profiles do not replace each other's.
pub fn build_with_profile(dir: &Path, bin: &str, profile: &str) -> Result<PathBuf> {
    ensure_toolchain(dir)?;
    if links_with_flip_link(dir) {
        ensure_flip_link()?;
    }
    let status = cargo()
        .args(["build", "--profile", profile, "--quiet", "--bin", bin])
        .current_dir(dir)
        // One target folder for every board: the crates they share (firmware, kinematics,
        // nalgebra, cortex-m...) are built once. The host build's other settings (`cargo test`,
        // `cargo run`) are not the board's.
        .env("CARGO_TARGET_DIR", target_dir())
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .status()
        .with_context(|| format!("cannot run cargo in {}", dir.display()))?;
    if !status.success() {
        bail!("building the {bin} binary ({profile} profile) in {} failed", dir.display());
    }
    Ok(target_dir().join(TARGET).join(profile_dir(profile)).join(bin))
}

/// The folder under the target's where cargo puts a profile's binaries: `debug` for `dev` (and
/// `test`), `release` for `bench`, a custom profile's own name otherwise.
pub fn profile_dir(profile: &str) -> &str {
    match profile {
        "dev" | "test" => "debug",
        "bench" => "release",
        other => other,
    }
}

/// The cargo that runs this (`CARGO` under cargo), or the one on the PATH.
fn cargo() -> Command {
    Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
}

/// `check()`'s outcome, computed on the first call in this process and remembered (a failure too,
/// reported again). A mutex rather than a once-cell, so that parallel tests wait for one install
/// to finish.
fn once<T: Clone>(cache: &Mutex<Option<Result<T, String>>>, check: impl FnOnce() -> Result<T, String>) -> Result<T> {
    let mut cached = cache.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    cached.get_or_insert_with(check).clone().map_err(|e| anyhow!("{e}"))
}

/// The linker wrapper a board may link with (`linker = "flip-link"` in its
/// `.cargo/config.toml`): it puts the stack below the statics, at the bottom of RAM, so that an
/// overflowing stack faults at the edge of RAM instead of overwriting the firmware's state.
pub const FLIP_LINK: &str = "flip-link";

/// Whether the board crate at `dir` links with [`FLIP_LINK`].
pub fn links_with_flip_link(dir: &Path) -> bool {
    std::fs::read_to_string(dir.join(".cargo/config.toml"))
        .is_ok_and(|config| config.lines().any(|l| l.trim() == format!("linker = \"{FLIP_LINK}\"")))
}

/// Makes sure [`FLIP_LINK`] is on the PATH, installing it with `cargo install` (a small crate,
/// seconds to build) when it is not. Checked once per process, as the toolchain is.
pub fn ensure_flip_link() -> Result<()> {
    static CHECKED: Mutex<Option<Result<(), String>>> = Mutex::new(None);
    once(&CHECKED, || {
        // Run without arguments it reports its own usage; only a missing program fails to start.
        if Command::new(FLIP_LINK).output().is_ok() {
            return Ok(());
        }
        eprintln!("note: the board build links with {FLIP_LINK}: installing it with cargo install (once)");
        let output = cargo()
            .args(["install", FLIP_LINK, "--locked", "--quiet"])
            .output()
            .map_err(|e| format!("cannot run cargo install {FLIP_LINK}: {e}"))?;
        if !output.status.success() {
            let stderr = String::from_utf8_lossy(&output.stderr);
            return Err(format!("cargo install {FLIP_LINK} failed: {}", stderr.trim().replace('\n', "; ")));
        }
        match Command::new(FLIP_LINK).output() {
            Ok(_) => Ok(()),
            Err(_) => Err(format!(
                "cargo install put {FLIP_LINK} where the PATH does not reach: add cargo's bin folder (~/.cargo/bin) to the PATH"
            )),
        }
    })
}

/// The target folder all board builds share: `firmware/boards/target`.
pub fn target_dir() -> PathBuf {
    boards_dir().join("target")
}

/// The Rust toolchain that cargo picks in a folder (rustup reads `rust-toolchain.toml` upwards).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Toolchain {
    /// `rustc --print sysroot`.
    pub sysroot: PathBuf,
    /// The host triple (`rustc -vV`).
    pub host: String,
}

/// What a board build needs from the toolchain and may lack.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Missing {
    /// The standard library for [`TARGET`].
    Target,
    /// The [`LLVM_TOOLS`] component.
    LlvmTools,
}

impl Toolchain {
    /// Asks `rustc` run in `dir` (so rustup resolves the toolchain the board build will use).
    pub fn of(dir: &Path) -> Result<Toolchain> {
        let rustc = |args: &[&str]| -> Result<String> {
            let output = Command::new("rustc")
                .args(args)
                .current_dir(dir)
                .output()
                .context("cannot run rustc (install Rust with rustup: https://rustup.rs)")?;
            if !output.status.success() {
                bail!("rustc {} failed: {}", args.join(" "), String::from_utf8_lossy(&output.stderr).trim());
            }
            Ok(String::from_utf8_lossy(&output.stdout).trim().to_string())
        };
        let sysroot = PathBuf::from(rustc(&["--print", "sysroot"])?);
        let host = rustc(&["-vV"])?
            .lines()
            .find_map(|l| l.strip_prefix("host: ").map(str::to_string))
            .ok_or_else(|| anyhow!("rustc -vV names no host triple"))?;
        Ok(Toolchain { sysroot, host })
    }

    /// The folder of the toolchain's LLVM tools (`llvm-objdump`, ...).
    pub fn llvm_bin(&self) -> PathBuf {
        self.sysroot.join("lib/rustlib").join(&self.host).join("bin")
    }

    /// What of [`TARGET`]'s standard library and the LLVM tools is not in the sysroot.
    pub fn missing(&self) -> Vec<Missing> {
        let mut missing = Vec::new();
        if !self.sysroot.join("lib/rustlib").join(TARGET).join("lib").is_dir() {
            missing.push(Missing::Target);
        }
        if !self.llvm_bin().join("llvm-objdump").is_file() {
            missing.push(Missing::LlvmTools);
        }
        missing
    }
}

/// Makes sure the toolchain used in `dir` has [`TARGET`] and [`LLVM_TOOLS`], installing what is
/// missing with rustup, and returns it. Checked once per process (a failure is remembered and
/// reported again).
pub fn ensure_toolchain(dir: &Path) -> Result<Toolchain> {
    static CHECKED: Mutex<Option<Result<Toolchain, String>>> = Mutex::new(None);
    once(&CHECKED, || {
        let outcome = Toolchain::of(dir).and_then(|toolchain| {
            install(&toolchain.missing(), "rustup", dir, &toolchain.sysroot)?;
            match toolchain.missing().as_slice() {
                [] => Ok(toolchain),
                still => bail!("rustup ran, but the toolchain still lacks {}", names(still)),
            }
        });
        outcome.map_err(|e| format!("{e:#}"))
    })
}

fn names(missing: &[Missing]) -> String {
    missing
        .iter()
        .map(|m| match m {
            Missing::Target => format!("the {TARGET} target"),
            Missing::LlvmTools => LLVM_TOOLS.to_string(),
        })
        .collect::<Vec<_>>()
        .join(" and ")
}

/// Installs `missing` with the rustup program `rustup`, run in `dir`; one line on stderr says so.
/// rustup's own progress output is kept and shown only if it fails. Without rustup, the error
/// names what to install.
pub fn install(missing: &[Missing], rustup: &str, dir: &Path, sysroot: &Path) -> Result<()> {
    if missing.is_empty() {
        return Ok(());
    }
    let what = names(missing);
    let toolchain = sysroot.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    if Command::new(rustup).arg("--version").output().is_err() {
        bail!(
            "the Rust toolchain at {} lacks {what}, and rustup is not installed: install rustup \
             (https://rustup.rs) and run `rustup target add {TARGET}` and `rustup component add {LLVM_TOOLS}`, \
             or install {what} for this toolchain",
            sysroot.display()
        );
    }
    eprintln!("note: the board build needs {what}: installing with rustup for toolchain {toolchain} (once)");
    for m in missing {
        let args: [&str; 3] = match m {
            Missing::Target => ["target", "add", TARGET],
            Missing::LlvmTools => ["component", "add", LLVM_TOOLS],
        };
        let output = Command::new(rustup)
            .args(args)
            .current_dir(dir)
            .output()
            .with_context(|| format!("cannot run {rustup} {}", args.join(" ")))?;
        if !output.status.success() {
            bail!(
                "{rustup} {} failed: {}",
                args.join(" "),
                String::from_utf8_lossy(&output.stderr).trim().replace('\n', "; ")
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder of its own, removed when dropped (also when the test fails).
    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("armctl-board-{name}-")).tempdir().unwrap()
    }

    #[test]
    fn a_sysroot_without_the_target_or_tools_lacks_both_and_one_with_them_lacks_nothing() {
        let temp = scratch("sysroot");
        let sysroot = temp.path();
        let toolchain = Toolchain { sysroot: sysroot.to_path_buf(), host: "x86_64-unknown-linux-gnu".into() };
        assert_eq!(toolchain.missing(), [Missing::Target, Missing::LlvmTools]);
        std::fs::create_dir_all(sysroot.join("lib/rustlib").join(TARGET).join("lib")).unwrap();
        assert_eq!(toolchain.missing(), [Missing::LlvmTools]);
        std::fs::create_dir_all(toolchain.llvm_bin()).unwrap();
        std::fs::write(toolchain.llvm_bin().join("llvm-objdump"), b"").unwrap();
        assert_eq!(toolchain.missing(), []);
    }

    #[test]
    fn without_rustup_the_error_is_one_line_naming_what_to_install() {
        let temp = scratch("no-rustup");
        let dir = temp.path();
        let e = install(&[Missing::Target], "armctl-test-no-such-rustup", dir, Path::new("/opt/rust"))
            .unwrap_err()
            .to_string();
        assert!(!e.contains('\n'), "{e}");
        assert!(e.contains("rustup is not installed") && e.contains(TARGET) && e.contains("/opt/rust"), "{e}");
        // Nothing missing: nothing to run, so no rustup needed.
        install(&[], "armctl-test-no-such-rustup", dir, Path::new("/opt/rust")).unwrap();
    }

    #[test]
    fn the_stm32_board_links_with_flip_link_and_the_mps2_board_does_not() {
        assert!(links_with_flip_link(&boards_dir().join("stm32f411")));
        // QEMU's board paints and measures its stack instead; flip-link would move it.
        assert!(!links_with_flip_link(&boards_dir().join("mps2-an386")));
    }

    #[test]
    fn each_profile_builds_into_its_own_folder() {
        assert_eq!(profile_dir("release"), "release");
        assert_eq!(profile_dir("dev"), "debug");
        assert_eq!(profile_dir("panic-test"), "panic-test");
    }

    #[test]
    fn the_workspace_toolchain_is_found() {
        let toolchain = Toolchain::of(&boards_dir()).unwrap();
        assert!(toolchain.sysroot.is_dir(), "{toolchain:?}");
        assert!(!toolchain.host.is_empty());
    }
}
