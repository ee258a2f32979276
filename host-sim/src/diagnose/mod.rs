//! `host-sim diagnose`: where the sim-to-real gap lies, which unmodelled
//! effect causes it and how far it shrinks once the effect is added.
//! See `docs/diagnosis.md`.
//!
//! Pipeline: `log` (schema CSV, defmt telemetry, `cranfield` converter,
//! validation) → `residual` (inverse dynamics against the nominal model:
//! torque, position and voltage channels) → `regions`/`spectrum` (where) →
//! `effects` + `fit` (which, trained on one part and scored on a held-out
//! part) → `report` (markdown, PNG, summary.json).

pub mod cli;
pub mod compare;
pub mod cranfield;
mod defmt_log;
pub mod disturbance;
pub mod effects;
pub mod events;
pub mod export;
pub mod figures;
pub mod generic;
pub mod fit;
pub mod gates;
pub mod log;
mod outcome;
pub mod phase;
pub mod plausible;
pub mod rank;
mod reference;
pub mod refit;
pub mod refit_joint;
pub mod regions;
pub mod replay;
pub mod report;
pub mod residual;
pub mod spectrum;
pub mod split;
pub mod summary;
pub mod verdict;

use anyhow::{bail, Result};
pub use cli::{read_log, run_cli, DiagnoseArgs};
use figures::shrink;
use log::{Log, Severity};
use residual::{Nominal, Segment, CHANNELS, NCH};
use std::collections::BTreeMap;
pub use split::slice_segment;
use split::split_segments;
pub use summary::{ChannelAnalysis, NotRanked, RankEntry, RegionComparison, Summary};

pub use outcome::Diagnosis;

/// Held-out shrink (primary channel, %) below which no effect is named.
pub const MIN_FINDING_PCT: f64 = 5.0;

/// What the diagnosis ranks: the library (default all of it; the
/// open-world suite holds effects out).
#[derive(Clone, Debug)]
pub struct Options {
    pub library: Vec<effects::Effect>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            library: effects::ALL.to_vec(),
        }
    }
}

/// The diagnosis of `log` (and optional held-out log) against `nominal`.
pub fn diagnose(
    log: &Log,
    heldout: Option<&Log>,
    nominal: Nominal,
    tilt_default_deg: f64,
) -> Result<Diagnosis> {
    diagnose_against(log, heldout, None, nominal, tilt_default_deg)
}

/// `diagnose`, comparing region by region with a healthy `reference` log.
pub fn diagnose_against(
    log: &Log,
    heldout: Option<&Log>,
    reference: Option<&Log>,
    nominal: Nominal,
    tilt_default_deg: f64,
) -> Result<Diagnosis> {
    diagnose_with(
        log,
        heldout,
        reference,
        nominal,
        tilt_default_deg,
        &Options::default(),
    )
}

/// Unit of channel `c`'s residual under this nominal.
pub fn channel_unit(nominal: &Nominal, c: usize) -> &'static str {
    match (nominal, c) {
        (Nominal::Physics(_), 0) => "N·m",
        (Nominal::Regression(_), 0) => "A (logged current)",
        (Nominal::Physics(_), 1) => "m (scale − motor side)",
        (Nominal::Regression(_), 1) => "m (tracking error)",
        _ => "V",
    }
}

