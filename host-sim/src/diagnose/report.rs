//! The diagnosis report: report.md, summary.json and PNG plots (residual
//! over time, residual by region heat map, residual spectrum, before/after
//! overlay on the held-out part).

use super::figures::{PRIMARY, REMAINING, WEIGHTED, WEIGHTED_ACTING};
use super::residual::{Segment, CHANNELS};
use super::{export, fit, regions, spectrum, Diagnosis};
use crate::report::plots::{line_chart, Series};
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

pub fn write(d: &Diagnosis, dir: &Path) -> Result<()> {
    crate::report::write_summary(&d.summary, dir)?;
    plots(d, dir)?;
    export::write(d, dir)?;
    std::fs::write(dir.join("report.md"), markdown(d))?;
    Ok(())
}

fn plots(d: &Diagnosis, dir: &Path) -> Result<()> {
    let c = d.primary;
    let held = d.heldout();
    let all: Vec<&Segment> = d.segments.iter().collect();
    let unit = ["N·m (or A)", "m", "V"][c];
    // Residual over time and overlay on the first held-out segment.
    if let Some(s) = held.iter().find(|s| s.r[c].is_some()) {
        let r = s.r[c].as_ref().expect("checked");
        let y = s.y[c].as_ref().expect("with r");
        let step = (s.len() / 4000).max(1);
        let mut series = vec![Series {
            name: "nominal residual",
            points: (0..s.len()).step_by(step).map(|i| (s.t[i], r[i])).collect(),
        }];
        let mut overlay = vec![
            Series {
                name: "measured",
                points: (0..s.len()).step_by(step).map(|i| (s.t[i], y[i])).collect(),
            },
            Series {
                name: "nominal model",
                points: (0..s.len())
                    .step_by(step)
                    .map(|i| (s.t[i], y[i] - r[i]))
                    .collect(),
            },
        ];
        for (name, tp) in [("after top effect", &d.top), ("after stack", &d.stack)] {
            if let Some((t, p)) = tp {
                let pred = fit::predict(t, p, s, &d.nominal);
                if let Some(pc) = &pred[c] {
                    series.push(Series {
                        name,
                        points: (0..s.len())
                            .step_by(step)
                            .map(|i| (s.t[i], r[i] - pc[i]))
                            .collect(),
                    });
                    overlay.push(Series {
                        name: if name == "after top effect" {
                            "nominal + top effect"
                        } else {
                            "nominal + stack"
                        },
                        points: (0..s.len())
                            .step_by(step)
                            .map(|i| (s.t[i], y[i] - r[i] + pc[i]))
                            .collect(),
                    });
                }
            }
        }
        line_chart(
            &dir.join("residual_time.png"),
            &format!("{} residual, held-out run", CHANNELS[c]),
            "time [s]",
            unit,
            &series,
        )?;
        line_chart(
            &dir.join("overlay.png"),
            &format!("{}: measured vs models, held-out run", CHANNELS[c]),
            "time [s]",
            unit,
            &overlay,
        )?;
    }
    // Spectrum before/after (log10 PSD).
    let (f, p) = spectrum::welch(&all, c);
    let mut series = vec![Series {
        name: "nominal residual",
        points: f
            .iter()
            .zip(&p)
            .skip(1)
            .map(|(f, p)| (*f, p.max(1e-30).log10()))
            .collect(),
    }];
    if let Some((t, pr)) = &d.stack {
        let segs_after: Vec<Segment> = all
            .iter()
            .map(|s| {
                let pred = fit::predict(t, pr, s, &d.nominal);
                let mut s2 = (*s).clone();
                if let (Some(r), Some(pc)) = (s2.r[c].as_mut(), &pred[c]) {
                    r.iter_mut().zip(pc).for_each(|(a, b)| *a -= b);
                }
                s2
            })
            .collect();
        let refs: Vec<&Segment> = segs_after.iter().collect();
        let (f2, p2) = spectrum::welch(&refs, c);
        series.push(Series {
            name: "after stack",
            points: f2
                .iter()
                .zip(&p2)
                .skip(1)
                .map(|(f, p)| (*f, p.max(1e-30).log10()))
                .collect(),
        });
    }
    line_chart(
        &dir.join("spectrum.png"),
        &format!("{} residual spectrum (Welch)", CHANNELS[c]),
        "frequency [Hz]",
        "log10 PSD",
        &series,
    )?;
    heat_map_png(
        &regions::heat_map(&all, c),
        &dir.join("heatmap.png"),
        CHANNELS[c],
    )?;
    if let Some(rp) = &d.summary.replay {
        for (name, tr) in &rp.traces {
            let step = (tr.len() / 4000).max(1);
            line_chart(
                &dir.join(format!("replay_{name}.png")),
                &format!("closed-loop replay: {name}"),
                "time [s]",
                name,
                &[
                    Series {
                        name: "logged",
                        points: tr.iter().step_by(step).map(|p| (p.0, p.1)).collect(),
                    },
                    Series {
                        name: "replayed (nominal plant + core)",
                        points: tr.iter().step_by(step).map(|p| (p.0, p.2)).collect(),
                    },
                ],
            )?;
        }
    }
    Ok(())
}

