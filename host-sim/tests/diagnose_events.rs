//! The time-structure analyses and the disturbance effect on synthetic
//! residuals with known structure: change points at known steps, the
//! energy share after events against its closed form, the dominant period
//! of a sinusoid, Ljung–Box against χ² tables, and the cross-validated
//! piecewise-constant disturbance.

use host_sim::diagnose::disturbance;
use host_sim::diagnose::events::{self, Remainder};
use host_sim::diagnose::residual::{Nominal, Physics, Segment, NCH, POSITION, TORQUE};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DT: f64 = 1e-3;

/// A segment whose torque residual is `r` (other signals: slow, unrelated).
fn seg(r: Vec<f64>, heldout: bool) -> Segment {
    let n = r.len();
    let t: Vec<f64> = (0..n).map(|i| i as f64 * DT).collect();
    let slow: Vec<f64> = t.iter().map(|t| (0.37 * t).sin()).collect();
    let mut s = Segment {
        heldout,
        t_rel: t.clone(),
        t,
        v: slow.clone(),
        a: slow.clone(),
        f_load: slow.clone(),
        iq: slow.clone(),
        x: slow.clone(),
        v_ref: slow,
        // At rest as far as the load regressors go: φ_torque = L/2π exactly.
        omega: vec![0.0; n],
        theta: vec![0.0; n],
        alpha: vec![0.0; n],
        f_ax: vec![0.0; n],
        c_loc: vec![0.0; n],
        sg_m: 10,
        dt: DT,
        ..Default::default()
    };
    s.y[TORQUE] = Some(r.clone());
    s.r[TORQUE] = Some(r);
    s
}

fn noise(n: usize, sd: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d = Normal::new(0.0, sd).unwrap();
    (0..n).map(|_| d.sample(&mut rng)).collect()
}

fn rem(s: &Segment) -> Remainder {
    vec![std::array::from_fn(|c| s.r[c].clone())]
}

