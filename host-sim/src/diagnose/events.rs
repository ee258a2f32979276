//! Events and time structure of a residual (issue 13 §2): change points in
//! the residual and in the logged signals, how the residual energy
//! concentrates after them against the share of time, event-locked
//! averages, autocorrelation with its dominant period, the Ljung–Box
//! whiteness test, slow (drift) share and correlation with the inputs; and
//! from these the remainder's character.

use super::residual::{Segment, CHANNELS, NCH};
use super::spectrum::fft;

/// Per segment and channel: the residual left (unweighted; every figure
/// here applies the standstill weights `Segment::weight`).
pub type Remainder = Vec<[Option<Vec<f64>>; NCH]>;

/// Half window of the two-window step detector, s: long enough to average
/// the ±10 ms Savitzky–Golay smoothing and the floor's jitter, short
/// against the 0.1–1 s between a real rig's load events.
pub const STEP_WINDOW_S: f64 = 0.05;
/// A change point: the step statistic exceeds this many robust sigmas
/// (1.4826 · MAD of the statistic over the whole record, which the rare
/// steps do not move). Calibrated per log for the disturbance effect.
pub const STEP_SIGMA: f64 = 8.0;
/// The window after an event the energy share is measured in, s (it
/// starts `EVENT_BEFORE_S` early: the smoothing spreads a step).
pub const EVENT_AFTER_S: f64 = 0.3;
pub const EVENT_BEFORE_S: f64 = 0.02;
/// Character thresholds: energy share after events beyond the time share
/// (points); the autocorrelation peak of a periodic remainder; the share
/// of energy slower than `SLOW_S`; the input correlation; the Ljung–Box
/// p-value below which the remainder is not white.
pub const LOCKED_EXCESS_POINTS: f64 = 25.0;
pub const PERIODIC_ACF: f64 = 0.3;
/// The speed's own autocorrelation at the remainder's period above which
/// the period is the move cycle.
pub const MOTION_CYCLE_ACF: f64 = 0.3;
pub const SLOW_S: f64 = 1.0;
pub const DRIFT_SLOW_SHARE_PCT: f64 = 60.0;
pub const INPUT_CORR: f64 = 0.5;
/// Share of the energy a linear combination of the inputs (`input_r2`)
/// explains above which the remainder is input-correlated (the multiple
/// correlation's square, as `INPUT_CORR`² for one input).
pub const INPUT_R2_PCT: f64 = 25.0;
pub const WHITE_P: f64 = 0.01;
/// Piecewise-constant (disturbance) explanation of the remainder above
/// which it is "steps" (event-locked) whatever the energy windows say.
pub const STEPS_SHARE_PCT: f64 = 50.0;
/// … provided the change points are steps, not a smoother: at least this
/// long between them on average, s.
pub const STEPS_MIN_INTERVAL_S: f64 = 0.5;
/// Periodic in the motor angle: the cross-validated share of the energy
/// sinusoids of the angle at a kinematic period (`kinematic_periods`,
/// `angle_features`) explain, %, at or above which the remainder has that
/// period — the same bar as the inputs' (a
/// quarter of the energy, ρ = 0.5 for one regressor).
pub const ANGLE_R2_PCT: f64 = 25.0;
/// A time period counts when its autocorrelation peak is at least this many
/// Bartlett standard errors (≈ 3: the 0.3 % level of one lag, a margin
/// for the search over lags).
pub const ACF_SIGNIFICANCE_Z: f64 = 3.0;
/// A slow remainder is a level shift (event-locked), not a drift, when one
/// step leaves at most this share of what a straight line leaves of its
/// `SLOW_S` average (`step_or_trend`).
pub const STEP_OVER_TREND: f64 = 0.5;

