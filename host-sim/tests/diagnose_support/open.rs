//! Open-world truth rigs: effects the ranked library does
//! not hold. An unmeasured force with a time course acts in the plant
//! (`UnmodelledEffects::load_pulses`); the sensor and drive effects are
//! applied to the logged signals where they physically arise (between the
//! plant and the log), each described at its function.

use super::random_effect;
use super::truth::plant_effects;
use host_sim::config::RigConfig;
use host_sim::diagnose::effects::Effect;
use host_sim::diagnose::log::Log;
use host_sim::diagnose::residual::{build_segments, Nominal, Physics, POSITION};
use host_sim::plant::UnmodelledEffects;
use host_sim::scenario::identification::{run, Experiment};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

pub const DURATION_S: f64 = 8.0;

/// Out-of-library effects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Novel {
    /// Unmeasured force, piecewise constant, changing every 0.8–2 s.
    ForceSteps,
    /// Short repeated unmeasured force pulses (0.08–0.25 s every 0.6–1.5 s).
    ForcePulses,
    /// Position sensors (encoder, scale) logged 2–5 ms late against current.
    SensorDelay,
    /// A lightly damped motor–rod mode (35–60 Hz, ζ 0.02–0.05) whose
    /// ringing on the position channel is 3–10× the channel's floor.
    StructuralResonance,
    /// Torque constant dropping with magnet temperature over the runs.
    TorqueConstantDrop,
    /// Current sensing saturates at 60 % of the training peak.
    CurrentSaturation,
    /// An encoder miscount burst: 0.02–0.06 rad lost over 40 ms, kept.
    EncoderMiscount,
    /// A column logged coarser than the rig file says, by draw: an encoder
    /// of 250–1000 counts/rev (the file says 10 000), the scale rounded to
    /// 5–20 µm (1 µm), the current rounded to 0.2–0.6 A (a 24 mA ADC).
    Quantisation,
}

pub const NOVEL: [Novel; 8] = [
    Novel::ForceSteps,
    Novel::ForcePulses,
    Novel::SensorDelay,
    Novel::StructuralResonance,
    Novel::TorqueConstantDrop,
    Novel::CurrentSaturation,
    Novel::EncoderMiscount,
    Novel::Quantisation,
];

impl Novel {
    pub fn name(self) -> &'static str {
        match self {
            Novel::ForceSteps => "force_steps",
            Novel::ForcePulses => "force_pulses",
            Novel::SensorDelay => "sensor_delay",
            Novel::StructuralResonance => "structural_resonance",
            Novel::TorqueConstantDrop => "torque_constant_drop",
            Novel::CurrentSaturation => "current_saturation",
            Novel::EncoderMiscount => "encoder_miscount_burst",
            Novel::Quantisation => "quantisation",
        }
    }
    /// An unmeasured force with a time course (the disturbance's target).
    pub fn is_force(self) -> bool {
        matches!(self, Novel::ForceSteps | Novel::ForcePulses)
    }
    /// Characters the remainder may rightly be given.
    pub fn characters(self) -> &'static [&'static str] {
        match self {
            Novel::ForceSteps | Novel::ForcePulses | Novel::EncoderMiscount => &["event-locked"],
            Novel::SensorDelay | Novel::CurrentSaturation => &["event-locked", "input-correlated"],
            // Ringing after every thrust change: periodic, and locked to
            // the events that excite it.
            Novel::StructuralResonance => &["periodic", "event-locked"],
            Novel::TorqueConstantDrop => &["drift", "input-correlated"],
            // A rounding error: noise while the signal crosses cells, a
            // function of the signal while it creeps.
            Novel::Quantisation => &["broadband (white)", "broadband (coloured)", "input-correlated"],
        }
    }
}

/// Characters a held-out library effect's remainder may rightly be given.
pub fn library_characters(e: Effect) -> &'static [&'static str] {
    match e {
        Effect::Cogging | Effect::LeadErrorPerRev | Effect::EncoderEccentricity => &["periodic"],
        Effect::ThermalDrift | Effect::LeadErrorCumulative => &["drift", "input-correlated"],
        Effect::Backlash => &["event-locked", "input-correlated", "drift"],
        // Offsets ripple once per electrical revolution; a gain follows the current.
        Effect::CurrentSensor => &["periodic", "input-correlated"],
        _ => &["input-correlated", "drift", "event-locked"],
    }
}

/// A pair of logs (training, held-out) with the true change times of the
/// held-out one (log time), where the truth has any.
pub struct Logs {
    pub train: Log,
    pub held: Log,
    pub held_events_s: Vec<f64>,
    /// The generic class that should name the truth, with its true
    /// parameters (`delay_ms`, `frequency_hz`, `level_n`), where it has one.
    pub generic_truth: Option<(&'static str, Vec<(&'static str, f64)>)>,
}

