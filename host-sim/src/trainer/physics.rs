//! Physics baseline: linear least squares on the deformation and friction
//! terms of DESIGN.md §3 (paper Eqs. 21–26), from the same four inputs.
//!
//! `ŷ = c0 + c1 F + c2 F x + c3 sgn(F)|F|^(2/3) + c4 sgn(v) + c5 v + c6 x`:
//! spring-like deformation (rod, bearing), screw tension growing along the
//! stroke, Hertz contact, Coulomb lost motion flipping with the direction of
//! motion, viscous lag, and the displacement itself (the length model's
//! main term). Whatever the network gains over this is what it learned
//! beyond the textbook terms.

use super::dataset::{Samples, N_INPUTS};
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

pub const FEATURES: [&str; 7] = ["1", "F", "F·x", "sgn(F)|F|^(2/3)", "sgn(v)", "v", "x"];

/// A fitted baseline.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PhysicsFit {
    pub coefficients: [f64; 7],
}

fn features(x: &[f64; N_INPUTS]) -> [f64; 7] {
    let (v, d, f) = (x[1], x[2], x[3]);
    let sgn = |a: f64| if a > 0.0 { 1.0 } else if a < 0.0 { -1.0 } else { 0.0 };
    [1.0, f, f * d, sgn(f) * f.abs().powf(2.0 / 3.0), sgn(v), v, d]
}

impl PhysicsFit {
    /// Least squares (SVD) on `s`, columns scaled to unit RMS for conditioning.
    pub fn fit(s: &Samples) -> Result<PhysicsFit> {
        let n = s.len();
        if n < FEATURES.len() {
            bail!("physics baseline: {n} samples for {} coefficients", FEATURES.len());
        }
        let rows: Vec<[f64; 7]> = s.inputs.iter().map(features).collect();
        let mut scale = [0.0; 7];
        for r in &rows {
            for (sc, v) in scale.iter_mut().zip(r) {
                *sc += v * v;
            }
        }
        let scale = scale.map(|q| if q > 0.0 { (q / n as f64).sqrt() } else { 1.0 });
        let a = DMatrix::from_fn(n, 7, |i, j| rows[i][j] / scale[j]);
        let b = DVector::from_column_slice(&s.target);
        let svd = a.svd(true, true);
        let sol = match svd.solve(&b, 1e-12) {
            Ok(x) => x,
            Err(e) => bail!("physics baseline: least squares failed: {e}"),
        };
        let mut coefficients = [0.0; 7];
        for j in 0..7 {
            coefficients[j] = sol[j] / scale[j];
        }
        Ok(PhysicsFit { coefficients })
    }

    pub fn predict(&self, x: &[f64; N_INPUTS]) -> f64 {
        features(x).iter().zip(&self.coefficients).map(|(f, c)| f * c).sum()
    }

    /// Residuals (prediction − truth) on `s`.
    pub fn residuals(&self, s: &Samples) -> Vec<f64> {
        s.inputs.iter().zip(&s.target).map(|(x, t)| self.predict(x) - t).collect()
    }
}
