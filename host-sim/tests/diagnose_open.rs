//! Open-world suite: truth rigs whose effect the ranked
//! library does not hold — each library effect held out in turn, and
//! effects the library never had (unmeasured force steps and pulses,
//! sensor delay, structural resonance, torque-constant drop with
//! temperature, current saturation, encoder miscount burst) — plus the
//! nominal rig, and the nominal rig diagnosed against a mismatched rig
//! file. Confusion: named right / disturbance-modelled / honestly
//! unexplained / wrong.
//!
//! CI runs `open_world_sample` (5 cases). The full suite writes
//! `target/diagnose_suite/open/{suite.json,report.md}`:
//! `cargo test --release --test diagnose_open -- --ignored --nocapture`.

mod diagnose_support;

use diagnose_support::open::{
    library_characters, library_logs, mismatched_rig, nominal_logs, novel_logs, Logs, Novel, NOVEL,
};
use diagnose_support::seed_base_env;
use diagnose_support::truth::nominal_rig;
use host_sim::diagnose::effects::{Effect, ALL};
use host_sim::diagnose::events;
use host_sim::diagnose::residual::{Nominal, Physics, CHANNELS};
use host_sim::diagnose::{diagnose_with, Options};
use std::fmt::Write as _;

#[derive(Clone, Copy, Debug)]
enum Spec {
    HeldOut(Effect, u64),
    Novel(Novel, u64),
    Nominal(u64),
    Mismatched(u64),
}

#[derive(Debug, serde::Serialize)]
struct Outcome {
    case: String,
    family: &'static str,
    category: &'static str,
    verdict: String,
    cause: Option<String>,
    /// Effects named together as not separable on the log.
    cause_group: Vec<String>,
    headline: String,
    top_effect: Option<String>,
    explained_pct: f64,
    remaining_gap_pct: f64,
    primary_channel: String,
    disturbance_weighted_pct: f64,
    disturbance_primary_pct: f64,
    /// Weighted over the channels a force acts on (torque, position).
    disturbance_acting_pct: f64,
    disturbance_levels: String,
    /// The most the all-channel weighted figure could reach with torque
    /// and position explained entirely (the voltage channel stays).
    disturbance_weighted_ceiling_pct: f64,
    disturbance_change_points: usize,
    character: String,
    character_ok: Option<bool>,
    character_why: String,
    /// The primary channel's statistics behind the character.
    character_stats: String,
    event_share_reported_pct: Option<f64>,
    event_share_truth_pct: Option<f64>,
    gates: Vec<String>,
    top_halves: Option<(f64, f64, f64)>,
    disturbance_locked_to_signals: Option<bool>,
    disturbance_signal_locked_vs_chance_pct: Option<(f64, f64)>,
    /// The generic class the truth should be named by, the class named (a
    /// `generic_structure` verdict, or a constant force from the re-fit),
    /// and the parameter's error against the truth, %.
    generic_truth: Option<String>,
    generic_named: Option<String>,
    generic_params: String,
    generic_param_err_pct: Option<f64>,
    /// The best generic fits, as fitted (class, channel, held-out shrink, parameters).
    generic_fits: Vec<String>,
    wall_s: f64,
}

