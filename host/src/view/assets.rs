//! The page's static files, embedded at build time (see build.rs), with their content types.

include!(concat!(env!("OUT_DIR"), "/view_assets.rs"));

/// The file at `path` under assets/ and its content type.
pub fn get(path: &str) -> Option<(&'static [u8], &'static str)> {
    let (_, bytes) = ASSETS.iter().find(|(name, _)| *name == path)?;
    Some((bytes, content_type(path)))
}

/// The content type of a file by its extension.
pub fn content_type(path: &str) -> &'static str {
    match path.rsplit_once('.').map(|(_, ext)| ext) {
        Some("html") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("json") => "application/json",
        Some("png") => "image/png",
        Some("stl") | Some("STL") => "model/stl",
        _ => "text/plain; charset=utf-8",
    }
}
