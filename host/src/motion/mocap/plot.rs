//! The retarget's PNG: the scaled human hand's path against the arm's tool path (forward
//! kinematics of the keyframes), seen from above (x-y) and from the side (x-z), in the arm's base
//! frame; keyframes IK could not reach are marked on the hand's path. The tool is drawn wide
//! under the hand, so that where it follows, the hand's line runs inside it.

use super::retarget::Retargeted;
use crate::support::plot::{colour, error, range, write_png};
use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Draws `r` to the PNG file `path`.
pub fn draw(path: &Path, r: &Retargeted, title: &str) -> Result<()> {
    write_png(path, (1600, 800), |root| panels(root, r, title))
}

fn panels(root: &DrawingArea<BitMapBackend<'_>, Shift>, r: &Retargeted, title: &str) -> Result<()> {
    root.fill(&WHITE).map_err(error)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(error)?;
    let halves = root.split_evenly((1, 2));
    for (panel, (name, a, b)) in halves.iter().zip([("from above", 1usize, "y (m)"), ("from the side", 2, "z (m)")]) {
        let all = || r.targets.iter().chain(&r.tool);
        // The same scale on both axes, so the paths keep their shape.
        let (x0, x1) = range(all().map(|p| p[0]));
        let (y0, y1) = range(all().map(|p| p[a]));
        let half = (x1 - x0).max(y1 - y0) / 2.0;
        let (xc, yc) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        let mut chart = ChartBuilder::on(panel)
            .caption(name, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(xc - half..xc + half, yc - half..yc + half)
            .map_err(error)?;
        chart
            .configure_mesh()
            .x_desc("x (m)")
            .y_desc(b)
            .light_line_style(RGBColor(235, 235, 235))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(error)?;
        let hand = colour(0);
        let tool = colour(1);
        chart
            .draw_series(LineSeries::new(r.tool.iter().map(|p| (p[0], p[a])), tool.stroke_width(4)))
            .map_err(error)?
            .label("arm tool (FK of the keyframes)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], tool.stroke_width(3)));
        chart
            .draw_series(LineSeries::new(r.targets.iter().map(|p| (p[0], p[a])), hand.stroke_width(2)))
            .map_err(error)?
            .label("human hand, scaled (target)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], hand.stroke_width(3)));
        let missed = colour(3);
        chart
            .draw_series(
                r.targets
                    .iter()
                    .zip(&r.reachable)
                    .filter(|(_, ok)| !**ok)
                    .map(|(p, _)| Cross::new((p[0], p[a]), 4, missed.stroke_width(1))),
            )
            .map_err(error)?
            .label("target out of reach")
            .legend(move |(x, y)| Cross::new((x + 10, y), 4, missed.stroke_width(1)));
        chart
            .draw_series(std::iter::once(Circle::new((0.0, 0.0), 6, BLACK.filled())))
            .map_err(error)?
            .label("arm base")
            .legend(|(x, y)| Circle::new((x + 10, y), 5, BLACK.filled()));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(error)?;
    }
    Ok(())
}
