//! What the inputs explain of the remainder: cross-validated
//! least squares on the logged inputs and their derivatives, and the
//! nonparametric (binned) regression on one input at a time. A remainder
//! the inputs predict is a model error, not an unmeasured disturbance.

use super::Remainder;
use crate::diagnose::residual::{Segment, POSITION, TORQUE};

/// Folds of the cross-validated regressions of the remainder (inputs,
/// kinematic angle): alternating blocks of this length, s — long against
/// the smoothing (±10 ms) and a move's own correlation, short against a
/// log, so either fold sees every kind of motion.
pub const CV_BLOCK_S: f64 = 0.5;

/// Least squares of the weighted remainder of channel `c` on per-sample
/// features (`feats[segment][sample]`, unweighted; the standstill weights
/// are applied here), two-fold cross-validated over alternating
/// `CV_BLOCK_S` blocks: each fold's samples are predicted by the fit on
/// the other. Returns the cross-validated share of the energy (about its
/// mean) explained, %, and per segment the cross-validated prediction
/// (unweighted) at every sample (empty where the channel is missing).
pub fn cv_regress(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    feats: &[Vec<Vec<f64>>],
) -> (f64, Vec<Vec<f64>>) {
    let p = feats
        .iter()
        .flat_map(|f| f.first())
        .map(Vec::len)
        .next()
        .unwrap_or(0);
    let empty = || segs.iter().map(|_| Vec::new()).collect::<Vec<_>>();
    if p == 0 {
        return (0.0, empty());
    }
    let fold = |s: &Segment, i: usize| ((s.t_rel[i] / CV_BLOCK_S) as usize) % 2;
    let mut ata = [
        nalgebra::DMatrix::<f64>::zeros(p, p),
        nalgebra::DMatrix::<f64>::zeros(p, p),
    ];
    let mut atb = [
        nalgebra::DVector::<f64>::zeros(p),
        nalgebra::DVector::<f64>::zeros(p),
    ];
    let (mut sy, mut syy, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for ((s, r), f) in segs.iter().zip(rem).zip(feats) {
        let Some(x) = &r[c] else { continue };
        let mut fi = vec![0.0; p];
        for i in 0..s.len() {
            let w = s.weight(c, i);
            let k = fold(s, i);
            for (a, v) in fi.iter_mut().zip(&f[i]) {
                *a = w * v;
            }
            let y = w * x[i];
            for a in 0..p {
                atb[k][a] += fi[a] * y;
                for b in 0..=a {
                    ata[k][(a, b)] += fi[a] * fi[b];
                }
            }
            sy += y;
            syy += y * y;
            n += 1.0;
        }
    }
    for m in &mut ata {
        for a in 0..p {
            for b in 0..a {
                m[(b, a)] = m[(a, b)];
            }
        }
    }
    let ss_tot = syy - sy * sy / n.max(1.0);
    if n < 20.0 || ss_tot <= 0.0 {
        return (0.0, empty());
    }
    // Columns scaled to unit diagonal, then a pseudo-inverse (collinear
    // features are common).
    let solve = |a: &nalgebra::DMatrix<f64>, b: &nalgebra::DVector<f64>| {
        let d = a
            .diagonal()
            .map(|v| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 });
        let dm = nalgebra::DMatrix::from_diagonal(&d);
        let beta = (&dm * a * &dm)
            .svd(true, true)
            .solve(&(&dm * b), 1e-10)
            .unwrap_or_else(|_| nalgebra::DVector::zeros(p));
        dm * beta
    };
    // Fold k is predicted by the fit on the other fold.
    let beta = [solve(&ata[1], &atb[1]), solve(&ata[0], &atb[0])];
    let mut ss_res = 0.0;
    let mut pred = Vec::with_capacity(segs.len());
    for ((s, r), f) in segs.iter().zip(rem).zip(feats) {
        let Some(x) = &r[c] else {
            pred.push(Vec::new());
            continue;
        };
        let pr: Vec<f64> = (0..s.len())
            .map(|i| {
                f[i].iter()
                    .zip(beta[fold(s, i)].iter())
                    .map(|(a, b)| a * b)
                    .sum()
            })
            .collect();
        for i in 0..s.len() {
            let w = s.weight(c, i);
            ss_res += (w * (x[i] - pr[i])).powi(2);
        }
        pred.push(pr);
    }
    ((100.0 * (1.0 - ss_res / ss_tot)).clamp(0.0, 100.0), pred)
}

