//! Six closed-loop legs following a pose trajectory through the core's
//! streamed setpoints (`Command::Stream`), one setpoint per leg per
//! position-loop period (1 kHz).
//!
//! Each period k (t_k = k T_s from the stream's start):
//! - the commanded pose state q(t_k) gives each leg its IK length as a
//!   stroke position (l − l_min, as in `six_legs`) and its length rate
//!   l̇ = J_q q̇ (analytic, `pose_jacobian`), and optionally its axial force
//!   from the plate dynamics plus its own rod's weight along the leg as
//!   `force_n` feedforward;
//! - the legs run one position-loop period; the loads are coupled through
//!   the plate exactly as in `six_legs` (FK of the six position references,
//!   rate and acceleration by differencing; see there for why references);
//! - the pose is solved by forward kinematics from the six rods and
//!   compared with the commanded pose at the reference's time.
//!
//! Time alignment: the core interpolates the setpoints over their measured
//! arrival interval, so its reference runs one setpoint interval behind
//! what was sent. After the period that follows setpoint k (at t_k + T_s)
//! the reference is q(t_k); the rods are compared with q(t_k), i.e. with the
//! commanded pose at the reference's time. `reference_lag_check_um` measures
//! that lag rather than assuming it.
//!
//! The trajectory is entered from rest: the legs first move (`MoveTo`) to
//! q(0)'s lengths, then the stream runs q0 + s(t)(Q(t) − q0) with s a
//! quintic smoothstep over the first `ramp_s` of the trajectory's own
//! clock, so no setpoint jumps in velocity; past `ramp_s` it is Q(t).

use super::dynamics::PoseState;
use super::kinematics::{Platform, Pose};
use super::six_legs::{new_leg, LegLoop, LegSetup, RigSpread, Worker, START_STROKE_M};
use super::trajectory::Trajectory;
use super::GRAVITY_M_S2;
use crate::config::RigConfig;
use anyhow::{anyhow, bail, Result};
use nalgebra::Vector6;
use servo_core::{Command, CommandOutcome, LimitFlags};

/// How a streamed run is made.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct StreamOptions {
    pub compensation: bool,
    /// Send each leg's expected axial load as the setpoint's `force_n`.
    pub force_feedforward: bool,
    pub spread: RigSpread,
    pub seed: u64,
    /// Length of the smoothstep entry into the trajectory (part of its
    /// duration), s.
    pub ramp_s: f64,
    /// Stream only the first this-many seconds of the trajectory; `None`:
    /// all of it.
    pub duration_s: Option<f64>,
    /// Every sine amplitude of the trajectory times this; `None`: the
    /// largest ≤ 1 that keeps every leg's rate within `SPEED_MARGIN` of the
    /// core's streaming velocity bound (`trajectory.max_velocity_m_s`).
    pub amplitude_scale: Option<f64>,
}

/// The fitted trajectories' peak leg rate, as a fraction of the core's
/// velocity bound: the position loop needs headroom above the feedforward.
pub const SPEED_MARGIN: f64 = 0.9;

impl StreamOptions {
    pub fn new(compensation: bool, force_feedforward: bool, spread: RigSpread) -> Self {
        Self { compensation, force_feedforward, spread, seed: 1, ramp_s: 1.0, duration_s: None, amplitude_scale: None }
    }
}

/// Per position-loop period, over the stream (plotted, not serialised).
#[derive(Clone, Debug, Default)]
pub struct StreamTrace {
    pub time_s: Vec<f64>,
    /// FK(rods) − commanded pose at the reference's time: mm, degrees.
    pub pose_error: Vec<[f64; 6]>,
    /// Rod length − commanded length at the reference's time, µm.
    pub terminal_error_um: Vec<[f64; 6]>,
    /// Position reference − motor side, µm.
    pub motor_tracking_um: Vec<[f64; 6]>,
}

