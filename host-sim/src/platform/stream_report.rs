//! The streamed six-leg runs `host-sim platform` makes, and the figures
//! summary.json takes from them.

use super::six_legs::{RigSpread, SixLegTrace};
use super::stream::{run_stream, StreamOptions, StreamRun};
use super::{plots, Platform, Trajectory};
use crate::config::RigConfig;
use anyhow::{anyhow, Result};
use serde::Serialize;
use std::path::Path;

/// The leg-level stroke: l_min + 5 mm → l_max − 5 mm → back (the paper's
/// 0 → 450 mm stroke within its ends) in 8 s, peak leg rate 0.173 m/s,
/// inside the drive's 0.2 m/s at full stroke.
pub const LEG_STROKE_MARGIN_M: f64 = 0.005;
pub const LEG_STROKE_PERIOD_S: f64 = 8.0;

/// A figure without and with each leg's observer compensation.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BeforeAfter {
    pub uncompensated: f64,
    pub compensated: f64,
}

/// Every streamed run, and the headline figures of the combined profile.
#[derive(Clone, Debug, Serialize)]
pub struct StreamFigures {
    /// Combined cueing profile, nominal rigs, no force feedforward.
    pub pose_error_position_rms_mm: BeforeAfter,
    pub pose_error_position_max_mm: BeforeAfter,
    pub pose_error_attitude_rms_deg: BeforeAfter,
    pub pose_error_attitude_max_deg: BeforeAfter,
    /// The uncompensated combined run's simulated / wall time (whole run).
    pub sim_realtime_factor: f64,
    /// Every trajectory (and the leg-level stroke, `leg_stroke`), without
    /// and with compensation, nominal rigs.
    pub runs: Vec<StreamRun>,
    /// Combined profile with the legs' rigs spread ±10 %.
    pub spread_runs: Vec<StreamRun>,
    /// Combined profile, nominal rigs, with each leg's expected axial load
    /// as `force_n` (compare with the same runs in `runs`).
    pub force_feedforward_runs: Vec<StreamRun>,
}

fn plot(r: &StreamRun, tag: &str, dir: &Path) -> Result<()> {
    let t = SixLegTrace { time_s: r.trace.time_s.clone(), terminal_error_um: r.trace.terminal_error_um.clone(), pose_error: r.trace.pose_error.clone() };
    let what = format!("{} streamed, {tag}, amplitude × {:.3}", r.trajectory, r.amplitude_scale);
    let titles = [
        format!("{what}: FK(rods) − commanded pose, position"),
        format!("{what}: FK(rods) − commanded pose, attitude"),
        format!("{what}: rod − commanded length"),
    ];
    plots::error_plots(&format!("stream_{}_{tag}", r.trajectory), &titles, &t, dir)
}

/// Runs every trajectory streamed on six legs and plots the combined runs
/// (`stream_combined_*_pose_position_error.png` and the like).
pub fn run_all(p: &Platform, rig: &RigConfig, out: &Path) -> Result<StreamFigures> {
    let go = |traj: &Trajectory, compensation: bool, ff: bool, spread: RigSpread| -> Result<StreamRun> {
        run_stream(p, rig, traj, &StreamOptions::new(compensation, ff, spread))
            .map_err(|e| anyhow!("streamed `{}` (compensation {compensation}, force feedforward {ff}): {e:#}", traj.name))
    };
    let mut runs = Vec::new();
    let mut trajectories = Trajectory::all(p);
    trajectories.push(Trajectory::leg_stroke(p, LEG_STROKE_MARGIN_M, LEG_STROKE_PERIOD_S));
    for traj in trajectories {
        for compensation in [false, true] {
            runs.push(go(&traj, compensation, false, RigSpread::NONE)?);
        }
    }
    let combined = Trajectory::combined(p);
    let spread_runs = vec![go(&combined, false, false, RigSpread::TEN_PERCENT)?, go(&combined, true, false, RigSpread::TEN_PERCENT)?];
    let force_feedforward_runs = vec![go(&combined, false, true, RigSpread::NONE)?, go(&combined, true, true, RigSpread::NONE)?];
    let find = |c: bool| runs.iter().find(|r| r.trajectory == combined.name && r.options.compensation == c).ok_or_else(|| anyhow!("no combined run"));
    let (off, on) = (find(false)?, find(true)?);
    for (r, tag) in [(off, "uncompensated"), (on, "compensated"), (&spread_runs[0], "spread_uncompensated"), (&spread_runs[1], "spread_compensated")] {
        plot(r, tag, out)?;
    }
    for r in runs.iter().filter(|r| r.trajectory == "leg_stroke") {
        plot(r, if r.options.compensation { "compensated" } else { "uncompensated" }, out)?;
    }
    let pair = |f: fn(&StreamRun) -> f64| BeforeAfter { uncompensated: f(off), compensated: f(on) };
    Ok(StreamFigures {
        pose_error_position_rms_mm: pair(|r| r.pose_error_position_rms_mm),
        pose_error_position_max_mm: pair(|r| r.pose_error_position_max_mm),
        pose_error_attitude_rms_deg: pair(|r| r.pose_error_attitude_rms_deg),
        pose_error_attitude_max_deg: pair(|r| r.pose_error_attitude_max_deg),
        sim_realtime_factor: off.sim_realtime_factor,
        runs,
        spread_runs,
        force_feedforward_runs,
    })
}
