//! Truth rigs for the withheld-effect suite: the nominal rigid-body model of
//! `diagnose::residual::Physics` plus one or two effects of the library with
//! random, physically plausible parameters, in closed loop with a PD +
//! feed-forward position controller and an ideal current loop, integrated at
//! 10 kHz and logged at 1 kHz with encoder (10 000 counts/rev) and scale
//! (1 µm) quantisation and current/voltage noise.
//!
//! This is a lightweight simulator written for the suite (not the full
//! `plant`): the plant has no hooks for most library effects (cogging,
//! backlash as play, lead and thermal errors, sensor gain/offset,
//! eccentricity). It shares only the nominal parameter set with the
//! diagnosis, which is what a truth rig = nominal + effect means.
#![allow(dead_code)]

pub mod truth;

use host_sim::config::RigConfig;
use host_sim::diagnose::effects::Effect;
use host_sim::diagnose::log::Log;
use host_sim::diagnose::residual::Physics;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// An effect with its true parameters (same meaning and order as the
/// library's `params()`, plus the shape parameter where it has one).
#[derive(Clone, Debug)]
pub struct TrueEffect {
    pub effect: Effect,
    pub params: Vec<f64>,
    pub hyper: f64,
}

fn sym(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    let v = rng.random_range(lo..hi);
    if rng.random_bool(0.5) {
        v
    } else {
        -v
    }
}

/// Random plausible parameters of `effect`.
pub fn random_effect(effect: Effect, rng: &mut ChaCha8Rng) -> TrueEffect {
    let (params, hyper) = match effect {
        Effect::CoulombAsym => {
            let big = rng.random_range(0.06..0.15);
            let small = rng.random_range(0.0..0.04);
            if rng.random_bool(0.5) {
                (vec![big, small], 0.0)
            } else {
                (vec![small, big], 0.0)
            }
        }
        Effect::ViscousAsym => {
            let big = rng.random_range(4e-4..1e-3);
            let small = rng.random_range(0.0..2e-4);
            if rng.random_bool(0.5) {
                (vec![big, small], 0.0)
            } else {
                (vec![small, big], 0.0)
            }
        }
        Effect::Stribeck => (vec![rng.random_range(0.08..0.2)], rng.random_range(3.0..20.0)),
        Effect::Backlash => (vec![rng.random_range(20e-6..100e-6)], 0.0),
        Effect::ScrewStiffness => (vec![rng.random_range(2.5e-8..9e-8)], 0.0),
        Effect::HertzContact => (vec![rng.random_range(1.5e-7..4e-7)], 0.0),
        Effect::CouplingCompliance => (vec![rng.random_range(3e-3..8e-3)], 0.0),
        Effect::LeadErrorCumulative => (vec![sym(rng, 50e-6, 200e-6)], 0.0),
        Effect::LeadErrorPerRev => {
            let (a, ph) = (rng.random_range(4e-6..10e-6), rng.random_range(0.0..std::f64::consts::TAU));
            (vec![a * ph.cos(), a * ph.sin()], 0.0)
        }
        Effect::ThermalDrift => (vec![rng.random_range(6e-6..2e-5)], 0.0),
        Effect::Cogging => {
            let (a, ph) = (rng.random_range(0.03..0.08), rng.random_range(0.0..std::f64::consts::TAU));
            let n = [6.0, 8.0, 12.0, 16.0, 24.0][rng.random_range(0..5)];
            (vec![a * ph.cos(), a * ph.sin()], n)
        }
        Effect::DeadTime => (vec![rng.random_range(0.3..1.2)], 0.0),
        Effect::CurrentSensor => (vec![sym(rng, 0.02, 0.06), sym(rng, 0.1, 0.4), sym(rng, 0.1, 0.4)], 0.0),
        Effect::EncoderEccentricity => {
            let (a, ph) = (rng.random_range(2e-3..6e-3), rng.random_range(0.0..std::f64::consts::TAU));
            (vec![a * ph.cos(), a * ph.sin()], 0.0)
        }
        Effect::LoadOffset => (vec![sym(rng, 60.0, 200.0)], 0.0),
    };
    TrueEffect { effect, params, hyper }
}

/// A smooth (cycloidal) point-to-point trajectory with dwells and a slowly
/// varying external force, drawn from `seed`.
pub struct Trajectory {
    pub x: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub f_ext: Vec<f64>,
}