fn run_case(spec: Spec) -> Outcome {
    let t0 = std::time::Instant::now();
    let rig = nominal_rig();
    let (name, family, logs, diag_rig, library, chars): (
        String,
        &str,
        Logs,
        _,
        Vec<Effect>,
        Option<&[&str]>,
    ) = match spec {
        Spec::HeldOut(e, seed) => (
            format!("held out: {}", e.name()),
            "held_out_library",
            library_logs(&rig, e, 50_000 + seed),
            rig.clone(),
            ALL.iter().copied().filter(|x| *x != e).collect(),
            Some(library_characters(e)),
        ),
        Spec::Novel(n, seed) => (
            n.name().to_string(),
            "novel",
            novel_logs(&rig, n, 60_000 + seed),
            rig.clone(),
            ALL.to_vec(),
            Some(n.characters()),
        ),
        Spec::Nominal(seed) => (
            "nominal rig".into(),
            "nominal",
            nominal_logs(&rig, 70_000 + seed),
            rig.clone(),
            ALL.to_vec(),
            None,
        ),
        Spec::Mismatched(seed) => (
            "nominal rig vs mismatched rig file".into(),
            "mismatched",
            nominal_logs(&rig, 80_000 + seed),
            mismatched_rig(&rig),
            ALL.to_vec(),
            None,
        ),
    };
    let p = Physics::from_rig(&diag_rig);
    let d = diagnose_with(
        &logs.train,
        Some(&logs.held),
        None,
        Nominal::Physics(p.clone()),
        p.tilt_deg,
        &Options { library },
    )
    .expect("diagnosis");
    let s = &d.summary;
    let v = &s.verdict;
    let category = match v.kind.as_str() {
        // The truth is never in the ranked library here: any cause is
        // wrong, and so is a group of library effects the log cannot
        // separate (the truth is not among them).
        "library_effect" | "library_group" => "wrong",
        "disturbance" => "disturbance_modelled",
        "rig_mismatch" => "rig_mismatch",
        "generic_structure" => "generic_structure",
        _ => "honestly_unexplained",
    };
    let primary = CHANNELS
        .iter()
        .position(|c| *c == s.primary_channel)
        .unwrap_or(0);
    let ts = s
        .time_structure
        .iter()
        .find(|t| t.channel == s.primary_channel);
    let (rep, tru) = if logs.held_events_s.is_empty() {
        (None, None)
    } else {
        let held = d.heldout();
        let rem = d.heldout_remainder();
        let ev = events::events_at(&held, &logs.held_events_s);
        let (e, _) = events::share_after(
            &held,
            &rem,
            primary,
            &ev,
            events::EVENT_BEFORE_S,
            events::EVENT_AFTER_S,
        );
        (ts.map(|t| t.energy_after_events_pct), Some(e))
    };
    let character = v.remainder_character.clone();
    // The generic class named: a generic structure, or the re-fit's
    // constant force (a disturbance without a time course).
    let named: Option<(String, Vec<(String, f64)>)> = if let Some(g) = &v.generic {
        Some((g.class.clone(), g.params.iter().map(|(k, x)| (k.clone(), *x)).collect()))
    } else if v.explained_by == "constant unmeasured force" {
        s.refit.as_ref().map(|r| ("constant_force".to_string(), vec![("level_n".to_string(), r.constant_force_n)]))
    } else {
        None
    };
    let param_err = match (&logs.generic_truth, &named) {
        (Some((tc, tp)), Some((nc, np))) if tc == nc => tp
            .first()
            .and_then(|(k, t)| np.iter().find(|(n, _)| n == k).map(|(_, x)| 100.0 * (x - t).abs() / t.abs()))
            .or(Some(0.0)),
        _ => None,
    };
    Outcome {
        generic_truth: logs.generic_truth.as_ref().map(|g| g.0.to_string()),
        generic_named: named.as_ref().map(|n| n.0.clone()),
        generic_params: named.as_ref().map_or(String::new(), |n| n.1.iter().map(|(k, x)| format!("{k}={x:.4}")).collect::<Vec<_>>().join(", ")),
        generic_param_err_pct: param_err,
        generic_fits: s.generic.iter().take(6).map(|g| format!("{} on {}: remainder {:.1} % (train {:.1} %), gap {:.1} % {:?} beyond {:?}", g.class, g.channel, g.remainder_shrink_pct, g.train_shrink_pct, g.primary_shrink_pct, g.params, g.beyond_pct)).collect(),
        case: name,
        family,
        category,
        verdict: v.kind.clone(),
        cause: v.cause.clone(),
        cause_group: v.cause_group.clone(),
        headline: v.headline.clone(),
        top_effect: s.top_effect.clone(),
        explained_pct: v.explained_pct,
        remaining_gap_pct: v.remaining_gap_pct,
        primary_channel: s.primary_channel.clone(),
        disturbance_weighted_pct: s.disturbance.as_ref().map_or(0.0, |x| x.weighted_shrink_pct),
        disturbance_primary_pct: s.disturbance.as_ref().map_or(0.0, |x| x.primary_shrink_pct),
        disturbance_acting_pct: s.disturbance.as_ref().map_or(0.0, |x| x.acting_weighted_shrink_pct),
        disturbance_levels: s.disturbance.as_ref().map_or(String::new(), |x| x.levels.clone()),
        disturbance_weighted_ceiling_pct: s.disturbance.as_ref().map_or(0.0, |x| x.weighted_ceiling_pct),
        disturbance_change_points: s.disturbance.as_ref().map_or(0, |x| x.heldout_change_points),
        character_ok: (category == "honestly_unexplained").then(|| chars.is_some_and(|c| c.contains(&character.as_str()))),
        character,
        character_why: v.remainder_why.clone(),
        character_stats: ts.map_or(String::new(), |t| format!(
            "angle n={} {:.0}%; inputs {:.0}%; acf {:.2}±{:.2} @{:.3}s; events {:.0}/{:.0}%; motion {:.0}/{:.0}%; steps {:.0}%; slow {:.0}%; step/trend {:.2}; LB p {:.1e}",
            t.angle_periods_per_rev, t.angle_explained_pct, t.input_r2_pct, t.acf_at_period, t.acf_standard_error,
            t.dominant_period_s.unwrap_or(f64::NAN), t.energy_after_events_pct, t.time_after_events_pct,
            t.energy_after_motion_pct, t.time_after_motion_pct, t.steps_explained_pct, t.slow_share_pct, t.step_over_trend, t.ljung_box_p)),
        event_share_reported_pct: rep,
        event_share_truth_pct: tru,
        gates: s.gates.iter().map(|g| format!("{}{}", g.kind, g.channel.as_ref().map_or(String::new(), |c| format!("({c})")))).collect(),
        top_halves: s.top_halves_primary_shrink_pct,
        disturbance_locked_to_signals: s.disturbance.as_ref().map(|x| x.locked_to_signals),
        disturbance_signal_locked_vs_chance_pct: s.disturbance.as_ref().map(|x| (x.signal_locked_pct, x.chance_pct)),
        wall_s: t0.elapsed().as_secs_f64(),
    }
}

