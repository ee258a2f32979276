//! The open-world verdict's rules (second held-out set): a
//! fired baseline gate governs the verdict, effects the log cannot
//! separate are named as a group, a named effect must leave a remainder
//! that the inputs no longer explain, and a current-sensor gain whose
//! back-EMF fell with it is a torque-constant change. Each rule on
//! hand-made inputs, so the rule and nothing else decides.

use host_sim::diagnose::disturbance::DisturbanceFit;
use host_sim::diagnose::events::TimeStructure;
use host_sim::diagnose::gates::Gate;
use host_sim::diagnose::generic::GenericFit;
use host_sim::diagnose::refit::Refit;
use host_sim::diagnose::residual::NCH;
use host_sim::diagnose::summary::RankEntry;
use host_sim::diagnose::verdict::{decide, Inputs, Verdict, ADEQUATE_INPUT_R2_MAX_PCT};
use std::collections::BTreeMap;

fn entry(effect: &str, primary: f64, indist: &[&str], params: &[(&str, f64)]) -> RankEntry {
    RankEntry {
        effect: effect.into(),
        description: String::new(),
        params: params.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
        weighted_shrink_pct: primary / 2.0,
        primary_shrink_pct: primary,
        heldout_shrink_by_channel: BTreeMap::new(),
        heldout_fit_before: 0.0,
        heldout_fit_after: 0.0,
        heldout_fit_after_by_channel: BTreeMap::new(),
        train_gap_shrink_pct: 0.0,
        indistinguishable_from: indist.iter().map(|s| s.to_string()).collect(),
    }
}

fn gate(kind: &str, channel: Option<&str>, figure: f64) -> Gate {
    Gate {
        kind: kind.into(),
        channel: channel.map(str::to_string),
        message: format!("GATE {kind}"),
        figure,
    }
}

fn structure(input_r2: f64) -> TimeStructure {
    TimeStructure {
        channel: "position".into(),
        character: "broadband (white)".into(),
        input_r2_pct: input_r2,
        ..Default::default()
    }
}

/// A stable top effect (the first of `ranking`) with stack shrink `lib` %.
#[allow(clippy::too_many_arguments)] // each argument is one of the verdict's inputs under test
fn run(
    ranking: &[RankEntry],
    gates: &[Gate],
    lib: f64,
    input_r2: f64,
    stack_train_fit: [Option<f64>; NCH],
    dist: Option<&DisturbanceFit>,
    back_emf: Option<f64>,
    still_implausible: Option<Vec<String>>,
) -> Verdict {
    let ts = structure(input_r2);
    decide(&Inputs {
        gates,
        ranking,
        top: ranking.first().map(|r| r.effect.as_str()),
        stack: &[ranking[0].effect.clone()],
        stack_weighted: lib / 2.0,
        stack_primary: lib,
        stack_torque: lib,
        stack_train_fit,
        dist,
        structure: Some(&ts),
        top_halves: Some((lib, lib, 0.05)),
        back_emf_heldout: back_emf,
        implausible_after_stack: still_implausible,
        refit: None,
        refit_dist: None,
        generic: None,
    })
}

const FITS: [Option<f64>; NCH] = [Some(90.0), Some(60.0), Some(95.0)];

#[test]
fn a_sound_baseline_and_an_adequate_effect_name_the_cause() {
    let r = [entry("hertz_contact", 85.0, &[], &[])];
    let v = run(&r, &[], 85.0, 10.0, FITS, None, Some(1.0), None);
    assert_eq!(v.kind, "library_effect", "{}", v.headline);
    assert_eq!(v.cause.as_deref(), Some("hertz_contact"));
}