/// One streamed run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StreamRun {
    pub trajectory: &'static str,
    pub options: StreamOptions,
    /// The amplitude scale streamed, and the largest leg rate at scale 1
    /// and as streamed, m/s.
    pub amplitude_scale: f64,
    pub peak_leg_rate_full_m_s: f64,
    pub peak_leg_rate_streamed_m_s: f64,
    pub streamed_s: f64,
    pub setpoints_per_leg: usize,
    /// |FK(rods) − q(t − T_s)|: position mm, attitude (norm of the Euler
    /// differences) degrees, RMS and max over the stream.
    pub pose_error_position_rms_mm: f64,
    pub pose_error_position_max_mm: f64,
    pub pose_error_attitude_rms_deg: f64,
    pub pose_error_attitude_max_deg: f64,
    /// Rod − commanded length at the reference's time, per leg, µm.
    pub terminal_error_rms_um: [f64; 6],
    pub terminal_error_max_um: [f64; 6],
    /// Position reference − motor side (telemetry), per leg, RMS µm: how
    /// well each drive tracks its own streamed reference.
    pub motor_tracking_rms_um: [f64; 6],
    /// Position reference − commanded length at lag 0, 1, 2 setpoint
    /// intervals, RMS over legs and stream, µm (the smallest names the lag).
    pub reference_lag_check_um: [f64; 3],
    /// Limit flags any leg reported while streaming (debug form).
    pub limits_seen: String,
    /// Whole run (entry move, stream, stop), simulated and wall-clock.
    pub simulated_s: f64,
    pub wall_s: f64,
    pub sim_realtime_factor: f64,
    #[serde(skip)]
    pub trace: StreamTrace,
}

/// s(u) = 10u³ − 15u⁴ + 6u⁵ on [0, 1] and its first two derivatives in t.
fn smoothstep(t: f64, ramp_s: f64) -> (f64, f64, f64) {
    if ramp_s <= 0.0 || t >= ramp_s {
        return (1.0, 0.0, 0.0);
    }
    let u = (t / ramp_s).max(0.0);
    let s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
    let ds = 30.0 * u * u * (1.0 - u) * (1.0 - u) / ramp_s;
    let dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (ramp_s * ramp_s);
    (s, ds, dds)
}

/// The commanded pose state t seconds into the stream.
pub fn commanded(traj: &Trajectory, ramp_s: f64, t: f64) -> PoseState {
    let full = traj.state(t);
    if t >= ramp_s {
        return full;
    }
    // During the ramp the trajectory's motion is faded in from its first
    // pose: q = q0 + s (Q(t) − q0); at t = ramp_s s = 1, ṡ = s̈ = 0.
    let q0 = traj.state(0.0).pose.to_vector();
    let (s, ds, dds) = smoothstep(t, ramp_s);
    let dq = full.pose.to_vector() - q0;
    PoseState {
        pose: Pose::from_vector(&(q0 + s * dq)),
        velocity: ds * dq + s * full.velocity,
        acceleration: dds * dq + 2.0 * ds * full.velocity + s * full.acceleration,
    }
}

/// The trajectory with every sine's amplitude times `k`.
pub fn scaled(traj: &Trajectory, k: f64) -> Trajectory {
    let mut t = traj.clone();
    for s in t.sines.iter_mut().flatten() {
        s.amplitude *= k;
    }
    t
}

/// The largest |l̇_i| along the streamed (ramped) trajectory, sampled at
/// 1 kHz, m/s.
pub fn peak_leg_rate(p: &Platform, traj: &Trajectory, ramp_s: f64) -> f64 {
    let n = (traj.duration_s * 1000.0).round() as usize;
    (0..=n)
        .map(|k| {
            let s = commanded(traj, ramp_s, k as f64 * 1e-3);
            (p.pose_jacobian(&s.pose) * s.velocity).amax()
        })
        .fold(0.0, f64::max)
}

/// The amplitude scale ≤ 1 that brings the peak leg rate to `v_max_m_s`
/// (rate is nearly linear in amplitude; two corrections settle it), with
/// the peak leg rates at scale 1 and at that scale (each pass samples the
/// whole trajectory: the run reports these rather than sample it again).
pub fn fit_scale(p: &Platform, traj: &Trajectory, ramp_s: f64, v_max_m_s: f64) -> (f64, f64, f64) {
    let full = peak_leg_rate(p, traj, ramp_s);
    let (mut k, mut peak): (f64, f64) = (1.0, full);
    for _ in 0..3 {
        if peak <= v_max_m_s {
            break;
        }
        k *= 0.995 * v_max_m_s / peak;
        peak = peak_leg_rate(p, &scaled(traj, k), ramp_s);
    }
    (k.min(1.0), full, peak)
}

