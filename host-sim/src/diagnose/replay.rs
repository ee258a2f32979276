//! Closed-loop replay: the nominal plant and the very control
//! core of the firmware, driven by the logged reference and load, every
//! logged signal compared with its replayed counterpart.
//!
//! The core plans its own jerk-limited moves (`Command::MoveTo`); the replay
//! issues one at each logged move start (the reference leaving rest) towards
//! the logged rest position, with the core's trajectory limits set to the
//! logged peak speed and acceleration, and feeds the remaining difference
//! between the logged reference and the core's as the external position
//! shift (bounded by `faults.observer_shift_max_m`; the share of samples
//! where it saturates is reported). The plant takes the logged external
//! force and tilt. Replay covers the first run of the log, up to `max_s`.

use super::log::Log;
use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::ClosedLoop;
use anyhow::{bail, Result};
use servo_core::{Command, Controller};

/// (time, logged, replayed) samples of one signal.
pub type Trace = Vec<(f64, f64, f64)>;

#[derive(Clone, Debug, serde::Serialize)]
pub struct SignalComparison {
    pub signal: String,
    /// 100·(1 − ‖logged − replayed‖/‖logged − mean‖).
    pub fit_pct: f64,
    pub rms_difference: f64,
    pub samples: usize,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Replay {
    pub simulated_s: f64,
    pub wall_s: f64,
    pub moves: usize,
    /// Samples where the reference difference exceeded the shift bound, %.
    pub shift_saturated_pct: f64,
    pub signals: Vec<SignalComparison>,
    /// Why the replay stopped early, if it did (a latched fault).
    pub aborted: Option<String>,
    /// Replayed traces (time, logged, replayed) per signal, for plots.
    #[serde(skip)]
    pub traces: Vec<(String, Trace)>,
}

/// Replays the first run of `log` (at most `max_s` seconds).
pub fn replay(rig: &RigConfig, log: &Log, max_s: f64) -> Result<Replay> {
    let t0 = std::time::Instant::now();
    let Some(reference) = log.get("position_reference_m") else {
        bail!("replay needs position_reference_m");
    };
    let (s, e) = log
        .segments()
        .into_iter()
        .next()
        .ok_or_else(|| anyhow::anyhow!("empty log"))?;
    let time = &log.get("time_s").expect("required")[s..e];
    let refx = &reference[s..e];
    let n = time.iter().take_while(|t| **t - time[0] <= max_s).count();
    if n < 10 {
        bail!("replay: fewer than 10 samples");
    }
    let dt = (time[n - 1] - time[0]) / (n - 1) as f64;
    let vref: Vec<f64> = (0..n)
        .map(|i| (refx[(i + 1).min(n - 1)] - refx[i.saturating_sub(1)]) / (dt * 2.0))
        .collect();
    let aref: Vec<f64> = (0..n)
        .map(|i| (vref[(i + 1).min(n - 1)] - vref[i.saturating_sub(1)]) / (dt * 2.0))
        .collect();
    let vmax = vref.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let amax = aref.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut control = rig.control;
    if vmax > 1e-6 {
        let top = (vmax as f32).min(control.trajectory.max_velocity_m_s.max(vmax as f32));
        control = crate::sim::with_top_speed(control, top);
    }
    if amax > 1e-6 {
        control.trajectory.max_acceleration_m_s2 =
            (amax as f32).clamp(0.05, 2.0 * control.trajectory.max_acceleration_m_s2);
    }
    let mut plant = Plant::new(rig.plant.clone(), 1);
    let x0 = rig.plant.stroke.initial_position_m;
    let k = rig.plant.screw.lead_m / std::f64::consts::TAU;
    let tilt = log.get("tilt_deg").map(|v| &v[s..e]);
    let f_ext = log.get("load_force_n").map(|v| &v[s..e]);
    let tilt0 = tilt.map_or(rig.plant.load.initial_tilt_deg, |v| v[0]);
    plant.set_external_force_n(f_ext.map_or(0.0, |v| v[0]));
    plant.set_initial_state((refx[0] - x0) / k, tilt0.to_radians());
    let controller = Controller::try_new(crate::sim::commissioned_control(control, &plant))
        .map_err(|e| anyhow::anyhow!("rig: {e}"))?;
    let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.controller
        .command(Command::SetHome {
            position_m: (refx[0] - x0) as f32,
        })
        .map_err(|e| anyhow::anyhow!("replay: SetHome refused: {e:?}"))?;
    cl.controller
        .command(Command::Enable)
        .map_err(|e| anyhow::anyhow!("replay: Enable refused: {e:?}"))?;
    let per_log = (dt * f64::from(control.rates.pwm_frequency_hz))
        .round()
        .max(1.0) as u64;
    let shift_max = f64::from(control.faults.observer_shift_max_m) * 0.95;
    let rest = |i: usize| vref[i].abs() < 0.01 * vmax.max(1e-9);
    let mut moves = 0;
    let mut saturated = 0usize;
    let mut aborted = None;
    let names = [
        "position_reference_m",
        "motor_angle_rad",
        "terminal_position_m",
        "current_q_a",
        "voltage_q_v",
    ];
    let mut traces: Vec<(String, Trace)> = names
        .iter()
        .filter(|name| log.has(name))
        .map(|name| (name.to_string(), Vec::with_capacity(n)))
        .collect();
    // Logged moves: (start, end, target). Each is issued so that the core's
    // move (duration estimated from its limits) is centred on the logged one.
    let (vc, ac, jc) = (
        f64::from(control.trajectory.max_velocity_m_s),
        f64::from(control.trajectory.max_acceleration_m_s2),
        f64::from(control.trajectory.max_jerk_m_s3),
    );
    let mut planned = Vec::new();
    let mut a = 1;
    while a < n {
        if rest(a - 1) && !rest(a) {
            let mut b = a;
            while b < n && !rest(b) {
                b += 1;
            }
            let d = (refx[b.min(n - 1)] - refx[a - 1]).abs();
            let t_core = (d / vc + vc / ac + ac / jc).max(2.0 * (d / ac).sqrt() + ac / jc);
            let t_log = (b - a) as f64 * dt;
            let start = a + (((t_log - t_core) / 2.0).max(0.0) / dt).round() as usize;
            planned.push((start, refx[b.min(n - 1)] - x0));
            a = b;
        }
        a += 1;
    }
    let mut next_move = 0;
    let mut i = 0;
    while i < n {
        // Inputs for this sample interval.
        if let Some(f) = f_ext {
            cl.plant.set_external_force_n(f[i]);
        }
        if let Some(tl) = tilt {
            cl.plant.set_tilt_rad(tl[i].to_radians());
        }
        if next_move < planned.len() && i >= planned[next_move].0 {
            let target = planned[next_move].1;
            if cl
                .controller
                .command(Command::MoveTo {
                    position_m: target as f32,
                })
                .is_ok()
            {
                moves += 1;
                next_move += 1;
            }
        }
        let tel = cl.controller.telemetry();
        let diff = refx[i] - x0 - f64::from(tel.position_reference_m);
        if diff.abs() > shift_max {
            saturated += 1;
        }
        let _ = cl.controller.command(Command::SetPositionShift {
            shift_m: diff.clamp(-shift_max, shift_max) as f32,
        });
        let mut tel = tel;
        for _ in 0..per_log {
            tel = cl.step();
        }
        if !tel.faults.is_empty() {
            aborted = Some(format!(
                "fault {:?} latched at log time {:.3} s",
                tel.faults, time[i]
            ));
            break;
        }
        let st = cl.sampled_state();
        for (name, tr) in &mut traces {
            let logged = log.get(name).expect("has")[s + i];
            let replayed = match name.as_str() {
                "position_reference_m" => {
                    x0 + f64::from(tel.position_reference_m) + f64::from(tel.position_shift_m)
                }
                "motor_angle_rad" => st.theta_m_rad,
                "terminal_position_m" => st.terminal_position_m,
                "current_q_a" => f64::from(tel.current_q_a),
                _ => f64::from(tel.voltage_q_v),
            };
            tr.push((time[i], logged, replayed));
        }
        i += 1;
    }
    let signals = traces
        .iter()
        .map(|(name, tr)| {
            let m = tr.iter().map(|p| p.1).sum::<f64>() / tr.len().max(1) as f64;
            let se: f64 = tr.iter().map(|p| (p.1 - p.2).powi(2)).sum();
            let sy: f64 = tr.iter().map(|p| (p.1 - m).powi(2)).sum();
            SignalComparison {
                signal: name.clone(),
                fit_pct: if sy > 0.0 {
                    100.0 * (1.0 - (se / sy).sqrt())
                } else {
                    f64::NAN
                },
                rms_difference: (se / tr.len().max(1) as f64).sqrt(),
                samples: tr.len(),
            }
        })
        .collect();
    Ok(Replay {
        simulated_s: cl.time_s(),
        wall_s: t0.elapsed().as_secs_f64(),
        moves,
        shift_saturated_pct: 100.0 * saturated as f64 / i.max(1) as f64,
        signals,
        aborted,
        traces,
    })
}