/// Central difference of `y` over ±`m` samples, per second.
fn derivative(y: &[f64], m: usize, dt: f64) -> Vec<f64> {
    let n = y.len();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(m), (i + m).min(n.saturating_sub(1)));
            if b > a {
                (y[b] - y[a]) / ((b - a) as f64 * dt)
            } else {
                0.0
            }
        })
        .collect()
}

/// The inputs the remainder is regressed on: 1, speed, direction of
/// motion, |speed|, acceleration, jerk, load, nut force, its rate,
/// current, position, and a drifting gain. Jerk and the force's rate are
/// there because a signal logged late by τ leaves `−τ ẏ`: a delay is
/// correlated with the inputs' derivatives.
///
/// A channel's residual is never explained by its own measured output or
/// by anything computed from it (`own_output_free`): on the torque channel
/// (the logged current minus the nominal) the current and the current ×
/// time are left out — its own noise and its own drift would explain
/// themselves — and the drifting gain is the *nominal* torque × time; on a
/// position channel measured by the scale alone (no encoder) speed,
/// acceleration and position come from the reference, not from the scale.
pub fn input_features(s: &Segment, c: usize) -> Vec<Vec<f64>> {
    let m = s.sg_m.max(1);
    let k = own_output_free(s, c);
    let jerk = derivative(&k.a, m, s.dt);
    let fdot = derivative(&s.f_ax, m, s.dt);
    (0..s.len())
        .map(|i| {
            let v = k.v[i];
            let sg = if v.abs() > 1e-4 {
                v.signum()
            } else {
                s.dir.get(i).copied().unwrap_or(0.0)
            };
            let fax = s.f_ax.get(i).copied().unwrap_or(0.0);
            vec![
                1.0,
                v,
                sg,
                v.abs(),
                k.a[i],
                jerk[i],
                s.f_load[i],
                fax,
                fdot[i],
                k.current[i],
                k.x[i],
                k.gain[i] * s.t_rel[i],
            ]
        })
        .collect()
}

/// The kinematics, current and gain signal channel `c`'s remainder may be
/// regressed on: none of them is the channel's own measured output or
/// computed from it.
pub struct OwnOutputFree {
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub x: Vec<f64>,
    /// The logged current, zero on the torque channel (its own output).
    pub current: Vec<f64>,
    /// What a drifting gain multiplies: the logged current on the other
    /// channels, the nominal torque (from the motion and the load) on the
    /// torque channel.
    pub gain: Vec<f64>,
}

pub fn own_output_free(s: &Segment, c: usize) -> OwnOutputFree {
    let n = s.len();
    let nominal_torque: Vec<f64> = match (&s.y[TORQUE], &s.r[TORQUE]) {
        (Some(y), Some(r)) => y.iter().zip(r).map(|(y, r)| y - r).collect(),
        _ => vec![0.0; n],
    };
    let torque = c == TORQUE;
    // A scale-only log: the motion is the scale's, which is the position
    // channel's output; the reference stands in (`input` holds it when
    // logged).
    let from_reference = c == POSITION && !s.encoder;
    OwnOutputFree {
        v: if from_reference { s.v_ref.clone() } else { s.v.clone() },
        a: if from_reference { s.a_ref.clone() } else { s.a.clone() },
        x: if from_reference { s.input.clone() } else { s.x.clone() },
        current: if torque { vec![0.0; n] } else { s.iq.clone() },
        gain: if torque { nominal_torque } else { s.iq.clone() },
    }
}