#[test]
fn effects_the_log_cannot_separate_are_named_as_a_group() {
    let r = [
        entry("coupling_compliance", 80.0, &["hertz_contact"], &[]),
        entry("hertz_contact", 79.0, &["coupling_compliance"], &[]),
        entry("screw_stiffness", 50.0, &[], &[]),
    ];
    let v = run(&r, &[], 80.0, 10.0, FITS, None, Some(1.0), None);
    assert_eq!(v.kind, "library_group", "{}", v.headline);
    assert!(v.cause.is_none());
    assert_eq!(v.cause_group, ["coupling_compliance", "hertz_contact"]);
    assert!(v.headline.contains("not separable"), "{}", v.headline);
}

#[test]
fn a_remainder_the_inputs_still_explain_names_nothing() {
    let r = [entry("coupling_compliance", 80.0, &[], &[])];
    let v = run(
        &r,
        &[],
        80.0,
        ADEQUATE_INPUT_R2_MAX_PCT + 5.0,
        FITS,
        None,
        Some(1.0),
        None,
    );
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
    assert!(v.cause.is_none());
    assert!(v.headline.contains("wrong shape"), "{}", v.headline);
}

#[test]
fn a_nominal_unsound_on_its_own_reference_leads_and_names_nothing() {
    let r = [entry("load_offset", 95.0, &[], &[])];
    let g = gate("reference_unsound", Some("torque"), -5.0);
    let v = run(&r, std::slice::from_ref(&g), 95.0, 10.0, FITS, None, Some(1.0), None);
    assert_eq!(v.kind, "baseline_mismatch", "{}", v.headline);
    assert!(v.cause.is_none() && v.cause_group.is_empty());
    assert!(
        v.headline.starts_with("**The nominal does not hold on what it was fitted on"),
        "{}",
        v.headline
    );
    assert!(v.headline.contains(&g.message), "{}", v.headline);
}

#[test]
fn a_poor_or_negative_fit_of_the_diagnosed_log_alone_blocks_nothing() {
    // The size of the gap is not a verdict on the nominal: a large
    // unmeasured force drives the diagnosed log's Fit below zero too.
    let r = [entry("load_offset", 95.0, &[], &[])];
    for f in [-20.0, 30.0] {
        let g = [gate("nominal_poor_fit", Some("torque"), f)];
        let v = run(&r, &g, 95.0, 10.0, [Some(40.0), Some(60.0), Some(95.0)], None, Some(1.0), None);
        assert_eq!(v.kind, "library_effect", "{}", v.headline);
        assert_ne!(v.kind, "rig_mismatch", "{}", v.headline);
    }
}

#[test]
fn a_back_emf_off_the_rig_file_is_a_rig_mismatch_with_the_refit_figures() {
    let r = [entry("load_offset", 95.0, &[], &[])];
    let g = [gate("physics_mismatch", Some("voltage"), 0.77)];
    let refit = Refit {
        changed: vec!["flux_linkage_wb 1.75e-2 → 1.35e-2 (-23 %)".into()],
        primary_shrink_pct: 88.0,
        weighted_shrink_pct: 80.0,
        halves_primary_shrink_pct: (86.0, 87.0),
        stable: true,
        ..Default::default()
    };
    let v = decide_with_refit(&r, &g, &refit, None);
    assert_eq!(v.kind, "rig_mismatch", "{}", v.headline);
    assert!(v.cause.is_none());
    assert_eq!(v.refitted, refit.changed);
    assert!(v.headline.contains("flux_linkage_wb"), "{}", v.headline);
    assert!((v.explained_pct - 88.0).abs() < 1e-9);
}

/// A disturbance that acts on the torque channel with its primary figure
/// there too (an unmeasured force loads the motor).
fn on_torque(d: DisturbanceFit) -> DisturbanceFit {
    DisturbanceFit {
        channels: vec!["torque".into(), "position".into()],
        shrink_by_channel: [("torque".to_string(), d.primary_shrink_pct)].into_iter().collect(),
        ..d
    }
}

