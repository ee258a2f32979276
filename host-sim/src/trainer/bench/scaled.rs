//! Figure group "scaled": the compiled weights with their prediction scaled
//! by the compliance ratio the drive identifies on its own
//! (`trainer::stiffness`: the lowering current step against the rig file's
//! design), uploaded as a block; friction identified as for "shipped".
//! The weights themselves are the shipped ones: only the output scale and
//! offset change, by the measured ratio.

use super::anatomy::scaled_weights;
use super::eval::{evaluate, Row};
use super::rigs::{shipped_bar_pct, BenchRig};
use crate::config::RigConfig;
use crate::trainer::stiffness::identify_compliance;
use anyhow::{Context, Result};
use rayon::prelude::*;
use servo_core::observer::block::COMPILED;

pub fn run(rigs: &[BenchRig], design: &RigConfig, seed: u64) -> Result<Vec<Row>> {
    rigs.par_iter()
        .map(|r| {
            let (tuned, _) = crate::tuning::identify_friction_sim(&r.rig, r.seed).with_context(|| r.name)?;
            let id = identify_compliance(&tuned, design, r.seed.wrapping_add(5)).with_context(|| format!("{}: identifying the compliance", r.name))?;
            let w = scaled_weights(&COMPILED, id.compliance_ratio);
            let mut row = evaluate(r.name, &tuned, Some(w), seed, shipped_bar_pct(r.name))?;
            row.details = serde_json::json!({ "compliance": id, "true_compliance_ratio": 1.0 / r.draw.stiffness });
            Ok(row)
        })
        .collect()
}
