//! Large gaps against a sound reference (physics rig file, or a healthy
//! reference log): unmeasured forces from 0.2× to 5× the RMS of the force
//! the motion needs — events on their own clock, events synchronised with
//! the motion, single long steps — a wrong rig file alone and with force
//! events, and training = reference with a held-out log carrying events.
//! Scored: the verdict's kind, the force's level and event times against
//! the truth, the primary-channel shrink, and the wrong parameter among
//! the re-fitted ones.
//!
//! CI runs `gap_smoke` (3 cases). The benchmark writes
//! `target/diagnose_suite/gap/{suite.json,report.md}`:
//! `cargo test --release --test diagnose_gap -- --ignored --nocapture`
//! (`DIAGNOSE_GAP_SET=tuning|seen|holdout` runs one set only;
//! `DIAGNOSE_GAP_SEED=N` runs the set drawn from seed N alone;
//! `DIAGNOSE_GAP_ONLY=force|wrong_rig|wrong_rig_force|training_is_reference|quiet`
//! runs one kind of truth only).

mod diagnose_support;

use diagnose_support::gap::{force_logs, move_starts, nominal_pair, quiet_nominal, wrong_rig, GapLogs, Timing, WrongParam};
use diagnose_support::seed_base_env;
use diagnose_support::truth::nominal_rig;
use host_sim::diagnose::disturbance::DisturbanceFit;
use host_sim::diagnose::figures::shrink;
use host_sim::diagnose::fit;
use host_sim::diagnose::residual::{build_segments, fit_regression, Nominal, Physics, CHANNELS, NCH, TORQUE};
use host_sim::diagnose::{diagnose_with, Diagnosis, Options};
use std::fmt::Write as _;

#[derive(Clone, Copy, Debug)]
enum Spec {
    /// Force events of a timing, seed, size factor (× the motion's force RMS).
    Force(Timing, u64, f64),
    WrongRig(WrongParam, u64),
    WrongRigForce(WrongParam, u64),
    TrainingIsReference(u64),
    /// No force and the right rig file (quiet experiment): a false alarm
    /// if anything is named.
    Quiet(u64),
}

#[derive(Debug, Default, serde::Serialize)]
struct Outcome {
    case: String,
    family: &'static str,
    seed: u64,
    verdict: String,
    headline: String,
    explained_pct: f64,
    /// Force truths: size factor, true level (N), the estimated event
    /// level (median over events, N) and its error, the median timing
    /// error of the event edges (ms), the disturbance's primary shrink.
    factor: Option<f64>,
    level_true_n: Option<f64>,
    level_est_n: Option<f64>,
    level_err_pct: Option<f64>,
    timing_err_ms: Option<f64>,
    edges_within_5ms_pct: Option<f64>,
    /// The fitted events (onset, offset, level from the baseline, each
    /// with its 1-sigma) beside the true ones (start s, end s, level N),
    /// and the share of true edges within 2 sigma of the nearest fitted
    /// edge (whether the stated uncertainties hold).
    events: Vec<host_sim::diagnose::disturbance::Event>,
    true_events: Vec<[f64; 3]>,
    edges_within_2sd_pct: Option<f64>,
    disturbance_primary_pct: Option<f64>,
    /// The most any estimate of the force could remove of the primary
    /// channel's held-out gap: the same held-out experiment run without
    /// the events leaves the nominal's own floor (weighted alike), %.
    ceiling_primary_pct: Option<f64>,
    /// The floor (the held-out experiment without the events, nominal
    /// residual, primary channel) and the share of its energy that is
    /// sensor noise: 1 − (the floor with exact sensors / the floor)², %.
    floor_primary: Option<f64>,
    floor_noise_share_pct: Option<f64>,
    /// How much of the floor a fit on a clean reference removes: the tool
    /// on the training and held-out experiments without the events, its
    /// library stack and its re-fit of the rig's parameters, held-out
    /// primary-channel shrink (of that diagnosis's primary channel), %.
    floor_stack_pct: Option<f64>,
    floor_refit_pct: Option<f64>,
    /// The primary-channel shrink of the gap above the floor: the RMS
    /// shrink of `sqrt(gap² − floor²)`, the part of the gap the events add
    /// (force and floor are independent, so their energies add), %.
    above_floor_shrink_pct: Option<f64>,
    train_fit_torque_pct: Option<f64>,
    /// Wrong-rig truths: the parameter and its factor, the re-fitted
    /// parameters beyond tolerance, whether the wrong one is among them.
    wrong_param: Option<String>,
    wrong_factor: Option<f64>,
    refitted: Vec<String>,
    wrong_param_refitted: Option<bool>,
    refit_primary_pct: Option<f64>,
    refit_halves_pct: Option<(f64, f64)>,
    refit_stable: Option<bool>,
    disturbance_locked: Option<bool>,
    /// The disturbance as scored: its shrink per channel, change points,
    /// and the jumps of its level at them (level unit).
    primary: String,
    dist_by_channel: std::collections::BTreeMap<String, f64>,
    dist_change_points: Option<usize>,
    dist_jumps: Vec<f64>,
    gates: Vec<String>,
    wall_s: f64,
}

