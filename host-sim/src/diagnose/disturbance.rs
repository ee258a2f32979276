//! The disturbance effect: an unmeasured external force (or
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

pub mod edges;
pub mod event_fit;
mod levels;
mod motion;
pub mod pulses;

pub use levels::Levels;
pub use motion::FOLLOWS_MIN_PCT;
pub use pulses::Event;

use super::events::{self, Remainder};
use super::figures::shrink;
use super::residual::{Nominal, Segment, NCH, POSITION, TORQUE};
use levels::{cv_levels, smoothed};

/// A channel carries the disturbance only if, on the training part, the
/// cross-validated levels shrink that channel's remainder by at least
/// this (%): an unmeasured force acts on torque and position alike, but
/// its deflection may sit below the position channel's floor, where
/// levels would only add noise.
pub const CHANNEL_MIN_PCT: f64 = 10.0;

/// Change points within this of a logged-signal event count as locked to
/// it, s.
pub const LOCK_TOL_S: f64 = 0.05;
/// Change points locked to logged-signal events: a share of them at least
/// `LOCKED_RATIO` times what chance puts near one, and at least
/// `LOCKED_EXCESS_POINTS` above chance — each change point weighted by
/// the residual energy it explains (`events::locked_share`), so that the
/// small steps a rod leaves as it stops (the seal's held friction in the
/// position channel) do not outvote an unmeasured force's large ones. The "disturbance" then follows the
/// motion or the measured load, so it is a model error of the nominal, not
/// an unmeasured external force (whose events have their own clock).
pub const LOCKED_RATIO: f64 = 2.0;
pub const LOCKED_EXCESS_POINTS: f64 = 10.0;
/// ... and only when chance is unlikely to give that share
/// (`events::lock_significant`: binomial tail over the change points'
/// effective number below this).
pub const LOCK_ALPHA: f64 = 0.01;

/// Thresholds (robust sigmas) tried on the training part.
pub const THRESHOLDS: [f64; 6] = [4.0, 6.0, 8.0, 12.0, 16.0, 24.0];

#[derive(Clone, Debug, Default, serde::Serialize)]
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
    /// Every held-out interval between change points with its level (in
    /// `level_unit`): the disturbance's time course.
    pub intervals: Vec<Interval>,
    /// The events: each departure of the levels from the level the log
    /// spends most of its time at, with its onset, offset and level (in
    /// `level_unit`, from that baseline) and their uncertainties.
    pub events: Vec<Event>,
    /// Where it acts: an external force on the rod, or the actuator input
    /// (the motor's torque or current), as far as the channels tell.
    pub side: String,
    pub median_abs_level: f64,
    pub max_abs_level: f64,
    /// Share of its change points within `LOCK_TOL_S` of a logged-signal
    /// event (move start/stop, reference-acceleration or load change), %,
    /// the share chance gives, %, and whether it is locked to them.
    pub signal_locked_pct: f64,
    pub chance_pct: f64,
    /// Cross-validated share of the interval levels' variance the motion
    /// explains, % (`None`: too few intervals). Change points at logged
    /// events whose levels do not follow the motion (under
    /// `FOLLOWS_MIN_PCT`) are a force that comes with the motion, not a
    /// model error: not locked.
    pub levels_follow_motion_pct: Option<f64>,
    pub locked_to_signals: bool,
    /// Channels it acts on (chosen on training).
    pub channels: Vec<String>,
    /// Held-out figures with stack + disturbance against the nominal
    /// (`figures::WEIGHTED`, `figures::PRIMARY`), and the primary-channel
    /// points it adds over the stack alone.
    pub weighted_shrink_pct: f64,
    /// The channels an unmeasured axial force acts on, fixed by the
    /// physics, not by the data: torque and position (a force on the rod
    /// loads the motor and deflects the drive train; the voltage equation
    /// holds no force), the logged current with a regression nominal.
    pub acting_channels: Vec<String>,
    /// `figures::WEIGHTED_ACTING`: the weighted figure over
    /// `acting_channels` only, %.
    pub acting_weighted_shrink_pct: f64,
    /// The most the weighted figure could reach with the acting channels
    /// explained entirely (the other channels' held-out gap after the
    /// stack stays), %.
    pub weighted_ceiling_pct: f64,
    /// How the levels act: `per_channel` or `force` (one force through
    /// the nominal model's torque and compliance), chosen on training.
    pub levels: String,
    pub primary_shrink_pct: f64,
    /// Held-out shrink of each channel's gap against the nominal, %.
    pub shrink_by_channel: std::collections::BTreeMap<String, f64>,
    pub over_stack_points: f64,
    /// Share of the stack's remainder it explains (weighted), %.
    /// (Zero channels: the levels helped no channel on training.)
    pub remainder_explained_pct: f64,
}

