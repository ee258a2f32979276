//! A gain that drifts with time: the channel's nominal prediction `N(t)`
//! times a slowly varying gain `g(t)`, piecewise linear between knots
//! `KNOT_S` apart (a magnet or winding warming over seconds to minutes).
//!
//! How far a gain has drifted is a state of each run, not a constant of
//! the rig: a held-out run that starts warm carries its own gain, which no
//! trajectory fitted on the training run's clock predicts. What transfers
//! is the structure — the remainder is the nominal times a slow gain — so
//! it is scored like the disturbance on a held-out log: the gain's course
//! is fitted on alternating `CV_BLOCK_S` blocks and scored on the blocks it
//! did not see (two folds), on the training and the held-out part alike.
//! A gain that does not move is a gain error, not a drift: on training the
//! drifting gain must explain `OVER_CONSTANT_PTS` more of the remainder
//! than one constant gain per run, scored the same way.
//!
//! With a logged motor temperature the gain is `g0 + g1 (T − T̄)`, `T̄` the
//! training mean: the temperature carries the state across runs, so this
//! one is fitted on training and scored on the held-out part like the
//! library, and it must add `OVER_CONSTANT_PTS` over a constant gain
//! fitted the same way.

use super::super::events::Remainder;
use super::super::figures::shrink;
use super::super::residual::{Segment, CHANNELS};
use super::{nominal_pred, rms, GenericFit};

/// Knot spacing of the slow gain, s: slower than the moves (≤ 1 s) and
/// their dwells, so the gain cannot follow the motion itself.
pub const KNOT_S: f64 = 2.0;
/// Cross-validation block, s: a few moves, shorter than a knot span so each
/// knot is fitted on both folds.
pub const CV_BLOCK_S: f64 = 0.5;
/// Points (of the remainder's RMS shrink, cross-validated on training) the
/// drifting gain must add over a constant gain per run.
pub const OVER_CONSTANT_PTS: f64 = 10.0;
/// The most a gain may move over the training runs and still be a drift
/// of a gain, %: magnets lose ≈ 0.1 %/K (NdFeB 0.12, SmCo 0.04), under
/// 20 % from cold to their limit; a course beyond this is a slow signal
/// of another kind the gain is bent to follow.
pub const MAX_GAIN_CHANGE_PCT: f64 = 50.0;

/// The weights of the hat functions on knots `KNOT_S` apart at `t` s from
/// the segment's start: (knot index, weight), at most two.
fn hats(t: f64) -> [(usize, f64); 2] {
    let u = (t / KNOT_S).max(0.0);
    let j = u.floor() as usize;
    let f = u - j as f64;
    [(j, 1.0 - f), (j + 1, f)]
}

/// Regressors of one segment: the nominal on each knot's hat (drift), or
/// the nominal alone (constant gain).
fn regressors(s: &Segment, c: usize, drifting: bool) -> (usize, Vec<Vec<(usize, f64)>>) {
    let n = nominal_pred(s, c);
    let p = if drifting {
        hats(s.t_rel.last().copied().unwrap_or(0.0))[1].0 + 1
    } else {
        1
    };
    let x = (0..s.len())
        .map(|i| {
            if drifting {
                hats(s.t_rel[i]).iter().map(|(j, h)| (*j, h * n[i])).collect()
            } else {
                vec![(0, n[i])]
            }
        })
        .collect();
    (p, x)
}

/// Regressors with the logged temperature: `N`, `N (T − t_ref)`.
fn temperature_regressors(s: &Segment, c: usize, t_ref: f64) -> Vec<Vec<(usize, f64)>> {
    let n = nominal_pred(s, c);
    (0..s.len()).map(|i| vec![(0, n[i]), (1, n[i] * (s.temperature_c[i] - t_ref))]).collect()
}

