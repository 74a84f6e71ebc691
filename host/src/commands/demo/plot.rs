//! The PNG plot of `armctl demo`: planned against measured joint curves (left column, one panel per
//! joint, then the gripper's opening, goal and load with the time it held something shaded) and
//! the tool path seen from above (x-y) and from the side (x-z) with equal-aspect axes
//! (right column). Phase starts are vertical lines across the joint panels; targets are crosses.
//!
//! [`write_demo_png`] checks the whole trace before it creates the file, so a bad trace gives a
//! one-line error and writes nothing. It does not panic on any input: values are required finite
//! and within ±[`LIMIT`], which keeps every axis range finite and wider than f64 rounding.

use crate::support::plot::{colour, error, write_png};
use anyhow::{bail, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// What the demo recorded, sampled once per control tick.
pub struct DemoTrace {
    /// Title (the arm's name).
    pub arm: String,
    /// One name per joint.
    pub joint_names: Vec<String>,
    /// Sample times (s), not decreasing.
    pub time: Vec<f64>,
    /// `[sample][joint]` (rad): the setpoints the controller sent.
    pub planned: Vec<Vec<f64>>,
    /// `[sample][joint]` (rad): positions read back from the servos.
    pub measured: Vec<Vec<f64>>,
    /// Tool position (m), forward kinematics of `planned`, per sample.
    pub tool_planned: Vec<[f64; 3]>,
    /// Tool position (m), forward kinematics of `measured`, per sample.
    pub tool_measured: Vec<[f64; 3]>,
    /// The Cartesian targets and keyframe points (m), drawn as crosses.
    pub targets: Vec<[f64; 3]>,
    /// `(start time, label)` of each phase, drawn as vertical lines.
    pub phases: Vec<(f64, String)>,
    /// The gripper, per sample (`None`: the arm has none, no panel).
    pub gripper: Option<GripperTrace>,
}

/// The gripper as the firmware reported it, once per sample.
pub struct GripperTrace {
    /// The goal opening, percent (0 closed to 100 open).
    pub goal: Vec<f64>,
    /// The measured opening, percent.
    pub opening: Vec<f64>,
    /// The load, percent of the servo's full effort.
    pub load: Vec<f64>,
    /// Whether the firmware said it holds something.
    pub holding: Vec<bool>,
}

/// Image width in pixels; the height grows with the number of joints beyond six.
pub const WIDTH: u32 = 1600;
/// The smallest image height in pixels.
pub const MIN_HEIGHT: u32 = 1000;
/// The most joints one image shows (each gets a panel at least [`PANEL_HEIGHT`] tall).
pub const MAX_JOINTS: usize = 32;
/// The largest magnitude accepted for any value (s, rad or m).
pub const LIMIT: f64 = 1e9;

/// Half the smallest span of a joint axis (rad) and of a tool-path axis (m), for still data.
const MIN_HALF_RAD: f64 = 0.05;
const MIN_HALF_M: f64 = 0.01;
const PANEL_HEIGHT: u32 = 150;
const TITLE_HEIGHT: u32 = 50;
/// Width of the joint column; the tool views get the rest.
const JOINT_COLUMN: u32 = 900;
const MARGIN: u32 = 10;
const X_LABELS: u32 = 40;
const Y_LABELS: u32 = 80;
const PHASE: RGBColor = RGBColor(150, 150, 150);
const TARGET: RGBColor = RGBColor(200, 0, 0);
const TOOL_PLANNED: RGBColor = RGBColor(40, 40, 40);
const TOOL_MEASURED: RGBColor = RGBColor(31, 119, 180);
const GRIPPER: RGBColor = RGBColor(90, 60, 160);
const LOAD: RGBColor = RGBColor(230, 120, 20);
const HELD: RGBColor = RGBColor(40, 170, 70);

/// Draws `trace` to the PNG file `path`.
pub fn write_demo_png(path: &Path, trace: &DemoTrace) -> Result<()> {
    check(trace)?;
    let panels = (trace.joint_names.len() + usize::from(trace.gripper.is_some())) as u32;
    let height = MIN_HEIGHT.max(TITLE_HEIGHT + panels * PANEL_HEIGHT);
    write_png(path, (WIDTH, height), |root| draw(root, trace))
        .map_err(|e| anyhow::anyhow!("cannot write plot {}: {e}", path.display()))
}

/// The checks that make drawing safe, each failing with a one-line message.
fn check(t: &DemoTrace) -> Result<()> {
    let n = t.time.len();
    let joints = t.joint_names.len();
    if n == 0 {
        bail!("empty trace: no samples");
    }
    if joints == 0 {
        bail!("empty trace: no joint names");
    }
    if joints > MAX_JOINTS {
        bail!("{joints} joints, at most {MAX_JOINTS} can be plotted");
    }
    for (name, len) in [
        ("planned", t.planned.len()),
        ("measured", t.measured.len()),
        ("tool_planned", t.tool_planned.len()),
        ("tool_measured", t.tool_measured.len()),
    ] {
        if len != n {
            bail!("length mismatch: {n} time samples but {len} {name} samples");
        }
    }
    for (name, rows) in [("planned", &t.planned), ("measured", &t.measured)] {
        if let Some((i, row)) = rows.iter().enumerate().find(|(_, row)| row.len() != joints) {
            bail!("length mismatch: {name}[{i}] has {} values for {joints} joints", row.len());
        }
    }
    let bad = |x: f64| !(x.is_finite() && x.abs() <= LIMIT);
    let describe = |x: f64| if x.is_finite() { format!("{x} (beyond ±{LIMIT})") } else { x.to_string() };
    if let Some((i, &x)) = t.time.iter().enumerate().find(|(_, &x)| bad(x)) {
        bail!("time[{i}] is {}", describe(x));
    }
    if let Some(i) = t.time.windows(2).position(|w| w[1] < w[0]) {
        bail!("time decreases from sample {i} to {}", i + 1);
    }
    for (name, rows) in [("planned", &t.planned), ("measured", &t.measured)] {
        for (i, row) in rows.iter().enumerate() {
            if let Some((j, &x)) = row.iter().enumerate().find(|(_, &x)| bad(x)) {
                bail!("{name}[{i}][{j}] is {}", describe(x));
            }
        }
    }
    for (name, points) in
        [("tool_planned", &t.tool_planned), ("tool_measured", &t.tool_measured), ("targets", &t.targets)]
    {
        for (i, p) in points.iter().enumerate() {
            if let Some((k, &x)) = p.iter().enumerate().find(|(_, &x)| bad(x)) {
                bail!("{name}[{i}][{k}] is {}", describe(x));
            }
        }
    }
    if let Some((i, (x, _))) = t.phases.iter().enumerate().find(|(_, (x, _))| bad(*x)) {
        bail!("phase {i} starts at {}", describe(*x));
    }
    if let Some(g) = &t.gripper {
        for (name, values) in [("gripper goal", &g.goal), ("gripper opening", &g.opening), ("gripper load", &g.load)] {
            if values.len() != n {
                bail!("length mismatch: {n} time samples but {} {name} samples", values.len());
            }
            if let Some((i, &x)) = values.iter().enumerate().find(|(_, &x)| bad(x)) {
                bail!("{name}[{i}] is {}", describe(x));
            }
        }
        if g.holding.len() != n {
            bail!("length mismatch: {n} time samples but {} gripper holding samples", g.holding.len());
        }
    }
    Ok(())
}

/// The range of `values` with 5 % padding, at least `2 * min_half` wide and wide enough to stay well
/// above f64 rounding at the values' magnitude (the values are finite and within ±[`LIMIT`]).
fn padded(values: impl Iterator<Item = f64>, min_half: f64) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
    if lo > hi {
        return (-min_half, min_half);
    }
    let half = (0.55 * (hi - lo)).max(min_half).max(1e-6 * lo.abs().max(hi.abs()));
    let mid = 0.5 * (lo + hi);
    (mid - half, mid + half)
}