pub fn trajectory(seed: u64, duration_s: f64, dt: f64) -> Trajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let n = (duration_s / dt).round() as usize;
    let (mut x, mut v, mut a) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    let mut pos: f64 = rng.random_range(0.05..0.45);
    let mut moves = usize::from(pos > 0.25);
    while x.len() < n {
        let dwell = rng.random_range(0.1..0.3);
        for _ in 0..(dwell / dt) as usize {
            x.push(pos);
            v.push(0.0);
            a.push(0.0);
        }
        // Moves alternate in direction (an identification experiment
        // excites both), random length and speed.
        let up = moves % 2 == 0;
        moves += 1;
        let len = rng.random_range(0.04..0.15);
        let target: f64 = if up && pos + len <= 0.47 || pos - len < 0.03 { pos + len } else { pos - len };
        let d = target - pos;
        let vmax = rng.random_range(0.05..0.2);
        let amax = 1.5;
        let t_move = (2.0 * d.abs() / vmax).max((std::f64::consts::TAU * d.abs() / amax).sqrt());
        let steps = (t_move / dt).ceil() as usize;
        for k in 1..=steps {
            let tau = k as f64 / steps as f64;
            let w = std::f64::consts::TAU;
            x.push(pos + d * (tau - (w * tau).sin() / w));
            v.push(d / t_move * (1.0 - (w * tau).cos()));
            a.push(d / (t_move * t_move) * w * (w * tau).sin());
        }
        pos = target;
    }
    x.truncate(n);
    v.truncate(n);
    a.truncate(n);
    let (amp, f, ph, off) = (
        rng.random_range(200.0..800.0),
        rng.random_range(0.15..0.5),
        rng.random_range(0.0..std::f64::consts::TAU),
        rng.random_range(-300.0..100.0),
    );
    let f_ext = (0..n).map(|i| off + amp * (std::f64::consts::TAU * f * i as f64 * dt + ph).sin()).collect();
    Trajectory { x, v, a, f_ext }
}

pub fn physics() -> Physics {
    Physics::from_rig(&RigConfig::nominal().expect("shipped rig"))
}

/// Simulates the truth rig on trajectory `seed` for `duration_s`; returns
/// the log in the schema (what the tool gets).
pub fn simulate(p: &Physics, effects: &[TrueEffect], seed: u64, duration_s: f64) -> Log {
    simulate_trajectory(p, effects, seed, &trajectory(seed, duration_s, 1e-3))
}

/// A single cycloidal move from `from` to `to` (m) in `t_move` s after 0.3 s
/// of rest, then rest until `duration_s`; constant external force.
pub fn single_move(from: f64, to: f64, t_move: f64, duration_s: f64) -> Trajectory {
    let dt = 1e-3;
    let n = (duration_s / dt).round() as usize;
    let w = std::f64::consts::TAU;
    let (mut x, mut v, mut a) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let tau = ((i as f64 * dt - 0.3) / t_move).clamp(0.0, 1.0);
        let d = to - from;
        let moving = tau > 0.0 && tau < 1.0;
        x.push(from + d * (tau - (w * tau).sin() / w));
        v.push(if moving { d / t_move * (1.0 - (w * tau).cos()) } else { 0.0 });
        a.push(if moving { d / (t_move * t_move) * w * (w * tau).sin() } else { 0.0 });
    }
    Trajectory { x, v, a, f_ext: vec![0.0; n] }
}