/// The full diagnosis with options.
pub fn diagnose_with(
    log: &Log,
    heldout: Option<&Log>,
    reference: Option<&Log>,
    nominal: Nominal,
    tilt_default_deg: f64,
    opts: &Options,
) -> Result<Diagnosis> {
    let issues = all_issues(log, heldout);
    if issues.iter().any(|i| i.severity == Severity::Error) {
        let list: Vec<String> = issues
            .iter()
            .filter(|i| i.severity == Severity::Error)
            .map(|i| i.to_string())
            .collect();
        bail!(
            "{}: the log has {} error(s); nothing is dropped silently, fix them first:\n  {}",
            log.source,
            list.len(),
            list.join("\n  ")
        );
    }
    if let Some(r) = reference {
        compare::comparable(log, r, "reference")?;
    }
    if let Some(h) = heldout {
        compare::comparable(log, h, "held-out log")?;
        // The training log is the reference and the held-out log is
        // another run: nothing can be trained on the reference (the nominal
        // was fitted on it), so the held-out log is diagnosed on its own,
        // cut between its events: half of them train, the other half score.
        if reference.is_some_and(|r| gates::same_data(log, r))
            && !gates::same_data(h, log)
        {
            let mut d = diagnose_split(h, None, reference, nominal, tilt_default_deg, opts, Split::AcrossEvents)?;
            d.summary.gates.insert(0, gates::training_is_reference_split(log, h));
            d.summary.verdict.headline = format!(
                "(Training = reference: the held-out log cross-validated across its events.) {}",
                d.summary.verdict.headline
            );
            return Ok(d);
        }
    }
    diagnose_split(log, heldout, reference, nominal, tilt_default_deg, opts, Split::InTime)
}

/// The issues of the log and the held-out log (marked as such).
fn all_issues(log: &Log, heldout: Option<&Log>) -> Vec<log::Issue> {
    let mut issues = log.issues.clone();
    if let Some(h) = heldout {
        issues.extend(h.issues.iter().cloned().map(|mut i| {
            i.message = format!("held-out log: {}", i.message);
            i
        }));
    }
    issues
}

/// How a single log is cut into training and held-out parts.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Split {
    /// Alternate runs, or 60 % / 40 % of one run in time.
    InTime,
    /// Between the residual's events, alternate pieces held out
    /// (`events::split_across_events`), else `InTime`.
    AcrossEvents,
}