fn decide_with_refit(
    ranking: &[RankEntry],
    gates: &[Gate],
    refit: &Refit,
    dist: Option<&DisturbanceFit>,
) -> Verdict {
    // On what the re-fit leaves, a force's steps keep their own figure.
    let rd = dist.map(|d| DisturbanceFit {
        over_stack_points: d.primary_shrink_pct - refit.primary_shrink_pct.max(0.0),
        ..d.clone()
    });
    decide_with_refit_dist(ranking, gates, refit, dist, rd.as_ref())
}

fn decide_with_refit_dist(
    ranking: &[RankEntry],
    gates: &[Gate],
    refit: &Refit,
    dist: Option<&DisturbanceFit>,
    refit_dist: Option<&DisturbanceFit>,
) -> Verdict {
    decide_full(ranking, gates, refit, dist, refit_dist, None)
}

fn decide_full(
    ranking: &[RankEntry],
    gates: &[Gate],
    refit: &Refit,
    dist: Option<&DisturbanceFit>,
    refit_dist: Option<&DisturbanceFit>,
    generic: Option<&GenericFit>,
) -> Verdict {
    let ts = structure(10.0);
    let lib = ranking.first().map_or(0.0, |r| r.primary_shrink_pct);
    decide(&Inputs {
        gates,
        ranking,
        top: ranking.first().map(|r| r.effect.as_str()),
        stack: &[ranking[0].effect.clone()],
        stack_weighted: lib / 2.0,
        stack_primary: lib,
        stack_torque: lib,
        stack_train_fit: FITS,
        dist,
        structure: Some(&ts),
        top_halves: Some((lib, lib, 0.05)),
        back_emf_heldout: Some(1.0),
        implausible_after_stack: None,
        refit: Some(refit),
        refit_dist,
        generic,
    })
}

#[test]
fn a_generic_structure_removing_as_much_as_a_disturbance_leads_it() {
    let r = [entry("current_sensor", 60.0, &[], &[])];
    let refit = Refit {
        changed: vec!["torque_constant_n_m_per_a 1.05e-1 → 1.10e-1 (+5 %)".into()],
        primary_shrink_pct: 58.0,
        halves_primary_shrink_pct: (50.0, 66.0),
        stable: true,
        ..Default::default()
    };
    let d = on_torque(DisturbanceFit {
        base: "nominal".into(),
        primary_shrink_pct: 82.0,
        over_stack_points: 22.0,
        heldout_change_points: 58,
        ..Default::default()
    });
    let drift = |primary: f64| GenericFit {
        class: "gain_drift".into(),
        channel: "torque".into(),
        primary_shrink_pct: primary,
        remainder_shrink_pct: 70.0,
        train_shrink_pct: 60.0,
        ..Default::default()
    };
    // On what the re-fit leaves the steps keep their own 24 points.
    let rd = DisturbanceFit { over_stack_points: 24.0, ..d.clone() };
    // A slow gain removing more than 58 change points: the drift leads.
    let v = decide_full(&r, &[], &refit, Some(&d), Some(&rd), Some(&drift(89.0)));
    assert_eq!(v.kind, "generic_structure", "{}", v.headline);
    assert!(v.headline.contains("at least as much"), "{}", v.headline);
    // Removing less than the disturbance: the disturbance keeps the lead.
    let v = decide_full(&r, &[], &refit, Some(&d), Some(&rd), Some(&drift(75.0)));
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
    // A refused fit names nothing, whatever it removes.
    let mut refused = drift(95.0);
    refused.refused = Some("a gain error, not a drift".into());
    let v = decide_full(&r, &[], &refit, Some(&d), Some(&rd), host_sim::diagnose::generic::named(std::slice::from_ref(&refused)));
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
}