/// The estimated level of each true event (level at its middle minus the
/// level just before it) and the timing error of each true edge against
/// the nearest change point, from the disturbance's intervals.
fn score_events(d: &DisturbanceFit, events: &[[f64; 3]]) -> (Option<f64>, Option<f64>, Option<f64>) {
    if !d.level_unit.starts_with('N') || d.intervals.is_empty() {
        return (None, None, None);
    }
    let at = |t: f64| {
        d.intervals
            .iter()
            .find(|iv| iv.start_s <= t && t < iv.end_s)
            .map(|iv| iv.level)
    };
    let mut est: Vec<f64> = events
        .iter()
        .filter_map(|e| {
            let mid = 0.5 * (e[0] + e[1]);
            let before = (e[0] - 0.1).max(0.0);
            Some(at(mid)? - at(before)?)
        })
        .collect();
    est.sort_by(f64::total_cmp);
    let level = est.get(est.len() / 2).copied();
    let cps: Vec<f64> = d.intervals.iter().skip(1).map(|iv| iv.start_s).collect();
    let mut errs: Vec<f64> = events
        .iter()
        .flat_map(|e| [e[0], e[1]])
        .filter(|t| *t < 7.95)
        .map(|t| cps.iter().map(|c| (c - t).abs()).fold(f64::INFINITY, f64::min) * 1e3)
        .collect();
    errs.sort_by(f64::total_cmp);
    let within = if errs.is_empty() {
        None
    } else {
        Some(100.0 * errs.iter().filter(|e| **e <= 5.0).count() as f64 / errs.len() as f64)
    };
    (level, errs.get(errs.len() / 2).copied(), within)
}

/// Share of true edges (before the log's last 50 ms) within twice the
/// stated 1-sigma of the nearest fitted edge, %.
fn edges_within_2sd(d: &DisturbanceFit, events: &[[f64; 3]]) -> Option<f64> {
    let fitted: Vec<(f64, f64)> = d.intervals.iter().filter_map(|iv| Some((iv.start_s, iv.start_sd_s?))).collect();
    let hits: Vec<bool> = events
        .iter()
        .flat_map(|e| [e[0], e[1]])
        .filter(|t| *t < 7.95)
        .filter_map(|t| fitted.iter().min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs())).map(|(c, sd)| (c - t).abs() <= 2.0 * sd))
        .collect();
    (!hits.is_empty()).then(|| 100.0 * hits.iter().filter(|h| **h).count() as f64 / hits.len() as f64)
}

fn physics(rig: &host_sim::config::RigConfig) -> Nominal {
    Nominal::Physics(Physics::from_rig(rig))
}

