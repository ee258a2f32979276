//! Bad input between logs: a log and a reference that cannot be compared
//! (sampling rates, units told apart by scale) are refused naming the
//! column and the figure; a reference too short to fit the nominal, or one
//! that never reverses, is refused naming the minimum. And the remainder's
//! character never explains a channel with its own measured output.

mod diagnose_support;

use diagnose_support::open::nominal_logs;
use diagnose_support::truth::nominal_rig;
use host_sim::diagnose::diagnose_against;
use host_sim::diagnose::events::input_features;
use host_sim::diagnose::log::Log;
use host_sim::diagnose::residual::{
    build_segments, fit_regression, Nominal, Physics, NREG, TORQUE, VOLTAGE,
};
use host_sim::diagnose::residual::MIN_SAMPLES_PER_REGRESSOR;
use std::collections::BTreeMap;

/// A back-and-forth move logged at `rate_hz` for `dur_s`, current in A.
fn log(name: &str, rate_hz: f64, dur_s: f64, current_scale: f64, one_way: bool) -> Log {
    let n = (rate_hz * dur_s) as usize;
    let t: Vec<f64> = (0..n).map(|k| k as f64 / rate_hz).collect();
    let x: Vec<f64> = t
        .iter()
        .map(|t| {
            if one_way {
                0.01 * t
            } else {
                0.05 * (std::f64::consts::TAU * 0.5 * t).sin()
            }
        })
        .collect();
    let cols = BTreeMap::from([
        ("time_s".to_string(), t.clone()),
        ("position_reference_m".to_string(), x.clone()),
        ("terminal_position_m".to_string(), x.iter().map(|v| v + 1e-5).collect()),
        (
            "current_q_a".to_string(),
            t.iter()
                .map(|t| current_scale * (1.0 + 0.5 * (std::f64::consts::TAU * 0.5 * t).cos()))
                .collect(),
        ),
        ("load_force_n".to_string(), vec![100.0; n]),
    ]);
    Log::from_columns(name, cols).unwrap()
}

#[test]
fn sampling_rates_more_than_one_percent_apart_are_refused_naming_the_column() {
    let reference = log("ref.csv", 1000.0, 6.0, 1.0, false);
    let reg = fit_regression(&reference).unwrap();
    // 1.5 % apart: refused; 0.5 % apart: compared.
    let other = log("log.csv", 985.0, 6.0, 1.0, false);
    let e = diagnose_against(&other, None, Some(&reference), Nominal::Regression(reg.clone()), 0.0)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`time_s`") && e.contains("985.0000 Hz") && e.contains("1000.0000 Hz"), "{e}");
    let close = log("log.csv", 995.0, 6.0, 1.0, false);
    let r = diagnose_against(&close, None, Some(&reference), Nominal::Regression(reg), 0.0);
    assert!(r.as_ref().err().is_none_or(|e| !e.to_string().contains("cannot be compared")), "{:?}", r.err());
}

#[test]
fn a_force_where_a_current_was_logged_is_refused_naming_the_column_and_scale() {
    let reference = log("ref.csv", 1000.0, 6.0, 1.0, false);
    let reg = fit_regression(&reference).unwrap();
    // The same column holding a force in N (hundreds) instead of amperes.
    let other = log("log.csv", 1000.0, 6.0, 300.0, false);
    let e = diagnose_against(&other, None, Some(&reference), Nominal::Regression(reg), 0.0)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`current_q_a`") && e.contains("×300"), "{e}");
}

#[test]
fn a_signal_logged_in_one_log_and_not_the_other_is_refused_naming_the_column() {
    let reference = log("ref.csv", 1000.0, 6.0, 1.0, false);
    let mut without = reference.columns.clone();
    without.remove("load_force_n");
    let without = Log::from_columns("ref_without_load.csv", without).unwrap();
    let reg = fit_regression(&without).unwrap();
    // The log carries a load the reference's nominal has no coefficient for.
    let other = log("log.csv", 1000.0, 6.0, 1.0, false);
    let e = diagnose_against(&other, None, Some(&without), Nominal::Regression(reg), 0.0)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`load_force_n`") && e.contains("logged in `log.csv` but not in the reference `ref_without_load.csv`"), "{e}");
    // Phase currents stand for the q current.
    let mut phases = reference.columns.clone();
    let iq = phases.remove("current_q_a").unwrap();
    phases.insert("current_a_a".into(), iq.clone());
    phases.insert("current_b_a".into(), iq);
    let phases = Log::from_columns("phases.csv", phases).unwrap();
    assert!(host_sim::diagnose::compare::comparable(&reference, &phases, "held-out log").is_ok());
}

#[test]
fn a_reference_too_short_or_one_way_is_refused_naming_the_minimum() {
    let min = MIN_SAMPLES_PER_REGRESSOR * NREG;
    let short = log("short.csv", 1000.0, 0.15, 1.0, false);
    let e = fit_regression(&short).err().expect("refused").to_string();
    assert!(e.contains(&format!("minimum {min}")), "{e}");
    let one_way = log("up.csv", 1000.0, 6.0, 1.0, true);
    let e = fit_regression(&one_way).err().expect("refused").to_string();
    assert!(e.contains("never reverses") && e.contains("at least one reversal"), "{e}");
    // Long enough and reversing: fitted.
    assert!(fit_regression(&log("ok.csv", 1000.0, 6.0, 1.0, false)).is_ok());
}

#[test]
fn the_torque_channel_is_never_explained_by_the_logged_current() {
    let rig = nominal_rig();
    let logs = nominal_logs(&rig, 5);
    let p = Physics::from_rig(&rig);
    let segs = build_segments(&logs.train, &Nominal::Physics(p), 90.0).unwrap();
    let s = &segs[0];
    let mut changed = s.clone();
    // Another current (noise, a drift): the torque channel's own output.
    for (k, i) in changed.iq.iter_mut().enumerate() {
        *i += 0.3 * (k as f64 * 0.37).sin() + 1e-3 * k as f64;
    }
    assert_eq!(input_features(s, TORQUE), input_features(&changed, TORQUE));
    // The voltage channel may use the current (its output is u_q).
    assert_ne!(input_features(s, VOLTAGE), input_features(&changed, VOLTAGE));
}

#[test]
fn a_log_too_short_for_two_parts_is_refused_naming_the_minimum() {
    // 20 samples at 1 kHz: the ±10-sample window twice plus 5 needs 25.
    let short = log("short.csv", 1000.0, 0.02, 1.0, false);
    let p = Physics::from_rig(&nominal_rig());
    let e = diagnose_against(&short, None, None, Nominal::Physics(p), 0.0).err().expect("refused").to_string();
    assert!(e.contains("short.csv") && e.contains("20 rows") && e.contains("at least 25 samples"), "{e}");
}
