//! What every PNG chart of armctl shares: the image size, one colour per joint, the embedded font,
//! y ranges with padding, and plotters' errors as `anyhow` errors.
//!
//! Text is drawn with plotters' `ab_glyph` renderer and the DejaVu Sans font embedded by the
//! `dejavu` crate, so no system fonts are needed.

use anyhow::anyhow;
use plotters::prelude::*;
use std::sync::Once;

/// Image size in pixels.
pub const SIZE: (u32, u32) = (1400, 1100);

/// Distinct colours for up to 12 joints (Tableau 10 plus two).
const COLOURS: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 128),
    RGBColor(128, 128, 0),
];

/// The colour of joint `joint` (they repeat after 12).
pub fn colour(joint: usize) -> RGBColor {
    COLOURS[joint % COLOURS.len()]
}

/// Registers the embedded DejaVu Sans as "sans-serif" (once per process).
pub fn register_font() {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        // The embedded font is valid TrueType; should it ever fail to load, text is just missing.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// A y range covering `values` with 5 % padding (never empty).
pub fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = if hi - lo > 1e-12 { (hi - lo) * 0.05 } else { 1.0f64.max(hi.abs() * 0.1) };
    (lo - pad, hi + pad)
}

/// A plotters error as an `anyhow` error (plotters' errors borrow the backend).
pub fn error(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow!("{e}")
}