fn run_case(spec: Spec) -> Outcome {
    let t0 = std::time::Instant::now();
    let rig = nominal_rig();
    let tilt = Physics::from_rig(&rig).tilt_deg;
    let opts = Options::default();
    let mut o = Outcome::default();
    let force_outcome = |o: &mut Outcome, d: &Diagnosis, g: &GapLogs| {
        let s = &d.summary;
        let dist = if s.verdict.explained_by.starts_with("re-fitted nominal +") {
            s.refit_disturbance.as_ref()
        } else {
            s.disturbance.as_ref()
        };
        let truth = g.events.first().map_or(0.0, |e| e[2]);
        o.factor = Some(g.factor);
        o.level_true_n = Some(truth);
        if let Some(d) = dist {
            let (lv, te, w5) = score_events(d, &g.events);
            o.level_est_n = lv;
            o.level_err_pct = lv.map(|l| 100.0 * (l - truth).abs() / truth.abs());
            o.timing_err_ms = te;
            o.edges_within_5ms_pct = w5;
            o.events = d.events.clone();
            o.true_events = g.events.clone();
            o.edges_within_2sd_pct = edges_within_2sd(d, &g.events);
            o.disturbance_primary_pct = Some(d.primary_shrink_pct);
            o.disturbance_locked = Some(d.locked_to_signals);
        }
        o.train_fit_torque_pct = s.channels.iter().find(|c| c.channel == "torque").map(|c| c.fit_train_pct);
        if let Some((gn, fl, fx)) = floors(&s.primary_channel, g, &d.nominal) {
            // The shrink if the force were known exactly: the gap down to
            // the same experiment's without the events.
            o.ceiling_primary_pct = Some(shrink(gn, fl));
            o.floor_primary = Some(fl);
            o.floor_noise_share_pct = Some(100.0 * (1.0 - (fx / fl).powi(2)));
            let after = gn * (1.0 - s.verdict.explained_pct / 100.0);
            let above = |x: f64| (x * x - fl * fl).max(0.0).sqrt();
            o.above_floor_shrink_pct = (gn > fl).then(|| shrink(above(gn), above(after)));
        }
        let tilt = Physics::from_rig(&nominal_rig()).tilt_deg;
        if let Ok(c) = diagnose_with(&g.train_clean, Some(&g.held_clean), None, physics(&nominal_rig()), tilt, &Options::default()) {
            o.floor_stack_pct = Some(c.summary.gap_shrink_stack_pct);
            o.floor_refit_pct = c.summary.refit.as_ref().map(|r| r.primary_shrink_pct);
        }
    };
    let d = match spec {
        Spec::Force(timing, seed, factor) => {
            let g = force_logs(&rig, timing, Some(factor), seed);
            let d = diagnose_with(&g.train, Some(&g.held), None, physics(&rig), tilt, &opts).expect("diagnosis");
            o.case = format!("force {timing:?}");
            o.family = "force";
            o.seed = seed;
            force_outcome(&mut o, &d, &g);
            d
        }
        Spec::WrongRig(which, seed) | Spec::WrongRigForce(which, seed) => {
            let (file, f) = wrong_rig(&rig, which, seed);
            let with_force = matches!(spec, Spec::WrongRigForce(..));
            let (d, g) = if with_force {
                let g = force_logs(&rig, Timing::Free, Some(1.0 + 2.0 * ((seed % 7) as f64 / 6.0)), seed);
                (diagnose_with(&g.train, Some(&g.held), None, physics(&file), tilt, &opts).expect("diagnosis"), Some(g))
            } else {
                let (tr, he) = nominal_pair(&rig, seed);
                (diagnose_with(&tr, Some(&he), None, physics(&file), tilt, &opts).expect("diagnosis"), None)
            };
            o.case = format!("wrong rig file: {which:?}{}", if with_force { " + force events" } else { "" });
            o.family = if with_force { "wrong_rig_force" } else { "wrong_rig" };
            o.seed = seed;
            o.wrong_param = Some(format!("{which:?}"));
            o.wrong_factor = Some(f);
            let r = d.summary.refit.as_ref();
            o.refitted = r.map_or(Vec::new(), |r| r.changed.clone());
            o.wrong_param_refitted = Some(o.refitted.iter().any(|p| which.refit_names().iter().any(|n| p.starts_with(n))));
            o.refit_primary_pct = r.map(|r| r.primary_shrink_pct);
            o.refit_halves_pct = r.map(|r| r.halves_primary_shrink_pct);
            o.refit_stable = r.map(|r| r.stable);
            if let Some(g) = &g {
                force_outcome(&mut o, &d, g);
            }
            d
        }
        Spec::TrainingIsReference(seed) => {
            let reference = quiet_nominal(&rig, 3000 + seed);
            let g = force_logs(&rig, Timing::Free, Some(1.0 + 2.0 * ((seed % 5) as f64 / 4.0)), seed);
            let reg = fit_regression(&reference).expect("regression");
            let d = diagnose_with(&reference, Some(&g.held), Some(&reference), Nominal::Regression(reg), tilt, &opts).expect("diagnosis");
            o.case = "training = reference, held-out log with force events".into();
            o.family = "training_is_reference";
            o.seed = seed;
            o.factor = Some(g.factor);
            o.disturbance_primary_pct = d.summary.disturbance.as_ref().map(|x| x.primary_shrink_pct);
            o.disturbance_locked = d.summary.disturbance.as_ref().map(|x| x.locked_to_signals);
            d
        }
        Spec::Quiet(seed) => {
            let (tr, he) = (quiet_nominal(&rig, 1000 + seed), quiet_nominal(&rig, 2000 + seed));
            o.case = "quiet nominal rig (no force, right rig file)".into();
            o.family = "quiet";
            o.seed = seed;
            diagnose_with(&tr, Some(&he), None, physics(&rig), tilt, &opts).expect("diagnosis")
        }
    };
    let s = &d.summary;
    let dist = if s.verdict.explained_by.starts_with("re-fitted nominal +") {
        s.refit_disturbance.as_ref()
    } else {
        s.disturbance.as_ref()
    };
    if let Some(x) = dist {
        o.dist_by_channel = x.shrink_by_channel.clone();
        o.dist_change_points = Some(x.heldout_change_points);
        o.dist_jumps = x.intervals.windows(2).filter(|w| w[0].run == w[1].run).map(|w| w[1].level - w[0].level).collect();
    }
    o.primary = s.primary_channel.clone();
    o.verdict = s.verdict.kind.clone();
    o.headline = s.verdict.headline.clone();
    o.explained_pct = s.verdict.explained_pct;
    o.gates = s.gates.iter().map(|g| format!("{}{}", g.kind, g.channel.as_ref().map_or(String::new(), |c| format!("({c})")))).collect();
    o.wall_s = t0.elapsed().as_secs_f64();
    o
}

