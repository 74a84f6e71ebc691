//! Embeds the browser view's static files (src/view/assets: the page and the vendored three.js) in
//! the binary, so `armctl view` works offline and from any folder: one `include_bytes!` per file,
//! listed in `$OUT_DIR/view_assets.rs`.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else {
            out.push(path);
        }
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/view/assets");
    println!("cargo:rerun-if-changed={}", root.display());
    let mut found = Vec::new();
    files(&root, &mut found);
    found.sort();
    let mut table = String::from(
        "/// The view's files: path under assets/, and contents.\npub static ASSETS: &[(&str, &[u8])] = &[\n",
    );
    for path in &found {
        let name = path.strip_prefix(&root).expect("under the root").to_string_lossy().replace('\\', "/");
        table.push_str(&format!("    ({name:?}, include_bytes!({:?})),\n", path.display().to_string()));
    }
    table.push_str("];\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("view_assets.rs");
    std::fs::write(out, table).expect("cannot write view_assets.rs");
}
