//! `host-sim platform`: the kinematic and dynamic figures of the platform
//! along the pose trajectories, the Table 4 reproduction, summary.json.

use super::table4::{reproduce_paper, SetResult};
use super::{plots, table4_md, Geometry, Platform, Pose, Trajectory};
use anyhow::{anyhow, Context, Result};
use serde::Serialize;
use std::path::Path;

/// Samples per second along the trajectories (the position-loop rate of
/// the legs is 1 kHz; 500 Hz resolves the 3.1 Hz component finely).
pub const SAMPLE_HZ: f64 = 500.0;
/// Leg errors for the trajectory-wide linear-vs-exact figure: ±0.3 mm
/// alternating, about the single leg's terminal error in the paper run,
/// with signs that tilt the plate (a common error only heaves it).
pub const LEG_ERROR_PATTERN_M: [f64; 6] = [3e-4, -3e-4, 3e-4, -3e-4, 3e-4, -3e-4];

/// One trajectory, sampled.
#[derive(Clone, Debug, Default)]
pub struct Sampled {
    pub time_s: Vec<f64>,
    /// (x, y, z mm; roll, pitch, yaw deg).
    pub pose: Vec<[f64; 6]>,
    pub lengths_m: Vec<[f64; 6]>,
    pub forces_n: Vec<[f64; 6]>,
}