fn draw(root: &DrawingArea<BitMapBackend, Shift>, t: &DemoTrace) -> Result<()> {
    root.fill(&WHITE).map_err(error)?;
    let title = format!("{}: planned (dashed) against measured (solid)", t.arm);
    let root = root.titled(&title, ("sans-serif", 26)).map_err(error)?;
    let (left, right) = root.split_horizontally(JOINT_COLUMN);
    draw_joints(&left, t)?;
    let (top, side) = right.split_vertically(right.dim_in_pixel().1 / 2);
    draw_view(&top, t, "top view", ("x (m)", 0), ("y (m)", 1))?;
    draw_view(&side, t, "side view", ("x (m)", 0), ("z (m)", 2))?;
    Ok(())
}

fn draw_joints(area: &DrawingArea<BitMapBackend, Shift>, t: &DemoTrace) -> Result<()> {
    let (t0, t1) = match (t.time.first(), t.time.last()) {
        (Some(&a), Some(&b)) if b - a >= 1e-6 * a.abs().max(1.0) => (a, b),
        (Some(&a), _) => padded(std::iter::once(a), 0.5),
        _ => (0.0, 1.0),
    };
    let panels = area.split_evenly((t.joint_names.len() + usize::from(t.gripper.is_some()), 1));
    let last = panels.len().saturating_sub(1);
    if let (Some(g), Some(panel)) = (&t.gripper, panels.last()) {
        draw_gripper(panel, t, g, (t0, t1))?;
    }
    for (j, (panel, name)) in panels.iter().zip(&t.joint_names).enumerate() {
        let c = colour(j);
        let (lo, hi) = padded(t.planned.iter().chain(&t.measured).map(|q| q[j]), MIN_HALF_RAD);
        let mut chart = ChartBuilder::on(panel)
            .margin(MARGIN)
            .x_label_area_size(if j == last { X_LABELS } else { X_LABELS / 2 + 4 })
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(error)?;
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(format!("{name} (rad)"))
            .y_labels(5)
            .light_line_style(RGBColor(235, 235, 235))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15));
        if j == last {
            mesh.x_desc("t (s)");
        }
        mesh.draw().map_err(error)?;
        for (start, label) in t.phases.iter().filter(|(s, _)| (t0..=t1).contains(s)) {
            chart
                .draw_series(std::iter::once(PathElement::new(vec![(*start, lo), (*start, hi)], PHASE.stroke_width(2))))
                .map_err(error)?;
            if j == 0 {
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!(" {label}"),
                        (*start, hi),
                        ("sans-serif", 15).into_font().color(&BLACK).pos(Pos::new(HPos::Left, VPos::Top)),
                    )))
                    .map_err(error)?;
            }
        }
        let worst = t.planned.iter().zip(&t.measured).map(|(p, m)| (p[j] - m[j]).abs()).fold(0.0, f64::max);
        chart
            .draw_series(LineSeries::new(
                t.time.iter().zip(&t.measured).map(|(&s, q)| (s, q[j])),
                c.mix(0.55).stroke_width(3),
            ))
            .map_err(error)?
            .label(format!("measured (max error {worst:.3} rad)"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.mix(0.55).stroke_width(3)));
        chart
            .draw_series(DashedLineSeries::new(
                t.time.iter().zip(&t.planned).map(|(&s, q)| (s, q[j])),
                6,
                4,
                c.stroke_width(2),
            ))
            .map_err(error)?
            .label("planned")
            .legend(move |(x, y)| DashedPathElement::new(vec![(x, y), (x + 24, y)], 6, 4, c.stroke_width(2)));
        if let ([s], [p], [m]) = (&t.time[..], &t.planned[..], &t.measured[..]) {
            // One sample draws no line; show it as dots.
            chart
                .draw_series([Circle::new((*s, m[j]), 5, c.mix(0.55).filled()), Circle::new((*s, p[j]), 3, c.filled())])
                .map_err(error)?;
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    Ok(())
}