/// One interval between change points with its level (unscaled: N for
/// `Levels::Force`, the channel's residual unit for `Levels::PerChannel`).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Interval {
    #[serde(skip)]
    pub channel: usize,
    pub run: usize,
    pub start_s: f64,
    pub end_s: f64,
    pub level: f64,
    /// 1-sigma uncertainty of `start_s` (the fitted edge; `None` at a
    /// segment's start) and of `level` (`None`: too short to tell).
    pub start_sd_s: Option<f64>,
    pub level_sd: Option<f64>,
}

/// Change points of a segment, each with the weighted residual energy it
/// explains.
pub type Steps = Vec<(usize, f64)>;


/// Change points of the disturbance are found on the torque remainder with
/// its standstill weights and on the position remainder weighted by
/// `max(standstill weight, DETECT_WEIGHT_FLOOR)`: the standstill fade
/// blinds a step detector to a force that comes or goes while the rod
/// stands still. At rest the position channel still measures the nut
/// force up to what the seal holds (≈ 45 N, ≈ 6 µm through the drive
/// train's compliance, against 30–70 µm for 200–500 N), while the torque
/// channel is then uncertain by the whole friction the nut and seal hold
/// (drag, efficiency friction μ (L/2π) |F| and seal: up to ≈ 0.2 N·m
/// against 0.16–0.4 N·m for the same force), so it keeps its fade.
/// Levels and scores keep the standstill weights on both.
pub const DETECT_WEIGHT_FLOOR: f64 = 0.5;

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