/// Bins of the nonparametric input regression (equal counts).
pub const INPUT_BINS: usize = 20;

/// Correlation ratio η² of the remainder on one input, cross-validated: the
/// weighted remainder's mean in each of `INPUT_BINS` equal-count bins of
/// the input, taken on one fold (`CV_BLOCK_S` blocks), predicts the other.
/// Any function of the input counts (a dead zone, a saturation, a friction
/// curve), not only a straight line. Returns the share explained, %.
pub fn binned_cv(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    input: &dyn Fn(&Segment, usize) -> f64,
) -> f64 {
    let mut rows: Vec<(f64, f64, usize)> = Vec::new(); // (input, weighted remainder, fold)
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        for (i, xi) in x.iter().enumerate().take(s.len()) {
            let w = s.weight(c, i);
            if w <= 0.0 {
                continue;
            }
            rows.push((
                input(s, i),
                w * xi,
                ((s.t_rel[i] / CV_BLOCK_S) as usize) % 2,
            ));
        }
    }
    let n = rows.len();
    if n < 20 * INPUT_BINS {
        return 0.0;
    }
    let mut keys: Vec<f64> = rows.iter().map(|r| r.0).collect();
    keys.sort_by(f64::total_cmp);
    let edges: Vec<f64> = (1..INPUT_BINS).map(|k| keys[k * n / INPUT_BINS]).collect();
    let bin = |v: f64| edges.partition_point(|e| *e <= v);
    let mut sum = [vec![0.0; INPUT_BINS], vec![0.0; INPUT_BINS]];
    let mut cnt = [vec![0.0; INPUT_BINS], vec![0.0; INPUT_BINS]];
    for r in &rows {
        let b = bin(r.0);
        sum[r.2][b] += r.1;
        cnt[r.2][b] += 1.0;
    }
    let mean = rows.iter().map(|r| r.1).sum::<f64>() / n as f64;
    let (mut ss_res, mut ss_tot) = (0.0, 0.0);
    for r in &rows {
        let (b, o) = (bin(r.0), 1 - r.2);
        let pred = if cnt[o][b] > 0.0 {
            sum[o][b] / cnt[o][b]
        } else {
            mean
        };
        ss_res += (r.1 - pred).powi(2);
        ss_tot += (r.1 - mean).powi(2);
    }
    if ss_tot > 0.0 {
        (100.0 * (1.0 - ss_res / ss_tot)).clamp(0.0, 100.0)
    } else {
        0.0
    }
}

/// The inputs `binned_cv` tries, by name: speed, acceleration, the
/// channel's own nominal prediction (the logged signal minus the residual:
/// on the torque channel the nominal torque, free of the current sensor's
/// noise), the current (not on the torque channel) and position.
pub fn binned_inputs(segs: &[&Segment], rem: &Remainder, c: usize) -> Vec<(String, f64)> {
    let nominal = |s: &Segment, i: usize| match (&s.y[c], &s.r[c]) {
        (Some(y), Some(r)) => y[i] - r[i],
        _ => 0.0,
    };
    let free: Vec<OwnOutputFree> = segs.iter().map(|s| own_output_free(s, c)).collect();
    let at = |s: &Segment| {
        segs.iter()
            .position(|x| std::ptr::eq(*x, s))
            .expect("a segment of this list")
    };
    let mut out = vec![
        (
            "speed".to_string(),
            binned_cv(segs, rem, c, &|s, i| free[at(s)].v[i]),
        ),
        (
            "acceleration".to_string(),
            binned_cv(segs, rem, c, &|s, i| free[at(s)].a[i]),
        ),
        (
            "nominal prediction".to_string(),
            binned_cv(segs, rem, c, &nominal),
        ),
        (
            "position".to_string(),
            binned_cv(segs, rem, c, &|s, i| free[at(s)].x[i]),
        ),
    ];
    if c != TORQUE {
        out.push((
            "current".to_string(),
            binned_cv(segs, rem, c, &|s, i| s.iq[i]),
        ));
    }
    out
}