/// One gain law `x` (shared by every run) fitted on `train` and scored on
/// `held`: the weighted RMS each leaves, and the coefficients.
fn shared_law(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, c: usize, p: usize, x: &dyn Fn(&Segment) -> Vec<Vec<(usize, f64)>>) -> (f64, f64, Vec<f64>) {
    let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
    let mut atb = nalgebra::DVector::<f64>::zeros(p);
    for (s, r) in train.iter().zip(rem_t) {
        let Some(y) = &r[c] else { continue };
        for (i, row) in x(s).iter().enumerate() {
            let w2 = s.weight(c, i).powi(2);
            for &(a, xa) in row {
                atb[a] += w2 * xa * y[i];
                for &(b, xb) in row {
                    ata[(a, b)] += w2 * xa * xb;
                }
            }
        }
    }
    let b: Vec<f64> = ata.svd(true, true).solve(&atb, 1e-12).map(|v| v.iter().copied().collect()).unwrap_or_else(|_| vec![0.0; p]);
    let left = |segs: &[&Segment], rem: &Remainder| {
        let (mut ss, mut n) = (0.0, 0usize);
        for (s, r) in segs.iter().zip(rem) {
            let Some(y) = &r[c] else { continue };
            for (i, row) in x(s).iter().enumerate() {
                ss += (s.weight(c, i) * (y[i] - predict(row, &b))).powi(2);
            }
            n += s.len();
        }
        if n == 0 { 0.0 } else { (ss / n as f64).sqrt() }
    };
    (left(train, rem_t), left(held, rem_h), b)
}

/// The gain drifting with the logged temperature, when every run logs it.
fn with_temperature(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, c: usize, nominal_rms_h: f64) -> Option<GenericFit> {
    let logged = |segs: &[&Segment]| !segs.is_empty() && segs.iter().all(|s| s.temperature_c.len() == s.len() && s.len() > 0);
    if !logged(train) || !logged(held) {
        return None;
    }
    let n: usize = train.iter().map(|s| s.len()).sum();
    let t_ref = train.iter().flat_map(|s| &s.temperature_c).sum::<f64>() / n as f64;
    let (base_t, base_h) = (rms(train, rem_t, c, None), rms(held, rem_h, c, None));
    if base_t <= 0.0 || base_h <= 0.0 {
        return None;
    }
    let (after_t, after_h, b) = shared_law(train, rem_t, held, rem_h, c, 2, &|s| temperature_regressors(s, c, t_ref));
    let (const_t, _, _) = shared_law(train, rem_t, held, rem_h, c, 1, &|s| {
        let n = nominal_pred(s, c);
        n.iter().map(|v| vec![(0, *v)]).collect()
    });
    let own_pts = shrink(base_t, after_t) - shrink(base_t, const_t);
    let (t_lo, t_hi) = train.iter().flat_map(|s| &s.temperature_c).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(*t), b.max(*t)));
    let change_pct = 100.0 * b.get(1).copied().unwrap_or(0.0).abs() * (t_hi - t_lo).max(0.0);
    let mut g = drift_fit(
        c,
        own_pts,
        change_pct,
        "one following the temperature",
        "over the logged temperatures",
        [shrink(nominal_rms_h, after_h), shrink(base_h, after_h), shrink(base_t, after_t)],
    );
    g.params.insert("gain_per_k".into(), b.get(1).copied().unwrap_or(0.0));
    g.params.insert("gain_at_mean_temperature".into(), b.first().copied().unwrap_or(0.0));
    g.params.insert("mean_temperature_c".into(), t_ref);
    Some(g)
}

/// A gain-drift result on channel `c`, refused when a constant gain explains
/// nearly as much (`own_pts` over it) or the gain would move implausibly far
/// (`change_pct` over `span`). `shrinks`: primary held-out, remainder
/// held-out, remainder training.
fn drift_fit(c: usize, own_pts: f64, change_pct: f64, drift: &str, span: &str, shrinks: [f64; 3]) -> GenericFit {
    let refused = if own_pts < OVER_CONSTANT_PTS {
        Some(format!("on training a constant gain explains within {OVER_CONSTANT_PTS} points as much as {drift} ({own_pts:.1} points less): a gain error, not a drift"))
    } else if change_pct > MAX_GAIN_CHANGE_PCT {
        Some(format!("the gain would move by {change_pct:.0} % {span} (a drifting gain moves under {MAX_GAIN_CHANGE_PCT:.0} %): a slow signal of another kind"))
    } else {
        None
    };
    let mut g = GenericFit {
        class: "gain_drift".into(),
        channel: CHANNELS[c].into(),
        primary_shrink_pct: shrinks[0],
        remainder_shrink_pct: shrinks[1],
        train_shrink_pct: shrinks[2],
        refused,
        ..Default::default()
    };
    g.params.insert("gain_change_pct".into(), change_pct);
    g.params.insert("over_constant_gain_points".into(), own_pts);
    g
}