#[derive(Clone, Debug, Serialize)]
pub struct TrajectoryFigures {
    pub name: &'static str,
    pub duration_s: f64,
    pub samples: usize,
    pub leg_length_min_m: f64,
    pub leg_length_max_m: f64,
    pub leg_force_min_n: f64,
    pub leg_force_max_n: f64,
    /// FK of the IK lengths against the pose, largest over the samples:
    /// position (m) and attitude × r_a (m).
    pub fk_ik_round_trip_max_m: f64,
    pub fk_iterations_max: usize,
    /// |J⁻¹ δl − (FK(l + δl) − FK(l))| for `LEG_ERROR_PATTERN_M`, largest.
    pub linear_vs_exact_position_um_max: f64,
    pub linear_vs_exact_attitude_deg_max: f64,
    /// The exact pose error of that pattern, largest.
    pub pattern_pose_error_position_mm_max: f64,
    pub pattern_pose_error_attitude_deg_max: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct PlatformSummary {
    pub geometry: Geometry,
    pub home_leg_length_m: f64,
    pub neutral_height_m: f64,
    pub weight_n: f64,
    pub static_neutral_leg_forces_n: [f64; 6],
    pub fk_ik_round_trip_max_m: f64,
    pub table4: Vec<SetResult>,
    pub table4_linear_vs_exact_position_mm_max: f64,
    pub table4_linear_vs_exact_attitude_deg_max: f64,
    pub leg_error_pattern_m: [f64; 6],
    pub trajectories: Vec<TrajectoryFigures>,
    /// Six closed-loop legs streamed along the combined cueing profile
    /// (amplitudes fitted to the drive's velocity bound), FK(rods) against
    /// the commanded pose at the reference's time: without and with each
    /// leg's observer compensation. Null without a rig.
    pub pose_error_position_rms_mm: Option<super::stream_report::BeforeAfter>,
    pub pose_error_position_max_mm: Option<super::stream_report::BeforeAfter>,
    pub pose_error_attitude_rms_deg: Option<super::stream_report::BeforeAfter>,
    pub pose_error_attitude_max_deg: Option<super::stream_report::BeforeAfter>,
    /// The six-leg streamed combined run (uncompensated), whole run.
    pub sim_realtime_factor: Option<f64>,
    pub closed_loop_status: &'static str,
    /// Every streamed run (per-leg terminal error, lag check, scales).
    pub streamed: Option<super::stream_report::StreamFigures>,
    /// Six closed-loop legs moving rest-to-rest to Table 4's given lengths
    /// (set 1, set 2): without and with the observer's compensation.
    pub six_legs_uncompensated: Option<super::six_legs::SixLegRun>,
    pub six_legs_compensated: Option<super::six_legs::SixLegRun>,
    /// The same with the legs' rigs spread within ±10 % (`RigSpread::TEN_PERCENT`).
    pub six_legs_spread_uncompensated: Option<super::six_legs::SixLegRun>,
    pub six_legs_spread_compensated: Option<super::six_legs::SixLegRun>,
    pub wall_s: f64,
}

fn mm_deg(q: &Pose) -> [f64; 6] {
    let v = q.to_vector();
    [v[0] * 1e3, v[1] * 1e3, v[2] * 1e3, v[3].to_degrees(), v[4].to_degrees(), v[5].to_degrees()]
}

/// Samples `traj`, refusing (with time, leg and limit) any pose outside the
/// workspace, and measures the kinematic figures along it.
pub fn evaluate(p: &Platform, traj: &Trajectory) -> Result<(Sampled, TrajectoryFigures)> {
    let n = (traj.duration_s * SAMPLE_HZ).round() as usize;
    let mut s = Sampled::default();
    let mut f = TrajectoryFigures {
        name: traj.name,
        duration_s: traj.duration_s,
        samples: n + 1,
        leg_length_min_m: f64::INFINITY,
        leg_length_max_m: f64::NEG_INFINITY,
        leg_force_min_n: f64::INFINITY,
        leg_force_max_n: f64::NEG_INFINITY,
        fk_ik_round_trip_max_m: 0.0,
        fk_iterations_max: 0,
        linear_vs_exact_position_um_max: 0.0,
        linear_vs_exact_attitude_deg_max: 0.0,
        pattern_pose_error_position_mm_max: 0.0,
        pattern_pose_error_attitude_deg_max: 0.0,
    };
    let mut guess = traj.state(0.0).pose;
    for k in 0..=n {
        let t = k as f64 / SAMPLE_HZ;
        let state = traj.state(t);
        let forces = p.leg_forces(&state).map_err(|e| anyhow!("trajectory `{}` at t = {t:.3} s: {e}", traj.name))?;
        let l = forces.legs.lengths_m;
        let fk = p.forward(&l, &guess).map_err(|e| anyhow!("trajectory `{}` at t = {t:.3} s: {e}", traj.name))?;
        let d = fk.pose.to_vector() - state.pose.to_vector();
        let round_trip = d.fixed_rows::<3>(0).norm().max(d.fixed_rows::<3>(3).norm() * p.geometry.top_radius_m);
        f.fk_ik_round_trip_max_m = f.fk_ik_round_trip_max_m.max(round_trip);
        f.fk_iterations_max = f.fk_iterations_max.max(fk.iterations);
        guess = fk.pose;
        let est = p.pose_error(&l, &LEG_ERROR_PATTERN_M, &guess).map_err(|e| anyhow!("trajectory `{}` at t = {t:.3} s: {e}", traj.name))?;
        let gap = est.difference();
        f.linear_vs_exact_position_um_max = f.linear_vs_exact_position_um_max.max(gap.position_norm_m() * 1e6);
        f.linear_vs_exact_attitude_deg_max = f.linear_vs_exact_attitude_deg_max.max(gap.attitude_norm_rad().to_degrees());
        f.pattern_pose_error_position_mm_max = f.pattern_pose_error_position_mm_max.max(est.exact.position_norm_m() * 1e3);
        f.pattern_pose_error_attitude_deg_max = f.pattern_pose_error_attitude_deg_max.max(est.exact.attitude_norm_rad().to_degrees());
        for i in 0..6 {
            f.leg_length_min_m = f.leg_length_min_m.min(l[i]);
            f.leg_length_max_m = f.leg_length_max_m.max(l[i]);
            f.leg_force_min_n = f.leg_force_min_n.min(forces.forces_n[i]);
            f.leg_force_max_n = f.leg_force_max_n.max(forces.forces_n[i]);
        }
        s.time_s.push(t);
        s.pose.push(mm_deg(&state.pose));
        s.lengths_m.push(l);
        s.forces_n.push(forces.forces_n);
    }
    Ok((s, f))
}

/// Everything `host-sim platform --out DIR` writes.
pub fn run(geometry: Geometry, rig: Option<&crate::config::RigConfig>, out: &Path) -> Result<PlatformSummary> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let p = Platform::new(geometry)?;
    let table4 = reproduce_paper(&p).map_err(|e| anyhow!("Table 4: {e}"))?;
    let md = table4_md::markdown(&p, &table4);
    let md_path = out.join("table4.md");
    std::fs::write(&md_path, md).with_context(|| format!("writing {}", md_path.display()))?;
    let mut trajectories = Vec::new();
    for traj in Trajectory::all(&p) {
        let (sampled, figures) = evaluate(&p, &traj)?;
        plots::trajectory_plots(traj.name, &sampled, out)?;
        trajectories.push(figures);
    }
    plots::geometry_png(&p, &out.join("geometry.png"))?;
    let targets: Vec<[f64; 6]> = super::table4::PAPER_SETS.iter().map(|s| s.given_mm.map(|v| v * 1e-3)).collect();
    let six = |spread: &super::six_legs::RigSpread, compensation: bool| -> Result<Option<super::six_legs::SixLegRun>> {
        rig.map(|rig| super::six_legs::run_moves(&p, rig, spread, &targets, compensation, 1)).transpose()
    };
    let (none, ten) = (super::six_legs::RigSpread::NONE, super::six_legs::RigSpread::TEN_PERCENT);
    let (six_off, six_on, spread_off, spread_on) = (six(&none, false)?, six(&none, true)?, six(&ten, false)?, six(&ten, true)?);
    for (tag, r) in [("uncompensated", &six_off), ("compensated", &six_on), ("spread_uncompensated", &spread_off), ("spread_compensated", &spread_on)] {
        if let Some(r) = r {
            plots::six_leg_plots(tag, &r.trace, out)?;
        }
    }
    let streamed = rig.map(|rig| super::stream_report::run_all(&p, rig, out)).transpose()?;
    let neutral = p.leg_forces(&super::PoseState {
        pose: p.neutral(),
        velocity: nalgebra::Vector6::zeros(),
        acceleration: nalgebra::Vector6::zeros(),
    })?;
    Ok(PlatformSummary {
        home_leg_length_m: p.geometry.home_leg_length_m(),
        neutral_height_m: p.neutral().position_m.z,
        weight_n: p.geometry.payload_mass_kg * super::GRAVITY_M_S2,
        static_neutral_leg_forces_n: neutral.forces_n,
        fk_ik_round_trip_max_m: trajectories.iter().map(|t| t.fk_ik_round_trip_max_m).fold(0.0, f64::max),
        table4_linear_vs_exact_position_mm_max: table4.iter().map(|r| r.linear_vs_exact_position_mm).fold(0.0, f64::max),
        table4_linear_vs_exact_attitude_deg_max: table4.iter().map(|r| r.linear_vs_exact_attitude_deg).fold(0.0, f64::max),
        table4,
        leg_error_pattern_m: LEG_ERROR_PATTERN_M,
        trajectories,
        pose_error_position_rms_mm: streamed.as_ref().map(|s| s.pose_error_position_rms_mm),
        pose_error_position_max_mm: streamed.as_ref().map(|s| s.pose_error_position_max_mm),
        pose_error_attitude_rms_deg: streamed.as_ref().map(|s| s.pose_error_attitude_rms_deg),
        pose_error_attitude_max_deg: streamed.as_ref().map(|s| s.pose_error_attitude_max_deg),
        sim_realtime_factor: streamed.as_ref().map(|s| s.sim_realtime_factor),
        closed_loop_status: if streamed.is_some() {
            "pose_error_*: combined cueing profile streamed at 1 kHz on six closed-loop legs, amplitudes × streamed.runs[].amplitude_scale to fit the drive's 0.2 m/s velocity bound (the full profile asks 0.64 m/s of a leg); six_legs_* are rest-to-rest moves to Table 4's given lengths"
        } else {
            "no rig given: closed-loop runs not made"
        },
        streamed,
        six_legs_uncompensated: six_off,
        six_legs_compensated: six_on,
        six_legs_spread_uncompensated: spread_off,
        six_legs_spread_compensated: spread_on,
        geometry: p.geometry,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}