fn heat_map_png(h: &regions::HeatMap, path: &Path, ch: &str) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("plotting {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (v0, v1) = (h.speed_edges[0], *h.speed_edges.last().expect("edges"));
    let (x0, x1) = (h.stroke_edges[0], *h.stroke_edges.last().expect("edges"));
    let x1 = if x1 > x0 { x1 } else { x0 + 1e-3 };
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("RMS {ch} residual by speed × stroke position"),
            ("sans-serif", 24),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(v0..v1, x0..x1)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("rod speed [m/s]")
        .y_desc("stroke position [m]")
        .draw()
        .map_err(|e| err(&e))?;
    let max = h
        .cells
        .iter()
        .flatten()
        .map(|c| c.0)
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-300);
    for (a, row) in h.cells.iter().enumerate() {
        for (b, (rms, n)) in row.iter().enumerate() {
            if *n == 0 {
                continue;
            }
            let u = (rms / max).clamp(0.0, 1.0);
            let col = RGBColor(
                (255.0 * u) as u8,
                (60.0 + 100.0 * (1.0 - u)) as u8,
                (255.0 * (1.0 - u)) as u8,
            );
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [
                        (h.speed_edges[a], h.stroke_edges[b]),
                        (h.speed_edges[a + 1], h.stroke_edges[b + 1]),
                    ],
                    col.filled(),
                )))
                .map_err(|e| err(&e))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{rms:.2e}"),
                    (
                        h.speed_edges[a] + 0.1 * (h.speed_edges[1] - h.speed_edges[0]),
                        0.5 * (h.stroke_edges[b] + h.stroke_edges[b + 1]),
                    ),
                    ("sans-serif", 14).into_font().color(&BLACK),
                )))
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