/// Generic classes scored apart from the four the figure is on.
const APART: [&str; 2] = ["count_loss", "quantisation"];

fn pct(a: usize, b: usize) -> f64 {
    if b == 0 {
        f64::NAN
    } else {
        100.0 * a as f64 / b as f64
    }
}

/// Runs the cases, writes report.md and suite.json into `dir`, returns the
/// outcomes and the figures.
fn suite(specs: &[Spec], dir_name: &str) -> (Vec<Outcome>, serde_json::Value) {
    let t0 = std::time::Instant::now();
    let out: Vec<Outcome> = specs.iter().map(|s| run_case(*s)).collect();
    let (figures, rep) = summarize(&out, t0.elapsed().as_secs_f64(), "Open-world suite");
    write(dir_name, &figures, &rep);
    (out, figures)
}

fn write(dir_name: &str, figures: &serde_json::Value, rep: &str) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("target/diagnose_suite")
        .join(dir_name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("report.md"), rep).unwrap();
    std::fs::write(
        dir.join("suite.json"),
        serde_json::to_string_pretty(figures).unwrap(),
    )
    .unwrap();
    println!("{rep}");
}

/// The figures (JSON) and the markdown table of a set of outcomes.
fn summarize(out: &[Outcome], wall_s: f64, title: &str) -> (serde_json::Value, String) {
    let n = out.len();
    let count = |c: &str| out.iter().filter(|o| o.category == c).count();
    let force: Vec<&Outcome> = out
        .iter()
        .filter(|o| o.case.starts_with("force_"))
        .collect();
    let force_ok = force
        .iter()
        .filter(|o| o.disturbance_weighted_pct >= 70.0)
        .count();
    // The nominal and mismatched cases have no true character to name.
    let unexpl: Vec<&Outcome> = out
        .iter()
        .filter(|o| o.character_ok.is_some() && matches!(o.family, "novel" | "held_out_library"))
        .collect();
    let char_ok = unexpl
        .iter()
        .filter(|o| o.character_ok == Some(true))
        .count();
    // Event-locked gaps: short force pulses (the energy sits after them).
    // Steps and the miscount leave a lasting offset, not an event-locked
    // gap; their shares are listed in the outcomes for reference.
    let ev: Vec<(f64, f64)> = out
        .iter()
        .filter(|o| o.case.starts_with("force_pulses"))
        .filter_map(|o| Some((o.event_share_reported_pct?, o.event_share_truth_pct?)))
        .collect();
    let ev_ok = ev.iter().filter(|(a, b)| (a - b).abs() <= 10.0).count();
    let mism: Vec<&Outcome> = out.iter().filter(|o| o.family == "mismatched").collect();
    // Gated: a baseline gate fired and governed the verdict (no cause of
    // any kind named).
    let mism_gated = mism
        .iter()
        .filter(|o| {
            o.gates
                .iter()
                .any(|g| g.starts_with("physics_mismatch") || g.starts_with("nominal_poor_fit"))
                && o.verdict == "rig_mismatch"
        })
        .count();
    // Truths a generic structure should name (sensor delay, resonance,
    // torque-constant drift, a load offset held out = a constant force).
    let generic: Vec<&Outcome> = out.iter().filter(|o| o.generic_truth.as_deref().is_some_and(|g| !APART.contains(&g))).collect();
    // Counts lost once (the encoder miscount burst) and a quantised column,
    // each scored apart from the four classes above: its truths named with
    // the parameter within 20 %, and the cases without it that it named.
    let right_within = |o: &&&Outcome| o.generic_named.is_some() && o.generic_named == o.generic_truth && o.generic_param_err_pct.is_some_and(|e| e <= 20.0);
    let apart: Vec<(&str, Vec<&Outcome>, usize, Vec<String>)> = APART
        .iter()
        .map(|class| {
            let truths: Vec<&Outcome> = out.iter().filter(|o| o.generic_truth.as_deref() == Some(*class)).collect();
            let ok = truths.iter().filter(right_within).count();
            let false_named = out.iter().filter(|o| o.generic_named.as_deref() == Some(*class) && o.generic_truth.as_deref() != Some(*class)).map(|o| o.case.clone()).collect();
            (*class, truths, ok, false_named)
        })
        .collect();
    let generic_ok = generic.iter().filter(|o| o.generic_named.is_some() && o.generic_named == o.generic_truth).count();
    let generic_ok_param = generic
        .iter()
        .filter(|o| o.generic_named.is_some() && o.generic_named == o.generic_truth && o.generic_param_err_pct.is_some_and(|e| e <= 20.0))
        .count();
    let mut figures = serde_json::json!({
        "cases": n,
        "confusion": {
            "named_right": 0,
            "disturbance_modelled": count("disturbance_modelled"),
            "honestly_unexplained": count("honestly_unexplained"),
            "wrong": count("wrong"),
        },
        "wrong_library_effect_named_pct": pct(count("wrong"), n),
        "wrong_cases": out.iter().filter(|o| o.category == "wrong").map(|o| format!("{} → {}", o.case, o.cause.clone().unwrap_or_else(|| o.cause_group.join(" or ")))).collect::<Vec<_>>(),
        "force_cases": force.len(),
        "force_disturbance_weighted_shrink_ge_70": force_ok,
        "force_disturbance_weighted_shrink_pct": force.iter().map(|o| o.disturbance_weighted_pct).collect::<Vec<_>>(),
        "force_disturbance_primary_shrink_pct": force.iter().map(|o| o.disturbance_primary_pct).collect::<Vec<_>>(),
        "force_disturbance_acting_weighted_shrink_pct": force.iter().map(|o| o.disturbance_acting_pct).collect::<Vec<_>>(),
        "force_disturbance_acting_weighted_shrink_ge_70": force.iter().filter(|o| o.disturbance_acting_pct >= 70.0).count(),
        "force_disturbance_primary_shrink_ge_70": force.iter().filter(|o| o.disturbance_primary_pct >= 70.0).count(),
        "force_disturbance_weighted_ceiling_pct": force.iter().map(|o| o.disturbance_weighted_ceiling_pct).collect::<Vec<_>>(),
        "unexplained_cases": unexpl.len(),
        "unexplained_character_named_right_pct": pct(char_ok, unexpl.len()),
        "event_share_cases": ev.len(),
        "event_share_within_10_points": ev_ok,
        "event_share_reported_vs_truth_pct": ev,
        "mismatched_cases_gated": format!("{mism_gated}/{}", mism.len()),
        "generic_cases": generic.len(),
        "nominal_named_generic": out.iter().filter(|o| o.family == "nominal" && o.generic_named.is_some()).count(),
        "generic_named_right_pct": pct(generic_ok, generic.len()),
        "generic_named_right_param_within_20pct_pct": pct(generic_ok_param, generic.len()),
        "wall_s": wall_s,
        "outcomes": out,
    });
    let mut rep = format!("# {title}\n\n");
    for (class, truths, ok, false_named) in &apart {
        figures[format!("{class}_cases")] = truths.len().into();
        figures[format!("{class}_named_right_param_within_20pct")] = (*ok).into();
        figures[format!("{class}_named_without_one")] = serde_json::json!(false_named);
        if !truths.is_empty() {
            let _ = writeln!(rep, "{class}: named with its parameter within 20 % {ok}/{}: {}. Named where there was none: {} {:?}.\n", truths.len(), truths.iter().map(|o| format!("{} ({}; err {})", o.generic_named.as_deref().unwrap_or("none"), o.generic_params, o.generic_param_err_pct.map_or("–".into(), |e| format!("{e:.1} %")))).collect::<Vec<_>>().join("; "), false_named.len(), false_named);
        }
    }
    let _ = writeln!(rep, "Generic structures: named by the right class {generic_ok}/{}, with the parameter within 20 % {generic_ok_param}/{}: {}.\n", generic.len(), generic.len(), generic.iter().map(|o| format!("{} → {} ({}; err {})", o.case, o.generic_named.as_deref().unwrap_or("none"), o.generic_params, o.generic_param_err_pct.map_or("–".into(), |e| format!("{e:.0} %")))).collect::<Vec<_>>().join("; "));
    let _ = writeln!(rep, "{n} cases, wall {wall_s:.1} s. Confusion: named right 0 (the truth is never in the ranked library), disturbance-modelled {}, honestly unexplained {}, wrong {} ({:.1} %).\n", count("disturbance_modelled"), count("honestly_unexplained"), count("wrong"), pct(count("wrong"), n));
    let _ = writeln!(rep, "| case | category | verdict | top (closed-world) | explained % | disturbance weighted all / torque+position / primary % (levels) | change points | character (ok?) | event share reported / truth % | gates |\n|---|---|---|---|---|---|---|---|---|---|");
    for o in out {
        let _ = writeln!(
            rep,
            "| {} | {} | {}{} | {} | {:.1} | {:.1} / {:.1} / {:.1} ({}) | {} | {} ({}) | {} | {} |",
            o.case,
            o.category,
            o.verdict,
            o.cause.as_ref().map_or_else(
                || if o.cause_group.is_empty() {
                    String::new()
                } else {
                    format!(": {}", o.cause_group.join(" or "))
                },
                |c| format!(": {c}")
            ),
            o.top_effect.as_deref().unwrap_or("none"),
            o.explained_pct,
            o.disturbance_weighted_pct,
            o.disturbance_acting_pct,
            o.disturbance_primary_pct,
            o.disturbance_levels,
            o.disturbance_change_points,
            o.character,
            o.character_ok.map_or("–", |b| if b { "yes" } else { "no" }),
            match (o.event_share_reported_pct, o.event_share_truth_pct) {
                (Some(a), Some(b)) => format!("{a:.1} / {b:.1}"),
                _ => "–".into(),
            },
            o.gates.join(", ")
        );
    }
    (figures, rep)
}