#[derive(Clone, Debug, serde::Serialize)]
pub struct EventOut {
    pub run: usize,
    pub t_s: f64,
    pub log_row: usize,
    /// Step size in the channel's units (after minus before).
    pub step: f64,
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct TimeStructure {
    pub channel: String,
    pub events_detected: usize,
    /// The first 40 events.
    pub events: Vec<EventOut>,
    pub window_s: [f64; 2],
    /// Residual energy within the windows after residual change points, %,
    /// against the share of (weighted) time they cover, %.
    pub energy_after_events_pct: f64,
    pub time_after_events_pct: f64,
    /// The same after logged motion events (move starts and stops).
    pub motion_events: usize,
    pub energy_after_motion_pct: f64,
    pub time_after_motion_pct: f64,
    /// Sign-aligned event-locked average, (lag s, value), 10 ms steps.
    pub event_locked_average: Vec<(f64, f64)>,
    /// Share of the in-window energy the event-locked average explains, %.
    pub locked_explained_pct: f64,
    pub dominant_period_s: Option<f64>,
    pub acf_at_period: f64,
    /// Bartlett's standard error of the autocorrelation at that lag.
    pub acf_standard_error: f64,
    pub ljung_box_q: f64,
    pub ljung_box_lags: usize,
    pub ljung_box_p: f64,
    pub white: bool,
    /// Energy of the `SLOW_S` moving average (offset and drift), %.
    pub slow_share_pct: f64,
    /// |ρ| of the remainder with speed, acceleration, load, current, position,
    /// direction of motion and current × time (a drifting gain).
    pub input_correlation: Vec<(String, f64)>,
    /// Share of the energy the inputs explain together, cross-validated
    /// over alternating `CV_BLOCK_S` blocks (least squares on
    /// `input_features`), %.
    pub input_r2_pct: f64,
    /// Share of the remainder a piecewise-constant signal between change
    /// points explains (cross-validated), %.
    pub steps_explained_pct: f64,
    /// Best number of periods per motor revolution and the share of the
    /// energy its sinusoids explain (cross-validated), %.
    pub angle_periods_per_rev: u32,
    pub angle_explained_pct: f64,
    /// One level shift's residual against a straight line's, on the slow
    /// part (`step_or_trend`).
    pub step_over_trend: f64,
    /// event-locked, periodic, drift, input-correlated, broadband (white)
    /// or broadband (coloured).
    pub character: String,
    pub character_why: String,
}

/// Two-window step statistic `mean(x[i..i+w]) − mean(x[i−w..i])` of the
/// weighted signal (0 where a window would leave the record).
pub fn step_stat(x: &[f64], wt: &[f64], w: usize) -> Vec<f64> {
    let n = x.len();
    let mut out = vec![0.0; n];
    if n < 2 * w + 1 || w == 0 {
        return out;
    }
    let mut px = vec![0.0; n + 1];
    let mut pw = vec![0.0; n + 1];
    for i in 0..n {
        px[i + 1] = px[i] + wt[i] * x[i];
        pw[i + 1] = pw[i] + wt[i];
    }
    for (i, o) in out.iter_mut().enumerate().take(n - w + 1).skip(w) {
        let (wa, wb) = (pw[i + w] - pw[i], pw[i] - pw[i - w]);
        if wa > 0.2 * w as f64 && wb > 0.2 * w as f64 {
            *o = (px[i + w] - px[i]) / wa - (px[i] - px[i - w]) / wb;
        }
    }
    out
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1
}

/// 1.4826 · MAD (a Gaussian's sigma), over the non-zero values.
pub fn robust_sigma(v: &[f64]) -> f64 {
    let mut a: Vec<f64> = v.iter().copied().filter(|x| *x != 0.0).collect();
    let m = median(&mut a);
    let mut d: Vec<f64> = a.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&mut d)
}

/// Change points of a segment from several channels' step statistics
/// (each in robust sigmas; the largest counts), at least `w` apart.
pub fn change_points(stats: &[Vec<f64>], sigmas: &[f64], w: usize, k: f64) -> Vec<usize> {
    let n = stats.first().map_or(0, Vec::len);
    let z: Vec<f64> = (0..n)
        .map(|i| {
            stats
                .iter()
                .zip(sigmas)
                .filter(|(_, s)| **s > 0.0)
                .map(|(d, s)| d[i].abs() / s)
                .fold(0.0, f64::max)
        })
        .collect();
    let mut cand: Vec<usize> = (0..n).filter(|&i| z[i] >= k).collect();
    cand.sort_by(|a, b| z[*b].total_cmp(&z[*a]));
    let mut taken: Vec<usize> = Vec::new();
    for i in cand {
        if taken.iter().all(|t| t.abs_diff(i) > w) {
            taken.push(i);
        }
    }
    taken.sort_unstable();
    taken
}

/// Weights of channel `c` of a segment.
pub fn weights(s: &Segment, c: usize) -> Vec<f64> {
    (0..s.len()).map(|i| s.weight(c, i)).collect()
}

/// Residual change points per segment, from the torque and position
/// channels (the ones an unmeasured force acts on), sigma per channel over
/// all segments.
pub fn detect(segs: &[&Segment], rem: &Remainder, k: f64) -> Vec<Vec<usize>> {
    detect_floor(segs, rem, k, [0.0; 2])
}