/// Weighted least squares of `y` on the sparse rows of `x` where `keep`.
fn solve(s: &Segment, c: usize, p: usize, x: &[Vec<(usize, f64)>], y: &[f64], keep: &dyn Fn(usize) -> bool) -> Vec<f64> {
    let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
    let mut atb = nalgebra::DVector::<f64>::zeros(p);
    for i in (0..s.len()).filter(|i| keep(*i)) {
        let w2 = s.weight(c, i).powi(2);
        for &(a, xa) in &x[i] {
            atb[a] += w2 * xa * y[i];
            for &(b, xb) in &x[i] {
                ata[(a, b)] += w2 * xa * xb;
            }
        }
    }
    ata.svd(true, true)
        .solve(&atb, 1e-12)
        .map(|v| v.iter().copied().collect())
        .unwrap_or_else(|_| vec![0.0; p])
}

fn predict(x: &[(usize, f64)], b: &[f64]) -> f64 {
    x.iter().map(|(j, v)| v * b.get(*j).copied().unwrap_or(0.0)).sum()
}

/// Two-fold cross-validated weighted RMS of what the gain model leaves on
/// channel `c` of the remainder, over the segments.
fn cv_rms(segs: &[&Segment], rem: &Remainder, c: usize, drifting: bool) -> f64 {
    let (mut ss, mut n) = (0.0, 0usize);
    for (s, r) in segs.iter().zip(rem) {
        let Some(y) = &r[c] else { continue };
        let (p, x) = regressors(s, c, drifting);
        let fold = |i: usize| ((s.t_rel[i] / CV_BLOCK_S).floor() as i64) % 2;
        for f in 0..2 {
            let b = solve(s, c, p, &x, y, &|i| fold(i) != f);
            for i in (0..s.len()).filter(|i| fold(*i) == f) {
                ss += (s.weight(c, i) * (y[i] - predict(&x[i], &b))).powi(2);
            }
        }
        n += s.len();
    }
    if n == 0 {
        0.0
    } else {
        (ss / n as f64).sqrt()
    }
}

/// The drifting gain on channel `c` (with the temperature when every run
/// logs it): fitted and scored as above;
/// `nominal_rms_h` is the nominal's held-out RMS on `c`. Its parameters are
/// the training runs' gain course: the least-squares slope of the fitted
/// gain over time (`drift_per_s`, fraction of the nominal per s) and its
/// range (`gain_change_pct`).
pub fn fit(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, c: usize, nominal_rms_h: f64) -> Option<GenericFit> {
    if let Some(g) = with_temperature(train, rem_t, held, rem_h, c, nominal_rms_h) {
        return Some(g);
    }
    let base_t = rms(train, rem_t, c, None);
    let base_h = rms(held, rem_h, c, None);
    if base_t <= 0.0 || base_h <= 0.0 {
        return None;
    }
    let after_t = cv_rms(train, rem_t, c, true);
    let const_t = cv_rms(train, rem_t, c, false);
    let after_h = cv_rms(held, rem_h, c, true);
    // The gain's course on training, all of each run fitted at once.
    let (mut st, mut sg, mut stt, mut stg, mut m) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (s, r) in train.iter().zip(rem_t) {
        let Some(y) = &r[c] else { continue };
        let (p, x) = regressors(s, c, true);
        let b = solve(s, c, p, &x, y, &|_| true);
        for (i, t) in s.t.iter().enumerate() {
            let g: f64 = hats(s.t_rel[i]).iter().map(|(j, h)| h * b.get(*j).copied().unwrap_or(0.0)).sum();
            (st, sg, stt, stg, m) = (st + t, sg + g, stt + t * t, stg + t * g, m + 1.0);
            (lo, hi) = (lo.min(g), hi.max(g));
        }
    }
    let slope = if m > 1.0 && m * stt - st * st > 0.0 {
        (m * stg - st * sg) / (m * stt - st * st)
    } else {
        0.0
    };
    let own_pts = shrink(base_t, after_t) - shrink(base_t, const_t);
    let change_pct = if hi >= lo { 100.0 * (hi - lo) } else { 0.0 };
    let mut g = drift_fit(
        c,
        own_pts,
        change_pct,
        "a gain drifting within each run",
        "over a run",
        [shrink(nominal_rms_h, after_h), shrink(base_h, after_h), shrink(base_t, after_t)],
    );
    g.params.insert("drift_per_s".into(), slope);
    Some(g)
}