fn run_exp(rig: &RigConfig, fx: &UnmodelledEffects, seed: u64) -> Log {
    let exp = Experiment::random(rig, seed, DURATION_S);
    run(rig, fx, &exp, seed).unwrap_or_else(|e| panic!("open truth rig, seed {seed}: {e}"))
}

/// Logs of the nominal rig with library effect `e` (random parameters).
pub fn library_logs(rig: &RigConfig, e: Effect, seed: u64) -> Logs {
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let truth = random_effect(e, &mut rng);
    let fx = plant_effects(rig, std::slice::from_ref(&truth));
    Logs {
        train: run_exp(rig, &fx, 1000 + seed),
        held: run_exp(rig, &fx, 2000 + seed),
        held_events_s: Vec::new(),
        // Held out of the library, a load offset is a constant unmeasured
        // force of its level.
        generic_truth: (e == Effect::LoadOffset).then(|| ("constant_force", vec![("level_n", truth.params[0])])),
    }
}

/// Pulses `[start, duration, level]` in log time over the log.
fn force_schedule(kind: Novel, rng: &mut ChaCha8Rng) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    let mut t = rng.random_range(0.3..1.0);
    while t < DURATION_S {
        match kind {
            Novel::ForceSteps => {
                let len = rng.random_range(0.8..2.0);
                let lvl =
                    rng.random_range(150.0..400.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                out.push([t, len, lvl]);
                t += len;
            }
            _ => {
                let len = rng.random_range(0.08..0.25);
                out.push([t, len, rng.random_range(200.0..500.0)]);
                t += len + rng.random_range(0.6..1.5);
            }
        }
    }
    out
}

fn with_column(
    log: &Log,
    name: &str,
    f: impl Fn(&[f64], &BTreeMap<String, Vec<f64>>) -> Vec<f64>,
) -> Log {
    let mut cols = log.columns.clone();
    let new = f(&cols[name], &log.columns);
    cols.insert(name.into(), new);
    Log::from_columns(&log.source, cols).expect("transformed log")
}

/// Weighted RMS over the diagnosis's segments of the nominal's position
/// residual on `log` (`sig` = None: the channel's floor), or of `sig` (a
/// signal added to the position channel) with the same weights, m.
pub fn position_floor(log: &Log, p: &Physics, sig: Option<&[f64]>) -> f64 {
    let segs = build_segments(log, &Nominal::Physics(p.clone()), p.tilt_deg).expect("segments of a truth log");
    let (mut ss, mut n) = (0.0f64, 0.0f64);
    for sg in &segs {
        let r = sg.r[POSITION].as_ref().expect("position residual");
        for i in 0..sg.len() {
            let v = sig.map_or(r[i], |d| d[sg.first_row + i]);
            ss += (sg.weight(POSITION, i) * v).powi(2);
            n += 1.0;
        }
    }
    (ss / n.max(1.0)).sqrt()
}