fn markdown(d: &Diagnosis) -> String {
    let s = &d.summary;
    let mut m = String::new();
    let _ = writeln!(m, "# Sim-to-real gap diagnosis\n");
    let _ = writeln!(
        m,
        "- log: `{}`{}",
        s.source,
        s.heldout_source
            .as_ref()
            .map_or(String::new(), |h| format!(", held-out log `{h}`"))
    );
    let _ = writeln!(m, "- nominal: {}", s.nominal);
    let _ = writeln!(
        m,
        "- {} samples; {} training and {} held-out segments; {} samples at each segment end used for differentiation only",
        s.samples, s.train_segments, s.heldout_segments, s.edge_samples_per_segment_end
    );
    let _ = writeln!(m, "- wall time {:.2} s\n", s.wall_s);
    if !s.gates.is_empty() {
        let _ = writeln!(m, "## Warnings (before any finding)\n");
        for g in &s.gates {
            let _ = writeln!(
                m,
                "- **{}**{}: {}",
                g.kind,
                g.channel
                    .as_ref()
                    .map_or(String::new(), |c| format!(" ({c})")),
                g.message
            );
        }
        let _ = writeln!(m);
    }
    let _ = writeln!(m, "## Verdict\n");
    let _ = writeln!(m, "{}\n", s.verdict.headline);
    let _ = writeln!(
        m,
        "Best-ranked library effect: {} — {PRIMARY} ({}) {:.1} %, {WEIGHTED} {:.1} % (fit of the {} channel {:.1} % → {:.1} %); greedy stack {:?}: {PRIMARY} {:.1} %, {WEIGHTED} {:.1} % (fit {:.1} %). {REMAINING}: {:.1} %.\n",
        s.top_effect.as_deref().unwrap_or("none"),
        s.primary_channel,
        s.gap_shrink_pct,
        s.gap_shrink_weighted_pct,
        s.primary_channel,
        s.heldout_fit_before,
        s.heldout_fit_after,
        s.stack,
        s.gap_shrink_stack_pct,
        s.gap_shrink_stack_weighted_pct,
        s.heldout_fit_after_stack,
        s.verdict.remaining_gap_pct
    );
    for (label, def) in &s.figure_definitions {
        let _ = writeln!(m, "- *{label}*: {def}");
    }
    let _ = writeln!(m);
    if !s.indistinguishable.is_empty() {
        let _ = writeln!(
            m,
            "Effects the data cannot tell apart: {}\n",
            s.indistinguishable
                .iter()
                .map(|(a, b)| format!("{a} ≈ {b}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if let Some(dz) = &s.disturbance {
        let _ = writeln!(m, "## Disturbance effect (estimated as a signal)\n");
        let _ = writeln!(
            m,
            "{}: levels `{}` on {:?} and threshold {:.0} σ chosen on training (cross-validated training shrink {:.1} %); on the held-out part {} change points (mean interval {:.2} s), levels median {:.3e}, max {:.3e} {}. With the stack: {PRIMARY} {:.1} %, {WEIGHTED} {:.1} % (at most {:.1} % with {:?} explained entirely), {WEIGHTED_ACTING} ({:?}) {:.1} % ({:+.1} points over the stack; {:.1} % of the stack's remainder). Levels cross-validated over alternate blocks of each interval.\n",
            dz.model,
            dz.levels,
            dz.channels,
            dz.threshold_sigma,
            dz.train_cv_shrink_pct,
            dz.heldout_change_points,
            dz.mean_interval_s,
            dz.median_abs_level,
            dz.max_abs_level,
            dz.level_unit,
            dz.primary_shrink_pct,
            dz.weighted_shrink_pct,
            dz.weighted_ceiling_pct,
            dz.acting_channels,
            dz.acting_channels,
            dz.acting_weighted_shrink_pct,
            dz.over_stack_points,
            dz.remainder_explained_pct
        );
        let _ = writeln!(
            m,
            "Its change points lie within {:.0} ms of a logged move, reference-acceleration or load change in {:.0} % of cases against {:.0} % by chance: {}\n",
            1e3 * super::disturbance::LOCK_TOL_S,
            dz.signal_locked_pct,
            dz.chance_pct,
            if dz.locked_to_signals {
                "locked to the logged signals — a model error of the nominal, not an unmeasured force (not counted in the verdict)"
            } else {
                "not locked to the logged signals (events with their own clock, as an unmeasured force has)"
            }
        );
        if !dz.change_times_s.is_empty() {
            let _ = writeln!(
                m,
                "Change points (run, s): {}\n",
                dz.change_times_s
                    .iter()
                    .map(|(r, t)| format!("({r}, {t:.3})"))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        if !dz.events.is_empty() {
            let _ = writeln!(m, "{}", super::disturbance::pulses::table(&dz.events, &dz.level_unit));
        }
    }
    if !s.time_structure.is_empty() {
        let _ = writeln!(
            m,
            "## Time structure of the held-out remainder (after the stack)\n"
        );
        let _ = writeln!(m, "| channel | character | change points | energy after them % | time share % | energy after move starts/stops % | time share % | steps explain % | dominant period s (ACF) | Ljung–Box p | slow share % | max input |ρ| |\n|---|---|---|---|---|---|---|---|---|---|---|---|");
        for t in &s.time_structure {
            let best = t
                .input_correlation
                .iter()
                .cloned()
                .fold((String::new(), 0.0), |a, b| if b.1 > a.1 { b } else { a });
            let _ = writeln!(
                m,
                "| {} | **{}** | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.2e} | {:.1} | {:.2} ({}) |",
                t.channel,
                t.character,
                t.events_detected,
                t.energy_after_events_pct,
                t.time_after_events_pct,
                t.energy_after_motion_pct,
                t.time_after_motion_pct,
                t.steps_explained_pct,
                t.dominant_period_s.map_or("–".into(), |p| format!("{p:.3} ({:.2})", t.acf_at_period)),
                t.ljung_box_p,
                t.slow_share_pct,
                best.1,
                best.0
            );
        }
        let _ = writeln!(m, "\nWindows: {:.0} ms before to {:.0} ms after each event. Event-locked averages, event lists and the residual series: summary.json, residual_<channel>.csv, residual_events_<channel>.png.\n", 1e3 * super::events::EVENT_BEFORE_S, 1e3 * super::events::EVENT_AFTER_S);
    }
    let _ = writeln!(
        m,
        "## Ranking (fitted on training, scored on held-out; shares of the gap)\n"
    );
    let _ = writeln!(
        m,
        "| # | effect | {WEIGHTED} % | {PRIMARY} ({}) % | fit before % | fit after % | parameters | indistinguishable from |",
        s.primary_channel
    );
    let _ = writeln!(m, "|---|---|---|---|---|---|---|---|");
    for (k, r) in s.ranking.iter().enumerate() {
        let params: Vec<String> = r
            .params
            .iter()
            .map(|(n, v)| format!("{n} = {v:.4e}"))
            .collect();
        let _ = writeln!(
            m,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} |",
            k + 1,
            r.effect,
            r.weighted_shrink_pct,
            r.primary_shrink_pct,
            r.heldout_fit_before,
            r.heldout_fit_after,
            params.join(", "),
            r.indistinguishable_from.join(", ")
        );
    }
    if !s.not_ranked.is_empty() {
        let _ = writeln!(m, "\nNot ranked:\n");
        for n in &s.not_ranked {
            let _ = writeln!(m, "- {} — **{}**: {}", n.effect, n.status, n.reason);
        }
    }
    let _ = writeln!(m, "\n## Where the gap lies\n");
    for c in &s.channels {
        let _ = writeln!(
            m,
            "### {} channel\n\nFit % (nominal): training {:.1}, held-out {:.1}; RMS residual {:.4e}.\n",
            c.channel, c.fit_train_pct, c.fit_heldout_pct, c.residual_rms
        );
        let _ = writeln!(
            m,
            "| split | region | samples | RMS | mean | energy % |\n|---|---|---|---|---|---|"
        );
        for r in &c.regions {
            let _ = writeln!(
                m,
                "| {} | {} | {} | {:.3e} | {:.3e} | {:.1} |",
                r.split, r.region, r.samples, r.rms, r.mean, r.energy_pct
            );
        }
        let _ = writeln!(
            m,
            "\nFrequency bands (energy %): {}\n",
            c.bands
                .iter()
                .map(|b| format!("{:.1}–{:.1} Hz: {:.1}", b.lo_hz, b.hi_hz, b.energy_pct))
                .collect::<Vec<_>>()
                .join("; ")
        );
        let _ = writeln!(m, "Windows with the most residual energy:\n");
        for w in &c.windows {
            let _ = writeln!(
                m,
                "- run {} t = {:.2}–{:.2} s (log row {}): {:.1} % of the energy, RMS {:.3e}",
                w.run, w.t_start_s, w.t_end_s, w.log_row, w.energy_pct, w.rms
            );
        }
        let k = &c.correlation;
        let _ = writeln!(
            m,
            "\nWhiteness: lag-1 autocorrelation {:.2}, {:.0} % of lags 1–25 outside the 95 % band ({}). Residual–input cross-correlation: max |ρ| {:.2} at lag {} samples (negative lags max {:.2}, positive {:.2}; closed-loop data correlate at negative lags through feedback).\n",
            k.autocorr_lag1,
            k.autocorr_outside_pct,
            if k.white { "white" } else { "not white: structure left to explain" },
            k.xcorr_max.abs(),
            k.xcorr_lag,
            k.xcorr_negative_lag_max,
            k.xcorr_positive_lag_max
        );
    }
    if let Some(r) = &s.replay {
        let _ = writeln!(m, "## Closed-loop replay\n");
        let _ = writeln!(
            m,
            "Nominal plant + the firmware's control core driven by the logged reference ({} moves re-planned by the core, the rest fed as position shift, saturated on {:.1} % of samples) and load: {:.1} s simulated in {:.1} s{}.\n",
            r.moves,
            r.shift_saturated_pct,
            r.simulated_s,
            r.wall_s,
            r.aborted.as_ref().map_or(String::new(), |a| format!("; stopped: {a}"))
        );
        let _ = writeln!(
            m,
            "| signal | Fit % | RMS difference | samples |\n|---|---|---|---|"
        );
        for sc in &r.signals {
            let _ = writeln!(
                m,
                "| {} | {:.1} | {:.3e} | {} |",
                sc.signal, sc.fit_pct, sc.rms_difference, sc.samples
            );
        }
        let _ = writeln!(m, "\nPlots: replay_<signal>.png.\n");
    }
    if !s.reference_comparison.is_empty() {
        let _ = writeln!(m, "## Where this log differs from the healthy reference\n");
        let _ =
            writeln!(m, "RMS residual against the same nominal, region by region (ratio > 1: worse than healthy).\n");
        let _ = writeln!(m, "| channel | split | region | RMS log | RMS reference | ratio | mean log | mean reference |\n|---|---|---|---|---|---|---|---|");
        for r in &s.reference_comparison {
            let _ = writeln!(
                m,
                "| {} | {} | {} | {:.3e} | {:.3e} | {:.2} | {:.3e} | {:.3e} |",
                r.channel,
                r.split,
                r.region,
                r.rms_log,
                r.rms_reference,
                r.ratio,
                r.mean_log,
                r.mean_reference
            );
        }
        let _ = writeln!(m);
    }
    if !s.ruled_out.is_empty() {
        let _ = writeln!(m, "## Analyses ruled out by missing columns\n");
        for r in &s.ruled_out {
            let _ = writeln!(m, "- {r}");
        }
    }
    if !s.issues.is_empty() {
        let _ = writeln!(m, "\n## Input notes\n");
        for i in s.issues.iter().take(50) {
            let _ = writeln!(m, "- {i}");
        }
    }
    let _ = writeln!(m, "\nPlots: residual_time.png, heatmap.png, spectrum.png, overlay.png, residual_events_<channel>.png; series: residual_<channel>.csv.");
    m
}