/// The held-out log's nominal gap on the primary channel, the floor (the
/// same experiment without the events) and the floor with exact sensors.
fn floors(primary: &str, g: &GapLogs, nominal: &Nominal) -> Option<(f64, f64, f64)> {
    let c = CHANNELS.iter().position(|x| *x == primary)?;
    let tilt = Physics::from_rig(&nominal_rig()).tilt_deg;
    let mut w = [0.0; NCH];
    w[c] = 1.0;
    let gap_of = |log| {
        let segs = build_segments(log, nominal, tilt).ok()?;
        let refs: Vec<_> = segs.iter().collect();
        Some(fit::gap(&refs, None, &w))
    };
    Some((gap_of(&g.held)?, gap_of(&g.held_clean)?, gap_of(&g.held_clean_exact)?))
}

fn pct(a: usize, b: usize) -> f64 {
    if b == 0 {
        f64::NAN
    } else {
        100.0 * a as f64 / b as f64
    }
}

fn summarize(out: &[Outcome], title: &str, wall_s: f64) -> (serde_json::Value, String) {
    let fam = |f: &str| out.iter().filter(|o| o.family == f).collect::<Vec<_>>();
    let force = fam("force");
    let n_f = force.len();
    let dist = force.iter().filter(|o| o.verdict == "disturbance").count();
    let lvl = force.iter().filter(|o| o.level_err_pct.is_some_and(|e| e <= 20.0)).count();
    let tim = force.iter().filter(|o| o.timing_err_ms.is_some_and(|e| e <= 5.0)).count();
    let shr = force.iter().filter(|o| o.verdict == "disturbance" && o.explained_pct >= 70.0).count();
    // Misses of the 70 % bar whose ceiling is itself under it: the floor,
    // not the estimate, keeps them short.
    let shr_capped = force.iter().filter(|o| !(o.verdict == "disturbance" && o.explained_pct >= 70.0) && o.ceiling_primary_pct.is_some_and(|c| c < 70.0)).count();
    let shr_ceiling = force.iter().filter(|o| o.ceiling_primary_pct.is_some_and(|c| c >= 70.0)).count();
    let shr_of_reachable = force.iter().filter(|o| o.verdict == "disturbance" && o.explained_pct >= 70.0 && o.ceiling_primary_pct.is_some_and(|c| c >= 70.0)).count();
    // The disturbance's share of the gap the events add (above the floor).
    let shr_above = force.iter().filter(|o| o.verdict == "disturbance" && o.above_floor_shrink_pct.is_some_and(|x| x >= 70.0)).count();
    let mut noise: Vec<f64> = force.iter().filter_map(|o| o.floor_noise_share_pct).collect();
    noise.sort_by(f64::total_cmp);
    let noise_range = format!("{:.0}–{:.0} % (median {:.0} %)", noise.first().copied().unwrap_or(f64::NAN), noise.last().copied().unwrap_or(f64::NAN), noise.get(noise.len() / 2).copied().unwrap_or(f64::NAN));
    let range = |v: Vec<f64>| {
        let mut v = v;
        v.sort_by(f64::total_cmp);
        format!("{:.0}–{:.0} %", v.first().copied().unwrap_or(f64::NAN), v.last().copied().unwrap_or(f64::NAN))
    };
    let floor_stack = range(force.iter().filter_map(|o| o.floor_stack_pct).collect());
    let floor_refit = range(force.iter().filter_map(|o| o.floor_refit_pct).collect());
    let neg_fit = force.iter().filter(|o| o.train_fit_torque_pct.is_some_and(|f| f < 0.0)).count();
    let wr = fam("wrong_rig");
    let wr_ok = wr.iter().filter(|o| o.verdict == "rig_mismatch" && o.wrong_param_refitted == Some(true)).count();
    let wrf = fam("wrong_rig_force");
    let wrf_ok = wrf.iter().filter(|o| matches!(o.verdict.as_str(), "rig_mismatch" | "disturbance") && o.wrong_param_refitted == Some(true) && o.explained_pct >= 66.7).count();
    let tr = fam("training_is_reference");
    let tr_ok = tr.iter().filter(|o| o.verdict == "disturbance").count();
    let quiet = fam("quiet");
    let quiet_named = quiet.iter().filter(|o| !matches!(o.verdict.as_str(), "unexplained" | "nothing_to_find")).count();
    let wrong_lib = out.iter().filter(|o| matches!(o.verdict.as_str(), "library_effect" | "library_group")).count();
    let by_timing = |t: &str| {
        let v: Vec<&&Outcome> = force.iter().filter(|o| o.case.ends_with(t)).collect();
        format!("{}/{}", v.iter().filter(|o| o.verdict == "disturbance").count(), v.len())
    };
    let figures = serde_json::json!({
        "cases": out.len(),
        "force_cases": n_f,
        "force_verdict_disturbance_pct": pct(dist, n_f),
        "force_verdict_disturbance_by_timing": {"free": by_timing("Free"), "synced": by_timing("Synced"), "long_step": by_timing("LongStep")},
        "force_level_within_20pct_pct": pct(lvl, n_f),
        "force_event_times_within_5ms_pct": pct(tim, n_f),
        "force_primary_shrink_ge_70_pct": pct(shr, n_f),
        "force_ceiling_ge_70_cases": shr_ceiling,
        "force_primary_shrink_ge_70_where_ceiling_ge_70": format!("{shr_of_reachable}/{shr_ceiling}"),
        "force_misses_with_ceiling_below_70": shr_capped,
        "force_above_floor_shrink_ge_70_pct": pct(shr_above, n_f),
        "force_floor_noise_share": noise_range,
        "force_floor_removed_by_clean_stack": floor_stack,
        "force_floor_removed_by_clean_refit": floor_refit,
        "force_cases_training_fit_below_zero": neg_fit,
        "wrong_rig_cases": wr.len(),
        "wrong_rig_verdict_rig_mismatch_with_param_pct": pct(wr_ok, wr.len()),
        "wrong_rig_force_cases": wrf.len(),
        "wrong_rig_force_both_found_pct": pct(wrf_ok, wrf.len()),
        "training_is_reference_cases": tr.len(),
        "training_is_reference_disturbance_pct": pct(tr_ok, tr.len()),
        "wrong_library_effect_named_pct": pct(wrong_lib, out.len()),
        "quiet_cases": quiet.len(),
        "quiet_named_something_pct": pct(quiet_named, quiet.len()),
        "wall_s": wall_s,
        "outcomes": out,
    });
    let mut rep = format!("# {title}\n\n{} cases, wall {wall_s:.1} s. Force truths: verdict disturbance {dist}/{n_f} (free {}, synced {}, long step {}), level within 20 % {lvl}/{n_f}, event times within 5 ms {tim}/{n_f}, primary shrink ≥ 70 % {shr}/{n_f} ({shr_of_reachable}/{shr_ceiling} of those whose ceiling — the same run without the events — is ≥ 70 %; {shr_capped} misses have a ceiling under 70 %), of the gap above the floor ≥ 70 % {shr_above}/{n_f}, sensor noise's share of the floor's energy {noise_range}, floor removed by a library stack fitted on a clean reference {floor_stack}, by a re-fit of the rig's parameters {floor_refit}; training Fit < 0 in {neg_fit}. Wrong rig file: rig mismatch with the parameter {wr_ok}/{}; with force events both found {wrf_ok}/{}. Training = reference: disturbance {tr_ok}/{}. Quiet nominal rig (false alarms): something named {quiet_named}/{}. Wrong library effect named: {wrong_lib}/{}.\n\n", out.len(), by_timing("Free"), by_timing("Synced"), by_timing("LongStep"), wr.len(), wrf.len(), tr.len(), quiet.len(), out.len());
    let _ = writeln!(rep, "| case | seed | verdict | explained % (ceiling; above floor; floor noise %) | factor | level true / est N (err %) | timing err ms (≤5 ms %) | train Fit torque % | refitted | locked | gates |\n|---|---|---|---|---|---|---|---|---|---|---|");
    let f1 = |x: Option<f64>| x.map_or("–".to_string(), |v| format!("{v:.1}"));
    for o in out {
        let _ = writeln!(
            rep,
            "| {} | {} | {} | {:.1} ({}; {}; {}) | {} | {} / {} ({}) | {} ({}) | {} | {} {} | {} | {} |",
            o.case, o.seed, o.verdict, o.explained_pct, f1(o.ceiling_primary_pct), f1(o.above_floor_shrink_pct), f1(o.floor_noise_share_pct), f1(o.factor), f1(o.level_true_n), f1(o.level_est_n), f1(o.level_err_pct),
            f1(o.timing_err_ms), f1(o.edges_within_5ms_pct), f1(o.train_fit_torque_pct), o.refitted.join("; "),
            o.refit_primary_pct.map_or(String::new(), |r| format!("(re-fit {r:.1} %, halves {:?}, stable {:?})", o.refit_halves_pct.map(|h| (h.0.round(), h.1.round())), o.refit_stable)),
            o.disturbance_locked.map_or("–", |b| if b { "yes" } else { "no" }), o.gates.join(", ")
        );
    }
    (figures, rep)
}