/// The gripper's panel, the bottom one of the joint column: its opening (solid) and goal (dashed)
/// in percent, its load in percent of full effort, and the time it held something shaded.
fn draw_gripper(
    panel: &DrawingArea<BitMapBackend, Shift>,
    t: &DemoTrace,
    g: &GripperTrace,
    (t0, t1): (f64, f64),
) -> Result<()> {
    let (lo, hi) = padded(g.goal.iter().chain(&g.opening).chain(&g.load).copied().chain([0.0, 100.0]), 1.0);
    let mut chart = ChartBuilder::on(panel)
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(error)?;
    chart
        .configure_mesh()
        .y_desc("gripper (%)")
        .x_desc("t (s)")
        .y_labels(5)
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(error)?;
    // Each run of samples that held something, shaded from its first to its last sample.
    let mut spans = Vec::new();
    let mut from = None;
    for (i, &held) in g.holding.iter().enumerate() {
        match (held, from) {
            (true, None) => from = Some(i),
            (false, Some(a)) => {
                spans.push((t.time[a], t.time[i - 1]));
                from = None;
            }
            _ => {}
        }
    }
    if let (Some(a), Some(&end)) = (from, t.time.last()) {
        spans.push((t.time[a], end));
    }
    chart
        .draw_series(spans.iter().map(|&(a, b)| Rectangle::new([(a, lo), (b, hi)], HELD.mix(0.25).filled())))
        .map_err(error)?
        .label("holding something")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 24, y + 5)], HELD.mix(0.25).filled()));
    for (start, _) in t.phases.iter().filter(|(s, _)| (t0..=t1).contains(s)) {
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(*start, lo), (*start, hi)], PHASE.stroke_width(2))))
            .map_err(error)?;
    }
    let series = |values: &[f64]| t.time.iter().copied().zip(values.iter().copied()).collect::<Vec<_>>();
    chart
        .draw_series(LineSeries::new(series(&g.opening), GRIPPER.mix(0.55).stroke_width(3)))
        .map_err(error)?
        .label("opening")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], GRIPPER.mix(0.55).stroke_width(3)));
    chart
        .draw_series(DashedLineSeries::new(series(&g.goal), 6, 4, GRIPPER.stroke_width(2)))
        .map_err(error)?
        .label("goal")
        .legend(|(x, y)| DashedPathElement::new(vec![(x, y), (x + 24, y)], 6, 4, GRIPPER.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(series(&g.load), LOAD.stroke_width(2)))
        .map_err(error)?
        .label("load (% of full effort)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], LOAD.stroke_width(2)));
    legend(&mut chart, SeriesLabelPosition::UpperLeft)
}

/// Ranges for an equal-aspect chart of `plot` pixels covering both given ranges.
fn equal_aspect(x: (f64, f64), y: (f64, f64), plot: (u32, u32)) -> ((f64, f64), (f64, f64)) {
    let (w, h) = (f64::from(plot.0.max(1)), f64::from(plot.1.max(1)));
    let per_pixel = ((x.1 - x.0) / w).max((y.1 - y.0) / h);
    let centre = |(lo, hi): (f64, f64), pixels: f64| {
        let mid = 0.5 * (lo + hi);
        (mid - 0.5 * per_pixel * pixels, mid + 0.5 * per_pixel * pixels)
    };
    (centre(x, w), centre(y, h))
}

fn draw_view(
    area: &DrawingArea<BitMapBackend, Shift>,
    t: &DemoTrace,
    caption: &str,
    (x_desc, a): (&str, usize),
    (y_desc, b): (&str, usize),
) -> Result<()> {
    let area = area.titled(caption, ("sans-serif", 20)).map_err(error)?;
    let (w, h) = area.dim_in_pixel();
    let plot = (w.saturating_sub(2 * MARGIN + Y_LABELS), h.saturating_sub(2 * MARGIN + X_LABELS));
    let points = || t.tool_planned.iter().chain(&t.tool_measured).chain(&t.targets);
    let (x, y) =
        equal_aspect(padded(points().map(|p| p[a]), MIN_HALF_M), padded(points().map(|p| p[b]), MIN_HALF_M), plot);
    let mut chart = ChartBuilder::on(&area)
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(error)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(error)?;
    chart
        .draw_series(LineSeries::new(
            t.tool_measured.iter().map(|p| (p[a], p[b])),
            TOOL_MEASURED.mix(0.6).stroke_width(3),
        ))
        .map_err(error)?
        .label("measured")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], TOOL_MEASURED.mix(0.6).stroke_width(3)));
    chart
        .draw_series(DashedLineSeries::new(
            t.tool_planned.iter().map(|p| (p[a], p[b])),
            6,
            4,
            TOOL_PLANNED.stroke_width(1),
        ))
        .map_err(error)?
        .label("planned")
        .legend(|(x, y)| DashedPathElement::new(vec![(x, y), (x + 24, y)], 6, 4, TOOL_PLANNED.stroke_width(1)));
    chart
        .draw_series(t.targets.iter().map(|p| Cross::new((p[a], p[b]), 6, TARGET.stroke_width(2))))
        .map_err(error)?
        .label("targets")
        .legend(|(x, y)| Cross::new((x + 12, y), 6, TARGET.stroke_width(2)));
    if let Some(p) = t.tool_measured.first() {
        chart
            .draw_series(std::iter::once(Circle::new((p[a], p[b]), 5, TOOL_MEASURED.filled())))
            .map_err(error)?
            .label("start")
            .legend(|(x, y)| Circle::new((x + 12, y), 5, TOOL_MEASURED.filled()));
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)
}

/// A chart of the plot: seconds, radians, percent or metres on both axes.
type Chart<'a, 'b> = ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The series' legend box at `position`.
fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, position: SeriesLabelPosition) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(error)
}
