//! The platform's PNGs: pose, leg lengths and leg forces along each
//! trajectory; the geometry seen from above and from the side.

use super::run::Sampled;
use super::six_legs::SixLegTrace;
use super::Platform;
use crate::report::plots::{line_chart, Series};
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// `{name}_pose.png`, `{name}_legs.png`, `{name}_forces.png`.
pub fn trajectory_plots(name: &str, s: &Sampled, dir: &Path) -> Result<()> {
    let series = |label: &'static str, f: &dyn Fn(usize) -> f64| Series { name: label, points: (0..s.time_s.len()).map(|k| (s.time_s[k], f(k))).collect() };
    let neutral_z = s.pose.first().map_or(0.0, |p| p[2]);
    line_chart(
        &dir.join(format!("{name}_pose_position.png")),
        &format!("{name}: platform position (z about the neutral height {neutral_z:.1} mm)"),
        "time [s]",
        "position [mm]",
        &[series("x", &|k| s.pose[k][0]), series("y", &|k| s.pose[k][1]), series("z − z0", &|k| s.pose[k][2] - neutral_z)],
    )?;
    line_chart(
        &dir.join(format!("{name}_pose_attitude.png")),
        &format!("{name}: platform attitude"),
        "time [s]",
        "angle [deg]",
        &[series("roll", &|k| s.pose[k][3]), series("pitch", &|k| s.pose[k][4]), series("yaw", &|k| s.pose[k][5])],
    )?;
    const LEGS: [&str; 6] = ["leg 1", "leg 2", "leg 3", "leg 4", "leg 5", "leg 6"];
    let legs: Vec<Series> = (0..6).map(|i| series(LEGS[i], &|k| s.lengths_m[k][i] * 1e3)).collect();
    line_chart(&dir.join(format!("{name}_leg_lengths.png")), &format!("{name}: leg lengths (joint to joint)"), "time [s]", "length [mm]", &legs)?;
    let forces: Vec<Series> = (0..6).map(|i| series(LEGS[i], &|k| s.forces_n[k][i])).collect();
    line_chart(
        &dir.join(format!("{name}_leg_forces.png")),
        &format!("{name}: leg axial force (compression +), plate + payload"),
        "time [s]",
        "force [N]",
        &forces,
    )
}

/// Top view (x–y) and side view (x–z) at the neutral pose, legs numbered.
pub fn geometry_png(p: &Platform, path: &Path) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1400, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (left, right) = root.split_horizontally(700);
    let pose = p.neutral();
    let legs = p.inverse(&pose);
    let top: Vec<[f64; 3]> = (0..6).map(|i| (pose.position_m + legs.arms[i]).into()).collect();
    let base: Vec<[f64; 3]> = p.joints.base.iter().map(|b| (*b).into()).collect();
    let r = p.geometry.base_radius_m * 1.15;
    let blue = RGBColor(31, 119, 180);
    let red = RGBColor(214, 39, 40);
    let grey = RGBColor(90, 90, 90);
    for (area, side) in [(&left, false), (&right, true)] {
        let (ylo, yhi) = if side { (-0.05, pose.position_m.z + 0.15) } else { (-r, r) };
        let title = if side { "side view (x–z), neutral pose" } else { "top view (x–y): base ● blue, top ● red" };
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(-r..r, ylo..yhi)
            .map_err(|e| err(&e))?;
        chart.configure_mesh().x_desc("x [m]").y_desc(if side { "z [m]" } else { "y [m]" }).draw().map_err(|e| err(&e))?;
        let v = |q: &[f64; 3]| if side { (q[0], q[2]) } else { (q[0], q[1]) };
        for (pts, color) in [(&base, blue), (&top, red)] {
            let mut ring: Vec<(f64, f64)> = pts.iter().map(v).collect();
            if !side {
                // Hexagon outline in azimuth order.
                let mut order: Vec<usize> = (0..6).collect();
                order.sort_by(|&a, &b| pts[a][1].atan2(pts[a][0]).total_cmp(&pts[b][1].atan2(pts[b][0])));
                ring = order.iter().chain(std::iter::once(&order[0])).map(|&i| v(&pts[i])).collect();
            }
            chart.draw_series(LineSeries::new(ring, color.stroke_width(2))).map_err(|e| err(&e))?;
            chart.draw_series(pts.iter().map(|q| Circle::new(v(q), 5, color.filled()))).map_err(|e| err(&e))?;
        }
        for i in 0..6 {
            let (a, b) = (v(&base[i]), v(&top[i]));
            chart.draw_series(LineSeries::new([a, b], grey.stroke_width(2))).map_err(|e| err(&e))?;
            let mid = (0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1));
            chart
                .draw_series(std::iter::once(Text::new(format!("{}", i + 1), mid, ("sans-serif", 20).into_font().color(&BLACK))))
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// `six_legs_{tag}_pose_error.png` (position and attitude) and
/// `six_legs_{tag}_terminal_error.png` over a six-leg run.
pub fn six_leg_plots(tag: &str, t: &SixLegTrace, dir: &Path) -> Result<()> {
    let titles = [
        format!("six closed-loop legs ({tag}): FK(rods) − FK(references), position"),
        format!("six closed-loop legs ({tag}): FK(rods) − FK(references), attitude"),
        format!("six closed-loop legs ({tag}): rod − position reference"),
    ];
    error_plots(&format!("six_legs_{tag}"), &titles, t, dir)
}

/// `{prefix}_pose_position_error.png`, `{prefix}_pose_attitude_error.png`,
/// `{prefix}_terminal_error.png`, titled `titles` in that order.
pub fn error_plots(prefix: &str, titles: &[String; 3], t: &SixLegTrace, dir: &Path) -> Result<()> {
    let series = |label: &'static str, f: &dyn Fn(usize) -> f64| Series { name: label, points: (0..t.time_s.len()).map(|k| (t.time_s[k], f(k))).collect() };
    line_chart(
        &dir.join(format!("{prefix}_pose_position_error.png")),
        &titles[0],
        "time [s]",
        "position error [mm]",
        &[series("x", &|k| t.pose_error[k][0]), series("y", &|k| t.pose_error[k][1]), series("z", &|k| t.pose_error[k][2])],
    )?;
    line_chart(
        &dir.join(format!("{prefix}_pose_attitude_error.png")),
        &titles[1],
        "time [s]",
        "attitude error [deg]",
        &[series("roll", &|k| t.pose_error[k][3]), series("pitch", &|k| t.pose_error[k][4]), series("yaw", &|k| t.pose_error[k][5])],
    )?;
    const LEGS: [&str; 6] = ["leg 1", "leg 2", "leg 3", "leg 4", "leg 5", "leg 6"];
    let legs: Vec<Series> = (0..6).map(|i| series(LEGS[i], &|k| t.terminal_error_um[k][i])).collect();
    line_chart(&dir.join(format!("{prefix}_terminal_error.png")), &titles[2], "time [s]", "terminal error [µm]", &legs)
}
