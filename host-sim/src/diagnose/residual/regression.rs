//! The regression nominal, for rigs whose physical parameters are not
//! known (the Cranfield stepper rig): current and tracking error linear in
//! features of the reference, fitted on healthy reference runs.

use super::{build_segments, Nominal, Segment, POSITION, TORQUE};
use crate::diagnose::log::Log;
use anyhow::{bail, Result};

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

pub fn reg_features(seg: &Segment, i: usize, f: f64, v_eps: f64) -> [f64; NREG] {
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

/// A reference must hold at least this many samples per regressor to fit
/// the nominal (after the filter edges): a least-squares fit of `NREG`
/// coefficients on fewer is an interpolation, not a model.
pub const MIN_SAMPLES_PER_REGRESSOR: usize = 20;

/// Fits the regression nominal on a healthy reference log. Refuses a
/// reference too short to fit it (fewer than `MIN_SAMPLES_PER_REGRESSOR`
/// × `NREG` samples) or one that never reverses (the direction terms
/// `sgn v`, `F·sgn v` need both directions), naming the minimum.
pub fn fit_regression(log: &Log) -> Result<Regression> {
    let segs = build_segments(log, &Nominal::Regression(zero_regression()), 0.0)?;
    let refs: Vec<&Segment> = segs.iter().collect();
    let n: usize = refs.iter().map(|s| s.len()).sum();
    let min = MIN_SAMPLES_PER_REGRESSOR * NREG;
    if n < min {
        bail!(
            "{}: the reference is too short to fit the nominal: {n} usable samples (after the ±{} filter-edge samples of each run), fewer than the minimum {min} ({MIN_SAMPLES_PER_REGRESSOR} per regressor × {NREG} regressors); give a longer healthy run",
            log.source,
            refs.first().map_or(0, |s| s.sg_m)
        );
    }
    let vmax = refs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let (pos, neg) = refs.iter().flat_map(|s| s.v_ref.iter()).fold((0, 0), |(p, q), v| {
        (p + usize::from(*v > 0.05 * vmax), q + usize::from(*v < -0.05 * vmax))
    });
    if vmax <= 0.0 || pos == 0 || neg == 0 {
        bail!(
            "{}: the reference never reverses ({pos} samples moving +, {neg} moving − beyond 5 % of the peak speed {vmax:.3e} m/s): the nominal's direction terms (sgn v, F·sgn v) need motion both ways, at least one reversal; give a healthy run that moves both ways",
            log.source
        );
    }
    Ok(fit_regression_segments(&refs))
}

/// A regression that predicts nothing (segments built with it keep the
/// kinematics and carry the logged signals as residuals).
pub fn zero_regression() -> Regression {
    Regression {
        v_eps: 1e-3,
        torque_coef: vec![0.0; NREG],
        position_coef: vec![0.0; NREG],
    }
}

/// Relative floor of the scaled Gram matrix's singular values kept in the
/// regression's solve (1e-8: a condition number of 10⁴ on the scaled
/// features themselves).
pub const GRAM_RCOND: f64 = 1e-8;

/// Fits the regression nominal on segments built with `zero_regression`.
pub fn fit_regression_segments(segs: &[&Segment]) -> Regression {
    let vmax = segs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let v_eps = (0.05 * vmax).max(1e-6);
    let solve = |ch: usize| -> Vec<f64> {
        let p = NREG;
        let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
        let mut atb = nalgebra::DVector::<f64>::zeros(p);
        for s in segs {
            let Some(y) = &s.y[ch] else { continue };
            for (i, yi) in y.iter().enumerate() {
                let f = reg_features(s, i, s.f_load[i], v_eps);
                for a in 0..p {
                    atb[a] += f[a] * yi;
                    for b in 0..p {
                        ata[(a, b)] += f[a] * f[b];
                    }
                }
            }
        }
        // Each feature scaled to unit RMS, and directions of the scaled
        // Gram matrix weaker than `GRAM_RCOND` of its strongest left
        // out: the lagged speeds are nearly collinear, and an unscaled,
        // untruncated solve cancels huge coefficients against each other —
        // exact on the samples fitted, wild on any other motion.
        let d: Vec<f64> = (0..p).map(|a| if ata[(a, a)] > 0.0 { 1.0 / ata[(a, a)].sqrt() } else { 0.0 }).collect();
        let scaled = nalgebra::DMatrix::<f64>::from_fn(p, p, |a, b| d[a] * ata[(a, b)] * d[b]);
        let rhs = nalgebra::DVector::<f64>::from_fn(p, |a, _| d[a] * atb[a]);
        let svd = scaled.svd(true, true);
        let smax = svd.singular_values.iter().fold(0.0f64, |m, x| m.max(*x));
        svd.solve(&rhs, GRAM_RCOND * smax)
            .map(|z| z.iter().zip(&d).map(|(z, d)| z * d).collect())
            .unwrap_or_else(|_| vec![0.0; p])
    };
    Regression {
        v_eps,
        torque_coef: solve(TORQUE),
        position_coef: solve(POSITION),
    }
}

/// Fit % (`100 (1 − ‖y − ŷ‖/‖y − ȳ‖)`) of the current and tracking-error
/// channels of segments built with `zero_regression`, under `reg`.
pub fn regression_fit_pct(reg: &Regression, segs: &[&Segment]) -> [Option<f64>; 2] {
    std::array::from_fn(|k| {
        let (ch, coef) = if k == 0 {
            (TORQUE, &reg.torque_coef)
        } else {
            (POSITION, &reg.position_coef)
        };
        let (mut sy, mut n) = (0.0, 0usize);
        for s in segs {
            if let Some(y) = &s.y[ch] {
                sy += y.iter().sum::<f64>();
                n += y.len();
            }
        }
        if n == 0 {
            return None;
        }
        let mean = sy / n as f64;
        let (mut sr, mut st) = (0.0, 0.0);
        for s in segs {
            let Some(y) = &s.y[ch] else { continue };
            for (i, yi) in y.iter().enumerate() {
                let f = reg_features(s, i, s.f_load[i], reg.v_eps);
                let yh: f64 = f.iter().zip(coef).map(|(a, b)| a * b).sum();
                sr += (yi - yh).powi(2);
                st += (yi - mean).powi(2);
            }
        }
        (st > 0.0).then(|| 100.0 * (1.0 - (sr / st).sqrt()))
    })
}
