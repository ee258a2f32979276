//! The disturbance effect (issue 13 §3): an unmeasured external force (or
//! a disturbance on the actuator input) estimated as a signal, piecewise
//! constant between change points of the residual.
//!
//! Held-out discipline: the one free choice, the change-point threshold,
//! is chosen on the training part; on the held-out part the levels are
//! cross-validated in time — each interval between change points is cut
//! into blocks of twice the smoothing window, and every block is
//! predicted by the level of the other blocks of its interval (2-fold,
//! alternate blocks), never by its own samples. A residual that is not
//! piecewise constant (white or fast) gains nothing; steps of an
//! unmeasured force are predicted across their own interval.
//! Change points are located on the held-out residual itself (their times
//! are what the effect reports); that leaks their positions, not levels.

use super::events::{self, Remainder};
use super::figures::shrink;
use super::residual::{Nominal, Segment, NCH, POSITION, TORQUE};

/// A channel carries the disturbance only if, on the training part, the
/// cross-validated levels shrink that channel's remainder by at least
/// this (%): an unmeasured force acts on torque and position alike, but
/// its deflection may sit below the position channel's floor, where
/// levels would only add noise.
pub const CHANNEL_MIN_PCT: f64 = 10.0;

/// Change points within this of a logged-signal event count as locked to
/// it, s.
pub const LOCK_TOL_S: f64 = 0.05;
/// Change points locked to logged-signal events: at least `LOCKED_RATIO`
/// times as often near one as chance puts them there, and at least
/// `LOCKED_EXCESS_POINTS` above chance. The "disturbance" then follows the
/// motion or the measured load, so it is a model error of the nominal, not
/// an unmeasured external force (whose events have their own clock).
pub const LOCKED_RATIO: f64 = 2.0;
pub const LOCKED_EXCESS_POINTS: f64 = 10.0;

/// Thresholds (robust sigmas) tried on the training part.
pub const THRESHOLDS: [f64; 6] = [4.0, 6.0, 8.0, 12.0, 16.0, 24.0];

#[derive(Clone, Debug, serde::Serialize)]
pub struct DisturbanceFit {
    pub model: String,
    /// What it is fitted on: `nominal` (the nominal residual) or `stack`
    /// (after the library stack), whichever leaves less on training.
    pub base: String,
    /// Weighted training gap after it (chooses the base).
    pub train_gap_after: f64,
    /// Change-point threshold chosen on training, robust sigmas.
    pub threshold_sigma: f64,
    /// Cross-validated weighted shrink of the training remainder with it, %.
    pub train_cv_shrink_pct: f64,
    pub heldout_change_points: usize,
    /// Change times on the held-out part (run, s), the first 40.
    pub change_times_s: Vec<(usize, f64)>,
    pub mean_interval_s: f64,
    /// Level unit: the force at the nut (N, physics nominal, from the
    /// torque channel via the lead) or the logged current (A, regression).
    pub level_unit: String,
    pub median_abs_level: f64,
    pub max_abs_level: f64,
    /// Share of its change points within `LOCK_TOL_S` of a logged-signal
    /// event (move start/stop, reference-acceleration or load change), %,
    /// the share chance gives, %, and whether it is locked to them.
    pub signal_locked_pct: f64,
    pub chance_pct: f64,
    pub locked_to_signals: bool,
    /// Channels it acts on (chosen on training).
    pub channels: Vec<String>,
    /// Held-out figures with stack + disturbance against the nominal
    /// (`figures::WEIGHTED`, `figures::PRIMARY`), and the primary-channel
    /// points it adds over the stack alone.
    pub weighted_shrink_pct: f64,
    pub primary_shrink_pct: f64,
    pub over_stack_points: f64,
    /// Share of the stack's remainder it explains (weighted), %.
    /// (Zero channels: the levels helped no channel on training.)
    pub remainder_explained_pct: f64,
}

/// Cross-validated piecewise-constant prediction of one channel.
fn cv_levels(s: &Segment, x: &[f64], c: usize, cps: &[usize]) -> (Vec<f64>, Vec<(usize, f64)>) {
    let b = 2 * (2 * s.sg_m + 1);
    let mut pred = vec![0.0; x.len()];
    let mut levels = Vec::new();
    let mut bounds = vec![0];
    bounds.extend(cps.iter().copied().filter(|i| *i > 0 && *i < x.len()));
    bounds.push(x.len());
    for iv in bounds.windows(2) {
        let (a, e) = (iv[0], iv[1]);
        let mut sw = [0.0; 2];
        let mut swx = [0.0; 2];
        for (i, xi) in x.iter().enumerate().take(e).skip(a) {
            let p = ((i - a) / b) % 2;
            let w2 = s.weight(c, i).powi(2);
            sw[p] += w2;
            swx[p] += w2 * xi;
        }
        let lv = |p: usize| if sw[p] > 0.0 { swx[p] / sw[p] } else { 0.0 };
        for (i, pr) in pred.iter_mut().enumerate().take(e).skip(a) {
            *pr = lv(1 - ((i - a) / b) % 2);
        }
        if sw[0] + sw[1] > 0.0 {
            levels.push((a, (swx[0] + swx[1]) / (sw[0] + sw[1])));
        }
    }
    (pred, levels)
}

