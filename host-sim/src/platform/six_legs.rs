//! Six closed-loop legs under the platform: each leg is the firmware's
//! control core (`servo_core::Controller`) against the full plant, and each
//! leg's axial load comes from the plate dynamics at every position-loop
//! period.
//!
//! Limits of this first version (docs/platform.md, "Six closed-loop legs"):
//! - `run_moves` uses the core's `MoveTo` (rest-to-rest, `Busy` while
//!   moving): point-to-point moves to given leg lengths (Table 4's), each
//!   leg on its own jerk-limited profile; the pose is judged at rest, as in
//!   §5.3. Continuous pose trajectories are streamed in `stream.rs`.
//! - Coupling at the position-loop rate: the pose is solved by forward
//!   kinematics from the six legs' position references, its rate and
//!   acceleration by differencing over the period; the leg forces so found
//!   load the plants over the next period (see `couple` for why the
//!   references and not the rods).
//! - Each leg's plant carries the upper-leg mass (Table 3, 13 kg) on its rod
//!   instead of the single-leg rig's payload; the plate and payload act only
//!   through the forces. Legs run on two threads (`leg_threads`),
//!   synchronised every position-loop period.

use super::dynamics::PoseState;
use super::kinematics::{Platform, Pose};
use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::ClosedLoop;
use anyhow::{anyhow, bail, Result};
use nalgebra::Vector6;
use servo_core::{Command, CommandOutcome, Controller};

pub(super) use super::leg_threads::Worker;

/// One leg: its closed loop and what it was last told.
pub(super) struct LegLoop {
    pub(super) cl: ClosedLoop,
}

impl LegLoop {
    pub(super) fn x_rod(&self) -> f64 {
        self.cl.plant.state().terminal_position_m
    }
}

/// The pose reached at rest after one move, against the commanded one.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MoveResult {
    pub target_lengths_mm: [f64; 6],
    /// Rod (terminal) position minus commanded, per leg, µm.
    pub terminal_error_um: [f64; 6],
    /// Motor-side position minus commanded, per leg, µm.
    pub motor_side_error_um: [f64; 6],
    /// FK(terminal lengths) − FK(commanded lengths): mm and degrees.
    pub pose_error_position_mm: [f64; 3],
    pub pose_error_attitude_deg: [f64; 3],
    pub leg_forces_n: [f64; 6],
    /// What each drive train carries: the leg force plus the weight of the
    /// rod and upper leg along the leg (compression positive).
    pub drive_train_load_n: [f64; 6],
}

/// Time histories of a run, one sample per position-loop period.
#[derive(Clone, Debug, Default)]
pub struct SixLegTrace {
    pub time_s: Vec<f64>,
    /// Rod minus position reference, per leg, µm.
    pub terminal_error_um: Vec<[f64; 6]>,
    /// FK(rods) − FK(references): x, y, z mm; roll, pitch, yaw degrees.
    pub pose_error: Vec<[f64; 6]>,
}

/// A whole run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SixLegRun {
    pub compensation: bool,
    pub rig_spread: RigSpread,
    pub moves: Vec<MoveResult>,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub sim_realtime_factor: f64,
    /// Largest |FK(rods) − FK(references)| over the whole run, moving or not.
    pub dynamic_pose_error_position_max_mm: f64,
    pub dynamic_pose_error_attitude_max_deg: f64,
    /// Per position-loop period (not in summary.json; plotted).
    #[serde(skip)]
    pub trace: SixLegTrace,
    /// Largest |pose error| at rest over the moves.
    pub pose_error_position_max_mm: f64,
    pub pose_error_attitude_max_deg: f64,
}

/// How the six legs' rigs differ from the shipped one: leg i's moving mass
/// (rod + upper leg) times `mass_scale[i]`, its drive train's stiffness
/// (every deformation term, δ1…δ5) times `stiffness_scale[i]`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RigSpread {
    pub mass_scale: [f64; 6],
    pub stiffness_scale: [f64; 6],
}

impl RigSpread {
    pub const NONE: Self = Self { mass_scale: [1.0; 6], stiffness_scale: [1.0; 6] };
    /// A fixed spread within ±10 %, no two legs alike.
    pub const TEN_PERCENT: Self = Self {
        mass_scale: [1.10, 0.92, 1.04, 0.90, 0.97, 1.07],
        stiffness_scale: [0.90, 1.06, 1.10, 0.95, 1.02, 0.93],
    };

    fn apply(&self, i: usize, params: &mut crate::plant::PlantParams) {
        params.rod.payload_mass_kg *= self.mass_scale[i];
        params.rod.nut_rod_mass_kg *= self.mass_scale[i];
        let k = self.stiffness_scale[i];
        let d = &mut params.deformation;
        d.contact.coefficient_m_per_n2_3 /= k;
        d.bearing.coefficient_m_per_n_k /= k;
        d.screw_axial.youngs_modulus_pa *= k;
        d.rod.youngs_modulus_pa *= k;
        d.torsion.shear_modulus_pa *= k;
    }
}

