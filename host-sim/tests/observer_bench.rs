//! The observer on rigs a second cylinder could be (`host-sim
//! observer-bench`), in a small variant: the shipped weights on the
//! nominal rig meet their bar on the paper's run, which no training cycle
//! is (held out by trajectory), and weights retrained from a rig's own
//! logs learn what the shipped ones cannot know: the rig's own lead error.

use host_sim::config::RigConfig;
use host_sim::scenario::dataset::{family_draws, generate, is_paper_trajectory, DatasetSpec};
use host_sim::trainer::bench::{retrained, rigs, shipped};

#[test]
fn no_training_cycle_is_the_papers_run() {
    let spec = DatasetSpec::default();
    for (k, &swing) in spec.tilt_swings_deg.iter().enumerate() {
        for top in &spec.tops_m {
            assert!(!is_paper_trajectory(*top, swing), "default cycle {k}: swing {swing}°, top {top} m");
        }
    }
    assert!(is_paper_trajectory(0.45, 30.0));
    // Asked for it, the dataset refuses, naming the cycle.
    let paper = DatasetSpec { tilt_swings_deg: vec![30.0], payload_scales: vec![1.0], tops_m: vec![0.45], family_rigs: 0, identify_friction: false, seed: 3 };
    let e = generate(&RigConfig::nominal().unwrap(), &paper).unwrap_err();
    assert!(format!("{e:#}").contains("the paper's run"), "{e:#}");
}

#[test]
fn family_draws_are_mirrored_so_their_mean_is_the_rig_file() {
    let spec = DatasetSpec::default();
    let d = family_draws(&spec);
    assert_eq!(d.len(), spec.family_rigs + 1);
    let n = spec.family_rigs as f64;
    let mean = |f: &dyn Fn(&host_sim::rigs::Draw) -> f64| d[1..].iter().map(|(_, x)| f(x)).sum::<f64>() / n;
    assert!((mean(&|x| x.stiffness) - 1.0).abs() < 1e-12);
    assert!((mean(&|x| x.coulomb) - 1.0).abs() < 1e-12);
    assert!(mean(&|x| x.lead_error_m_per_m).abs() < 1e-15);
    // Within the asked spread: stiffness ±15 %, friction ±30 %, C7 lead.
    for (name, x) in &d[1..] {
        assert!((0.85..=1.15).contains(&x.stiffness), "{name}");
        assert!((0.7..=1.3).contains(&x.coulomb) && (0.7..=1.3).contains(&x.screw_mu), "{name}");
        assert!(x.lead_error_m_per_m.abs() <= host_sim::rigs::C7_LEAD_ERROR_M_PER_M, "{name}");
    }
}

#[test]
fn shipped_holds_on_nominal_and_retraining_learns_the_lead() {
    let base = RigConfig::nominal().unwrap();
    let chosen: Vec<_> = rigs::bench_rigs(&base).into_iter().filter(|r| r.name == "nominal" || r.name == "lead_+50um_per_300mm").collect();
    assert_eq!(chosen.len(), 2);
    let seed = 6141;
    let s = shipped::run(&chosen, None, seed).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let r = retrained::run(&chosen, 2, seed, dir.path()).unwrap();
    for row in s.iter().chain(&r) {
        eprintln!("{}: {:.0} → {:.1} µm, {:.1} %", row.rig, row.terminal_error_max_um_off, row.terminal_error_max_um_on, row.reduction_pct);
    }
    assert_eq!(s[0].passed, Some(true), "shipped weights on the nominal rig: {:.1} % < 90 %", s[0].reduction_pct);
    // The lead error (75 µm at 450 mm) is not in the shipped weights: they
    // leave it; the route fits the lead from the rig's logs and tells the
    // drive, which then moves in the rod's metres.
    assert!(s[1].reduction_pct < 70.0, "{}", s[1].reduction_pct);
    assert!(r[1].reduction_pct > s[1].reduction_pct + 20.0, "retrained {:.1} % against shipped {:.1} %", r[1].reduction_pct, s[1].reduction_pct);
    // The friction was identified into the feedforward before logging.
    let ff = &r[0].details["route"]["friction_feedforward"]["param_set"];
    assert_eq!(ff.as_array().map(|a| a.len()), Some(2), "{ff}");
    let lead = &r[1].details["route"]["lead"]["fit"]["scale_error"];
    assert!((lead.as_f64().unwrap() - rigs::LEAD_ERROR_M_PER_M).abs() * 0.3e6 < 2.0, "fitted lead error {lead}");
    for row in &r {
        assert!(row.details["logged_motion_s"].as_f64().unwrap() <= retrained::MAX_LOGGED_MOTION_S);
    }
}
