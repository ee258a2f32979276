//! Figure group "retrained": on every rig, the documented route (friction
//! identified into the feedforward, logs → `dataset-from-logs` → `train
//! --hidden 8` → upload → verify on the simulated drive), then the
//! evaluation run with the weights the drive runs after the upload.

use super::eval::{evaluate, Row};
use super::rigs::{BenchRig, RETRAINED_BAR_PCT};
use crate::trainer::route::{run_route, RoutePlan};
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use std::path::Path;

/// The most logged motion a retraining may use (s).
pub const MAX_LOGGED_MOTION_S: f64 = 600.0;

pub fn run(rigs: &[BenchRig], cycles: usize, seed: u64, out: &Path) -> Result<Vec<Row>> {
    rigs.par_iter()
        .map(|r| {
            let mut plan = RoutePlan::new(cycles);
            plan.seed = r.seed;
            let route = run_route(&r.rig, &plan, &out.join(r.name).join("route")).with_context(|| r.name)?;
            if route.moving_s > MAX_LOGGED_MOTION_S {
                bail!("{}: the route logged {:.0} s of motion, more than {MAX_LOGGED_MOTION_S} s", r.name, route.moving_s);
            }
            let mut row = evaluate(r.name, &route.rig, Some(route.weights), seed, Some(RETRAINED_BAR_PCT))?;
            row.details = serde_json::json!({
                "logged_drive_time_s": route.logged_s,
                "logged_motion_s": route.moving_s,
                "route_s": route.total_s,
                "route": route.summary,
            });
            Ok(row)
        })
        .collect()
}