#[test]
fn the_stronger_of_refit_and_disturbance_leads() {
    let r = [entry("viscous_asym", 30.0, &[], &[])];
    let refit = |shrink: f64| Refit {
        changed: vec!["moving_mass_kg 1.407e2 → 2.100e2 (+49 %)".into()],
        primary_shrink_pct: shrink,
        halves_primary_shrink_pct: (shrink, shrink),
        stable: true,
        ..Default::default()
    };
    let d = on_torque(DisturbanceFit {
        base: "nominal".into(),
        primary_shrink_pct: 85.0,
        over_stack_points: 55.0,
        heldout_change_points: 12,
        side: "an external force on the rod".into(),
        ..Default::default()
    });
    // Events no re-fit removes: the disturbance leads, with the re-fit's
    // figure beside it.
    let v = decide_with_refit(&r, &[], &refit(35.0), Some(&d));
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
    assert!(v.headline.contains("an external force on the rod"), "{}", v.headline);
    assert!(v.headline.contains("re-fitting the nominal's own parameters removes"), "{}", v.headline);
    // A re-fit explaining more than the disturbance: a rig mismatch.
    let v = decide_with_refit(&r, &[], &refit(92.0), Some(&d));
    assert_eq!(v.kind, "rig_mismatch", "{}", v.headline);
    // An unstable re-fit is no rig mismatch, whatever it removes.
    let mut unstable = refit(92.0);
    unstable.stable = false;
    let v = decide_with_refit(&r, &[], &unstable, Some(&d));
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
    // A re-fit with no parameter beyond tolerance names no rig mismatch.
    let mut unchanged = refit(92.0);
    unchanged.changed.clear();
    let v = decide_with_refit(&r, &[], &unchanged, None);
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
}

#[test]
fn implausible_fits_block_library_causes_but_not_a_disturbance() {
    let r = [entry("lead_error_cumulative", 82.0, &[], &[])];
    let g = [gate("implausible_fits", None, 2.0)];
    let v = run(&r, &g, 82.0, 10.0, FITS, None, Some(1.0), None);
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
    assert!(
        v.headline.starts_with("**Warning — GATE implausible_fits"),
        "{}",
        v.headline
    );
    // Refitted on what the stack leaves, one effect stays implausible: the
    // stack accounts for the gate, the cause survives.
    let still = Some(vec!["thermal_drift".to_string()]);
    let v = run(&r, &g, 82.0, 10.0, FITS, None, Some(1.0), still);
    assert_eq!(
        v.cause.as_deref(),
        Some("lead_error_cumulative"),
        "{}",
        v.headline
    );
    assert!(
        v.headline.contains("the stack accounts for them"),
        "{}",
        v.headline
    );
    let still = Some(vec!["thermal_drift".to_string(), "backlash".to_string()]);
    let v = run(&r, &g, 82.0, 10.0, FITS, None, Some(1.0), still);
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
    let d = on_torque(DisturbanceFit {
        base: "stack".into(),
        primary_shrink_pct: 90.0,
        over_stack_points: 8.0,
        ..Default::default()
    });
    // On the blocked stack's remainder, adding 8 points: the stack's work,
    // not the disturbance's.
    let v = run(&r, &g, 82.0, 10.0, FITS, Some(&d), Some(1.0), None);
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
    // Adding its own 20 points, or fitted on the nominal residual: a
    // disturbance, the warning still first.
    for d in [
        DisturbanceFit {
            over_stack_points: 25.0,
            ..d.clone()
        },
        DisturbanceFit {
            base: "nominal".into(),
            ..d.clone()
        },
    ] {
        let v = run(&r, &g, 82.0, 10.0, FITS, Some(&d), Some(1.0), None);
        assert_eq!(v.kind, "disturbance", "{}", v.headline);
        assert!(v.headline.starts_with("**Warning"), "{}", v.headline);
    }
}

#[test]
fn a_current_gain_with_a_falling_back_emf_is_a_torque_constant_change() {
    let r = [entry("current_sensor", 75.0, &[], &[("gain_error", 0.06)])];
    // A sensor gain: the back-EMF is the rig file's.
    let v = run(&r, &[], 75.0, 10.0, FITS, None, Some(0.998), None);
    assert_eq!(v.cause.as_deref(), Some("current_sensor"), "{}", v.headline);
    // The flux fell with the torque constant: 6 % of both.
    let v = run(&r, &[], 75.0, 10.0, FITS, None, Some(0.94), None);
    assert_eq!(v.kind, "unexplained", "{}", v.headline);
    assert!(
        v.headline.contains("torque-constant change"),
        "{}",
        v.headline
    );
}

