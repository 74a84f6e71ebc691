//! What every PNG chart of armctl shares: the image size, one colour per joint, the embedded font,
//! y ranges with padding, plotters' errors as `anyhow` errors, and the PNG file itself.
//!
//! Text is drawn with plotters' `ab_glyph` renderer and the DejaVu Sans font embedded by the
//! `dejavu` crate, so no system fonts are needed. Charts are drawn into an RGB buffer and encoded
//! with the `png` crate: plotters' own file output would bring the whole `image` crate, a tenth of
//! armctl's dependency build, for one format.

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::BufWriter;
use std::path::Path;
use std::sync::Once;

/// Draws a chart of `size` pixels with `draw` (the embedded font registered first), then writes it
/// to `path` as an 8-bit RGB PNG. The file is created only once the chart is drawn, so a chart that
/// fails leaves no file behind.
pub fn write_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    register_font();
    let (width, height) = size;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(&root)?;
        root.present().map_err(error)?;
    }
    let file = std::fs::File::create(path)?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&rgb)?;
    writer.finish()?;
    Ok(())
}

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
fn register_font() {
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
