//! The regression nominal, for rigs whose physical parameters are not
//! known (the Cranfield stepper rig): current and tracking error linear in
//! features of the reference, fitted on healthy reference runs.

use super::{build_segments, Nominal, Segment, POSITION, TORQUE};
use crate::diagnose::log::Log;
use anyhow::Result;

/// Nominal regression: `current ≈ Σ a_j f_j`, `tracking error ≈ Σ b_j g_j`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Regression {
    pub v_eps: f64,
    pub torque_coef: Vec<f64>,
    pub position_coef: Vec<f64>,
}

/// Regression features: a constant, the reference speed's sign, the
/// reference speed now and 2, 4, 8 and 12 samples ago (the drive's lag),
/// the reference acceleration, the load and the load × sign.
pub const REG_FEATURES: [&str; 10] = [
    "1",
    "sgn(v)",
    "v",
    "v[-2]",
    "v[-4]",
    "v[-8]",
    "v[-12]",
    "a",
    "F",
    "F·sgn(v)",
];
pub const NREG: usize = REG_FEATURES.len();

pub(super) fn reg_features(seg: &Segment, i: usize, f: f64, v_eps: f64) -> [f64; NREG] {
    let v = seg.v_ref[i];
    let lag = |k: usize| seg.v_ref[i.saturating_sub(k)];
    let s = (v / v_eps).tanh();
    [
        1.0,
        s,
        v,
        lag(2),
        lag(4),
        lag(8),
        lag(12),
        seg.a_ref[i],
        f / 1000.0,
        f / 1000.0 * s,
    ]
}

/// Fits the regression nominal on reference segments (built with a zero
/// regression, which leaves the kinematics intact).
pub fn fit_regression(log: &Log) -> Result<Regression> {
    let zero = Regression {
        v_eps: 1e-3,
        torque_coef: vec![0.0; NREG],
        position_coef: vec![0.0; NREG],
    };
    let segs = build_segments(log, &Nominal::Regression(zero.clone()), 0.0)?;
    let vmax = segs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let v_eps = (0.05 * vmax).max(1e-6);
    let solve = |ch: usize, feats: &dyn Fn(&Segment, usize) -> Vec<f64>, p: usize| -> Vec<f64> {
        let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
        let mut atb = nalgebra::DVector::<f64>::zeros(p);
        for s in &segs {
            let Some(y) = &s.y[ch] else { continue };
            for (i, yi) in y.iter().enumerate() {
                let f = feats(s, i);
                for a in 0..p {
                    atb[a] += f[a] * yi;
                    for b in 0..p {
                        ata[(a, b)] += f[a] * f[b];
                    }
                }
            }
        }
        ata.svd(true, true)
            .solve(&atb, 1e-12)
            .map(|v| v.iter().copied().collect())
            .unwrap_or_else(|_| vec![0.0; p])
    };
    let fext = |s: &Segment, i: usize| s.f_load[i];
    let tc = solve(
        TORQUE,
        &|s, i| reg_features(s, i, fext(s, i), v_eps).to_vec(),
        NREG,
    );
    let pc = solve(
        POSITION,
        &|s, i| reg_features(s, i, fext(s, i), v_eps).to_vec(),
        NREG,
    );
    Ok(Regression {
        v_eps,
        torque_coef: tc,
        position_coef: pc,
    })
}
