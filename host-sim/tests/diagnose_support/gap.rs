//! Truth rigs for the large-gap cases: unmeasured forces from 0.2× to 5×
//! the RMS of the force the motion needs (events synchronised with the
//! motion or not, or a single long step), a wrong rig file alone and with
//! force events, and a healthy reference with a held-out log that carries
//! events. The force acts in the plant (`UnmodelledEffects::load_pulses`);
//! the load actuator holds nothing here (its logged force is zero, the
//! weight stays), so the motion's own force is the scale the events are
//! measured against and, at the top of the range, the nominal's Fit on
//! the log falls below zero.

use super::open::DURATION_S;
use host_sim::config::RigConfig;
use host_sim::diagnose::log::Log;
use host_sim::diagnose::residual::{build_segments, Nominal, Physics};
use host_sim::plant::UnmodelledEffects;
use host_sim::scenario::identification::{run, Experiment};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// When the force events come.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Timing {
    /// Short pulses (0.08–0.25 s every 0.6–1.5 s) on their own clock.
    Free,
    /// Short pulses starting 0–30 ms after each move starts.
    Synced,
    /// One long step (2–4 s) starting 1.5–3.5 s into the log.
    LongStep,
}

/// A rig-file parameter the rig file gets wrong, and the re-fitted
/// parameter that must name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum WrongParam {
    /// Payload mass ×0.6–0.8 or ×1.3–1.6.
    Payload,
    /// Flux linkage (and with it the torque constant) ×0.8–0.87 or ×1.15–1.25.
    Flux,
}

impl WrongParam {
    /// Re-fitted parameter names any of which names this one.
    pub fn refit_names(self) -> &'static [&'static str] {
        match self {
            WrongParam::Payload => &["moving_mass_kg"],
            WrongParam::Flux => &["flux_linkage_wb", "torque_constant_n_m_per_a"],
        }
    }
}

/// A truth: logs, the true held-out events (start, end, level N, log
/// time) and the size factor; `held_clean` is the held-out experiment run
/// without the events (the nominal's own floor on that motion).
pub struct GapLogs {
    pub train: Log,
    pub held: Log,
    pub held_clean: Log,
    /// `held_clean` with exact sensors (no current or bus noise, a 24-bit
    /// ADC, a 1 nm scale; the encoder keeps its counts, which the control
    /// uses): what of the floor is the nominal's modelling error, not noise.
    pub held_clean_exact: Log,
    /// The training experiment without the events: a clean reference of
    /// the same rig, to measure how much of the floor a fit on a
    /// reference removes.
    pub train_clean: Log,
    pub events: Vec<[f64; 3]>,
    pub factor: f64,
    pub f_motion_rms_n: f64,
}

/// The identification experiment with the load actuator holding nothing.
pub fn quiet_experiment(rig: &RigConfig, seed: u64) -> Experiment {
    let mut e = Experiment::random(rig, seed, DURATION_S);
    e.force_offset_n = 0.0;
    e.force_amplitude_n = 0.0;
    e
}

/// RMS about its mean of the nut force the logged motion needs (inertia,
/// seal friction, load), from the nominal model, N.
pub fn motion_force_rms(rig: &RigConfig, log: &Log) -> f64 {
    let p = Physics::from_rig(rig);
    let segs = build_segments(log, &Nominal::Physics(p.clone()), p.tilt_deg).expect("segments");
    let f: Vec<f64> = segs.iter().flat_map(|s| s.f_ax.iter().copied()).collect();
    let m = f.iter().sum::<f64>() / f.len() as f64;
    (f.iter().map(|x| (x - m).powi(2)).sum::<f64>() / f.len() as f64).sqrt()
}

/// Move starts of a log (reference speed rising through 5 % of its peak), s.
pub fn move_starts(log: &Log) -> Vec<f64> {
    let t = log.get("time_s").expect("time");
    let x = log.get("position_reference_m").expect("reference");
    let v: Vec<f64> = (0..t.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(t.len() - 1));
            (x[b] - x[a]) / (t[b] - t[a])
        })
        .collect();
    let vmax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    (1..t.len())
        .filter(|k| v[*k].abs() >= 0.05 * vmax && v[k - 1].abs() < 0.05 * vmax)
        .map(|k| t[k])
        .collect()
}