/// Steps of ±1 every 700 samples, starting at 500.
fn steps(n: usize) -> (Vec<f64>, Vec<usize>) {
    let at: Vec<usize> = (0..)
        .map(|k| 500 + 700 * k)
        .take_while(|i| *i < n)
        .collect();
    let r = (0..n)
        .map(|i| {
            if at.iter().filter(|a| **a <= i).count() % 2 == 1 {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    (r, at)
}

#[test]
fn change_points_sit_at_the_steps() {
    let n = 8000;
    let (r, at) = steps(n);
    let x: Vec<f64> = r.iter().zip(noise(n, 0.1, 1)).map(|(a, b)| a + b).collect();
    let s = seg(x, true);
    let cps = events::detect(&[&s], &rem(&s), events::STEP_SIGMA);
    assert_eq!(cps[0].len(), at.len(), "{:?} vs {at:?}", cps[0]);
    for (c, a) in cps[0].iter().zip(&at) {
        assert!(c.abs_diff(*a) <= 3, "change point {c} for a step at {a}");
    }
}

#[test]
fn energy_share_after_events_has_its_closed_form() {
    // Residual 1 for 100 samples after each event, 0 elsewhere: all the
    // energy lies within the 300 ms windows; the time share is the windows'
    // 321 samples (20 before, 300 after, the event's own) per event.
    let n = 10_000;
    let ev: Vec<usize> = (0..10).map(|k| 400 + 900 * k).collect();
    let r: Vec<f64> = (0..n)
        .map(|i| {
            if ev.iter().any(|e| i >= *e && i < e + 100) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    let s = seg(r, true);
    let (e, t) = events::share_after(
        &[&s],
        &rem(&s),
        TORQUE,
        std::slice::from_ref(&ev),
        events::EVENT_BEFORE_S,
        events::EVENT_AFTER_S,
    );
    assert!((e - 100.0).abs() < 1e-9, "energy share {e}");
    let expect = 100.0 * (10 * 321) as f64 / n as f64;
    assert!((t - expect).abs() < 1e-9, "time share {t} vs {expect}");
    // Events given as times land on the same samples.
    let times: Vec<f64> = ev.iter().map(|i| *i as f64 * DT).collect();
    assert_eq!(events::events_at(&[&s], &times)[0], ev);
}

#[test]
fn a_sinusoid_is_periodic_at_its_period_and_noise_is_white() {
    let n = 8000;
    let f = 7.0;
    let x: Vec<f64> = (0..n)
        .map(|i| (std::f64::consts::TAU * f * i as f64 * DT).sin())
        .zip(noise(n, 0.2, 2))
        .map(|(a, b)| a + b)
        .collect();
    let s = seg(x, true);
    let ts = events::analyse(
        &[&s],
        &rem(&s),
        TORQUE,
        &[vec![]],
        0.0,
        &events::kinematic_periods(Some(4)),
    );
    let p = ts.dominant_period_s.expect("a period");
    assert!((p - 1.0 / f).abs() <= 2.0 * DT, "period {p} vs {}", 1.0 / f);
    assert_eq!(ts.character, "periodic", "{}", ts.character_why);

    let w = seg(noise(n, 1.0, 3), true);
    let tw = events::analyse(
        &[&w],
        &rem(&w),
        TORQUE,
        &[vec![]],
        0.0,
        &events::kinematic_periods(Some(4)),
    );
    assert!(
        tw.white && tw.ljung_box_p > events::WHITE_P,
        "white noise: p = {}",
        tw.ljung_box_p
    );
    assert_eq!(tw.character, "broadband (white)", "{}", tw.character_why);
}

#[test]
fn ljung_box_matches_chi_square_tables() {
    // χ²(20) upper 5 % point 31.410, 1 % point 37.566 (tables).
    assert!((events::chi2_sf(31.410, 20) - 0.05).abs() < 0.003);
    assert!((events::chi2_sf(37.566, 20) - 0.01).abs() < 0.001);
    // An AR(1) series with ρ = 0.5: Q ≈ n Σ ρ^{2k} ≫ the 1 % point.
    let e = noise(2000, 1.0, 4);
    let mut x = vec![0.0; 2000];
    for i in 1..2000 {
        x[i] = 0.5 * x[i - 1] + e[i];
    }
    let (q, p) = events::ljung_box(&x, 20);
    assert!(q > 500.0 && p < 1e-6, "Q {q}, p {p}");
}

#[test]
fn piecewise_constant_disturbance_is_found_and_noise_is_not_modelled() {
    let n = 8000;
    let phys = Physics::from_rig(&host_sim::config::RigConfig::nominal().unwrap());
    let nominal = Nominal::Physics(phys.clone());
    let w = {
        let mut w = [0.0; NCH];
        w[TORQUE] = 1.0;
        w
    };
    // Steps of 0.2 N·m on a 0.02 N·m floor: training and held-out alike but
    // at other times.
    let mk = |shift: usize, seed: u64, held: bool| {
        let (r, _) = steps(n + shift);
        seg(
            r[shift..]
                .iter()
                .zip(noise(n, 0.02, seed))
                .map(|(a, b)| 0.2 * a + b)
                .collect(),
            held,
        )
    };
    let (tr, he) = (mk(0, 5, false), mk(333, 6, true));
    let (rt, rh) = (rem(&tr), rem(&he));
    let g_h = disturbance::gap(&[&he], &rh, None, &w);
    let (d, _, _) = disturbance::fit(&[&tr], &rt, &[&he], &rh, &nominal, &w, TORQUE, g_h, g_h);
    assert!(
        d.primary_shrink_pct >= 80.0,
        "steps: shrink {:.1} %",
        d.primary_shrink_pct
    );
    // Levels: the force 0.2 N·m / (L/2π) at the nut.
    assert!(
        (d.max_abs_level - 0.2 / phys.k).abs() < 0.1 * 0.2 / phys.k,
        "level {} N",
        d.max_abs_level
    );

    let (tn, hn) = (seg(noise(n, 0.02, 7), false), seg(noise(n, 0.02, 8), true));
    let (rtn, rhn) = (rem(&tn), rem(&hn));
    let g = disturbance::gap(&[&hn], &rhn, None, &w);
    let (dn, _, _) = disturbance::fit(&[&tn], &rtn, &[&hn], &rhn, &nominal, &w, TORQUE, g, g);
    assert!(
        dn.primary_shrink_pct.abs() < 5.0,
        "white noise: shrink {:.1} %",
        dn.primary_shrink_pct
    );
}

#[test]
fn locked_share_weighs_change_points_by_the_energy_they_explain() {
    let s = seg(vec![0.0; 1000], true);
    // One logged event at sample 200: ±50 ms covers 101 of 1000 samples.
    let sig = vec![vec![200]];
    let cps = vec![vec![(210, 3.0), (700, 1.0)]];
    let (lk, ch) = events::locked_share(&[&s], &cps, &sig, 0.05);
    assert!(
        (lk - 75.0).abs() < 1e-9 && (ch - 10.1).abs() < 1e-9,
        "locked {lk} %, chance {ch} %"
    );
    // Equal weights: the share of change points.
    let (lk1, _) = events::locked_share(&[&s], &[vec![(210, 1.0), (700, 1.0)]], &sig, 0.05);
    assert!((lk1 - 50.0).abs() < 1e-9, "{lk1}");
}

#[test]
fn a_force_disturbance_is_carried_to_the_position_channel() {
    // An unmeasured force of ±300 N steps: the torque channel sees
    // (L/2π) F, the position channel the drive train's deflection −c F,
    // each on its floor. The disturbance acts on both and its levels are
    // the force in N.
    let n = 8000;
    let phys = Physics::from_rig(&host_sim::config::RigConfig::nominal().unwrap());
    let nominal = Nominal::Physics(phys.clone());
    let c = 1.5e-7;
    let mk = |shift: usize, seed: u64, held: bool| {
        let (f, _) = steps(n + shift);
        let f: Vec<f64> = f[shift..].iter().map(|v| 300.0 * (2.0 * v - 1.0)).collect();
        let mut s = seg(
            f.iter()
                .zip(noise(n, 0.02, seed))
                .map(|(f, e)| phys.k * f + e)
                .collect(),
            held,
        );
        s.c_loc = vec![c; n];
        let p: Vec<f64> = f
            .iter()
            .zip(noise(n, 1e-6, seed + 100))
            .map(|(f, e)| -c * f + e)
            .collect();
        s.y[POSITION] = Some(p.clone());
        s.r[POSITION] = Some(p);
        s
    };
    let (tr, he) = (mk(0, 11, false), mk(333, 12, true));
    let (rt, rh) = (rem(&tr), rem(&he));
    let w = host_sim::diagnose::fit::channel_weights(&[&tr]);
    let g_h = disturbance::gap(&[&he], &rh, None, &w);
    let mut wp = [0.0; NCH];
    wp[TORQUE] = 1.0;
    let gp = disturbance::gap(&[&he], &rh, None, &wp);
    let (d, _, _) = disturbance::fit(&[&tr], &rt, &[&he], &rh, &nominal, &w, TORQUE, g_h, gp);
    assert_eq!(d.channels, ["torque", "position"], "{d:?}");
    assert_eq!(d.acting_channels, ["torque", "position"]);
    assert!(
        d.acting_weighted_shrink_pct >= 80.0,
        "torque + position: shrink {:.1} %",
        d.acting_weighted_shrink_pct
    );
    assert!(
        (d.max_abs_level - 300.0).abs() < 30.0,
        "level {} N",
        d.max_abs_level
    );
}