/// The cross-validated piecewise-constant prediction of the torque and
/// position channels in `use_ch`, with the change points (each with the
/// weighted energy it explains) and the levels.
pub fn predict(
    segs: &[&Segment],
    rem: &Remainder,
    k: f64,
    use_ch: &[bool; NCH],
    mode: Levels,
    nominal: &Nominal,
    w: &[f64; NCH],
) -> (Remainder, Vec<Steps>, Vec<Interval>) {
    let floor = [0.0, DETECT_WEIGHT_FLOOR];
    let fitted: Vec<Vec<event_fit::Edge>> = events::detect_floor(segs, rem, k, floor)
        .iter()
        .zip(segs.iter().zip(rem))
        .map(|(cp, (s, r))| event_fit::fit_edges(s, r, cp, k, floor, smoothed))
        .collect();
    let cps: Vec<Vec<usize>> = fitted.iter().map(|v| v.iter().map(|e| e.i).collect()).collect();
    let chans: Vec<usize> = [TORQUE, POSITION]
        .into_iter()
        .filter(|c| use_ch[*c])
        .collect();
    let mut levels = Vec::new();
    let mut steps = Vec::new();
    let pred = segs
        .iter()
        .zip(rem)
        .zip(cps.iter().zip(&fitted))
        .map(|((s, r), (cp, edges))| {
            let (p, lv, st) = cv_levels(s, r, &chans, cp, mode, nominal, w);
            levels.extend(lv.into_iter().map(|f| Interval {
                channel: f.channel,
                run: s.run,
                start_s: s.t[f.start],
                end_s: s.t[f.end - 1] + s.dt,
                level: f.level,
                start_sd_s: edges.iter().find(|e| e.i == f.start).map(|e| e.sd_s),
                level_sd: f.sd,
            }));
            // Change points with no channel in use still count (zero weight).
            steps.push(if chans.is_empty() {
                cp.iter().map(|i| (*i, 0.0)).collect()
            } else {
                st
            });
            p
        })
        .collect();
    (pred, steps, levels)
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
    // Level model, threshold and channels on training: per model and
    // threshold, the channels the levels help; the combination whose
    // (channel-gated) cross-validated gap is least.
    let modes: &[Levels] = match nominal {
        Nominal::Physics(_) => &[Levels::PerChannel, Levels::Force],
        Nominal::Regression(_) => &[Levels::PerChannel],
    };
    let (mode, k, use_ch, train_gap) = modes
        .iter()
        .flat_map(|m| THRESHOLDS.iter().map(move |k| (*m, *k)))
        .map(|(m, k)| {
            let p = predict(train, rem_train, k, &all_ch, m, nominal, w).0;
            let use_ch: [bool; NCH] = std::array::from_fn(|c| {
                shrink(
                    gap(train, rem_train, None, &one(c)),
                    gap(train, rem_train, Some(&p), &one(c)),
                ) >= CHANNEL_MIN_PCT
            });
            let g = gap(
                train,
                rem_train,
                Some(&predict(train, rem_train, k, &use_ch, m, nominal, w).0),
                w,
            );
            (m, k, use_ch, g)
        })
        .min_by(|a, b| a.3.total_cmp(&b.3))
        .unwrap_or((Levels::PerChannel, events::STEP_SIGMA, [false; NCH], base_t));
    let (pred, steps, levels) = predict(held, rem_held, k, &use_ch, mode, nominal, w);
    let cps: Vec<Vec<usize>> = steps
        .iter()
        .map(|v| v.iter().map(|x| x.0).collect())
        .collect();
    let (lk, ch) = events::locked_share(held, &steps, &events::signal_events(held), LOCK_TOL_S);
    let g_stack = gap(held, rem_held, None, w);
    let g = gap(held, rem_held, Some(&pred), w);
    let wp = one(primary);
    let gp = gap(held, rem_held, Some(&pred), &wp);
    let gp_stack = gap(held, rem_held, None, &wp);
    // The levels are reported where a force is measured: the torque
    // channel (the motor supplies the force; N at the nut with the rig's
    // physics, the logged current with a regression nominal) when the
    // disturbance acts there, else the first channel it acts on.
    let used: Vec<usize> = (0..NCH).filter(|c| use_ch[*c]).collect();
    let level_ch = if used.contains(&TORQUE) {
        Some(TORQUE)
    } else {
        used.first().copied()
    };
    let (scale, unit) = match (nominal, mode, level_ch) {
        (_, _, None) => (0.0, "none (the levels helped no channel on training)"),
        (Nominal::Physics(_), Levels::Force, _) => (
            1.0,
            "N (force at the nut, from the torque and position channels)",
        ),
        (Nominal::Physics(p), _, Some(TORQUE)) => {
            (1.0 / p.k, "N (force at the nut, from the torque channel)")
        }
        (Nominal::Physics(_), _, Some(_)) => (1.0, "m (scale − motor side)"),
        (Nominal::Regression(_), _, Some(TORQUE)) => {
            (1.0, "A (logged current: an input disturbance)")
        }
        (Nominal::Regression(_), _, Some(_)) => (1.0, "m (tracking error)"),
    };
    let intervals: Vec<Interval> = levels
        .iter()
        .filter(|l| Some(l.channel) == level_ch)
        .map(|l| Interval {
            level: l.level * scale,
            level_sd: l.level_sd.map(|v| v * scale.abs()),
            ..l.clone()
        })
        .collect();
    let follows = motion::levels_follow_motion(held, &intervals);
    let mut abs: Vec<f64> = intervals.iter().map(|l| l.level.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let n_cp: usize = cps.iter().map(Vec::len).sum();
    // An axial force loads the motor and deflects the drive train (or, in
    // a regression nominal, shows in the current and in the tracking
    // error): torque and position, never the voltage equation.
    let acting: Vec<usize> = [TORQUE, POSITION]
        .into_iter()
        .filter(|c| w[*c] > 0.0)
        .collect();
    let w_act: [f64; NCH] = std::array::from_fn(|c| if acting.contains(&c) { w[c] } else { 0.0 });
    let dur: f64 = held.iter().map(|s| s.len() as f64 * s.dt).sum();
    let fitd = DisturbanceFit {
        model: "unmeasured force (input disturbance) piecewise constant between change points of the residual".into(),
        base: String::new(),
        signal_locked_pct: lk,
        chance_pct: ch,
        levels_follow_motion_pct: follows,
        locked_to_signals: lk >= LOCKED_RATIO * ch
            && lk - ch >= LOCKED_EXCESS_POINTS
            && events::lock_significant(&steps, lk, ch, LOCK_ALPHA)
            && follows.is_none_or(|f| f >= FOLLOWS_MIN_PCT),
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
        events: pulses::events(&intervals),
        intervals,
        side: match (nominal, mode) {
            (_, _) if used.is_empty() => "nothing (the levels helped no channel on training)".into(),
            (Nominal::Physics(_), Levels::Force) => "an external force on the rod (one force explains the motor torque and the drive train's deflection together)".into(),
            (Nominal::Physics(_), _) if use_ch[POSITION] && use_ch[TORQUE] => "an external force on the rod (it deflects the drive train as it loads the motor)".into(),
            (Nominal::Physics(_), _) if use_ch[TORQUE] => "the actuator input (the motor's torque: no deflection of the drive train follows it), or a force too small to deflect the drive train above its floor".into(),
            (Nominal::Physics(_), _) => "the position measurement only (a deflection no torque follows: the scale or its mount)".into(),
            (Nominal::Regression(_), _) if use_ch[TORQUE] && use_ch[POSITION] => "an external force or the actuator input (both show in the current and the tracking error; a regression nominal cannot tell them apart)".into(),
            (Nominal::Regression(_), _) if use_ch[TORQUE] => "the actuator input or a load (the current only)".into(),
            (Nominal::Regression(_), _) => "the position (tracking error) only: no current follows it".into(),
        },
        median_abs_level: abs.get(abs.len() / 2).copied().unwrap_or(0.0),
        max_abs_level: abs.last().copied().unwrap_or(0.0),
        weighted_shrink_pct: shrink(gap_nominal_h, g),
        acting_channels: acting.iter().map(|c| super::residual::CHANNELS[*c].to_string()).collect(),
        acting_weighted_shrink_pct: shrink(super::fit::gap(held, None, &w_act), gap(held, rem_held, Some(&pred), &w_act)),
        levels: mode.name().into(),
        weighted_ceiling_pct: {
            // The other channels' energy over every channel's samples (as
            // the weighted figure counts them).
            let w_other: [f64; NCH] = std::array::from_fn(|c| if acting.contains(&c) { 0.0 } else { w[c] });
            let count = |wc: &[f64; NCH]| -> usize {
                held.iter().zip(rem_held).map(|(s, r)| (0..NCH).filter(|c| r[*c].is_some() && wc[*c] != 0.0).count() * s.len()).sum()
            };
            let frac = count(&w_other) as f64 / count(w).max(1) as f64;
            shrink(gap_nominal_h, gap(held, rem_held, None, &w_other) * frac.sqrt())
        },
        primary_shrink_pct: shrink(gap_nominal_primary_h, gp),
        shrink_by_channel: (0..NCH)
            .filter(|c| held.iter().any(|s| s.r[*c].is_some()))
            .map(|c| {
                let wc = one(c);
                (
                    super::residual::CHANNELS[c].to_string(),
                    shrink(super::fit::gap(held, None, &wc), gap(held, rem_held, Some(&pred), &wc)),
                )
            })
            .collect(),
        over_stack_points: shrink(gap_nominal_primary_h, gp) - shrink(gap_nominal_primary_h, gp_stack),
        channels: (0..NCH).filter(|c| use_ch[*c]).map(|c| super::residual::CHANNELS[c].to_string()).collect(),
        remainder_explained_pct: shrink(g_stack, g),
    };
    (fitd, pred, cps)
}
