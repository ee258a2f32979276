//! Figure group "shipped": the compiled weights, unchanged, on every rig.
//! The drive is set up as docs/tuning.md's bench workflow says before the
//! observer is used: its friction identified and written into the
//! friction feedforward. The same run with the rig file's friction is in
//! each row's details.

use super::eval::{evaluate, Row};
use super::rigs::{shipped_bar_pct, BenchRig};
use anyhow::{Context, Result};
use rayon::prelude::*;
use servo_core::observer::block::Weights;

/// `weights`: `None` for the compiled model.
pub fn run(rigs: &[BenchRig], weights: Option<&'static Weights>, seed: u64) -> Result<Vec<Row>> {
    rigs.par_iter()
        .map(|r| {
            let (tuned, ident) = crate::tuning::identify_friction_sim(&r.rig, r.seed).with_context(|| r.name)?;
            let mut row = evaluate(r.name, &tuned, weights, seed, shipped_bar_pct(r.name))?;
            let as_file = evaluate(r.name, &r.rig, weights, seed, None)?;
            row.details = serde_json::json!({
                "friction_feedforward": crate::tuning::friction_param_set_lines(&tuned.control),
                "identified_coulomb_n_m": ident.coulomb_n_m,
                "rig_file_friction": {
                    "terminal_error_max_um_off": as_file.terminal_error_max_um_off,
                    "terminal_error_max_um_on": as_file.terminal_error_max_um_on,
                    "reduction_pct": as_file.reduction_pct,
                },
            });
            Ok(row)
        })
        .collect()
}
