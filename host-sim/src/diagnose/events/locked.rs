//! Event-locked energy: how much of the residual's energy
//! falls in the windows after events against the share of time those
//! windows cover, and how many change points sit at a logged-signal event.
//! A remainder that an unmeasured force leaves concentrates there; one the
//! model leaves everywhere does not.

use super::Remainder;
use crate::diagnose::residual::Segment;

/// The window after an event the energy share is measured in, s (it
/// starts `EVENT_BEFORE_S` early: the smoothing spreads a step).
pub const EVENT_AFTER_S: f64 = 0.3;
pub const EVENT_BEFORE_S: f64 = 0.02;

/// Share of the change points within `tol_s` of a logged-signal event, %,
/// and the share expected by chance (the time those windows cover), %.
/// Each change point counts with its weight (`(sample, weight)`: the
/// residual energy it explains), so a few large steps of an unmeasured
/// force are not outvoted by many small ones at the stops; with equal
/// weights it is the share of change points.
pub fn locked_share(
    segs: &[&Segment],
    cps: &[Vec<(usize, f64)>],
    sig: &[Vec<usize>],
    tol_s: f64,
) -> (f64, f64) {
    let (mut near, mut n, mut covered, mut total) = (0.0, 0.0, 0usize, 0usize);
    for ((s, cp), ev) in segs.iter().zip(cps).zip(sig) {
        let tol = (tol_s / s.dt).round() as usize;
        let mut mask = vec![false; s.len()];
        for &e in ev {
            for m in mask
                .iter_mut()
                .take((e + tol + 1).min(s.len()))
                .skip(e.saturating_sub(tol))
            {
                *m = true;
            }
        }
        covered += mask.iter().filter(|m| **m).count();
        total += s.len();
        near += cp
            .iter()
            .filter(|(i, _)| mask[*i])
            .map(|(_, w)| w)
            .sum::<f64>();
        n += cp.iter().map(|(_, w)| w).sum::<f64>();
    }
    let pct = |a: f64, b: f64| if b > 0.0 { 100.0 * a / b } else { 0.0 };
    (pct(near, n), pct(covered as f64, total as f64))
}

/// Whether a locked share is more than chance can give: the change
/// points' effective number `n = (Σw)²/Σw²` (a few large steps count as
/// few, however many small ones sit beside them), of which `locked_pct`
/// lie near a logged event where chance puts `chance_pct`; the binomial
/// tail P(X ≥ k | n, p) must fall under `alpha`. Two edges of one long
/// force step, one of which lands near a move by chance, prove nothing.
pub fn lock_significant(cps: &[Vec<(usize, f64)>], locked_pct: f64, chance_pct: f64, alpha: f64) -> bool {
    let (s1, s2) = cps
        .iter()
        .flatten()
        .fold((0.0, 0.0), |(a, b), (_, w)| (a + w, b + w * w));
    if s2 <= 0.0 {
        return false;
    }
    let n = ((s1 * s1 / s2).round() as u64).max(1);
    let k = ((locked_pct / 100.0) * n as f64).round() as u64;
    let p = (chance_pct / 100.0).clamp(1e-9, 1.0 - 1e-9);
    // P(X ≥ k), X ~ Binomial(n, p), summed in logs.
    let ln_c = |n: u64, j: u64| -> f64 {
        (1..=j).map(|i| ((n - j + i) as f64).ln() - (i as f64).ln()).sum()
    };
    let tail: f64 = (k..=n)
        .map(|j| (ln_c(n, j) + j as f64 * p.ln() + (n - j) as f64 * (1.0 - p).ln()).exp())
        .sum();
    tail < alpha
}

/// Energy share (%) of channel `c` within `[e − before, e + after]` of the
/// events, and the share of weighted time those windows cover (%).
pub fn share_after(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    ev: &[Vec<usize>],
    before_s: f64,
    after_s: f64,
) -> (f64, f64) {
    let (mut e_in, mut e_all, mut t_in, mut t_all) = (0.0, 0.0, 0.0, 0.0);
    for ((s, r), ev) in segs.iter().zip(rem).zip(ev) {
        let Some(x) = &r[c] else { continue };
        let mut mask = vec![false; s.len()];
        let (b, a) = (
            (before_s / s.dt).round() as usize,
            (after_s / s.dt).round() as usize,
        );
        for &e in ev {
            for m in mask
                .iter_mut()
                .take((e + a + 1).min(s.len()))
                .skip(e.saturating_sub(b))
            {
                *m = true;
            }
        }
        for i in 0..s.len() {
            let w = s.weight(c, i);
            let en = (w * x[i]).powi(2);
            e_all += en;
            t_all += w * w;
            if mask[i] {
                e_in += en;
                t_in += w * w;
            }
        }
    }
    let pct = |a: f64, b: f64| if b > 0.0 { 100.0 * a / b } else { 0.0 };
    (pct(e_in, e_all), pct(t_in, t_all))
}