/// Weighted gap (as `fit::gap`) of a remainder minus an optional prediction.
pub fn gap(segs: &[&Segment], rem: &Remainder, pred: Option<&Remainder>, w: &[f64; NCH]) -> f64 {
    let (mut ss, mut n) = (0.0, 0usize);
    for (k, (s, r)) in segs.iter().zip(rem).enumerate() {
        for c in 0..NCH {
            let Some(x) = &r[c] else { continue };
            if w[c] == 0.0 {
                continue;
            }
            let p = pred.and_then(|p| p[k][c].as_ref());
            for i in 0..x.len() {
                ss += (w[c] * s.weight(c, i) * (x[i] - p.map_or(0.0, |p| p[i]))).powi(2);
            }
            n += x.len();
        }
    }
    if n == 0 {
        0.0
    } else {
        (ss / n as f64).sqrt()
    }
}

/// The cross-validated piecewise-constant prediction of every torque and
/// position channel, with the change points and the torque levels.
pub fn predict(segs: &[&Segment], rem: &Remainder, k: f64, use_ch: &[bool; NCH]) -> (Remainder, Vec<Vec<usize>>, Vec<f64>) {
    let cps = events::detect(segs, rem, k);
    let mut levels = Vec::new();
    let pred = segs
        .iter()
        .zip(rem)
        .zip(&cps)
        .map(|((s, r), cp)| {
            std::array::from_fn(|c| {
                let x = r[c].as_ref()?;
                if (c != TORQUE && c != POSITION) || !use_ch[c] {
                    return Some(vec![0.0; x.len()]);
                }
                let (p, lv) = cv_levels(s, x, c, cp);
                if c == TORQUE {
                    levels.extend(lv.iter().map(|l| l.1));
                }
                Some(p)
            })
        })
        .collect();
    (pred, cps, levels)
}

/// Fits the disturbance on the training remainder and scores it on the
/// held-out one. `gap_nominal_h` and `gap_nominal_primary_h`: the
/// nominal's held-out gaps, for the shrink figures; `stack_gap_h`: the
/// stack's.
#[allow(clippy::too_many_arguments)]
pub fn fit(
    train: &[&Segment],
    rem_train: &Remainder,
    held: &[&Segment],
    rem_held: &Remainder,
    nominal: &Nominal,
    w: &[f64; NCH],
    primary: usize,
    gap_nominal_h: f64,
    gap_nominal_primary_h: f64,
) -> (DisturbanceFit, Remainder, Vec<Vec<usize>>) {
    let base_t = gap(train, rem_train, None, w);
    let all_ch = [true; NCH];
    let one = |c: usize| {
        let mut wc = [0.0; NCH];
        wc[c] = 1.0;
        wc
    };
    // Threshold and channels on training: per threshold, the channels the
    // levels help; the threshold whose (channel-gated) gap is least.
    let (k, use_ch, train_gap) = THRESHOLDS
        .iter()
        .map(|k| {
            let p = predict(train, rem_train, *k, &all_ch).0;
            let use_ch: [bool; NCH] = std::array::from_fn(|c| {
                shrink(gap(train, rem_train, None, &one(c)), gap(train, rem_train, Some(&p), &one(c))) >= CHANNEL_MIN_PCT
            });
            let g = gap(train, rem_train, Some(&predict(train, rem_train, *k, &use_ch).0), w);
            (*k, use_ch, g)
        })
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .unwrap_or((events::STEP_SIGMA, [false; NCH], base_t));
    let (pred, cps, levels) = predict(held, rem_held, k, &use_ch);
    let (lk, ch) = events::locked_share(held, &cps, &events::signal_events(held), LOCK_TOL_S);
    let g_stack = gap(held, rem_held, None, w);
    let g = gap(held, rem_held, Some(&pred), w);
    let wp = one(primary);
    let gp = gap(held, rem_held, Some(&pred), &wp);
    let gp_stack = gap(held, rem_held, None, &wp);
    let (scale, unit) = match nominal {
        Nominal::Physics(p) => (1.0 / p.k, "N (force at the nut, from the torque channel)"),
        Nominal::Regression(_) => (1.0, "A (logged current: an input disturbance)"),
    };
    let mut abs: Vec<f64> = levels.iter().map(|l| (l * scale).abs()).collect();
    abs.sort_by(f64::total_cmp);
    let n_cp: usize = cps.iter().map(Vec::len).sum();
    let dur: f64 = held.iter().map(|s| s.len() as f64 * s.dt).sum();
    let fitd = DisturbanceFit {
        model: "unmeasured force (input disturbance) piecewise constant between change points of the residual".into(),
        base: String::new(),
        signal_locked_pct: lk,
        chance_pct: ch,
        locked_to_signals: lk >= LOCKED_RATIO * ch && lk - ch >= LOCKED_EXCESS_POINTS,
        train_gap_after: train_gap,
        threshold_sigma: k,
        train_cv_shrink_pct: shrink(base_t, train_gap),
        heldout_change_points: n_cp,
        change_times_s: held
            .iter()
            .zip(&cps)
            .flat_map(|(s, cp)| cp.iter().map(move |i| (s.run, s.t[*i])))
            .take(40)
            .collect(),
        mean_interval_s: dur / (n_cp + held.len()).max(1) as f64,
        level_unit: unit.into(),
        median_abs_level: abs.get(abs.len() / 2).copied().unwrap_or(0.0),
        max_abs_level: abs.last().copied().unwrap_or(0.0),
        weighted_shrink_pct: shrink(gap_nominal_h, g),
        primary_shrink_pct: shrink(gap_nominal_primary_h, gp),
        over_stack_points: shrink(gap_nominal_primary_h, gp) - shrink(gap_nominal_primary_h, gp_stack),
        channels: (0..NCH).filter(|c| use_ch[*c]).map(|c| super::residual::CHANNELS[c].to_string()).collect(),
        remainder_explained_pct: shrink(g_stack, g),
    };
    (fitd, pred, cps)
}