/// Logs of a novel truth rig.
pub fn novel_logs(rig: &RigConfig, kind: Novel, seed: u64) -> Logs {
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let none = UnmodelledEffects::default();
    let p = Physics::from_rig(rig);
    match kind {
        Novel::ForceSteps | Novel::ForcePulses => {
            let mut logs = Vec::new();
            let mut held_events = Vec::new();
            for s in [1000 + seed, 2000 + seed] {
                let sched = force_schedule(kind, &mut rng);
                let settle = Experiment::random(rig, s, DURATION_S).settle_s;
                let fx = UnmodelledEffects {
                    load_disturbance_n: 1.0,
                    load_pulses: sched.iter().map(|q| [q[0] + settle, q[1], q[2]]).collect(),
                    ..Default::default()
                };
                held_events = sched.iter().flat_map(|q| [q[0], q[0] + q[1]]).collect();
                logs.push(run_exp(rig, &fx, s));
            }
            let held = logs.pop().expect("two");
            Logs {
                train: logs.pop().expect("two"),
                held,
                held_events_s: held_events,
                generic_truth: None,
            }
        }
        Novel::SensorDelay => {
            let d = rng.random_range(2..=5usize);
            let delay = |v: &[f64], _: &BTreeMap<String, Vec<f64>>| {
                (0..v.len()).map(|i| v[i.saturating_sub(d)]).collect()
            };
            let f = |l: Log| {
                with_column(
                    &with_column(&l, "motor_angle_rad", delay),
                    "terminal_position_m",
                    delay,
                )
            };
            Logs {
                train: f(run_exp(rig, &none, 1000 + seed)),
                held: f(run_exp(rig, &none, 2000 + seed)),
                held_events_s: vec![],
                generic_truth: Some(("delay", vec![("delay_ms", d as f64)])),
            }
        }
        Novel::StructuralResonance => {
            // A lightly damped mode between the screw's thrust and the
            // scale: f and ζ in the range of a motor–rod axial mode of this
            // size of cylinder (35–60 Hz, ζ 0.02–0.05). Its size is set
            // against what the tool can see at all: the ringing's weighted
            // RMS on the position channel is drawn at 3–10× the nominal's
            // own position residual (its floor) on the training run, and
            // that compliance, a constant of the rig, is kept for the
            // held-out run.
            let (fr, zeta, ratio) = (
                rng.random_range(35.0..60.0),
                rng.random_range(0.02..0.05),
                rng.random_range(3.0..10.0),
            );
            let wr = std::f64::consts::TAU * fr;
            // The mode driven by the screw's thrust K_t i_q / (L/2π):
            // y'' + 2ζω y' + ω² y = ω² c_f F; the scale reads its ringing
            // y − c_f F (the static compliance is a library compliance,
            // not a resonance). With c_f = 1 this is the ringing per
            // newton-metre of compliance.
            let ringing = |l: &Log| -> Vec<f64> {
                let (i, t) = (&l.columns["current_q_a"], &l.columns["time_s"]);
                let (mut y, mut v) = (0.0, 0.0);
                (0..t.len())
                    .map(|k| {
                        let dt = if k > 0 { (t[k] - t[k - 1]) / 20.0 } else { 0.0 };
                        let f = p.kt * i[k] / p.k;
                        for _ in 0..20 {
                            v += dt * (wr * wr * (f - y) - 2.0 * zeta * wr * v);
                            y += dt * v;
                        }
                        y - f
                    })
                    .collect()
            };
            let train = run_exp(rig, &none, 1000 + seed);
            let c_f = ratio * position_floor(&train, &p, None) / position_floor(&train, &p, Some(&ringing(&train)));
            let f = |l: Log| {
                let ring = ringing(&l);
                with_column(&l, "terminal_position_m", |x, _| x.iter().zip(&ring).map(|(a, b)| a + c_f * b).collect())
            };
            Logs {
                train: f(train),
                held: f(run_exp(rig, &none, 2000 + seed)),
                held_events_s: vec![],
                generic_truth: Some(("resonance", vec![("frequency_hz", fr), ("damping_ratio", zeta), ("stiffness_n_per_um", 1e-6 / c_f)])),
            }
        }
        Novel::TorqueConstantDrop => {
            // NdFeB flux −0.12 %/K; the magnets warm by ΔT_max (1 − e^{−t/τ})
            // from the training run's start on; the held-out run follows it.
            // The torque constant and the back-EMF are both 1.5 p ψ_f and
            // p ω ψ_f: the drive needs 1/(1 − β ΔT) of the current for the
            // same torque (the plant's torque is the nominal K_t × its
            // current), and the current loop, in steady state, commands
            // u_q = R i_q + L di_q/dt + p ω ψ_f (1 − β ΔT): the logged u_q
            // loses the back-EMF's share and gains R × the extra current.
            let (dtm, tau, beta) = (rng.random_range(40.0..80.0), 3.0, 1.2e-3);
            let warm = move |l: Log, t0: f64| {
                let mut cols = l.columns.clone();
                let (t, i, th, u) = (
                    &l.columns["time_s"],
                    &l.columns["current_q_a"],
                    &l.columns["motor_angle_rad"],
                    &l.columns["voltage_q_v"],
                );
                let n = t.len();
                let drop: Vec<f64> = t
                    .iter()
                    .map(|tk| beta * dtm * (1.0 - (-(tk + t0) / tau).exp()))
                    .collect();
                let i_new: Vec<f64> = (0..n).map(|k| i[k] / (1.0 - drop[k])).collect();
                // Motor speed by central differences of the logged angle.
                let om = |k: usize| {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                    if b > a {
                        (th[b] - th[a]) / (t[b] - t[a])
                    } else {
                        0.0
                    }
                };
                let u_new: Vec<f64> = (0..n)
                    .map(|k| {
                        u[k] + p.r_ohm * (i_new[k] - i[k])
                            - p.pole_pairs * om(k) * p.flux_wb * drop[k]
                    })
                    .collect();
                cols.insert("current_q_a".into(), i_new);
                cols.insert("voltage_q_v".into(), u_new);
                Log::from_columns(&l.source, cols).expect("transformed log")
            };
            let train = warm(run_exp(rig, &none, 1000 + seed), 0.0);
            // The true drift rate as the tool states it: the least-squares
            // slope over the training run's diagnosed rows of the logged
            // torque channel's gain against the nominal. The logged current
            // is 1/(1 − drop) of the nominal's, so the gain less one is
            // drop/(1 − drop) (fraction per s).
            let (mut st, mut sg, mut stt, mut stg, mut m) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for seg in build_segments(&train, &Nominal::Physics(p.clone()), p.tilt_deg).expect("segments") {
                for t in &seg.t {
                    let d = beta * dtm * (1.0 - (-t / tau).exp());
                    let g = d / (1.0 - d);
                    (st, sg, stt, stg, m) = (st + t, sg + g, stt + t * t, stg + t * g, m + 1.0);
                }
            }
            let slope = (m * stg - st * sg) / (m * stt - st * st);
            Logs {
                train,
                held: warm(run_exp(rig, &none, 2000 + seed), DURATION_S),
                held_events_s: vec![],
                generic_truth: Some(("gain_drift", vec![("drift_per_s", slope)])),
            }
        }
        Novel::CurrentSaturation => {
            let train = run_exp(rig, &none, 1000 + seed);
            let lim = 0.6
                * train
                    .get("current_q_a")
                    .expect("current")
                    .iter()
                    .fold(0.0f64, |m, v| m.max(v.abs()));
            let clip = move |i: &[f64], _: &BTreeMap<String, Vec<f64>>| {
                i.iter().map(|v| v.clamp(-lim, lim)).collect()
            };
            Logs {
                train: with_column(&train, "current_q_a", clip),
                held: with_column(&run_exp(rig, &none, 2000 + seed), "current_q_a", clip),
                held_events_s: vec![],
                generic_truth: None,
            }
        }
        Novel::Quantisation => quantised_logs(rig, seed),
        Novel::EncoderMiscount => {
            let burst = |l: Log, rng: &mut ChaCha8Rng| {
                let (tb, lost) = (
                    rng.random_range(1.0..DURATION_S - 1.0),
                    rng.random_range(0.02..0.06),
                );
                let f = move |a: &[f64], cols: &BTreeMap<String, Vec<f64>>| {
                    let t = &cols["time_s"];
                    (0..a.len())
                        .map(|k| a[k] - lost * ((t[k] - tb) / 0.04).clamp(0.0, 1.0))
                        .collect()
                };
                (with_column(&l, "motor_angle_rad", f), tb, lost)
            };
            let (train, _, _) = burst(run_exp(rig, &none, 1000 + seed), &mut rng);
            let (held, tb, lost) = burst(run_exp(rig, &none, 2000 + seed), &mut rng);
            Logs {
                train,
                held,
                held_events_s: vec![tb],
                // The motor angle loses `lost`: the scale − motor difference
                // gains it from then on.
                generic_truth: Some(("count_loss", vec![("lost_rad", lost)])),
            }
        }
    }
}