fn schedule(timing: Timing, level: f64, starts: &[f64], rng: &mut ChaCha8Rng) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    match timing {
        Timing::Free => {
            let mut t = rng.random_range(0.3..1.0);
            while t < DURATION_S - 0.3 {
                let len = rng.random_range(0.08..0.25);
                out.push([t, t + len, level]);
                t += len + rng.random_range(0.6..1.5);
            }
        }
        Timing::Synced => {
            for s in starts {
                let t = s + rng.random_range(0.0..0.03);
                let len = rng.random_range(0.08..0.25);
                if t + len < DURATION_S - 0.1 {
                    out.push([t, t + len, level]);
                }
            }
        }
        Timing::LongStep => {
            let t = rng.random_range(1.5..3.5);
            out.push([t, t + rng.random_range(2.0..4.0), level]);
        }
    }
    out
}

/// One log of the experiment `seed` with force events (`factor` × the
/// motion's force RMS measured on that experiment without them).
fn with_events(rig: &RigConfig, seed: u64, timing: Timing, factor: f64, sign: f64, rng: &mut ChaCha8Rng) -> (Log, Vec<[f64; 3]>, f64, Log) {
    let exp = quiet_experiment(rig, seed);
    let clean = run(rig, &UnmodelledEffects::default(), &exp, seed).expect("clean run");
    let f_rms = motion_force_rms(rig, &clean);
    let sched = schedule(timing, sign * factor * f_rms, &move_starts(&clean), rng);
    let fx = UnmodelledEffects {
        load_disturbance_n: 1.0,
        load_pulses: sched
            .iter()
            .map(|q| [q[0] + exp.settle_s, q[1] - q[0], q[2]])
            .collect(),
        ..Default::default()
    };
    (run(rig, &fx, &exp, seed).expect("run with events"), sched, f_rms, clean)
}

/// Force events of `timing` at a size factor drawn log-uniform in
/// [0.2, 5] (or `factor` if given) on both the training and the held-out
/// log (each its own experiment and events).
pub fn force_logs(rig: &RigConfig, timing: Timing, factor: Option<f64>, seed: u64) -> GapLogs {
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed ^ 0x6a9);
    let factor = factor.unwrap_or_else(|| (rng.random_range(0.2f64.ln()..5f64.ln())).exp());
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let (train, _, _, train_clean) = with_events(rig, 1000 + seed, timing, factor, sign, &mut rng);
    let (held, events, f_rms, held_clean) = with_events(rig, 2000 + seed, timing, factor, sign, &mut rng);
    let mut exact = rig.clone();
    let se = &mut exact.plant.sensors;
    se.current_noise_a = 0.0;
    se.bus_voltage_noise_v = 0.0;
    se.adc_bits = 24;
    se.linear_scale_resolution_m = 1e-9;
    let held_clean_exact = run(&exact, &UnmodelledEffects::default(), &quiet_experiment(rig, 2000 + seed), 2000 + seed).expect("exact-sensor run");
    GapLogs {
        train,
        held,
        held_clean,
        held_clean_exact,
        train_clean,
        events,
        factor,
        f_motion_rms_n: f_rms,
    }
}

/// The rig file with one parameter wrong (random side and size).
pub fn wrong_rig(rig: &RigConfig, which: WrongParam, seed: u64) -> (RigConfig, f64) {
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed ^ 0x3c1);
    let mut r = rig.clone();
    let up = rng.random_bool(0.5);
    let f = match which {
        WrongParam::Payload => {
            let f = if up { rng.random_range(1.3..1.6) } else { rng.random_range(0.6..0.8) };
            r.plant.rod.payload_mass_kg *= f;
            f
        }
        WrongParam::Flux => {
            let f = if up { rng.random_range(1.15..1.25) } else { rng.random_range(0.8..0.87) };
            r.plant.motor.flux_linkage_wb *= f;
            f
        }
    };
    (r, f)
}

/// The nominal rig's logs on two random identification experiments (the
/// load actuator sweeping the net load through zero).
pub fn nominal_pair(rig: &RigConfig, seed: u64) -> (Log, Log) {
    let none = UnmodelledEffects::default();
    let go = |s: u64| run(rig, &none, &Experiment::random(rig, s, DURATION_S), s).expect("run");
    (go(1000 + seed), go(2000 + seed))
}

/// The nominal rig on a quiet experiment (the load actuator holding
/// nothing), no events: a healthy reference of the same kind of motion.
pub fn quiet_nominal(rig: &RigConfig, seed: u64) -> Log {
    run(rig, &UnmodelledEffects::default(), &quiet_experiment(rig, seed), seed).expect("run")
}
