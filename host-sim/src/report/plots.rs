//! PNG plots a person can look at.

use crate::scenario::{Direction, RunTrace};
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// One named line.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: Vec<(f64, f64)>,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

fn bounds(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for (px, py) in series.iter().flat_map(|s| s.points.iter()).filter(|(a, b)| a.is_finite() && b.is_finite()) {
        x = (x.0.min(*px), x.1.max(*px));
        y = (y.0.min(*py), y.1.max(*py));
    }
    let pad = |(lo, hi): (f64, f64)| {
        if !lo.is_finite() {
            (0.0, 1.0)
        } else if hi - lo < 1e-12 {
            (lo - 1.0, hi + 1.0)
        } else {
            let m = 0.05 * (hi - lo);
            (lo - m, hi + m)
        }
    };
    (pad(x), pad(y))
}

/// Draws lines on shared axes into a PNG.
pub fn line_chart(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<()> {
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let ((x0, x1), (y0, y1)) = bounds(series);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 26))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(s.name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// The four plots of the paper run.
pub fn paper_plots(trace: &RunTrace, dir: &Path) -> Result<()> {
    let t = |i: usize| trace.truth[i].time_s;
    let n = trace.telemetry.len();
    let series = |name, f: &dyn Fn(usize) -> f64| Series { name, points: (0..n).map(|i| (t(i), f(i))).collect() };

    line_chart(
        &dir.join("positions.png"),
        "Reference, motor-side and terminal position",
        "time [s]",
        "position [mm]",
        &[
            series("reference", &|i| f64::from(trace.telemetry[i].position_reference_m) * 1e3),
            series("motor side (L·θm/2π)", &|i| trace.truth[i].motor_side_position_m * 1e3),
            series("terminal (grating scale)", &|i| trace.truth[i].terminal_position_m * 1e3),
        ],
    )?;

    let leg = |d: Direction, name| Series {
        name,
        points: (0..n)
            .filter(|&i| trace.direction[i] == d)
            .map(|i| {
                let r = f64::from(trace.telemetry[i].position_reference_m);
                (r * 1e3, (trace.truth[i].terminal_position_m - r) * 1e3)
            })
            .collect(),
    };
    line_chart(
        &dir.join("terminal_error_vs_position.png"),
        "Terminal error (terminal − reference) along the stroke",
        "reference position [mm]",
        "terminal error [mm]",
        &[leg(Direction::Elongation, "elongation (tilt 90→60→90°)"), leg(Direction::Contraction, "contraction (tilt 90→120→90°)")],
    )?;

    line_chart(
        &dir.join("currents.png"),
        "d-q currents",
        "time [s]",
        "current [A]",
        &[
            series("i_q reference", &|i| f64::from(trace.telemetry[i].current_q_reference_a)),
            series("i_q measured", &|i| f64::from(trace.telemetry[i].current_q_a)),
            series("i_d measured", &|i| f64::from(trace.telemetry[i].current_d_a)),
        ],
    )?;

    line_chart(
        &dir.join("speed.png"),
        "Motor speed",
        "time [s]",
        "speed [rad/s]",
        &[
            series("reference", &|i| f64::from(trace.telemetry[i].speed_reference_rad_s)),
            series("encoder PLL estimate", &|i| f64::from(trace.telemetry[i].speed_rad_s)),
            series("true", &|i| trace.truth[i].motor_speed_rad_s),
        ],
    )?;
    Ok(())
}

/// Terminal error along the stroke without and with compensation.
pub fn compensation_plot(before: &RunTrace, after: &RunTrace, dir: &Path) -> Result<()> {
    let leg = |trace: &RunTrace, d: Direction, name| Series {
        name,
        points: trace
            .telemetry
            .iter()
            .zip(&trace.truth)
            .filter(|(_, x)| x.direction == d)
            .map(|(t, x)| {
                let r = f64::from(t.position_reference_m);
                (r * 1e3, (x.terminal_position_m - r) * 1e3)
            })
            .collect(),
    };
    line_chart(
        &dir.join("compensation.png"),
        "Terminal error before and after observer compensation",
        "reference position [mm]",
        "terminal error [mm]",
        &[
            leg(before, Direction::Elongation, "elongation, uncompensated"),
            leg(before, Direction::Contraction, "contraction, uncompensated"),
            leg(after, Direction::Elongation, "elongation, compensated"),
            leg(after, Direction::Contraction, "contraction, compensated"),
        ],
    )
}