fn check_options(o: &StreamOptions, traj: &Trajectory) -> Result<()> {
    if !(o.ramp_s.is_finite() && o.ramp_s >= 0.0) {
        bail!("stream ramp_s must be finite and ≥ 0, got {}", o.ramp_s);
    }
    if let Some(d) = o.duration_s {
        if !(d.is_finite() && d > 0.0 && d <= traj.duration_s) {
            bail!("stream duration_s must be in (0, {}] s (trajectory `{}`), got {d}", traj.duration_s, traj.name);
        }
    }
    if let Some(k) = o.amplitude_scale {
        if !(k.is_finite() && k > 0.0) {
            bail!("stream amplitude_scale must be finite and > 0, got {k}");
        }
    }
    Ok(())
}

/// Runs the six legs along `traj` by streamed setpoints.
pub fn run_stream(p: &Platform, rig: &RigConfig, full: &Trajectory, o: &StreamOptions) -> Result<StreamRun> {
    check_options(o, full)?;
    let started = std::time::Instant::now();
    let v_max = f64::from(rig.control.trajectory.max_velocity_m_s);
    let (scale, peak_full, peak_streamed) = match o.amplitude_scale {
        Some(k) => (k, peak_leg_rate(p, full, o.ramp_s), peak_leg_rate(p, &scaled(full, k), o.ramp_s)),
        None => fit_scale(p, full, o.ramp_s, SPEED_MARGIN * v_max),
    };
    let traj = &scaled(full, scale);
    let peak_rates = (peak_full, peak_streamed);
    let lmin = p.geometry.leg_min_length_m;
    let l0 = p.geometry.leg_initial_length_m;
    let stream_s = o.duration_s.unwrap_or(traj.duration_s);
    // Refuse a trajectory outside the workspace before any leg moves.
    let divider = u64::from(rig.control.rates.position_loop_divider);
    let dt = divider as f64 / f64::from(rig.control.rates.pwm_frequency_hz);
    let n = (stream_s / dt).round() as usize;
    for k in (0..=n).step_by(10) {
        let t = k as f64 * dt;
        p.inverse_checked(&commanded(traj, o.ramp_s, t).pose).map_err(|e| anyhow!("trajectory `{}` at t = {t:.3} s: {e}", traj.name))?;
    }
    let start = p.forward(&[l0 + START_STROKE_M; 6], &p.home()).map_err(|e| anyhow!("start pose: {e}"))?.pose;
    let at_rest = |pose: Pose| PoseState { pose, velocity: Vector6::zeros(), acceleration: Vector6::zeros() };
    let f0 = p.leg_forces(&at_rest(start)).map_err(|e| anyhow!("start pose: {e}"))?.forces_n;
    let setup = LegSetup { rig, spread: &o.spread, seed: o.seed, compensation: o.compensation };
    let mut legs: Vec<Box<LegLoop>> = (0..6).map(|i| new_leg(&setup, p, i, &start, f0[i])).collect::<Result<_>>()?;
    let worker = Worker::spawn();
    let mut plate = Plate { pose: start, hist: [start.to_vector(); 3], dt };
    // Settle, then move at rest to the trajectory's first pose.
    let settle = (0.3 / dt).round() as usize;
    for _ in 0..settle {
        plate.couple(p, &worker, &mut legs, divider)?;
    }
    let first = p.inverse_checked(&commanded(traj, o.ramp_s, 0.0).pose)?;
    for (i, leg) in legs.iter_mut().enumerate() {
        let x = (first.lengths_m[i] - lmin) as f32;
        match leg.cl.controller.command(Command::MoveTo { position_m: x }) {
            Ok(CommandOutcome::Accepted) => {}
            other => bail!("leg {}: entry move to {x} m: {other:?}", i + 1),
        }
    }
    let mut waited = 0.0;
    while legs.iter().any(|l| l.cl.controller.move_in_progress()) {
        plate.couple(p, &worker, &mut legs, divider).map_err(|e| e.context("entry move"))?;
        waited += dt;
        if waited > 20.0 {
            bail!("the legs did not reach the trajectory's first pose within 20 s");
        }
    }
    for _ in 0..settle {
        plate.couple(p, &worker, &mut legs, divider)?;
    }
    // The stream.
    let m_rod: [f64; 6] = std::array::from_fn(|i| legs[i].cl.plant.params().rod.nut_rod_mass_kg + legs[i].cl.plant.params().rod.payload_mass_kg);
    let mut trace = StreamTrace::default();
    let mut lag_sq = [0.0; 3];
    let mut lag_n = 0usize;
    let mut sent: Vec<[f64; 6]> = Vec::with_capacity(n + 1);
    let mut commanded_poses: Vec<Pose> = Vec::with_capacity(n + 1);
    let mut rod_pose = plate.pose;
    let mut limits = LimitFlags::NONE;
    for k in 0..=n {
        let t = k as f64 * dt;
        let state = commanded(traj, o.ramp_s, t);
        let forces = p.leg_forces(&state).map_err(|e| anyhow!("trajectory `{}` at t = {t:.4} s: {e}", traj.name))?;
        let rates = p.pose_jacobian(&state.pose) * state.velocity;
        for (i, leg) in legs.iter_mut().enumerate() {
            let x = forces.legs.lengths_m[i] - lmin;
            let ff = o.force_feedforward.then(|| (forces.forces_n[i] + m_rod[i] * GRAVITY_M_S2 * forces.legs.units[i].z) as f32);
            let c = Command::Stream { position_m: x as f32, velocity_m_s: rates[i] as f32, force_n: ff };
            match leg.cl.controller.command(c) {
                Ok(CommandOutcome::Accepted) => {}
                other => bail!("leg {}: setpoint at t = {t:.4} s ({x} m, {} m/s): {other:?}", i + 1, rates[i]),
            }
        }
        sent.push(forces.legs.lengths_m);
        commanded_poses.push(state.pose);
        plate.couple(p, &worker, &mut legs, divider).map_err(|e| e.context(format!("streaming, setpoint {k}")))?;
        for leg in legs.iter() {
            limits.insert(leg.cl.controller.telemetry().limits);
        }
        // After this period the reference stands at setpoint k − lag.
        let refs: [f64; 6] = std::array::from_fn(|i| lmin + f64::from(legs[i].cl.controller.telemetry().position_reference_m));
        if k >= 2 {
            for (lag, acc) in lag_sq.iter_mut().enumerate() {
                *acc += (0..6).map(|i| (refs[i] - sent[k - lag][i]).powi(2)).sum::<f64>();
            }
            lag_n += 6;
        }
        if k >= 1 {
            let rods: [f64; 6] = std::array::from_fn(|i| lmin + legs[i].x_rod());
            rod_pose = p.newton(&rods, &rod_pose).map_err(|e| anyhow!("rods at t = {t:.4} s: {e}"))?.pose;
            let want = &commanded_poses[k - 1];
            let d = rod_pose.to_vector() - want.to_vector();
            trace.time_s.push(t);
            trace.pose_error.push([d[0] * 1e3, d[1] * 1e3, d[2] * 1e3, d[3].to_degrees(), d[4].to_degrees(), d[5].to_degrees()]);
            trace.terminal_error_um.push(std::array::from_fn(|i| (rods[i] - sent[k - 1][i]) * 1e6));
            trace.motor_tracking_um.push(std::array::from_fn(|i| {
                let tel = legs[i].cl.controller.telemetry();
                f64::from(tel.position_reference_m - tel.motor_position_m) * 1e6
            }));
        }
    }
    for (i, leg) in legs.iter_mut().enumerate() {
        leg.cl.controller.command(Command::StreamEnd).map_err(|e| anyhow!("leg {}: StreamEnd refused: {e:?}", i + 1))?;
    }
    for _ in 0..settle {
        plate.couple(p, &worker, &mut legs, divider)?;
    }
    let simulated_s = legs[0].cl.time_s();
    let wall_s = started.elapsed().as_secs_f64();
    Ok(summarise(traj.name, *o, scale, peak_rates, trace, lag_sq.map(|s| (s / lag_n.max(1) as f64).sqrt() * 1e6), limits, n + 1, stream_s, simulated_s, wall_s))
}

