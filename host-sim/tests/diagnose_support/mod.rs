//! Truth rigs for the diagnosis tests: library effects with random,
//! physically plausible parameters (`random_effect`), switched on in the
//! full host-sim plant and run in closed loop with the control core
//! (`truth`). The diagnosis shares only the nominal rig with them, which is
//! what a truth rig = nominal + effect means.
#![allow(dead_code)]

pub mod gap;
pub mod open;
pub mod truth;

use host_sim::diagnose::effects::Effect;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

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
        Effect::Stribeck => (
            vec![rng.random_range(0.08..0.2)],
            rng.random_range(3.0..20.0),
        ),
        Effect::Backlash => (vec![rng.random_range(20e-6..100e-6)], 0.0),
        Effect::ScrewStiffness => (vec![rng.random_range(2.5e-8..9e-8)], 0.0),
        Effect::HertzContact => (vec![rng.random_range(1.5e-7..4e-7)], 0.0),
        Effect::CouplingCompliance => (vec![rng.random_range(3e-3..8e-3)], 0.0),
        Effect::LeadErrorCumulative => (vec![sym(rng, 50e-6, 200e-6)], 0.0),
        Effect::LeadErrorPerRev => {
            let (a, ph) = (
                rng.random_range(4e-6..10e-6),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            (vec![a * ph.cos(), a * ph.sin()], 0.0)
        }
        Effect::ThermalDrift => (vec![rng.random_range(6e-6..2e-5)], 0.0),
        Effect::Cogging => {
            let (a, ph) = (
                rng.random_range(0.03..0.08),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            let n = [6.0, 8.0, 12.0, 16.0, 24.0][rng.random_range(0..5)];
            (vec![a * ph.cos(), a * ph.sin()], n)
        }
        Effect::DeadTime => (vec![rng.random_range(0.3..1.2)], 0.0),
        Effect::CurrentSensor => (
            vec![sym(rng, 0.02, 0.06), sym(rng, 0.1, 0.4), sym(rng, 0.1, 0.4)],
            0.0,
        ),
        Effect::EncoderEccentricity => {
            let (a, ph) = (
                rng.random_range(2e-3..6e-3),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            (vec![a * ph.cos(), a * ph.sin()], 0.0)
        }
        Effect::LoadOffset => (vec![sym(rng, 60.0, 200.0)], 0.0),
    };
    TrueEffect {
        effect,
        params,
        hyper,
    }
}

/// A seed base given in the environment (`NAME=9000`): runs that set alone,
/// so a fresh held-out set is drawn without editing the suite.
pub fn seed_base_env(name: &str) -> Option<u64> {
    let v = std::env::var(name).ok()?;
    match v.parse() {
        Ok(n) => Some(n),
        Err(_) => panic!("{name}={v:?}: not a seed (a non-negative integer)"),
    }
}
