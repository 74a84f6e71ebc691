//! PNG charts of a sampled trajectory: position, velocity and acceleration panels stacked, one
//! colour per joint, keyframes marked (dots on the position panel, grey lines across all three).

use super::trajectory::{Row, Sampled};
use crate::support::plot::{colour, error, range, write_png, SIZE};
use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// A panel's name and the per-joint values it plots from a row.
type Quantity = (&'static str, fn(&Row) -> &Vec<f64>);

/// Draws `s` to the PNG file `path`.
pub fn draw(path: &Path, s: &Sampled, title: &str) -> Result<()> {
    write_png(path, SIZE, |root| panels(root, s, title))
}

fn panels(root: &DrawingArea<BitMapBackend<'_>, Shift>, s: &Sampled, title: &str) -> Result<()> {
    root.fill(&WHITE).map_err(error)?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(error)?;
    let panels = root.split_evenly((3, 1));
    let t0 = s.rows.first().map_or(0.0, |r| r.t);
    let t1 = s.rows.last().map_or(1.0, |r| r.t).max(t0 + 1e-9);
    let quantities: [Quantity; 3] =
        [("position (rad or m)", |r| &r.q), ("velocity (/s)", |r| &r.v), ("acceleration (/s²)", |r| &r.a)];
    for (panel, (name, get)) in panels.iter().zip(quantities) {
        let (lo, hi) = range(s.rows.iter().flat_map(|r| get(r).iter().copied()));
        let mut chart = ChartBuilder::on(panel)
            .caption(name, ("sans-serif", 20))
            .margin(8)
            .x_label_area_size(42)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(error)?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .light_line_style(RGBColor(235, 235, 235))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(error)?;
        // Keyframe times across the panel, under the curves.
        for &t in &s.keyframe_times {
            chart
                .draw_series(std::iter::once(PathElement::new(vec![(t, lo), (t, hi)], RGBColor(170, 170, 170))))
                .map_err(error)?;
        }
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(t0, 0.0), (t1, 0.0)], BLACK.mix(0.4))))
            .map_err(error)?;
        for joint in 0..s.joints {
            let c = colour(joint);
            let series = chart
                .draw_series(LineSeries::new(s.rows.iter().map(|r| (r.t, get(r)[joint])), c.stroke_width(2)))
                .map_err(error)?;
            if name.starts_with("position") {
                series
                    .label(format!("q{}", joint + 1))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
                chart
                    .draw_series(
                        s.keyframe_times
                            .iter()
                            .zip(&s.keyframe_positions)
                            .map(|(&t, q)| Circle::new((t, q[joint]), 5, c.filled())),
                    )
                    .map_err(error)?;
            }
        }
        if name.starts_with("position") {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(error)?;
        }
    }
    Ok(())
}
