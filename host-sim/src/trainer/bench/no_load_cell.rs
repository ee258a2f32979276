//! Figure group "no_load_cell": every rig with its load cell switched off,
//! the observer reading the drive's current-based force estimate
//! (`control.compensation.force_from_estimate`), the shipped estimate
//! weights (host-sim/data/observer/no_load_cell_model.json) uploaded. The
//! drive has its friction identified first, as for the shipped weights:
//! the estimate takes that friction out of the motor torque. The bar is
//! asked on the nominal rig; the model, how it is trained and why it is
//! held out are `host-sim observer-no-load-cell` (docs/observer-retraining.md,
//! "Without a load cell").

use super::eval::{evaluate, Row};
use super::rigs::BenchRig;
use crate::scenario::no_load_cell::{without_load_cell, BAR_PCT};
use anyhow::{Context, Result};
use rayon::prelude::*;
use servo_core::observer::block::Weights;
use std::path::Path;

/// The shipped estimate weights, beside the rig files.
pub const MODEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/observer/no_load_cell_model.json");

pub fn run(rigs: &[BenchRig], seed: u64) -> Result<Vec<Row>> {
    let weights: &'static Weights = Box::leak(Box::new(crate::tool::observer::read_model(Path::new(MODEL))?));
    rigs.par_iter()
        .map(|r| {
            let (tuned, _) = crate::tuning::identify_friction_sim(&r.rig, r.seed).with_context(|| r.name)?;
            let bar = (r.name == "nominal").then_some(BAR_PCT);
            evaluate(r.name, &without_load_cell(&tuned), Some(weights), seed, bar)
        })
        .collect()
}
