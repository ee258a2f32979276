//! Figures of a model on a set of samples (paper Table 2: MSE, RMSE, MAPE).
//!
//! MAPE follows the paper's use of it on the terminal positioning *length*:
//! `100 · mean |L̂ − L| / L` over samples whose true length `L` exceeds
//! [`MAPE_LENGTH_FLOOR_M`] (near a zero length the ratio is meaningless). For
//! the error model `L̂ = L − e + ê`, so `|L̂ − L| = |ê − e|` whatever the sign
//! convention of the error column. "Before compensation" figures take the
//! whole error as the residual (no observer).

use super::dataset::{Samples, N_INPUTS};
use super::network::TrainedModel;
use serde::Serialize;

/// Samples with a true terminal length at or below this are left out of MAPE.
pub const MAPE_LENGTH_FLOOR_M: f64 = 0.01;

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    pub samples: usize,
    pub mse_m2: f64,
    pub rmse_m: f64,
    pub rmse_um: f64,
    pub max_abs_um: f64,
    /// `None` when no sample is longer than the floor.
    pub mape_pct: Option<f64>,
    pub mape_samples: usize,
    /// Inputs outside the trained range (the prediction clamps them, as the
    /// firmware does): samples with any input out, and per input below/above.
    pub out_of_range_samples: usize,
    pub out_of_range_fraction: f64,
    pub below_range_per_input: [usize; N_INPUTS],
    pub above_range_per_input: [usize; N_INPUTS],
}

/// Figures from residuals (prediction − truth, metres) and true lengths.
pub fn from_residuals(residuals: &[f64], lengths_m: &[f64]) -> Metrics {
    let n = residuals.len();
    let mse = if n == 0 { 0.0 } else { residuals.iter().map(|r| r * r).sum::<f64>() / n as f64 };
    let max_abs = residuals.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    let (mut ape, mut n_ape) = (0.0, 0usize);
    for (r, &l) in residuals.iter().zip(lengths_m) {
        if l > MAPE_LENGTH_FLOOR_M {
            ape += r.abs() / l;
            n_ape += 1;
        }
    }
    Metrics {
        samples: n,
        mse_m2: mse,
        rmse_m: mse.sqrt(),
        rmse_um: mse.sqrt() * 1e6,
        max_abs_um: max_abs * 1e6,
        mape_pct: (n_ape > 0).then(|| 100.0 * ape / n_ape as f64),
        mape_samples: n_ape,
        out_of_range_samples: 0,
        out_of_range_fraction: 0.0,
        below_range_per_input: [0; N_INPUTS],
        above_range_per_input: [0; N_INPUTS],
    }
}

/// The model on `s` (predictions clamp inputs to the trained range).
pub fn evaluate(model: &TrainedModel, s: &Samples) -> Metrics {
    let mut residuals = Vec::with_capacity(s.len());
    let (mut below, mut above, mut out) = ([0usize; N_INPUTS], [0usize; N_INPUTS], 0usize);
    for (x, &t) in s.inputs.iter().zip(&s.target) {
        let (y, clamped) = model.predict(x);
        residuals.push(y - t);
        if clamped {
            out += 1;
        }
        for j in 0..N_INPUTS {
            if x[j] < model.norm.input_min[j] {
                below[j] += 1;
            } else if x[j] > model.norm.input_max[j] {
                above[j] += 1;
            }
        }
    }
    let mut m = from_residuals(&residuals, &s.length_m);
    m.out_of_range_samples = out;
    m.out_of_range_fraction = if s.is_empty() { 0.0 } else { out as f64 / s.len() as f64 };
    m.below_range_per_input = below;
    m.above_range_per_input = above;
    m
}

/// "Before compensation": the semi-closed loop leaves the whole terminal error.
pub fn uncompensated(s: &Samples) -> Metrics {
    from_residuals(&s.error_m, &s.length_m)
}