#[test]
fn a_wrong_rig_file_chopped_into_steps_is_a_rig_mismatch() {
    // A payload error: the disturbance chops its smooth weight error into
    // steps and removes a little more than the re-fit, but on what the
    // re-fit leaves its steps add nothing.
    let r = [entry("load_offset", 20.0, &[], &[])];
    let refit = Refit {
        changed: vec!["moving_mass_kg 8.64e1 → 1.48e2 (+71 %)".into()],
        primary_shrink_pct: 89.4,
        halves_primary_shrink_pct: (90.0, 87.0),
        stable: true,
        ..Default::default()
    };
    let d = on_torque(DisturbanceFit {
        base: "nominal".into(),
        primary_shrink_pct: 93.6,
        over_stack_points: 73.6,
        heldout_change_points: 34,
        ..Default::default()
    });
    let chopped = DisturbanceFit {
        over_stack_points: 3.0,
        ..d.clone()
    };
    let v = decide_with_refit_dist(&r, &[], &refit, Some(&d), Some(&chopped));
    assert_eq!(v.kind, "rig_mismatch", "{}", v.headline);
    // The same figures with steps that survive the re-fit: a disturbance.
    let kept = DisturbanceFit {
        over_stack_points: 30.0,
        ..d.clone()
    };
    let v = decide_with_refit_dist(&r, &[], &refit, Some(&kept), Some(&kept));
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
}

#[test]
fn a_small_force_leads_on_the_torque_channel_a_position_only_signal_does_not() {
    // Nothing in the library or the re-fit; a force at a fifth of the
    // motion's own: under the floor on the primary (position) channel, but
    // the strongest explanation on the torque channel.
    let r = [entry("load_offset", 2.7, &[], &[])];
    let small = DisturbanceFit {
        base: "nominal".into(),
        primary_shrink_pct: 23.4,
        over_stack_points: 20.7,
        channels: vec!["torque".into(), "position".into()],
        shrink_by_channel: [("torque".to_string(), 29.8), ("position".to_string(), 23.4)].into_iter().collect(),
        ..Default::default()
    };
    let v = run(&r, &[], 2.7, 10.0, FITS, Some(&small), Some(1.0), None);
    assert_eq!(v.kind, "disturbance", "{}", v.headline);
    assert!((v.explained_pct - 23.4).abs() < 1e-9, "the share as measured: {}", v.explained_pct);
    assert!(v.headline.contains("torque channel 29.8 %"), "{}", v.headline);
    // The same signal on the position channel alone: the scale or its
    // mount, not a force.
    let position_only = DisturbanceFit {
        channels: vec!["position".into()],
        shrink_by_channel: [("torque".to_string(), 0.0), ("position".to_string(), 23.4)].into_iter().collect(),
        ..small.clone()
    };
    let v = run(&r, &[], 2.7, 10.0, FITS, Some(&position_only), Some(1.0), None);
    assert_ne!(v.kind, "disturbance", "{}", v.headline);
    // Locked to the logged signals (a model error following the motion):
    // nothing, however much it removes on the torque channel.
    let locked = DisturbanceFit {
        locked_to_signals: true,
        ..small.clone()
    };
    let v = run(&r, &[], 2.7, 10.0, FITS, Some(&locked), Some(1.0), None);
    assert_ne!(v.kind, "disturbance", "{}", v.headline);
    // On the torque channel but no stronger than the stack there: nothing.
    let weak = DisturbanceFit {
        shrink_by_channel: [("torque".to_string(), 15.0)].into_iter().collect(),
        ..small
    };
    let v = run(&r, &[], 2.7, 10.0, FITS, Some(&weak), Some(1.0), None);
    assert_ne!(v.kind, "disturbance", "{}", v.headline);
}