/// The legs start at rest this far out of l_0 (Table 3's retracted length,
/// = l_min): the rod sits behind the motor side by its deformation, and at
/// exactly l_min that would already be outside the workspace.
pub const START_STROKE_M: f64 = 0.005;

pub(super) struct LegSetup<'a> {
    pub(super) rig: &'a RigConfig,
    pub(super) spread: &'a RigSpread,
    pub(super) seed: u64,
    pub(super) compensation: bool,
}

pub(super) fn new_leg(s: &LegSetup, p: &Platform, i: usize, start: &Pose, force_n: f64) -> Result<Box<LegLoop>> {
    let (rig, seed, compensation) = (s.rig, s.seed, s.compensation);
    let mut params = rig.plant.clone();
    params.rod.payload_mass_kg = p.geometry.upper_leg_mass_kg;
    s.spread.apply(i, &mut params);
    let mut plant = Plant::try_new(params, seed.wrapping_mul(7).wrapping_add(i as u64)).map_err(|e| anyhow!("leg {}: {e}", i + 1))?;
    let legs = p.inverse(start);
    plant.set_external_force_n(force_n);
    let theta = (START_STROKE_M - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad();
    plant.set_initial_state(theta, legs.units[i].z.asin());
    // A commissioned leg (offset and reference known at the start); the
    // power-up itself is `host-sim power-up`'s subject.
    let mut controller = Controller::try_new(crate::sim::commissioned_control(rig.control, &plant))
        .map_err(|e| anyhow!("leg {}: rig: {e}", i + 1))?;
    // The drive is told where it is (homing), as on the platform.
    let mut probe = plant.clone();
    let _ = controller.step(&probe.sample());
    controller
        .command(Command::SetHome { position_m: START_STROKE_M as f32 })
        .map_err(|e| anyhow!("leg {}: homing refused: {e:?}", i + 1))?;
    let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.controller.command(Command::Enable).map_err(|e| anyhow!("leg {}: enable refused: {e:?}", i + 1))?;
    cl.controller
        .command(Command::SetCompensation { enabled: compensation })
        .map_err(|e| anyhow!("leg {}: compensation refused: {e:?}", i + 1))?;
    Ok(Box::new(LegLoop { cl }))
}

/// From rest at l_0 (every leg retracted, Table 3's initial length), moves
/// the legs to each set of `targets_m` in turn and measures the pose at rest.
pub fn run_moves(p: &Platform, rig: &RigConfig, spread: &RigSpread, targets_m: &[[f64; 6]], compensation: bool, seed: u64) -> Result<SixLegRun> {
    let l0 = p.geometry.leg_initial_length_m;
    let lmin = p.geometry.leg_min_length_m;
    let start = p.forward(&[l0 + START_STROKE_M; 6], &p.home()).map_err(|e| anyhow!("start pose: {e}"))?.pose;
    let at_rest = |pose: Pose| PoseState { pose, velocity: Vector6::zeros(), acceleration: Vector6::zeros() };
    let f0 = p.leg_forces(&at_rest(start)).map_err(|e| anyhow!("start pose: {e}"))?.forces_n;
    let worker = Worker::spawn();
    let mut legs: Vec<Box<LegLoop>> = {
        let setup = LegSetup { rig, spread, seed, compensation };
        (0..6).map(|i| new_leg(&setup, p, i, &start, f0[i])).collect::<Result<_>>()?
    };
    let divider = u64::from(rig.control.rates.position_loop_divider);
    let dt = divider as f64 / f64::from(rig.control.rates.pwm_frequency_hz);
    let mut pose = start;
    let mut hist = [start.to_vector(); 3];
    let mut last_forces = f0;
    let started = std::time::Instant::now();
    let mut moves = Vec::new();
    let settle_s = 0.3;
    let dwell_s = 0.5;
    // Couples the legs through the plate for one position-loop period. The
    // loads follow the legs' reference motion (their position references,
    // jerk-limited and smooth), not the measured rods: the plate's 85 kg fed
    // back explicitly, one period late, onto 17 kg rods is the classic
    // added-mass instability of explicit co-simulation. The rods follow
    // their references to micrometres, so the loads differ by as little.
    let mut trace = SixLegTrace::default();
    let mut rod_pose = start;
    let mut couple = |legs: &mut Vec<Box<LegLoop>>, hist: &mut [Vector6<f64>; 3], pose: &mut Pose| -> Result<[f64; 6]> {
        worker.step(legs, divider)?;
        let lengths: [f64; 6] = std::array::from_fn(|i| lmin + f64::from(legs[i].cl.controller.telemetry().position_reference_m));
        *pose = p.newton(&lengths, pose).map_err(|e| anyhow!("t = {:.4} s: {e}", legs[0].cl.time_s()))?.pose;
        hist.rotate_right(1);
        hist[0] = pose.to_vector();
        let state = PoseState {
            pose: *pose,
            velocity: (hist[0] - hist[1]) / dt,
            acceleration: (hist[0] - 2.0 * hist[1] + hist[2]) / (dt * dt),
        };
        let f = p.leg_forces(&state).map_err(|e| anyhow!("t = {:.4} s: {e}", legs[0].cl.time_s()))?;
        for (i, leg) in legs.iter_mut().enumerate() {
            leg.cl.plant.set_external_force_n(f.forces_n[i]);
            leg.cl.plant.set_tilt_rad(f.legs.units[i].z.asin());
        }
        let rods: [f64; 6] = std::array::from_fn(|i| lmin + legs[i].x_rod());
        rod_pose = p.newton(&rods, &rod_pose).map_err(|e| anyhow!("rods at t = {:.4} s: {e}", legs[0].cl.time_s()))?.pose;
        let d = rod_pose.to_vector() - pose.to_vector();
        trace.time_s.push(legs[0].cl.time_s());
        trace.terminal_error_um.push(std::array::from_fn(|i| (rods[i] - lengths[i]) * 1e6));
        trace.pose_error.push([d[0] * 1e3, d[1] * 1e3, d[2] * 1e3, d[3].to_degrees(), d[4].to_degrees(), d[5].to_degrees()]);
        Ok(f.forces_n)
    };
    for _ in 0..(settle_s / dt).round() as usize {
        last_forces = couple(&mut legs, &mut hist, &mut pose)?;
    }
    for target in targets_m {
        p.check_lengths(target).map_err(|e| anyhow!("target {target:?}: {e}"))?;
        for (i, leg) in legs.iter_mut().enumerate() {
            let x = (target[i] - lmin) as f32;
            match leg.cl.controller.command(Command::MoveTo { position_m: x }) {
                Ok(CommandOutcome::Accepted) => {}
                other => bail!("leg {}: move to {x} m: {other:?}", i + 1),
            }
        }
        let max_s = 20.0;
        let mut waited = 0.0;
        while legs.iter().any(|l| l.cl.controller.move_in_progress()) {
            last_forces = couple(&mut legs, &mut hist, &mut pose)?;
            waited += dt;
            if waited > max_s {
                bail!("the legs did not finish a move within {max_s} s");
            }
        }
        for _ in 0..(dwell_s / dt).round() as usize {
            last_forces = couple(&mut legs, &mut hist, &mut pose)?;
        }
        let terminal: [f64; 6] = std::array::from_fn(|i| lmin + legs[i].x_rod());
        let motor: [f64; 6] = std::array::from_fn(|i| lmin + legs[i].cl.plant.state().motor_side_position_m);
        let want = p.forward(target, &pose).map_err(|e| anyhow!("target pose: {e}"))?.pose;
        let got = p.forward(&terminal, &want).map_err(|e| anyhow!("reached pose: {e}"))?.pose;
        let d = got.to_vector() - want.to_vector();
        moves.push(MoveResult {
            target_lengths_mm: target.map(|v| v * 1e3),
            terminal_error_um: std::array::from_fn(|i| (terminal[i] - target[i]) * 1e6),
            motor_side_error_um: std::array::from_fn(|i| (motor[i] - target[i]) * 1e6),
            pose_error_position_mm: [d[0] * 1e3, d[1] * 1e3, d[2] * 1e3],
            pose_error_attitude_deg: [d[3].to_degrees(), d[4].to_degrees(), d[5].to_degrees()],
            leg_forces_n: last_forces,
            drive_train_load_n: std::array::from_fn(|i| legs[i].cl.plant.state().load_force_n),
        });
    }
    let simulated_s = legs[0].cl.time_s();
    let wall_s = started.elapsed().as_secs_f64();
    let norm3 = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    Ok(SixLegRun {
        compensation,
        rig_spread: *spread,
        pose_error_position_max_mm: moves.iter().map(|m| norm3(&m.pose_error_position_mm)).fold(0.0, f64::max),
        pose_error_attitude_max_deg: moves.iter().map(|m| norm3(&m.pose_error_attitude_deg)).fold(0.0, f64::max),
        moves,
        simulated_s,
        wall_s,
        sim_realtime_factor: simulated_s / wall_s,
        dynamic_pose_error_position_max_mm: trace.pose_error.iter().map(|e| norm3(&[e[0], e[1], e[2]])).fold(0.0, f64::max),
        dynamic_pose_error_attitude_max_deg: trace.pose_error.iter().map(|e| norm3(&[e[3], e[4], e[5]])).fold(0.0, f64::max),
        trace,
    })
}
