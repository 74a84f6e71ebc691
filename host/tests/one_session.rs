//! The link's session is the one place in the product that builds a request to the firmware:
//! `HostMessage::` appears in host/src only under link/ (the client's handshake and polls, the
//! arm's configuration, the session, and `link::flood`: the requests of a host that floods the
//! link, which `bench loop-pass` writes without waiting). A drive command, the demo, a rig,
//! teleoperation or the view that built its own message would bypass the session's waits and
//! checks.

use std::path::{Path, PathBuf};

fn sources(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, found);
        } else if path.extension().is_some_and(|e| e == "rs") {
            found.push(path);
        }
    }
}

/// The files under `src` (relative paths) whose code names `HostMessage::`, outside comments.
fn builders(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    sources(src, &mut files);
    let mut found: Vec<String> = files
        .iter()
        .filter(|f| {
            std::fs::read_to_string(f)
                .unwrap()
                .lines()
                .any(|line| !line.trim_start().starts_with("//") && line.contains("HostMessage::"))
        })
        .map(|f| f.strip_prefix(src).unwrap().to_string_lossy().replace('\\', "/"))
        .collect();
    found.sort();
    found
}

#[test]
fn only_the_link_builds_requests() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = builders(&src);
    assert!(found.iter().any(|f| f == "link/session.rs"), "the reader found the session: {found:?}");
    let outside: Vec<&String> = found.iter().filter(|f| !f.starts_with("link/")).collect();
    assert!(outside.is_empty(), "HostMessage built outside link/ (use link::session::Session): {outside:?}");
}

#[test]
fn the_reader_finds_a_builder_where_there_is_one() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("view")).unwrap();
    std::fs::write(dir.path().join("view/loop.rs"), "fn f() { send(&HostMessage::Stop); }\n").unwrap();
    std::fs::write(dir.path().join("quiet.rs"), "// HostMessage::Stop in a comment\n").unwrap();
    assert_eq!(builders(dir.path()), ["view/loop.rs"]);
}