#[test]
fn open_world_sample() {
    let specs = [
        Spec::Novel(Novel::ForcePulses, 0),
        Spec::Novel(Novel::StructuralResonance, 0),
        Spec::HeldOut(Effect::LoadOffset, 0),
        Spec::Nominal(0),
        Spec::Mismatched(0),
    ];
    let (out, _) = suite(&specs, "open_sample");
    for o in &out {
        assert_ne!(
            o.category, "wrong",
            "{}: a library effect named as the cause: {}",
            o.case, o.headline
        );
    }
    let pulses = &out[0];
    assert_eq!(
        pulses.category, "disturbance_modelled",
        "{}",
        pulses.headline
    );
    let (rep, tru) = (
        pulses.event_share_reported_pct.unwrap(),
        pulses.event_share_truth_pct.unwrap(),
    );
    assert!(
        (rep - tru).abs() <= 15.0,
        "event share reported {rep:.1} % vs truth {tru:.1} %"
    );
    assert!(
        out[3].verdict != "disturbance" && out[3].cause.is_none(),
        "nominal rig: {}",
        out[3].headline
    );
    assert!(
        out[4]
            .gates
            .iter()
            .any(|g| g.starts_with("physics_mismatch") || g.starts_with("nominal_poor_fit")),
        "mismatched rig file not flagged: {:?}",
        out[4].gates
    );
    // The back-EMF gate governs the verdict: a rig mismatch.
    assert_eq!(out[4].verdict, "rig_mismatch", "{}", out[4].headline);
}