/// `simulate` on a given trajectory (sampled at 1 kHz).
pub fn simulate_trajectory(p: &Physics, effects: &[TrueEffect], seed: u64, tr: &Trajectory) -> Log {
    let dt_log = 1e-3;
    let sub = 10;
    let h = dt_log / sub as f64;
    let n = tr.x.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(7919) + 1);
    let find = |e: Effect| effects.iter().find(|t| t.effect == e);
    let tilt = p.tilt_deg;
    let j_eq = p.j_eq();
    let counts = 10_000.0;
    let q_enc = std::f64::consts::TAU / counts;
    let load_offset = find(Effect::LoadOffset).map_or(0.0, |e| e.params[0]);
    // Start at rest on the reference.
    let mut theta = (tr.x[0] - p.x0) / p.k;
    let mut omega = 0.0;
    let mut alpha: f64 = 0.0;
    let mut play = p.x0 + p.k * theta;
    let mut integ = 0.0;
    let mut omega_est = 0.0;
    let mut theta_meas_prev = f64::NAN;
    let mut i_true_prev = 0.0;
    let wn = std::f64::consts::TAU * 25.0;
    let (kp, kd, ki) = (j_eq * wn * wn, 2.0 * 0.8 * wn * j_eq, j_eq * wn * wn * wn / 10.0);
    let mut cols: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let names = [
        "time_s",
        "position_reference_m",
        "motor_angle_rad",
        "terminal_position_m",
        "current_q_a",
        "voltage_q_v",
        "bus_voltage_v",
        "load_force_n",
        "tilt_deg",
    ];
    for k in names {
        cols.insert(k.into(), Vec::with_capacity(n));
    }
    let ecc =
        |th: f64| find(Effect::EncoderEccentricity).map_or(0.0, |e| e.params[0] * th.sin() + e.params[1] * th.cos());
    let mut f_ax_prev = p.load_n(tr.f_ext[0] + load_offset, tilt);
    for i in 0..n {
        let t = i as f64 * dt_log;
        // --- sample sensors at the period start ---
        let theta_meas = ((theta + ecc(theta)) / q_enc).round() * q_enc;
        if theta_meas_prev.is_nan() {
            theta_meas_prev = theta_meas;
        }
        let w_raw = (theta_meas - theta_meas_prev) / dt_log;
        theta_meas_prev = theta_meas;
        omega_est += 0.3 * (w_raw - omega_est);
        // --- controller ---
        let th_ref = (tr.x[i] - p.x0) / p.k;
        let (w_ref, a_ref) = (tr.v[i] / p.k, tr.a[i] / p.k);
        let f_log = p.load_n(tr.f_ext[i], tilt);
        let e = th_ref - theta_meas;
        integ += e * dt_log;
        let t_cmd =
            j_eq * a_ref + p.k * f_log + p.friction(w_ref, f_log) + kp * e + ki * integ + kd * (w_ref - omega_est);
        let i_meas = (t_cmd / p.kt).clamp(-40.0, 40.0);
        let th_e = p.pole_pairs * theta;
        let i_true = match find(Effect::CurrentSensor) {
            Some(cs) => {
                let o_q = -cs.params[1] * th_e.sin() + cs.params[2] * th_e.cos();
                (i_meas - o_q) / (1.0 + cs.params[0])
            }
            None => i_meas,
        };
        let t_m = p.kt * i_true;
        // --- log (state at the period start) ---
        let f_load_true = p.load_n(tr.f_ext[i] + load_offset, tilt);
        let f_ax = f_load_true + p.m_moving * p.k * alpha;
        let x_motor = p.x0 + p.k * theta;
        let x_in = x_motor;
        if let Some(b) = find(Effect::Backlash) {
            let half = 0.5 * b.params[0];
            if x_in - play > half {
                play = x_in - half;
            } else if x_in - play < -half {
                play = x_in + half;
            }
        } else {
            play = x_in;
        }
        let mut term = play - p.deflection(f_ax, x_motor);
        for te in effects {
            let q = &te.params;
            term += match te.effect {
                Effect::ScrewStiffness => -q[0] * f_ax * x_motor,
                Effect::HertzContact => {
                    let fp = p.contact_preload_n;
                    -q[0] * f_ax.signum() * ((f_ax.abs() + fp).powf(2.0 / 3.0) - fp.powf(2.0 / 3.0))
                }
                Effect::CouplingCompliance => -p.k * q[0] * (t_m - p.j_rot * alpha),
                Effect::LeadErrorCumulative => q[0] * p.k * theta,
                Effect::LeadErrorPerRev => q[0] * theta.sin() + q[1] * theta.cos(),
                Effect::ThermalDrift => q[0] * x_motor * t,
                _ => 0.0,
            };
        }
        let term_meas = (term / 1e-6).round() * 1e-6;
        let didt = (i_true - i_true_prev) / dt_log;
        i_true_prev = i_true;
        let dead = find(Effect::DeadTime).map_or(0.0, |d| d.params[0] * (i_true / 0.1).tanh());
        let u_q = p.r_ohm * i_true
            + p.l_q_h * didt
            + p.pole_pairs * omega * p.flux_wb
            + dead
            + 0.02 * rng.random_range(-1.0..1.0);
        let push = |c: &mut BTreeMap<String, Vec<f64>>, k: &str, v: f64| c.get_mut(k).expect("column").push(v);
        push(&mut cols, "time_s", t);
        push(&mut cols, "position_reference_m", tr.x[i]);
        push(&mut cols, "motor_angle_rad", theta_meas);
        push(&mut cols, "terminal_position_m", term_meas);
        push(&mut cols, "current_q_a", i_meas + 0.02 * (rng.random_range(-1.0..1.0) + rng.random_range(-1.0..1.0)));
        push(&mut cols, "voltage_q_v", u_q);
        push(&mut cols, "bus_voltage_v", 48.0);
        push(&mut cols, "load_force_n", tr.f_ext[i]);
        push(&mut cols, "tilt_deg", tilt);
        // --- integrate the period ---
        for _ in 0..sub {
            let mut t_eff = 0.0;
            let sgn = p.sgn(omega);
            for te in effects {
                let q = &te.params;
                t_eff += match te.effect {
                    Effect::CoulombAsym => q[0] * sgn.max(0.0) + q[1] * sgn.min(0.0),
                    Effect::ViscousAsym => q[0] * omega.max(0.0) + q[1] * omega.min(0.0),
                    Effect::Stribeck => q[0] * (-(omega / te.hyper).powi(2)).exp() * sgn,
                    Effect::Cogging => q[0] * (te.hyper * theta).sin() + q[1] * (te.hyper * theta).cos(),
                    _ => 0.0,
                };
            }
            let fric = p.friction(omega, f_ax_prev);
            alpha = (t_m - t_eff - p.k * f_load_true - fric) / j_eq;
            f_ax_prev = f_load_true + p.m_moving * p.k * alpha;
            omega += alpha * h;
            theta += omega * h;
        }
    }
    Log::from_columns("truth-rig", cols).expect("consistent columns")
}
