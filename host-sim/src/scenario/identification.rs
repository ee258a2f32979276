//! Identification runs for the sim-to-real diagnosis: the plant
//! (nominal, or a truth rig with `UnmodelledEffects`) in closed loop with
//! the firmware's control core, driven through the core's own planner
//! (`Command::MoveTo`), under a load actuator's force, logged at 1 kHz in
//! the diagnose CSV schema from the core's telemetry — what a real rig's
//! firmware log holds.
//!
//! The experiment is random but fair to every effect: moves of random
//! length alternate in direction with random dwells, the core's speed and
//! acceleration limits are drawn per run, and the external force sweeps
//! the net axial load (weight + force) through zero, so load-dependent
//! stiffness, lost motion and unmeasured load all show.

use crate::config::RigConfig;
use crate::diagnose::log::Log;
use crate::plant::{Plant, UnmodelledEffects};
use crate::sim::ClosedLoop;
use anyhow::{anyhow, bail, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use servo_core::{Command, CommandError, Controller};
use std::collections::BTreeMap;
use std::f64::consts::TAU;

/// One identification experiment.
#[derive(Clone, Debug)]
pub struct Experiment {
    pub duration_s: f64,
    /// Not logged: the loop settles from the plant's initial equilibrium
    /// (a truth rig's effects are not in it) and the load ramps in.
    pub settle_s: f64,
    pub log_rate_hz: f64,
    pub tilt_deg: f64,
    pub start_m: f64,
    /// (dwell before the move, s; target, m) in order.
    pub moves: Vec<(f64, f64)>,
    pub max_velocity_m_s: f64,
    pub max_acceleration_m_s2: f64,
    /// External force `offset + amplitude sin(2π f t + phase)`, N (+ opposes extension).
    pub force_offset_n: f64,
    pub force_amplitude_n: f64,
    pub force_hz: f64,
    pub force_phase_rad: f64,
}

impl Experiment {
    /// A random experiment from `seed` for `rig`, `duration_s` logged.
    pub fn random(rig: &RigConfig, seed: u64, duration_s: f64) -> Experiment {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1d_e47);
        let p = &rig.plant;
        let tilt_deg = p.load.initial_tilt_deg;
        let weight = (p.rod.nut_rod_mass_kg + p.rod.payload_mass_kg) * p.load.gravity_m_s2 * tilt_deg.to_radians().sin();
        let (lo, hi) = (f64::from(rig.control.limits.stroke_min_m) + 0.03, f64::from(rig.control.limits.stroke_max_m) - 0.03);
        let start_m = rng.random_range(lo + 0.05..hi - 0.05);
        let mut moves = Vec::new();
        let mut pos = start_m;
        let mut t = 0.0;
        let mut up = rng.random_bool(0.5);
        while t < duration_s {
            let dwell = rng.random_range(0.1..0.35);
            let len = rng.random_range(0.02..0.12);
            let target = if up && pos + len <= hi || pos - len < lo { pos + len } else { pos - len };
            up = target < pos;
            moves.push((dwell, target));
            t += dwell + 0.15 + (target - pos).abs() / 0.1;
            pos = target;
        }
        Experiment {
            duration_s,
            settle_s: 0.6,
            log_rate_hz: 1000.0,
            tilt_deg,
            start_m,
            moves,
            max_velocity_m_s: rng.random_range(0.05..0.2),
            max_acceleration_m_s2: rng.random_range(0.5..2.5),
            // The net load `weight + force` sweeps through zero.
            force_offset_n: -weight * rng.random_range(0.5..1.0),
            force_amplitude_n: rng.random_range(800.0..1400.0),
            force_hz: rng.random_range(0.15..0.4),
            force_phase_rad: rng.random_range(0.0..TAU),
        }
    }

    /// The external force at log time `t` (ramped in over the settling).
    pub fn force_n(&self, t: f64) -> f64 {
        let ramp = ((t + self.settle_s) / self.settle_s.max(1e-9)).clamp(0.0, 1.0);
        ramp * (self.force_offset_n + self.force_amplitude_n * (TAU * self.force_hz * t + self.force_phase_rad).sin())
    }
}

