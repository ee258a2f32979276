//! `tune bench --family DIR`: the tuning benchmark on every rig of a family
//! (identification, proposal and check all on that rig), a row per rig, every
//! loop result in one table, the worst case over the family.

use super::cli::{bench, BenchCase};
use crate::rigs::family::{write_family_report, RigRow, Worst};
use crate::rigs::FamilyRig;
use anyhow::Result;
use rayon::prelude::*;
use std::path::Path;

/// The figure's own numbers from one rig's bench summary: (accepted
/// loops, passing loops, largest |bandwidth error| %, signed; largest
/// overshoot excess over its tolerance, points; refused cases).
fn rig_figures(s: &serde_json::Value) -> (usize, usize, Option<f64>, Option<f64>, usize) {
    let table = s["table"].as_array().cloned().unwrap_or_default();
    let pass = table.iter().filter(|r| r["pass"].as_bool() == Some(true)).count();
    let bw = table
        .iter()
        .filter_map(|r| r["bandwidth_error_pct"].as_f64())
        .max_by(|a, b| a.abs().total_cmp(&b.abs()));
    let os = table
        .iter()
        .filter_map(|r| {
            let (a, g, tol) = (r["asked_overshoot_pct"].as_f64()?, r["achieved_overshoot_pct"].as_f64()?, r["overshoot_tolerance_pct"].as_f64()?);
            Some((g - a).abs() - tol)
        })
        .max_by(f64::total_cmp);
    let refused = s["refused"].as_array().map_or(0, Vec::len);
    (table.len(), pass, bw, os, refused)
}

/// The bench (`cases`, else the built-in ones) on each rig of `family`,
/// rigs in parallel; each rig's bench in `out/<rig>/`, the family's in `out`.
pub fn bench_family(family: &[FamilyRig], family_dir: &Path, cases: Option<&Path>, out: &Path) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    // A rig whose bench stops (its identification's tests latch a fault,
    // say) is a failed row naming why; the other rigs still report.
    let done: Vec<(String, Result<serde_json::Value>)> =
        family.par_iter().map(|r| (r.name.clone(), bench(&r.rig, &out.join(&r.name), cases))).collect();
    let mut rows = Vec::new();
    let mut table = Vec::new();
    let mut refused = Vec::new();
    for (name, s) in &done {
        let s = match s {
            Ok(s) => s,
            Err(e) => {
                rows.push(RigRow {
                    rig: name.clone(),
                    passed: false,
                    verdict: format!("the bench stopped: {e:#}"),
                    figures: ["loops_accepted", "loops_passed", "cases_refused", "bandwidth_error_worst_pct", "bandwidth_error_worst_abs_pct", "overshoot_excess_worst_pct"]
                        .iter()
                        .map(|n| ((*n).to_string(), None))
                        .collect(),
                });
                continue;
            }
        };
        let (loops, pass, bw, os, n_refused) = rig_figures(s);
        let mut why = vec![];
        if loops == 0 {
            why.push("no ask accepted".to_string());
        }
        for r in s["check_failed"].as_array().into_iter().flatten() {
            why.push(format!("{}: the check failed: {}", r["case"].as_str().unwrap_or("?"), r["check_failed"].as_str().unwrap_or("?")));
        }
        for r in s["table"].as_array().into_iter().flatten().filter(|r| r["pass"].as_bool() != Some(true)) {
            why.push(format!(
                "{} {}: {:.2} Hz for {} Hz ({:+.0} %), overshoot {:.2} % for {:.1} %",
                r["case"].as_str().unwrap_or("?"),
                r["loop"].as_str().unwrap_or("?"),
                r["achieved_bandwidth_hz"].as_f64().unwrap_or(f64::NAN),
                r["asked_bandwidth_hz"],
                r["bandwidth_error_pct"].as_f64().unwrap_or(f64::NAN),
                r["achieved_overshoot_pct"].as_f64().unwrap_or(f64::NAN),
                r["asked_overshoot_pct"].as_f64().unwrap_or(f64::NAN),
            ));
        }
        for r in s["table"].as_array().into_iter().flatten() {
            let mut r = r.clone();
            r["rig"] = serde_json::json!(name);
            if let Some(o) = r.as_object_mut() {
                o.remove("frf_vs_model");
            }
            table.push(r);
        }
        for r in s["refused"].as_array().into_iter().flatten() {
            refused.push(serde_json::json!({ "rig": name, "case": r["case"], "refused": r["refused"] }));
        }
        rows.push(RigRow {
            rig: name.clone(),
            passed: why.is_empty(),
            verdict: if why.is_empty() { "ok".into() } else { why.join("; ") },
            figures: vec![
                ("loops_accepted".into(), Some(loops as f64)),
                ("loops_passed".into(), Some(pass as f64)),
                ("cases_refused".into(), Some(n_refused as f64)),
                ("bandwidth_error_worst_pct".into(), bw),
                ("bandwidth_error_worst_abs_pct".into(), bw.map(f64::abs)),
                ("overshoot_excess_worst_pct".into(), os),
            ],
        });
    }
    let accepted = table.len();
    let passed = table.iter().filter(|r| r["pass"].as_bool() == Some(true)).count();
    write_family_report(
        "tune bench",
        family_dir,
        &rows,
        &[("bandwidth_error_worst_abs_pct", Worst::Max), ("overshoot_excess_worst_pct", Worst::Max), ("loops_passed", Worst::Min), ("cases_refused", Worst::Max)],
        serde_json::json!({
            "figure": "every accepted loop result within 20 % of its ask on every rig (bandwidth ±20 %; overshoot ±20 % of asks ≥ 5 %, ±1 point below); asks a rig cannot carry refused with the reason",
            "loops_accepted": accepted,
            "loops_passed": passed,
            "all_accepted_pass": accepted > 0 && passed == accepted,
            "cases": match cases { Some(p) => serde_json::json!(p.display().to_string()), None => serde_json::to_value(super::cli::bench_cases().into_iter().map(|c: BenchCase| c.name).collect::<Vec<_>>())? },
            "table": table,
            "refused": refused,
        }),
        t0.elapsed().as_secs_f64(),
        out,
    )
}