#[allow(clippy::too_many_arguments)]
fn summarise(
    name: &'static str,
    options: StreamOptions,
    amplitude_scale: f64,
    (peak_leg_rate_full_m_s, peak_leg_rate_streamed_m_s): (f64, f64),
    trace: StreamTrace,
    reference_lag_check_um: [f64; 3],
    limits: LimitFlags,
    setpoints: usize,
    streamed_s: f64,
    simulated_s: f64,
    wall_s: f64,
) -> StreamRun {
    let norm3 = |a: f64, b: f64, c: f64| (a * a + b * b + c * c).sqrt();
    let pos: Vec<f64> = trace.pose_error.iter().map(|e| norm3(e[0], e[1], e[2])).collect();
    let att: Vec<f64> = trace.pose_error.iter().map(|e| norm3(e[3], e[4], e[5])).collect();
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let leg = |i: usize| trace.terminal_error_um.iter().map(|e| e[i]).collect::<Vec<f64>>();
    let motor = |i: usize| trace.motor_tracking_um.iter().map(|e| e[i]).collect::<Vec<f64>>();
    StreamRun {
        trajectory: name,
        options,
        amplitude_scale,
        peak_leg_rate_full_m_s,
        peak_leg_rate_streamed_m_s,
        streamed_s,
        setpoints_per_leg: setpoints,
        pose_error_position_rms_mm: rms(&pos),
        pose_error_position_max_mm: max(&pos),
        pose_error_attitude_rms_deg: rms(&att),
        pose_error_attitude_max_deg: max(&att),
        terminal_error_rms_um: std::array::from_fn(|i| rms(&leg(i))),
        terminal_error_max_um: std::array::from_fn(|i| max(&leg(i))),
        motor_tracking_rms_um: std::array::from_fn(|i| rms(&motor(i))),
        reference_lag_check_um,
        limits_seen: format!("{limits:?}"),
        simulated_s,
        wall_s,
        sim_realtime_factor: simulated_s / wall_s,
        trace,
    }
}

