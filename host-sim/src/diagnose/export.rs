//! Residual time series per channel (`residual_<channel>.csv`) and their
//! plots with the detected events marked (`residual_events_<channel>.png`).

use super::residual::{Segment, CHANNELS, NCH};
use super::{fit, Diagnosis};
use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use std::path::Path;

/// Writes one CSV per available channel: every sample of both parts with
/// its weight, the nominal residual, the residual after the stack and (on
/// the held-out part) after the disturbance, and the event flag.
pub fn write(d: &Diagnosis, dir: &Path) -> Result<()> {
    let held: Vec<&Segment> = d.heldout();
    for c in 0..NCH {
        if d.segments.iter().all(|s| s.r[c].is_none()) {
            continue;
        }
        let path = dir.join(format!("residual_{}.csv", CHANNELS[c]));
        let mut w =
            csv::Writer::from_path(&path).with_context(|| format!("writing {}", path.display()))?;
        w.write_record([
            "part",
            "run",
            "time_s",
            "log_row",
            "weight",
            "nominal_residual",
            "after_stack",
            "after_disturbance",
            "change_point",
        ])?;
        let mut hk = 0;
        for s in &d.segments {
            let Some(r) = &s.r[c] else {
                hk += usize::from(s.heldout);
                continue;
            };
            let after = d
                .stack
                .as_ref()
                .and_then(|(t, p)| fit::predict(t, p, s, &d.nominal)[c].clone());
            let dist = if s.heldout {
                d.disturbance_heldout.get(hk).and_then(|p| p[c].clone())
            } else {
                None
            };
            let cps: &[usize] = if s.heldout {
                d.change_points.get(hk).map_or(&[], Vec::as_slice)
            } else {
                &[]
            };
            for i in 0..s.len() {
                let a = r[i] - after.as_ref().map_or(0.0, |p| p[i]);
                let base = if d
                    .summary
                    .disturbance
                    .as_ref()
                    .is_some_and(|z| z.base == "nominal")
                {
                    r[i]
                } else {
                    a
                };
                let ad = dist.as_ref().map_or(f64::NAN, |p| base - p[i]);
                w.write_record(&[
                    if s.heldout { "heldout" } else { "train" }.to_string(),
                    s.run.to_string(),
                    format!("{:.6}", s.t[i]),
                    (s.first_row + i + 1).to_string(),
                    format!("{:.4}", s.weight(c, i)),
                    format!("{:.6e}", r[i]),
                    format!("{a:.6e}"),
                    format!("{ad:.6e}"),
                    u8::from(cps.binary_search(&i).is_ok()).to_string(),
                ])?;
            }
            hk += usize::from(s.heldout);
        }
        w.flush()?;
        if let Some(k) = held.iter().position(|s| s.r[c].is_some()) {
            plot(
                d,
                held[k],
                k,
                c,
                &dir.join(format!("residual_events_{}.png", CHANNELS[c])),
            )?;
        }
    }
    Ok(())
}

fn plot(d: &Diagnosis, s: &Segment, k: usize, c: usize, path: &Path) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    let r = s.r[c].as_ref().expect("checked");
    let after = d
        .stack
        .as_ref()
        .and_then(|(t, p)| fit::predict(t, p, s, &d.nominal)[c].clone());
    // The residual the disturbance was fitted on: the stack's remainder, or
    // the nominal residual when that left less on training.
    let on_nominal = d
        .summary
        .disturbance
        .as_ref()
        .is_some_and(|z| z.base == "nominal");
    let after = if on_nominal { None } else { after };
    let rem: Vec<f64> = (0..s.len())
        .map(|i| s.weight(c, i) * (r[i] - after.as_ref().map_or(0.0, |p| p[i])))
        .collect();
    let dist: Option<Vec<f64>> = d.disturbance_heldout.get(k).and_then(|p| p[c].clone());
    let step = (s.len() / 4000).max(1);
    let (lo, hi) = rem
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let pad = 0.05 * (hi - lo).max(1e-30);
    let (t0, t1) = (s.t[0], s.t[s.len() - 1].max(s.t[0] + 1e-6));
    let root = BitMapBackend::new(path, (1200, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut ch = ChartBuilder::on(&root)
        .caption(
            format!(
                "{} {}, held-out run, change points marked",
                CHANNELS[c],
                if on_nominal {
                    "nominal residual"
                } else {
                    "remainder after the stack"
                }
            ),
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))
        .map_err(|e| err(&e))?;
    ch.configure_mesh()
        .x_desc("time [s]")
        .y_desc("weighted residual")
        .draw()
        .map_err(|e| err(&e))?;
    if let Some(cps) = d.change_points.get(k) {
        for &i in cps {
            ch.draw_series(std::iter::once(PathElement::new(
                vec![(s.t[i], lo - pad), (s.t[i], hi + pad)],
                RED.mix(0.5).stroke_width(1),
            )))
            .map_err(|e| err(&e))?;
        }
    }
    ch.draw_series(LineSeries::new(
        (0..s.len()).step_by(step).map(|i| (s.t[i], rem[i])),
        BLUE.stroke_width(1),
    ))
    .map_err(|e| err(&e))?
    .label(if on_nominal {
        "nominal residual"
    } else {
        "remainder after the stack"
    })
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    if let Some(p) = dist {
        ch.draw_series(LineSeries::new(
            (0..s.len())
                .step_by(step)
                .map(|i| (s.t[i], s.weight(c, i) * p[i])),
            GREEN.stroke_width(2),
        ))
        .map_err(|e| err(&e))?
        .label("disturbance (cross-validated)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREEN));
    }
    ch.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
