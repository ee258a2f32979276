//! The remainder's character: from its events and time
//! structure — energy after change points against the share of time,
//! event-locked averages, the dominant period, whiteness, the slow (drift)
//! share and what the inputs explain — the remainder is named event-locked,
//! periodic, drift, input-correlated or broadband. The measurements live in
//! the submodules (one job each); this file holds the thresholds, the
//! summary record and the classification that reads them.

mod change_points;
mod cross;
mod drift;
mod inputs;
mod locked;
mod periodicity;

pub use change_points::*;
pub use cross::split_across_events;
pub use drift::*;
pub use inputs::*;
pub use locked::*;
use periodicity::acf;
pub use periodicity::*;

use super::residual::{Segment, CHANNELS, NCH};

/// Per segment and channel: the residual left (unweighted; every figure
/// here applies the standstill weights `Segment::weight`).
pub type Remainder = Vec<[Option<Vec<f64>>; NCH]>;

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
    // Never the channel's own output (`inputs::own_output_free`): on the
    // torque channel no current, and the drifting gain is the nominal
    // torque's.
    let torque = c == super::residual::TORQUE;
    let free: Vec<inputs::OwnOutputFree> = segs.iter().map(|s| inputs::own_output_free(s, c)).collect();
    let mut names = vec!["speed", "acceleration", "load", "position", "direction of motion"];
    if !torque {
        names.push("current");
    }
    names.push(if torque {
        "nominal torque × time (a drifting gain)"
    } else {
        "current × time (a drifting gain)"
    });
    let input_correlation: Vec<(String, f64)> = names
        .iter()
        .map(|name| {
            let (mut sxy, mut sxx, mut syy, mut sx, mut sy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for ((s, r), f) in segs.iter().zip(rem).zip(&free) {
                let Some(x) = &r[c] else { continue };
                let u: Vec<f64> = match *name {
                    "speed" => f.v.clone(),
                    "acceleration" => f.a.clone(),
                    "load" => s.f_load.clone(),
                    "position" => f.x.clone(),
                    "current" => f.current.clone(),
                    "direction of motion" => f
                        .v
                        .iter()
                        .enumerate()
                        .map(|(i, v)| {
                            if v.abs() > 1e-4 {
                                v.signum()
                            } else {
                                s.dir.get(i).copied().unwrap_or(0.0)
                            }
                        })
                        .collect(),
                    _ => f.gain.iter().zip(&s.t_rel).map(|(g, t)| g * t).collect(),
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
                if var > 0.0 { (cov / var.sqrt()).abs() } else { 0.0 },
            )
        })
        .collect();
    let best_in = input_correlation
        .iter()
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
        // The periodic part carries about `acf_p` of what the inputs leave,
        // `acf_p · (100 − input_r2)` % of the energy: the period names the
        // remainder only if that is at least what the inputs explain. (A
        // signal logged late by τ leaves `−τ ẏ`, which the inputs'
        // derivatives explain; what they leave of it repeats with the moves.)
        && acf_p * (100.0 - input_r2_pct) >= input_r2_pct
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