fn write(dir_name: &str, figures: &serde_json::Value, rep: &str) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/diagnose_suite").join(dir_name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("report.md"), rep).unwrap();
    std::fs::write(dir.join("suite.json"), serde_json::to_string_pretty(figures).unwrap()).unwrap();
    println!("{rep}");
}

/// One set of cases from seed `base`: `n` of each force timing, `n` of
/// each wrong parameter alone and with force events, `n` training =
/// reference.
fn specs(base: u64, n: u64) -> Vec<Spec> {
    let mut v = Vec::new();
    for k in 0..n {
        let s = base + k;
        // Size factors stratified over [0.2, 5] (log scale): the k-th of
        // n equal bins, a point in it fixed by the seed and the timing.
        for (j, t) in [Timing::Free, Timing::Synced, Timing::LongStep].into_iter().enumerate() {
            let u = ((s as f64 + 0.37 * j as f64) * 0.618_034).fract();
            let bin = (k + j as u64) % n;
            let factor = (0.2f64.ln() + (bin as f64 + u) / n as f64 * 25f64.ln()).exp();
            v.push(Spec::Force(t, s, factor));
        }
        for w in [WrongParam::Payload, WrongParam::Flux] {
            v.push(Spec::WrongRig(w, s));
            v.push(Spec::WrongRigForce(w, s));
        }
        v.push(Spec::TrainingIsReference(s));
        v.push(Spec::Quiet(s));
    }
    v
}

