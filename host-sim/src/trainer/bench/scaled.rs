//! Figure group "scaled": the compiled weights with their prediction scaled
//! by the compliance ratio the drive identifies on its own, through the
//! host tool's `drive identify stiffness` code (`tool::stiffness`: the
//! probe on a simulated drive of the rig over the protocol, against the rig
//! file's design); friction identified as for "shipped". The weights
//! themselves are the shipped ones: only the output scale and offset
//! change, by the measured ratio.

use super::eval::{evaluate, Row};
use super::rigs::{shipped_bar_pct, BenchRig};
use crate::config::RigConfig;
use crate::tool::stiffness::{identify_simulated, scaled_block};
use anyhow::{Context, Result};
use rayon::prelude::*;

pub fn run(rigs: &[BenchRig], design: &RigConfig, seed: u64) -> Result<Vec<Row>> {
    rigs.par_iter()
        .map(|r| {
            let (tuned, _) = crate::tuning::identify_friction_sim(&r.rig, r.seed).with_context(|| r.name)?;
            let id = identify_simulated(&tuned, design, r.seed.wrapping_add(5)).with_context(|| format!("{}: identifying the compliance", r.name))?;
            let w: &'static _ = Box::leak(Box::new(scaled_block(&id)));
            let mut row = evaluate(r.name, &tuned, Some(w), seed, shipped_bar_pct(r.name))?;
            row.details = serde_json::json!({ "compliance": id, "true_compliance_ratio": 1.0 / r.draw.stiffness });
            Ok(row)
        })
        .collect()
}