/// The suite's cases: every library effect held out once, `novel_reps`
/// draws of each novel truth, two nominal and two mismatched cases, all
/// from seed offset `base` on.
fn specs(base: u64, novel_reps: u64) -> Vec<Spec> {
    let mut specs: Vec<Spec> = ALL.iter().map(|e| Spec::HeldOut(*e, base)).collect();
    for rep in 0..novel_reps {
        specs.extend(NOVEL.iter().map(|n| Spec::Novel(*n, base + rep)));
    }
    for rep in 0..2 {
        specs.push(Spec::Nominal(base + rep));
        specs.push(Spec::Mismatched(base + rep));
    }
    specs
}

/// Seed offset of the held-out draws: cases never looked at while the
/// thresholds and the disturbance were set (those were set on seeds 0, 1).
const HOLDOUT_SEED_BASE: u64 = 100;
/// Seed offset of the second held-out draws (character rules):
/// drawn like the first, run once after the method was fixed on the tuning
/// and the first held-out seeds. Its failures were then studied (the
/// verdict's gate, group, adequacy and flux rules, the primary channel):
/// it is no longer held out.
const HOLDOUT2_SEED_BASE: u64 = 200;
/// Seed offset of the third held-out draws: drawn like the others, run
/// once after the changes made on the second set's failures were final.
const HOLDOUT3_SEED_BASE: u64 = 300;
/// Seed offset of the fourth held-out draws: drawn like the others, run
/// once after the character rule on the inputs' share (a period names the
/// remainder only if it carries at least what the inputs explain) was
/// final — every earlier set had been seen when that rule was made.
const HOLDOUT4_SEED_BASE: u64 = 400;