/// Logs of a rig whose one sensor logs coarser than the rig file says:
/// draw `seed % 3` picks the column (the encoder with fewer counts, the
/// scale rounded, the current rounded), the step drawn in its range; both
/// logs carry it (it is the rig's sensor). The truth is the step in the
/// column's unit.
pub fn quantised_logs(rig: &RigConfig, seed: u64) -> Logs {
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let none = UnmodelledEffects::default();
    let (column, step, floor) = match seed % 3 {
        // An encoder reports the count it has reached: a floor.
        0 => ("motor_angle_rad", std::f64::consts::TAU / rng.random_range(250.0f64..1000.0).round(), true),
        1 => ("terminal_position_m", rng.random_range(5e-6..20e-6), false),
        _ => ("current_q_a", rng.random_range(0.2..0.6), false),
    };
    let q = move |v: &[f64], _: &BTreeMap<String, Vec<f64>>| -> Vec<f64> {
        v.iter().map(|x| step * if floor { (x / step).floor() } else { (x / step).round() }).collect()
    };
    Logs {
        train: with_column(&run_exp(rig, &none, 1000 + seed), column, q),
        held: with_column(&run_exp(rig, &none, 2000 + seed), column, q),
        held_events_s: vec![],
        generic_truth: Some(("quantisation", vec![("step", step)])),
    }
}

/// The nominal rig file with another build's torque constant (flux ×1.3)
/// and payload (+50 %): the "wrong rig file" case.
pub fn mismatched_rig(rig: &RigConfig) -> RigConfig {
    let mut r = rig.clone();
    r.plant.motor.flux_linkage_wb *= 1.3;
    r.plant.rod.payload_mass_kg *= 1.5;
    r
}

/// The nominal rig's logs (no effect).
pub fn nominal_logs(rig: &RigConfig, seed: u64) -> Logs {
    let none = UnmodelledEffects::default();
    Logs {
        train: run_exp(rig, &none, 1000 + seed),
        held: run_exp(rig, &none, 2000 + seed),
        held_events_s: vec![],
        generic_truth: None,
    }
}