/// The plate between the legs: the pose FK'd from the legs' position
/// references, its last three values for differencing.
struct Plate {
    pose: Pose,
    hist: [Vector6<f64>; 3],
    dt: f64,
}

impl Plate {
    /// Runs the legs one position-loop period and hands each plant the leg
    /// force (and tilt) the plate dynamics ask of the references' motion.
    fn couple(&mut self, p: &Platform, worker: &Worker, legs: &mut Vec<Box<LegLoop>>, divider: u64) -> Result<()> {
        worker.step(legs, divider)?;
        let t = legs[0].cl.time_s();
        let lmin = p.geometry.leg_min_length_m;
        let lengths: [f64; 6] = std::array::from_fn(|i| lmin + f64::from(legs[i].cl.controller.telemetry().position_reference_m));
        self.pose = p.newton(&lengths, &self.pose).map_err(|e| anyhow!("t = {t:.4} s: {e}"))?.pose;
        self.hist.rotate_right(1);
        self.hist[0] = self.pose.to_vector();
        let dt = self.dt;
        let state = PoseState {
            pose: self.pose,
            velocity: (self.hist[0] - self.hist[1]) / dt,
            acceleration: (self.hist[0] - 2.0 * self.hist[1] + self.hist[2]) / (dt * dt),
        };
        let f = p.leg_forces(&state).map_err(|e| anyhow!("t = {t:.4} s: {e}"))?;
        for (i, leg) in legs.iter_mut().enumerate() {
            leg.cl.plant.set_external_force_n(f.forces_n[i]);
            leg.cl.plant.set_tilt_rad(f.legs.units[i].z.asin());
        }
        Ok(())
    }
}