#[test]
#[ignore = "full open-world suite, the tuning seeds and four held-out seed sets (≈ 3–5 min): cargo test --release --test diagnose_open -- --ignored --nocapture"]
fn open_world_suite() {
    let t0 = std::time::Instant::now();
    // `DIAGNOSE_OPEN_SEED=N`: the set drawn from seed N alone (3 draws).
    if let Some(base) = seed_base_env("DIAGNOSE_OPEN_SEED") {
        let out: Vec<Outcome> = specs(base, 3).into_iter().map(run_case).collect();
        let (mut figures, rep) = summarize(&out, t0.elapsed().as_secs_f64(), &format!("Open-world suite, seeds from {base} (DIAGNOSE_OPEN_SEED)"));
        figures["seed_base"] = base.into();
        write("open", &figures, &rep);
        return;
    }
    let out: Vec<Outcome> = specs(0, 2).into_iter().map(run_case).collect();
    let (mut figures, mut rep) = summarize(
        &out,
        t0.elapsed().as_secs_f64(),
        "Open-world suite (seeds the thresholds were set on)",
    );
    // Each held-out set: its JSON key, seed base and title. Skip the later
    // ones while developing: DIAGNOSE_SKIP_HOLDOUT2=1 skips the second to
    // fourth, DIAGNOSE_SKIP_HOLDOUT3=1 the third and fourth,
    // DIAGNOSE_SKIP_HOLDOUT4=1 the fourth.
    let skip2 = std::env::var_os("DIAGNOSE_SKIP_HOLDOUT2").is_some();
    let skip3 = skip2 || std::env::var_os("DIAGNOSE_SKIP_HOLDOUT3").is_some();
    let skip4 = skip3 || std::env::var_os("DIAGNOSE_SKIP_HOLDOUT4").is_some();
    let sets = [
        ("holdout_seeds", "holdout_seed_base", HOLDOUT_SEED_BASE, "Held-out seeds (from 100 on; not used to set anything)", false),
        ("holdout_seeds_2", "holdout2_seed_base", HOLDOUT2_SEED_BASE, "Second held-out seeds (from 200 on; run once after the character method was fixed, then studied for the verdict's rules: no longer held out)", skip2),
        ("holdout_seeds_3", "holdout3_seed_base", HOLDOUT3_SEED_BASE, "Third held-out seeds (from 300 on; run once, after the verdict's rules were final)", skip3),
        ("holdout_seeds_4", "holdout4_seed_base", HOLDOUT4_SEED_BASE, "Fourth held-out seeds (from 400 on; run once, after the character rule on the inputs' share was final)", skip4),
    ];
    for (key, base_key, base, title, skip) in sets {
        if skip {
            continue;
        }
        let t = std::time::Instant::now();
        let held: Vec<Outcome> = specs(base, 3).into_iter().map(run_case).collect();
        let (hf, hr) = summarize(&held, t.elapsed().as_secs_f64(), title);
        figures[key] = hf;
        figures[base_key] = base.into();
        rep.push('\n');
        rep.push_str(&hr);
    }
    figures["total_wall_s"] = t0.elapsed().as_secs_f64().into();
    write("open", &figures, &rep);
}