#[allow(clippy::too_many_arguments)]
fn diagnose_split(
    log: &Log,
    heldout: Option<&Log>,
    reference: Option<&Log>,
    nominal: Nominal,
    tilt_default_deg: f64,
    opts: &Options,
    split: Split,
) -> Result<Diagnosis> {
    let t0 = std::time::Instant::now();
    let issues = all_issues(log, heldout);
    let mut segments = residual::build_segments(log, &nominal, tilt_default_deg)?;
    if let Some(h) = heldout {
        for s in &mut segments {
            s.heldout = false;
        }
        let mut hs = residual::build_segments(h, &nominal, tilt_default_deg)?;
        for s in &mut hs {
            s.heldout = true;
        }
        segments.extend(hs);
    } else if split == Split::AcrossEvents {
        segments = match events::split_across_events(
            &segments,
            disturbance::THRESHOLDS[0],
            [0.0, disturbance::DETECT_WEIGHT_FLOOR],
        ) {
            Some(s) => s,
            None => split_segments(segments),
        };
    } else {
        segments = split_segments(segments);
    }
    let reference_gates = reference::judge_regression(&nominal, reference, &mut segments)?;
    let train: Vec<&Segment> = segments.iter().filter(|s| !s.heldout).collect();
    let held: Vec<&Segment> = segments.iter().filter(|s| s.heldout).collect();
    if train.is_empty() || held.is_empty() {
        bail!(
            "{}: too little data for a training and a held-out part: {}",
            log.source,
            log.too_short()
        );
    }
    let dt = train[0].t.get(1).map_or(1e-3, |t1| t1 - train[0].t[0]);
    let w = fit::channel_weights(&train);
    let gap_before_h = fit::gap(&held, None, &w);
    let fit_before_h = fit::fit_pct(&held, None);
    let fit_before_t = fit::fit_pct(&train, None);

    let rk = rank::rank(&opts.library, &train, &held, &nominal, &w);
    let primary = rk.primary;
    let mut gates = gates::identity(log, heldout, reference);
    gates.extend(gates::fit_gates(
        &train,
        &fit_before_t,
        &fit_before_h,
        &nominal,
        &rk.not_ranked,
        &|c| channel_unit(&nominal, c),
    ));
    gates.extend(reference_gates);
    let blocked = gates
        .iter()
        .any(|g| g.kind.ends_with("_is_training") || g.kind.ends_with("_is_reference"));
    let top = if blocked { None } else { rk.top.clone() };
    let (stack_terms, stack_params) = if blocked {
        (Vec::new(), Vec::new())
    } else {
        (rk.stack_terms.clone(), rk.stack_params.clone())
    };
    let stack_gap = if blocked { gap_before_h } else { rk.stack_gap };
    let stack = (!stack_terms.is_empty()).then(|| (stack_terms.clone(), stack_params.clone()));
    let mut wp = [0.0; NCH];
    wp[primary] = 1.0;
    let gap_primary_h = fit::gap(&held, None, &wp);
    let stack_pred = |segs: &[&Segment]| -> Vec<fit::ChannelPred> {
        segs.iter()
            .map(|s| match &stack {
                Some((t, p)) => fit::predict(t, p, s, &nominal),
                None => std::array::from_fn(|c| s.r[c].as_ref().map(|r| vec![0.0; r.len()])),
            })
            .collect()
    };
    let pred_h = stack_pred(&held);
    let stack_fit = fit::fit_pct(&held, Some(&pred_h))[primary].unwrap_or(f64::NAN);
    let stack_primary_shrink = if stack.is_some() {
        shrink(gap_primary_h, fit::gap(&held, Some(&pred_h), &wp))
    } else {
        0.0
    };
    let mut sp = BTreeMap::new();
    let mut k = 0;
    for t in &stack_terms {
        for n in t.effect.params_for(&nominal) {
            sp.insert(format!("{}.{}", t.effect.name(), n), stack_params[k]);
            k += 1;
        }
    }

    // The remainder after the stack: disturbance and time structure.
    let remainder = |segs: &[&Segment], pred: &[fit::ChannelPred]| -> events::Remainder {
        segs.iter()
            .zip(pred)
            .map(|(s, p)| {
                std::array::from_fn(|c| {
                    let r = s.r[c].as_ref()?;
                    Some(r.iter().zip(p[c].as_ref()?).map(|(a, b)| a - b).collect())
                })
            })
            .collect()
    };
    let rem_h = remainder(&held, &pred_h);
    let pred_t = stack_pred(&train);
    let rem_t = remainder(&train, &pred_t);
    // Whether the stack accounts for a poor nominal fit (verdict).
    let stack_train_fit = if stack.is_some() {
        fit::fit_pct(&train, Some(&pred_t))
    } else {
        fit_before_t
    };
    // The disturbance on the stack's remainder or on the nominal residual
    // (a stack fitted on training may carry a wrong constant into the
    // held-out part), whichever leaves less on training.
    let nominal_rem = |segs: &[&Segment]| -> events::Remainder {
        segs.iter()
            .map(|s| std::array::from_fn(|c| s.r[c].clone()))
            .collect()
    };
    let (rem_hn, rem_tn) = (nominal_rem(&held), nominal_rem(&train));
    let on_stack = disturbance::fit(
        &train,
        &rem_t,
        &held,
        &rem_h,
        &nominal,
        &w,
        primary,
        gap_before_h,
        gap_primary_h,
    );
    let on_nominal = disturbance::fit(
        &train,
        &rem_tn,
        &held,
        &rem_hn,
        &nominal,
        &w,
        primary,
        gap_before_h,
        gap_primary_h,
    );
    let use_nominal = stack.is_some() && on_nominal.0.train_gap_after < on_stack.0.train_gap_after;
    let (mut dist, dist_pred, cps) = if use_nominal { on_nominal } else { on_stack };
    dist.base = if use_nominal || stack.is_none() {
        "nominal".into()
    } else {
        "stack".into()
    };
    dist.over_stack_points = dist.primary_shrink_pct - stack_primary_shrink.max(0.0);
    let rem_base = if use_nominal { &rem_hn } else { &rem_h };
    // A lock to the moves is judged on the steps the reference does not
    // repeat at the same phase of its own moves (`phase`).
    if let (Some(r), true) = (reference, dist.locked_to_signals) {
        gates.extend(phase::recheck_lock(&mut dist, &held, rem_base, &cps, r, &nominal, tilt_default_deg)?);
    }
    let cps_fixed = events::detect(&held, &rem_h, events::STEP_SIGMA);
    let steps_pct = |c: usize| {
        let mut wc = [0.0; NCH];
        wc[c] = 1.0;
        shrink(
            disturbance::gap(&held, rem_base, None, &wc),
            disturbance::gap(&held, rem_base, Some(&dist_pred), &wc),
        )
    };
    let avail: Vec<usize> = (0..NCH).filter(|c| fit_before_h[*c].is_some()).collect();
    let kinematic = events::kinematic_periods(match &nominal {
        Nominal::Physics(p) => Some(p.pole_pairs.round() as u32),
        Nominal::Regression(_) => None,
    });
    let time_structure: Vec<events::TimeStructure> = avail
        .iter()
        .map(|&c| {
            // Events at the fixed, conservative threshold (the disturbance's
            // may be lower: more change points can help its levels).
            let cps_c = if c == residual::VOLTAGE {
                vec![Vec::new(); held.len()]
            } else {
                cps_fixed.clone()
            };
            // Steps that follow the logged signals are motion-locked model
            // error, not steps of their own.
            let steps = if c == residual::VOLTAGE || dist.locked_to_signals {
                0.0
            } else {
                steps_pct(c)
            };
            events::analyse(&held, &rem_h, c, &cps_c, steps, &kinematic)
        })
        .collect();

    // Where the gap lies, per channel (all data, nominal residual).
    let all: Vec<&Segment> = segments.iter().collect();
    let channels: Vec<ChannelAnalysis> = avail
        .iter()
        .map(|&c| {
            let (f, p) = spectrum::welch(&all, c);
            let rms = (all
                .iter()
                .filter_map(|s| s.r[c].as_ref())
                .flat_map(|r| r.iter().map(|x| x * x))
                .sum::<f64>()
                / all.iter().map(|s| s.len()).sum::<usize>().max(1) as f64)
                .sqrt();
            ChannelAnalysis {
                channel: CHANNELS[c].into(),
                fit_train_pct: fit_before_t[c].unwrap_or(f64::NAN),
                fit_heldout_pct: fit_before_h[c].unwrap_or(f64::NAN),
                residual_rms: rms,
                regions: regions::split(&all, c),
                bands: spectrum::bands(&f, &p),
                windows: spectrum::top_windows(&all, c, (0.5f64).max(20.0 * dt), 5),
                correlation: spectrum::correlation(&all, c, 25),
            }
        })
        .collect();
    let reference_comparison = match reference {
        Some(rl) => reference::compare_regions(&all, rl, &nominal, tilt_default_deg, &avail)?,
        None => Vec::new(),
    };
    let ranking: Vec<RankEntry> = rk.ranked.iter().map(|r| r.0.clone()).collect();
    let top_entry = ranking.first().filter(|_| top.is_some()).cloned();
    let stack_names: Vec<String> = stack_terms
        .iter()
        .map(|t| t.effect.name().to_string())
        .collect();
    let stack_weighted = if stack.is_some() {
        shrink(gap_before_h, stack_gap).max(0.0)
    } else {
        0.0
    };
    let top_name = top.as_ref().map(|t| t.0[0].effect.name().to_string());
    // Implausible fits that survive the stack (refitted on its remainder).
    let implausible: Vec<String> = rk
        .not_ranked
        .iter()
        .filter(|n| n.status == "implausible")
        .map(|n| n.effect.clone())
        .collect();
    let implausible_after_stack = stack
        .as_ref()
        .filter(|_| !implausible.is_empty())
        .map(|(t, p)| plausible::still_implausible(&implausible, (t, p), &train, &nominal, &w));
    // The rig-mismatch explanation: the nominal's own parameters re-fitted
    // on training; and the disturbance on what the re-fit leaves.
    let (refit, refit_dist) = if blocked {
        (None, None)
    } else {
        let (rf, pred_rh) = refit::fit(&train, &held, &nominal, &w, primary);
        let pred_rt: Vec<fit::ChannelPred> = train
            .iter()
            .map(|s| refit::predict_on(&rf, s, &nominal))
            .collect();
        let (rem_rh, rem_rt) = (remainder(&held, &pred_rh), remainder(&train, &pred_rt));
        let (mut d, _, _) = disturbance::fit(
            &train,
            &rem_rt,
            &held,
            &rem_rh,
            &nominal,
            &w,
            primary,
            gap_before_h,
            gap_primary_h,
        );
        d.base = "refit".into();
        d.over_stack_points = d.primary_shrink_pct - rf.primary_shrink_pct.max(0.0);
        (Some(rf), Some(d))
    };
    // Generic structures on what the stack leaves (torque and position).
    let generic = if blocked {
        Vec::new()
    } else {
        generic::fit_all(&train, &rem_t, &held, &rem_h, &nominal)
    };
    let verdict = verdict::decide(&verdict::Inputs {
        generic: generic::named(&generic),
        refit: refit.as_ref(),
        refit_dist: refit_dist.as_ref(),
        implausible_after_stack,
        gates: &gates,
        ranking: &ranking,
        top: top_name.as_deref(),
        stack: &stack_names,
        stack_weighted,
        stack_primary: stack_primary_shrink.max(0.0),
        stack_torque: if stack.is_some() && avail.contains(&residual::TORQUE) {
            let mut wt = [0.0; NCH];
            wt[residual::TORQUE] = 1.0;
            shrink(fit::gap(&held, None, &wt), fit::gap(&held, Some(&pred_h), &wt)).max(0.0)
        } else {
            0.0
        },
        stack_train_fit,
        dist: Some(&dist),
        structure: time_structure
            .iter()
            .find(|t| t.channel == CHANNELS[primary]),
        top_halves: if blocked { None } else { rk.top_halves },
        back_emf_heldout: match &nominal {
            Nominal::Physics(p) => gates::back_emf_scale(&held, p),
            Nominal::Regression(_) => None,
        },
    });
    let summary = Summary {
        source: log.source.clone(),
        heldout_source: heldout.map(|h| h.source.clone()),
        nominal: match &nominal {
            Nominal::Physics(_) => "rig physics ([plant] of the rig TOML)".into(),
            Nominal::Regression(r) => format!(
                "regression fitted on the reference log: {}",
                serde_json::to_string(r)?
            ),
        },
        samples: log.len() + heldout.map_or(0, Log::len),
        train_segments: train.len(),
        heldout_segments: held.len(),
        edge_samples_per_segment_end: residual::half_width(dt),
        ruled_out: log.ruled_out(),
        issues,
        channels,
        reference_comparison,
        primary_channel: CHANNELS[primary].into(),
        top_effect: top_name,
        heldout_fit_before: fit_before_h[primary].unwrap_or(f64::NAN),
        heldout_fit_after: top_entry
            .as_ref()
            .map_or(fit_before_h[primary].unwrap_or(f64::NAN), |e| {
                e.heldout_fit_after
            }),
        gap_shrink_pct: top_entry
            .as_ref()
            .map_or(0.0, |e| e.primary_shrink_pct.max(0.0)),
        gap_shrink_weighted_pct: top_entry
            .as_ref()
            .map_or(0.0, |e| e.weighted_shrink_pct.max(0.0)),
        ranking,
        not_ranked: rk.not_ranked,
        indistinguishable: rk.indist,
        stack: stack_names,
        stack_params: sp,
        heldout_fit_after_stack: stack_fit,
        gap_shrink_stack_pct: stack_primary_shrink.max(0.0),
        gap_shrink_stack_weighted_pct: stack_weighted,
        top_halves_primary_shrink_pct: rk.top_halves,
        figure_definitions: figures::definitions(CHANNELS[primary]),
        gates,
        time_structure,
        disturbance: Some(dist),
        refit,
        refit_disturbance: refit_dist,
        generic,
        verdict,
        wall_s: t0.elapsed().as_secs_f64(),
        replay: None,
    };
    drop(train);
    drop(held);
    drop(all);
    Ok(Diagnosis {
        summary,
        nominal,
        segments,
        primary,
        top,
        stack,
        disturbance_heldout: dist_pred,
        change_points: cps,
    })
}