/// `detect` on the remainder weighted by `max(weight, floor[c])` (torque,
/// position).
pub fn detect_floor(
    segs: &[&Segment],
    rem: &Remainder,
    k: f64,
    floor: [f64; 2],
) -> Vec<Vec<usize>> {
    let chans: Vec<usize> = (0..2)
        .filter(|c| rem.iter().any(|r| r[*c].is_some()))
        .collect();
    let stats: Vec<Vec<Vec<f64>>> = segs
        .iter()
        .zip(rem)
        .map(|(s, r)| {
            let w = ((STEP_WINDOW_S / s.dt).round() as usize).max(3);
            chans
                .iter()
                .map(|&c| {
                    let wt: Vec<f64> = weights(s, c).into_iter().map(|v| v.max(floor[c])).collect();
                    r[c].as_ref()
                        .map_or(vec![0.0; s.len()], |x| step_stat(x, &wt, w))
                })
                .collect()
        })
        .collect();
    let sig: Vec<f64> = chans
        .iter()
        .enumerate()
        .map(|(j, _)| {
            robust_sigma(
                &stats
                    .iter()
                    .flat_map(|st| st[j].iter().copied())
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    segs.iter()
        .zip(&stats)
        .map(|(s, st)| {
            change_points(
                st,
                &sig,
                ((STEP_WINDOW_S / s.dt).round() as usize).max(3),
                k,
            )
        })
        .collect()
}

/// Events in the logged signals: move starts and stops, and change points
/// of the reference acceleration (the jerk-limited phases) and of the
/// logged load.
pub fn signal_events(segs: &[&Segment]) -> Vec<Vec<usize>> {
    let mot = motion_events(segs);
    segs.iter()
        .zip(mot)
        .map(|(s, mut ev)| {
            let w = ((STEP_WINDOW_S / s.dt).round() as usize).max(3);
            let ones = vec![1.0; s.len()];
            for sig in [&s.a_ref, &s.f_load] {
                let st = step_stat(sig, &ones, w);
                let sd = robust_sigma(&st);
                if sd > 0.0 {
                    ev.extend(change_points(&[st], &[sd], w, STEP_SIGMA));
                }
            }
            ev.sort_unstable();
            ev.dedup();
            ev
        })
        .collect()
}

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

/// Move starts and stops: the reference speed crossing 5 % of its peak.
pub fn motion_events(segs: &[&Segment]) -> Vec<Vec<usize>> {
    let vmax = segs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    segs.iter()
        .map(|s| {
            let th = 0.05 * vmax;
            (1..s.len())
                .filter(|&i| (s.v_ref[i].abs() > th) != (s.v_ref[i - 1].abs() > th))
                .collect()
        })
        .collect()
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

/// Events (segment, sample) nearest to the given times of one log's
/// segments; times outside every segment are dropped.
pub fn events_at(segs: &[&Segment], times: &[f64]) -> Vec<Vec<usize>> {
    segs.iter()
        .map(|s| {
            times
                .iter()
                .filter(|t| {
                    s.t.first().is_some_and(|t0| **t >= *t0)
                        && s.t.last().is_some_and(|t1| **t <= *t1)
                })
                .map(|t| s.t.partition_point(|x| x < t).min(s.len() - 1))
                .collect()
        })
        .collect()
}

/// Autocorrelation (lags 0..=max_lag) of the weighted remainder, by FFT.
fn acf(segs: &[&Segment], rem: &Remainder, c: usize, max_lag: usize) -> Vec<f64> {
    let mut acc = vec![0.0; max_lag + 1];
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let n = x.len();
        let mut nfft = 1;
        while nfft < 2 * n {
            nfft <<= 1;
        }
        let mean = (0..n).map(|i| s.weight(c, i) * x[i]).sum::<f64>() / n.max(1) as f64;
        let mut re: Vec<f64> = (0..nfft)
            .map(|i| {
                if i < n {
                    s.weight(c, i) * x[i] - mean
                } else {
                    0.0
                }
            })
            .collect();
        let mut im = vec![0.0; nfft];
        fft(&mut re, &mut im);
        let mut p: Vec<f64> = re.iter().zip(&im).map(|(a, b)| a * a + b * b).collect();
        let mut q = vec![0.0; nfft];
        fft(&mut p, &mut q);
        for (l, a) in acc.iter_mut().enumerate().take(max_lag.min(n - 1) + 1) {
            *a += p[l] / nfft as f64;
        }
    }
    let a0 = acc[0];
    acc.iter()
        .map(|a| if a0 > 0.0 { a / a0 } else { 0.0 })
        .collect()
}

/// Complementary error function (Abramowitz & Stegun 7.1.26, |ε| < 1.5e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let y = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let r = y * (-z * z).exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Upper tail of χ² with `k` degrees of freedom (Wilson–Hilferty).
pub fn chi2_sf(q: f64, k: usize) -> f64 {
    let k = k as f64;
    let z = ((q / k).powf(1.0 / 3.0) - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Ljung–Box Q over `h` lags of a series, with its p-value.
pub fn ljung_box(x: &[f64], h: usize) -> (f64, f64) {
    let n = x.len();
    if n <= h + 2 {
        return (0.0, 1.0);
    }
    let m = x.iter().sum::<f64>() / n as f64;
    let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    if c0 <= 0.0 {
        return (0.0, 1.0);
    }
    let q: f64 = (1..=h)
        .map(|k| {
            let rho = (k..n).map(|i| (x[i] - m) * (x[i - k] - m)).sum::<f64>() / c0;
            rho * rho / (n - k) as f64
        })
        .sum::<f64>()
        * (n * (n + 2)) as f64;
    (q, chi2_sf(q, h))
}

/// The time structure of channel `c` of a remainder. `steps_explained_pct`
/// comes from the disturbance fit (cross-validated piecewise constant).
pub fn analyse(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    cps: &[Vec<usize>],
    steps_explained_pct: f64,
    periods_per_rev: &[u32],
) -> TimeStructure {
    let dt = segs.first().map_or(1e-3, |s| s.dt);
    let (e_ev, t_ev) = share_after(segs, rem, c, cps, EVENT_BEFORE_S, EVENT_AFTER_S);
    let mot = motion_events(segs);
    let (e_mo, t_mo) = share_after(segs, rem, c, &mot, EVENT_BEFORE_S, EVENT_AFTER_S);
    // Sign-aligned event-locked average over [−0.1, +0.5] s.
    let (pre, post) = ((0.1 / dt).round() as usize, (0.5 / dt).round() as usize);
    let mut sum = vec![0.0; pre + post + 1];
    let mut cnt = vec![0.0; pre + post + 1];
    let mut events = Vec::new();
    let w = ((STEP_WINDOW_S / dt).round() as usize).max(3);
    for ((s, r), ev) in segs.iter().zip(rem).zip(cps) {
        let Some(x) = &r[c] else { continue };
        let st = step_stat(x, &weights(s, c), w);
        for &e in ev {
            let sg = if st[e] < 0.0 { -1.0 } else { 1.0 };
            if events.len() < 40 {
                events.push(EventOut {
                    run: s.run,
                    t_s: s.t[e],
                    log_row: s.first_row + e + 1,
                    step: st[e],
                });
            }
            for (j, (a, b)) in sum.iter_mut().zip(cnt.iter_mut()).enumerate() {
                let Some(i) = (e + j).checked_sub(pre).filter(|i| *i < s.len()) else {
                    continue;
                };
                let wi = s.weight(c, i);
                *a += sg * wi * x[i];
                *b += wi;
            }
        }
    }
    let tmpl: Vec<f64> = sum
        .iter()
        .zip(&cnt)
        .map(|(a, b)| if *b > 0.0 { a / b } else { 0.0 })
        .collect();
    let (mut num, mut den) = (0.0, 0.0);
    for ((s, r), ev) in segs.iter().zip(rem).zip(cps) {
        let Some(x) = &r[c] else { continue };
        let st = step_stat(x, &weights(s, c), w);
        for &e in ev {
            let sg = if st[e] < 0.0 { -1.0 } else { 1.0 };
            for (j, t) in tmpl.iter().enumerate() {
                let Some(i) = (e + j).checked_sub(pre).filter(|i| *i < s.len()) else {
                    continue;
                };
                let wi = s.weight(c, i);
                num += (wi * x[i] - sg * wi * t).powi(2);
                den += (wi * x[i]).powi(2);
            }
        }
    }
    let locked_explained_pct = if den > 0.0 {
        100.0 * (1.0 - num / den)
    } else {
        0.0
    };
    let step10 = ((0.01 / dt).round() as usize).max(1);
    let event_locked_average = (0..tmpl.len())
        .step_by(step10)
        .map(|j| (j as f64 * dt - pre as f64 * dt, tmpl[j]))
        .collect();
    // Autocorrelation: dominant period = highest peak after the first zero
    // crossing, up to 5 s or half the shortest segment.
    let min_len = segs
        .iter()
        .zip(rem)
        .filter(|(_, r)| r[c].is_some())
        .map(|(s, _)| s.len())
        .min()
        .unwrap_or(0);
    let max_lag = ((5.0 / dt) as usize).min(min_len / 2).max(2);
    // What the inputs explain (cross-validated), and the remainder without
    // it: a period the remainder inherits from the motion through the
    // inputs is not a periodic disturbance of its own.
    let in_feats: Vec<Vec<Vec<f64>>> = segs.iter().map(|s| input_features(s, c)).collect();
    let (linear_r2_pct, in_pred) = cv_regress(segs, rem, c, &in_feats);
    let binned = binned_inputs(segs, rem, c);
    let best_binned =
        binned
            .iter()
            .cloned()
            .fold((String::new(), 0.0), |m, v| if v.1 > m.1 { v } else { m });
    let input_r2_pct = linear_r2_pct.max(best_binned.1);
    let cleaned: Remainder = rem
        .iter()
        .zip(&in_pred)
        .map(|(r, p)| {
            std::array::from_fn(|k| {
                let x = r[k].as_ref()?;
                Some(if k == c && p.len() == x.len() {
                    x.iter().zip(p).map(|(a, b)| a - b).collect()
                } else {
                    x.clone()
                })
            })
        })
        .collect();
    let (angle_n, angle_r2_pct, _) = angle_periodic(segs, rem, c, periods_per_rev);
    let rho = acf(segs, &cleaned, c, max_lag);
    let (mut period, mut acf_p, mut acf_se) = (None, 0.0, 0.0);
    if let Some(z0) = rho.iter().position(|v| *v < 0.0) {
        if let Some((l, v)) = rho
            .iter()
            .enumerate()
            .skip(z0)
            .max_by(|a, b| a.1.total_cmp(b.1))
        {
            if *v > 0.0 && l < max_lag {
                period = Some(l as f64 * dt);
                acf_p = *v;
                // Bartlett's standard error of the autocorrelation at lag l
                // (a series correlated up to l − 1): √((1 + 2 Σ ρ_j²) / N),
                // N the samples at that lag. A slow remainder's ACF wanders
                // far more than white noise's 1/√N.
                let n_eff: usize = segs
                    .iter()
                    .zip(&cleaned)
                    .filter(|(_, r)| r[c].is_some())
                    .map(|(s, _)| s.len().saturating_sub(l))
                    .sum();
                let s2: f64 = rho[1..l].iter().map(|r| r * r).sum();
                acf_se = ((1.0 + 2.0 * s2) / n_eff.max(1) as f64).sqrt();
            }
        }
    }
    // A period the motion itself repeats with (the speed's magnitude
    // correlates at that lag) is the experiment's move cycle: locked to
    // the motion, not a periodic disturbance.
    let motion_cycle = period.is_some_and(|p| {
        let l = (p / dt).round() as usize;
        let speed: Remainder = segs
            .iter()
            .map(|s| {
                std::array::from_fn(|k| (k == c).then(|| s.v_ref.iter().map(|v| v.abs()).collect()))
            })
            .collect();
        // A cycle: the speed decorrelates (a move ends) and correlates again.
        let r = acf(segs, &speed, c, l);
        r.iter().any(|v| *v < 0.0) && r.get(l).is_some_and(|v| *v >= MOTION_CYCLE_ACF)
    });
    // Ljung–Box on block means over the smoothing window (2m+1 samples), so
    // the Savitzky–Golay smoothing's own correlation does not count.
    let mut blocks = Vec::new();
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let b = 2 * s.sg_m + 1;
        for k in 0..s.len() / b {
            blocks.push(
                (k * b..(k + 1) * b)
                    .map(|i| s.weight(c, i) * x[i])
                    .sum::<f64>()
                    / b as f64,
            );
        }
    }
    let h = 20.min(blocks.len() / 5).max(1);
    let (q, p) = ljung_box(&blocks, h);
    // Slow share: energy of the SLOW_S moving average.
    let (mut slow, mut tot) = (0.0, 0.0);
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let half = ((0.5 * SLOW_S / s.dt) as usize).max(1);
        let mut pre_s = vec![0.0; s.len() + 1];
        for (i, xi) in x.iter().enumerate() {
            pre_s[i + 1] = pre_s[i] + s.weight(c, i) * xi;
        }
        for (i, xi) in x.iter().enumerate() {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(s.len()));
            slow += ((pre_s[b] - pre_s[a]) / (b - a) as f64).powi(2);
            tot += (s.weight(c, i) * xi).powi(2);
        }
    }
    let slow_share_pct = if tot > 0.0 { 100.0 * slow / tot } else { 0.0 };
    let input_correlation: Vec<(String, f64)> = [
        ("speed", 0usize),
        ("acceleration", 1),
        ("load", 2),
        ("current", 3),
        ("position", 4),
        ("direction of motion", 5),
        ("current × time (a drifting gain)", 6),
    ]
    .iter()
    .map(|(name, k)| {
        let (mut sxy, mut sxx, mut syy, mut sx, mut sy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (s, r) in segs.iter().zip(rem) {
            let Some(x) = &r[c] else { continue };
            let sgn: Vec<f64>;
            let u: &[f64] = match *k {
                5 => {
                    sgn =
                        s.v.iter()
                            .enumerate()
                            .map(|(i, v)| {
                                if v.abs() > 1e-4 {
                                    v.signum()
                                } else {
                                    s.dir.get(i).copied().unwrap_or(0.0)
                                }
                            })
                            .collect();
                    &sgn
                }
                6 => {
                    sgn = s.iq.iter().zip(&s.t_rel).map(|(i, t)| i * t).collect();
                    &sgn
                }
                _ => [&s.v, &s.a, &s.f_load, &s.iq, &s.x][*k],
            };
            for i in 0..s.len() {
                let a = s.weight(c, i) * x[i];
                sxy += a * u[i];
                sxx += a * a;
                syy += u[i] * u[i];
                sx += a;
                sy += u[i];
                n += 1.0;
            }
        }
        let cov = sxy / n - sx * sy / n / n;
        let var = (sxx / n - (sx / n).powi(2)) * (syy / n - (sy / n).powi(2));
        (
            name.to_string(),
            if var > 0.0 {
                (cov / var.sqrt()).abs()
            } else {
                0.0
            },
        )
    })
    .collect();
    let best_in = input_correlation
        .iter()
        .filter(|(n, _)| !(c == super::residual::TORQUE && n == "current"))
        .cloned()
        .fold((String::new(), 0.0), |m, v| if v.1 > m.1 { v } else { m });
    let white = p > WHITE_P;
    let duration: f64 = segs.iter().map(|s| s.len() as f64 * s.dt).sum();
    let n_ev: usize = cps.iter().map(Vec::len).sum();
    let (is_step, step_t, step_ratio) = step_or_trend(segs, rem, c);
    let (character, why) = if angle_r2_pct >= ANGLE_R2_PCT {
        (
            "periodic",
            format!("{angle_n} period(s) per motor revolution explain {angle_r2_pct:.0} % of its energy faster than {SLOW_S} s (cross-validated; the inputs {input_r2_pct:.0} % of all of it)"),
        )
    } else if period.is_some()
        && acf_p >= PERIODIC_ACF
        && acf_p >= ACF_SIGNIFICANCE_Z * acf_se
        && !motion_cycle
    {
        (
            "periodic",
            format!(
                "autocorrelation {acf_p:.2} (Bartlett standard error {acf_se:.2}) at a period of {:.3} s once the inputs' share is removed",
                period.unwrap_or(0.0)
            ),
        )
    } else if n_ev > 0
        && (e_ev - t_ev >= LOCKED_EXCESS_POINTS
            || (steps_explained_pct >= STEPS_SHARE_PCT
                && duration / n_ev as f64 >= STEPS_MIN_INTERVAL_S))
    {
        (
            "event-locked",
            format!(
                "{n_ev} change points; {e_ev:.0} % of the energy within {:.0} ms after them in {t_ev:.0} % of the time; steps between them explain {steps_explained_pct:.0} %",
                1e3 * EVENT_AFTER_S
            ),
        )
    } else if slow_share_pct >= DRIFT_SLOW_SHARE_PCT && is_step {
        (
            "event-locked",
            format!("{slow_share_pct:.0} % of the energy is slower than {SLOW_S} s, and one level shift at {step_t:.2} s leaves {:.0} % of what a trend leaves", 100.0 * step_ratio),
        )
    } else if slow_share_pct >= DRIFT_SLOW_SHARE_PCT {
        (
            "drift",
            format!(
                "{slow_share_pct:.0} % of the energy is slower than {SLOW_S} s (offset or drift)"
            ),
        )
    } else if input_r2_pct >= INPUT_R2_PCT {
        (
            "input-correlated",
            format!(
                "the inputs explain {input_r2_pct:.0} % of its energy (cross-validated: linear in them together {linear_r2_pct:.0} %, any function of the {} alone {:.0} %); |ρ| = {:.2} with the {}",
                best_binned.0, best_binned.1, best_in.1, best_in.0
            ),
        )
    } else if mot.iter().any(|m| !m.is_empty()) && e_mo - t_mo >= LOCKED_EXCESS_POINTS {
        (
            "event-locked",
            format!("{e_mo:.0} % of the energy within {:.0} ms after move starts and stops in {t_mo:.0} % of the time", 1e3 * EVENT_AFTER_S),
        )
    } else if white {
        (
            "broadband (white)",
            format!(
                "Ljung–Box p = {p:.3} over {h} lags of {:.0} ms blocks",
                1e3 * dt * 21.0
            ),
        )
    } else {
        (
            "broadband (coloured)",
            format!("not white (Ljung–Box p = {p:.1e}) but no events, period, drift or input it follows"),
        )
    };
    TimeStructure {
        channel: CHANNELS[c].into(),
        events_detected: n_ev,
        events,
        window_s: [EVENT_BEFORE_S, EVENT_AFTER_S],
        energy_after_events_pct: e_ev,
        time_after_events_pct: t_ev,
        motion_events: mot.iter().map(Vec::len).sum(),
        energy_after_motion_pct: e_mo,
        time_after_motion_pct: t_mo,
        event_locked_average,
        locked_explained_pct,
        dominant_period_s: period,
        acf_at_period: acf_p,
        acf_standard_error: acf_se,
        ljung_box_q: q,
        ljung_box_lags: h,
        ljung_box_p: p,
        white,
        slow_share_pct,
        input_correlation,
        input_r2_pct,
        steps_explained_pct,
        angle_periods_per_rev: angle_n,
        angle_explained_pct: angle_r2_pct,
        step_over_trend: step_ratio,
        character: character.into(),
        character_why: why,
    }
}

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
/// motion, |speed|, acceleration, jerk, load, nut force, its rate, current
/// (not on the torque channel, whose residual is the current minus the
/// nominal: its noise would explain itself), position, current × time (a
/// drifting gain). Jerk and the force's rate are there because a signal
/// logged late by τ leaves `−τ ẏ`: a delay is correlated with the inputs'
/// derivatives.
pub fn input_features(s: &Segment, c: usize) -> Vec<Vec<f64>> {
    let m = s.sg_m.max(1);
    let jerk = derivative(&s.a, m, s.dt);
    let fdot = derivative(&s.f_ax, m, s.dt);
    (0..s.len())
        .map(|i| {
            let v = s.v[i];
            let sg = if v.abs() > 1e-4 {
                v.signum()
            } else {
                s.dir.get(i).copied().unwrap_or(0.0)
            };
            let iq = if c == super::residual::TORQUE {
                0.0
            } else {
                s.iq[i]
            };
            let fax = s.f_ax.get(i).copied().unwrap_or(0.0);
            vec![
                1.0,
                v,
                sg,
                v.abs(),
                s.a[i],
                jerk[i],
                s.f_load[i],
                fax,
                fdot[i],
                iq,
                s.x[i],
                s.iq[i] * s.t_rel[i],
            ]
        })
        .collect()
}

/// Periods per motor revolution of the kinematic-period test, known before
/// the data are seen (no search): the screw's revolution (the motor drives
/// it directly: encoder eccentricity, once-per-revolution lead error) and
/// its second harmonic, and with the rig's pole pairs `p` the electrical
/// period `p` and `2p` (current-sensor offsets and gain mismatch).
pub fn kinematic_periods(pole_pairs: Option<u32>) -> Vec<u32> {
    let mut v = vec![1, 2];
    if let Some(p) = pole_pairs.filter(|p| *p > 0) {
        v.extend([p, 2 * p]);
    }
    v.sort_unstable();
    v.dedup();
    v
}

/// Features of a remainder periodic in the motor angle with `n` periods per
/// revolution: `sin nθ`, `cos nθ` (an error on the angle or the force) and
/// their second time derivatives `n(α cos nθ − n ω² sin nθ)`, … (the same
/// error seen through the differentiation into acceleration), and 1.
pub fn angle_features(s: &Segment, n: f64) -> Vec<Vec<f64>> {
    (0..s.len())
        .map(|i| {
            let (sn, cs) = (n * s.theta[i]).sin_cos();
            let (om, al) = (
                s.omega.get(i).copied().unwrap_or(0.0),
                s.alpha.get(i).copied().unwrap_or(0.0),
            );
            vec![
                1.0,
                sn,
                cs,
                n * (al * cs - n * om * om * sn),
                -n * (al * sn + n * om * om * cs),
            ]
        })
        .collect()
}

/// The best of the kinematic periods (periods per revolution) and its
/// cross-validated share of the remainder's fast part (faster than
/// `SLOW_S`), %.
pub fn angle_periodic(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    periods: &[u32],
) -> (u32, f64, Vec<Vec<f64>>) {
    let mut best = (0, 0.0, segs.iter().map(|_| Vec::new()).collect());
    if segs.iter().all(|s| {
        s.theta
            .iter()
            .all(|t| *t == s.theta.first().copied().unwrap_or(0.0))
    }) {
        return best;
    }
    // Fast parts only (each signal minus its `SLOW_S` moving average): an
    // angle period shows while the angle sweeps; at rest a sinusoid of the
    // angle is a constant that would fit the rest levels of a slow
    // remainder (an offset, a step) through the positions the rod rests at.
    let hp = |x: &[f64], s: &Segment| -> Vec<f64> {
        let n = x.len();
        let half = ((0.5 * SLOW_S / s.dt) as usize).max(1);
        let mut pre = vec![0.0; n + 1];
        for (i, v) in x.iter().enumerate() {
            pre[i + 1] = pre[i] + v;
        }
        (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
                x[i] - (pre[b] - pre[a]) / (b - a) as f64
            })
            .collect()
    };
    let fast: Remainder = segs
        .iter()
        .zip(rem)
        .map(|(s, r)| {
            std::array::from_fn(|k| {
                if k == c {
                    r[k].as_ref().map(|x| hp(x, s))
                } else {
                    None
                }
            })
        })
        .collect();
    for &n in periods {
        let feats: Vec<Vec<Vec<f64>>> = segs
            .iter()
            .map(|s| {
                let f = angle_features(s, f64::from(n));
                let cols: Vec<Vec<f64>> = (1..5)
                    .map(|j| hp(&f.iter().map(|r| r[j]).collect::<Vec<_>>(), s))
                    .collect();
                (0..s.len())
                    .map(|i| vec![1.0, cols[0][i], cols[1][i], cols[2][i], cols[3][i]])
                    .collect()
            })
            .collect();
        let (r2, pred) = cv_regress(segs, &fast, c, &feats);
        if r2 > best.1 {
            best = (n, r2, pred);
        }
    }
    best
}

/// Does one level shift explain the slow part of the remainder better than
/// a trend? On the `SLOW_S` moving average of the weighted remainder, per
/// segment: the residual sum of squares of the best single step (two levels)
/// against that of a straight line; a step when it leaves at most
/// `STEP_OVER_TREND` of the line's. Returns (is a step, its time s, ratio).
pub fn step_or_trend(segs: &[&Segment], rem: &Remainder, c: usize) -> (bool, f64, f64) {
    let (mut sse_step, mut sse_line, mut t_step, mut best_gain) = (0.0, 0.0, f64::NAN, 0.0);
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let n = s.len();
        if n < 10 {
            continue;
        }
        let half = ((0.5 * SLOW_S / s.dt) as usize).max(1);
        let mut pre = vec![0.0; n + 1];
        for (i, xi) in x.iter().enumerate() {
            pre[i + 1] = pre[i] + s.weight(c, i) * xi;
        }
        let y: Vec<f64> = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
                (pre[b] - pre[a]) / (b - a) as f64
            })
            .collect();
        // Straight line.
        let t: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let (mt, my) = (
            t.iter().sum::<f64>() / n as f64,
            y.iter().sum::<f64>() / n as f64,
        );
        let stt: f64 = t.iter().map(|v| (v - mt).powi(2)).sum();
        let sty: f64 = t.iter().zip(&y).map(|(a, b)| (a - mt) * (b - my)).sum();
        let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
        sse_line += syy - if stt > 0.0 { sty * sty / stt } else { 0.0 };
        // Best single step: maximise the between-level sum of squares.
        let mut cy = 0.0;
        let (mut gain, mut at) = (0.0, 0);
        for k in 1..n {
            cy += y[k - 1] - my;
            let g = cy * cy * n as f64 / (k as f64 * (n - k) as f64);
            if g > gain {
                gain = g;
                at = k;
            }
        }
        sse_step += syy - gain;
        if gain > best_gain {
            best_gain = gain;
            t_step = s.t[at];
        }
    }
    let ratio = if sse_line > 0.0 {
        sse_step / sse_line
    } else {
        1.0
    };
    (ratio <= STEP_OVER_TREND, t_step, ratio)
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
        for i in 0..s.len() {
            let w = s.weight(c, i);
            if w <= 0.0 {
                continue;
            }
            rows.push((
                input(s, i),
                w * x[i],
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
    let mut out = vec![
        ("speed".to_string(), binned_cv(segs, rem, c, &|s, i| s.v[i])),
        (
            "acceleration".to_string(),
            binned_cv(segs, rem, c, &|s, i| s.a[i]),
        ),
        (
            "nominal prediction".to_string(),
            binned_cv(segs, rem, c, &nominal),
        ),
        (
            "position".to_string(),
            binned_cv(segs, rem, c, &|s, i| s.x[i]),
        ),
    ];
    if c != super::residual::TORQUE {
        out.push((
            "current".to_string(),
            binned_cv(segs, rem, c, &|s, i| s.iq[i]),
        ));
    }
    out
}