impl Spec {
    fn family(self) -> &'static str {
        match self {
            Spec::Force(..) => "force",
            Spec::WrongRig(..) => "wrong_rig",
            Spec::WrongRigForce(..) => "wrong_rig_force",
            Spec::TrainingIsReference(_) => "training_is_reference",
            Spec::Quiet(_) => "quiet",
        }
    }
}

/// Seeds the method was developed on.
const TUNING_SEED_BASE: u64 = 0;
/// An earlier held-out set, since studied case by case while the method
/// was changed: a development set now, not an independent one.
const SEEN_SEED_BASE: u64 = 1000;
/// Held-out seeds: drawn after the method was fixed, run once. Every
/// base run before (0–3, 1000–1003, 4000–4003, 5000–5003, 5010–5013,
/// 5020–5023, 5030–5033, 5040–5043 and the development sets) is spent; this one is
/// the latest fresh draw.
const HOLDOUT_SEED_BASE: u64 = 5050;

#[test]
#[ignore = "large-gap benchmark (≈ 3–9 min): cargo test --release --test diagnose_gap -- --ignored --nocapture"]
fn gap_suite() {
    let set = std::env::var("DIAGNOSE_GAP_SET").unwrap_or_default();
    let custom = seed_base_env("DIAGNOSE_GAP_SEED");
    let n: u64 = std::env::var("DIAGNOSE_GAP_N").ok().and_then(|v| v.parse().ok()).unwrap_or(4);
    let t0 = std::time::Instant::now();
    let mut figures = serde_json::json!({});
    let mut rep = String::new();
    let sets = match custom {
        Some(base) => vec![("custom", base, format!("Large-gap suite, seeds from {base} (DIAGNOSE_GAP_SEED)"))],
        None => vec![
            ("tuning", TUNING_SEED_BASE, "Large-gap suite, tuning seeds (from 0; the method was developed on them)".into()),
            ("seen", SEEN_SEED_BASE, "Large-gap suite, seen seeds (from 1000; held out once, then studied while the method was changed)".into()),
            ("holdout", HOLDOUT_SEED_BASE, format!("Large-gap suite, held-out seeds (from {HOLDOUT_SEED_BASE}; run once after the method was fixed)")),
        ],
    };
    for (key, base, title) in sets {
        if custom.is_none() && !set.is_empty() && set != key {
            continue;
        }
        let t = std::time::Instant::now();
        let only = std::env::var("DIAGNOSE_GAP_ONLY").unwrap_or_default();
        let out: Vec<Outcome> = specs(base, n).into_iter().filter(|s| only.is_empty() || s.family() == only).map(run_case).collect();
        let (f, r) = summarize(&out, &title, t.elapsed().as_secs_f64());
        figures[key] = f;
        figures[format!("{key}_seed_base")] = base.into();
        rep.push_str(&r);
        rep.push('\n');
    }
    figures["total_wall_s"] = t0.elapsed().as_secs_f64().into();
    write("gap", &figures, &rep);
}