/// Seed offset of an earlier held-out set of generic-structure draws,
/// since studied while the classes were changed (a development set now).
const GENERIC_SEEN_SEED_BASE: u64 = 500;
/// Seed offset of the generic-structure draws held out from their
/// development (the tuning draws are seeds 0–3; 700–703 and the later
/// development sets, 800–803 among them, are spent), run once.
const GENERIC_HOLDOUT_SEED_BASE: u64 = 810;

/// The truths a generic structure should name — sensor delay, structural
/// resonance, torque-constant drift, a load offset held out of the library
/// (a constant unmeasured force), and apart from them an encoder miscount
/// and a quantised column — four draws each, with the nominal rig.
/// `DIAGNOSE_GENERIC_SET=tuning|seen|holdout` (default all three);
/// `DIAGNOSE_GENERIC_SEED=N` runs the draws from seed N alone.
#[test]
#[ignore = "generic-structure benchmark (≈ 1–2 min): cargo test --release --test diagnose_open generic_structures -- --ignored --nocapture"]
fn generic_structures() {
    let set = std::env::var("DIAGNOSE_GENERIC_SET").unwrap_or_default();
    let custom = seed_base_env("DIAGNOSE_GENERIC_SEED");
    let t0 = std::time::Instant::now();
    let mut figures = serde_json::json!({});
    let mut rep = String::new();
    let sets = match custom {
        Some(base) => vec![("custom", base, format!("Generic structures, seeds from {base} (DIAGNOSE_GENERIC_SEED)"))],
        None => vec![
            ("tuning", 0u64, "Generic structures, tuning seeds (0–3; the classes were developed on them)".into()),
            ("seen", GENERIC_SEEN_SEED_BASE, "Generic structures, seen seeds (from 500; held out once, then studied while the classes were changed)".into()),
            ("holdout", GENERIC_HOLDOUT_SEED_BASE, format!("Generic structures, held-out seeds (from {GENERIC_HOLDOUT_SEED_BASE}; run once after the method was fixed)")),
        ],
    };
    for (key, base, title) in sets {
        if custom.is_none() && !set.is_empty() && set != key {
            continue;
        }
        let t = std::time::Instant::now();
        let mut specs = Vec::new();
        for k in 0..4 {
            for n in [Novel::SensorDelay, Novel::StructuralResonance, Novel::TorqueConstantDrop] {
                specs.push(Spec::Novel(n, base + k));
            }
            specs.push(Spec::HeldOut(Effect::LoadOffset, base + k));
            specs.push(Spec::Novel(Novel::EncoderMiscount, base + k));
            specs.push(Spec::Novel(Novel::Quantisation, base + k));
            specs.push(Spec::Nominal(base + k));
        }
        let out: Vec<Outcome> = specs.into_iter().map(run_case).collect();
        let (f, r) = summarize(&out, t.elapsed().as_secs_f64(), &title);
        figures[key] = f;
        figures[format!("{key}_seed_base")] = base.into();
        rep.push_str(&r);
        rep.push('\n');
    }
    figures["total_wall_s"] = t0.elapsed().as_secs_f64().into();
    write("open_generic", &figures, &rep);
}
