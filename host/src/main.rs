//! `armctl`: see `armctl --help`. All the work is in the library so tests drive the same code.

fn main() {
    let stdout = std::io::stdout();
    let stderr = std::io::stderr();
    let code = armctl::cli::main(std::env::args_os(), &mut stdout.lock(), &mut stderr.lock());
    std::process::exit(code);
}