/// CI: short force events five times the motion's own force are a
/// disturbance with their level and times; a wrong payload in the rig file
/// is a rig mismatch naming the mass.
#[test]
fn gap_smoke() {
    let o = run_case(Spec::Force(Timing::Free, 7, 5.0));
    assert_eq!(o.verdict, "disturbance", "{}", o.headline);
    assert!(o.explained_pct >= 70.0, "{}", o.headline);
    let err = o.level_err_pct.expect("level in N");
    assert!(err <= 20.0, "level {:?} vs {:?} N", o.level_est_n, o.level_true_n);
    assert!(o.timing_err_ms.is_some_and(|t| t <= 5.0), "timing {:?} ms", o.timing_err_ms);
    let o = run_case(Spec::WrongRig(WrongParam::Payload, 7));
    assert_eq!(o.verdict, "rig_mismatch", "{}", o.headline);
    assert_eq!(o.wrong_param_refitted, Some(true), "{:?}", o.refitted);
}

/// A healthy reference's regression nominal holds on the half of the
/// reference it was not fitted on (the current channel): the lagged speeds
/// are nearly collinear, and a solve that lets their coefficients cancel
/// is exact on the half it fitted and wild on the other. These quiet
/// references each failed that check before the regression's solve was
/// scaled and truncated (held-out current Fit 56.6–58.7 % against
/// 81.3–85.0 % in-sample, a drop over the 20-point gate).
#[test]
fn a_healthy_reference_holds_its_regression_on_its_own_halves() {
    let rig = nominal_rig();
    for seed in [12611, 12612, 12616] {
        let reference = quiet_nominal(&rig, seed);
        let reg = fit_regression(&reference).expect("regression");
        let gates = host_sim::diagnose::gates::reference_gates(&reference, &reg).expect("gates");
        let unsound: Vec<String> = gates
            .iter()
            .filter(|g| g.kind == "reference_unsound" && g.channel.as_deref() == Some("torque"))
            .map(|g| g.message.clone())
            .collect();
        assert!(unsound.is_empty(), "seed {seed}: {unsound:?}");
    }
}