/// Columns of the log, in the diagnose schema.
pub const COLUMNS: [&str; 9] = [
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

/// Runs `exp` on the rig with `effects`; returns the log (time from the
/// end of the settling). Fails if the core latches a fault.
pub fn run(rig: &RigConfig, effects: &UnmodelledEffects, exp: &Experiment, seed: u64) -> Result<Log> {
    let mut control = crate::sim::with_top_speed(rig.control, exp.max_velocity_m_s as f32);
    control.trajectory.max_acceleration_m_s2 = exp.max_acceleration_m_s2 as f32;
    let x0 = rig.plant.stroke.initial_position_m;
    let r = rig.plant.metres_per_rad();
    // Plant time starts with the settling; a warm-up counts from the log start.
    let mut eff = effects.clone();
    eff.thermal_start_s += exp.settle_s;
    let mut plant = Plant::with_effects(rig.plant.clone(), eff, seed)?;
    plant.set_external_force_n(exp.force_n(-exp.settle_s));
    plant.set_initial_state((exp.start_m - x0) / r, exp.tilt_deg.to_radians());
    let controller =
        Controller::try_new(crate::sim::commissioned_control(control, &plant)).map_err(|e| anyhow!("control parameters: {e:?}"))?;
    let bus = rig.plant.inverter.nominal_bus_voltage_v;
    let mut cl = ClosedLoop::new(controller, plant, bus);
    cl.controller.command(Command::SetHome { position_m: (exp.start_m - x0) as f32 }).map_err(|e| anyhow!("SetHome: {e:?}"))?;
    cl.controller.command(Command::Enable).map_err(|e| anyhow!("Enable: {e:?}"))?;
    let per_log = (f64::from(control.rates.pwm_frequency_hz) / exp.log_rate_hz).round().max(1.0) as u64;
    let dt = per_log as f64 / f64::from(control.rates.pwm_frequency_hz);
    let n_settle = (exp.settle_s / dt).round() as i64;
    let n_log = (exp.duration_s / dt).round() as i64;
    let mut cols: BTreeMap<String, Vec<f64>> = COLUMNS.iter().map(|c| (c.to_string(), Vec::with_capacity(n_log as usize))).collect();
    let mut next = 0usize;
    // Dwell of the next move counts from the end of the previous one.
    let mut rest_since = 0.0;
    let mut moving_to: Option<f64> = None;
    for k in -n_settle..n_log {
        let t = k as f64 * dt;
        let force = exp.force_n(t);
        cl.plant.set_external_force_n(force);
        if let Some(target) = moving_to {
            let reached = (f64::from(cl.controller.telemetry().position_reference_m) + x0 - target).abs() < 1e-6;
            if reached {
                moving_to = None;
                rest_since = t;
            }
        }
        if k >= 0 && moving_to.is_none() && next < exp.moves.len() && t - rest_since >= exp.moves[next].0 {
            let target = exp.moves[next].1;
            match cl.controller.command(Command::MoveTo { position_m: (target - x0) as f32 }) {
                Ok(_) => {
                    moving_to = Some(f64::from((target - x0) as f32) + x0);
                    next += 1;
                }
                Err(CommandError::Busy) => {}
                Err(e) => bail!("MoveTo refused at {t:.3} s: {e:?}"),
            }
        }
        let mut tel = cl.controller.telemetry();
        for _ in 0..per_log {
            tel = cl.step();
        }
        if !tel.faults.is_empty() {
            bail!("fault {:?} latched at {t:.3} s", tel.faults);
        }
        if k < 0 {
            continue;
        }
        // The telemetry describes the last sampling instant of the period.
        let row = [
            t,
            x0 + f64::from(tel.position_reference_m),
            f64::from(tel.motor_angle_rad),
            tel.terminal_position_m.map_or(f64::NAN, f64::from),
            f64::from(tel.current_q_a),
            f64::from(tel.voltage_q_v),
            f64::from(tel.bus_voltage_v),
            force,
            exp.tilt_deg,
        ];
        for (c, v) in COLUMNS.iter().zip(row) {
            cols.get_mut(*c).expect("column").push(v);
        }
    }
    if !rig.plant.sensors.linear_scale_enabled {
        cols.remove("terminal_position_m");
    }
    Log::from_columns("identification-run", cols)
}