/// The physics nominal's floor on a healthy run is not concentrated at the
/// move starts. There the motor turns first and winds up the drive train
/// against the rod seal while the rod still stands; the seal holds
/// whatever that puts on it until it breaks away, which no friction law
/// of the motor's speed predicts. Without fading the rod's own standstill
/// (the scale's speed) the first 50 ms of the moves, 7 % of the time,
/// held 91–93 % of the torque channel's weighted residual energy (seed
/// 9900); with it, 14–39 % on these runs.
#[test]
fn the_nominal_floor_does_not_sit_at_the_move_starts() {
    let rig = nominal_rig();
    let tilt = Physics::from_rig(&rig).tilt_deg;
    for seed in [9920, 9921, 9922] {
        let log = quiet_nominal(&rig, seed);
        let segs = build_segments(&log, &physics(&rig), tilt).expect("segments");
        let starts = move_starts(&log);
        let (mut e_in, mut e_all, mut t_in, mut t_all) = (0.0, 0.0, 0.0, 0.0);
        for s in &segs {
            let r = s.r[TORQUE].as_ref().expect("torque channel");
            for i in 0..s.len() {
                let e = (s.weight(TORQUE, i) * r[i]).powi(2);
                let near = starts.iter().any(|t0| s.t[i] >= t0 - 0.01 && s.t[i] < t0 + 0.05);
                e_all += e;
                t_all += 1.0;
                if near {
                    e_in += e;
                    t_in += 1.0;
                }
            }
        }
        let (share, time) = (e_in / e_all, t_in / t_all);
        println!("seed {seed}: {:.1} % of the energy in {:.1} % of the time", 100.0 * share, 100.0 * time);
        assert!(share < 0.6, "seed {seed}: {:.1} % of the torque floor's energy within 50 ms of a move start, {:.1} % of the time", 100.0 * share, 100.0 * time);
    }
}

/// A change point at a move is model error when the reference's own
/// residual repeats its step at the same phase of the same kind of move,
/// and an event when it does not (or when it sits away from the moves).
#[test]
fn a_step_at_a_move_is_model_error_only_if_the_reference_repeats_it() {
    use host_sim::diagnose::events::Remainder;
    use host_sim::diagnose::phase::not_repeated;
    use host_sim::diagnose::residual::Segment;
    let dt = 1e-3;
    let n = 5000;
    // Moves +, −, +, − starting at 0.5, 1.5, 2.5, 3.5 s, each 0.5 s long.
    let v_ref: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            let k = ((t - 0.5) / 1.0).floor();
            let in_move = t >= 0.5 && (t - 0.5 - k) < 0.5 && k < 4.0;
            if in_move { if k as i64 % 2 == 0 { 0.1 } else { -0.1 } } else { 0.0 }
        })
        .collect();
    // Model error: the residual steps up by 1 for 100 ms, 10 ms after each
    // move start; on the diagnosed log a force adds 2 to the one after
    // the move at 2.5 s, and another steps in at 4.2 s, away from a move.
    let model = |i: usize| -> f64 {
        let t = i as f64 * dt;
        [0.5, 1.5, 2.5, 3.5].iter().map(|s| if t >= s + 0.01 && t < s + 0.11 { 1.0 } else { 0.0 }).sum()
    };
    let seg = |r: Vec<f64>| {
        let mut s = Segment { t: (0..n).map(|i| i as f64 * dt).collect(), v_ref: v_ref.clone(), dt, ..Default::default() };
        s.r[TORQUE] = Some(r);
        s
    };
    let reference = seg((0..n).map(model).collect());
    let held_r: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            model(i) + if (2.51..2.61).contains(&t) { 2.0 } else { 0.0 } + if (4.2..4.3).contains(&t) { 1.0 } else { 0.0 }
        })
        .collect();
    let held = seg(held_r.clone());
    let rem: Remainder = vec![std::array::from_fn(|c| if c == TORQUE { Some(held_r.clone()) } else { None })];
    let cps = vec![vec![510, 1510, 2510, 4200]];
    let (kept, repeated) = not_repeated(&[&held], &rem, &cps, &[&reference]);
    assert_eq!(repeated, 2, "the steps at 0.5 s and 1.5 s recur in the reference: {kept:?}");
    assert_eq!(kept, vec![vec![2510, 4200]], "the force at 2.5 s and the step at 4.2 s are events");
}
