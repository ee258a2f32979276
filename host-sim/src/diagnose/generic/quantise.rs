//! Quantisation coarser than the rig file expects: an encoder with fewer
//! counts, a scale or a current logged with fewer digits. A quantised
//! column only ever takes the values `a + k q` of a lattice (its staircase),
//! and the channel it feeds carries the rounding error `Q(x) − x` of the
//! true signal `x`.
//!
//! The class is named only on its own evidence, never on the residual's
//! size alone:
//! - **a lattice** (the log's staircase): the column's values sit on one
//!   (`LATTICE_MIN` of the phase `2π v / q` agrees across the samples; an
//!   unquantised or noisy column scores ≈ 1/√N) and cross at least
//!   `MIN_LEVELS` of its steps;
//! - **coarser than the rig**: the step is at least `COARSER` times the
//!   resolution the rig file gives that sensor (one encoder count, the
//!   scale's step, one current-ADC step), so the nominal rig's own
//!   encoder and scale are never named;
//! - **the residual's staircase**: the channel's remainder follows the
//!   rounding of the nominal's prediction of the column (the motion and the
//!   load through the nominal and the stack), `Q(x̂) − x̂` through the
//!   channel it enters (the position channel as itself or `−(L/2π)` of the
//!   angle's, the torque channel `K_t` times the smoothed current's), one
//!   amplitude fitted on training and scored on the held-out part. This
//!   is evidence for the current only: the position channel is the scale
//!   less the motor side sample by sample, so wherever its remainder is
//!   under half a step the predicted value rounds to the logged one and
//!   the predicted rounding is that remainder, by construction. There the
//!   lattice is the evidence, and the figure is reported, not gated on.
//!
//! A rounding error is noise wherever the signal crosses steps: no model
//! predicts it sample by sample better than the prediction locates the
//! true value within a step. What the class states it explains is what
//! the rounding accounts for, its error's energy through the channel as a
//! share of the remainder's, given as the shrink its removal would give.

use super::super::events::Remainder;
use super::super::figures::shrink;
use super::super::residual::{sg_smooth, Nominal, Physics, Segment, CHANNELS, POSITION, TORQUE};
use super::{lsq, rms, Basis, GenericFit};

/// Agreement of the samples' phase on the lattice (1: every sample on it).
pub const LATTICE_MIN: f64 = 0.9;
/// Steps the column must cross for its staircase to be seen.
pub const MIN_LEVELS: f64 = 10.0;
/// How many times the rig file's resolution the step must be.
pub const COARSER: f64 = 2.0;
/// Where in a cell the sensor switches to the next value, tried on
/// training: 0 a floor (an encoder's count), ½ rounding to the nearest.
const SWITCH_GRID: usize = 8;
/// How far the nominal's prediction of the true value may be off, in
/// steps, tried on training: a prediction good to a small part of a step
/// sees the sawtooth, a worse one only its first harmonics.
const BLUR_GRID: [f64; 6] = [0.0, 0.05, 0.1, 0.15, 0.2, 0.3];
const HARMONICS: usize = 16;
/// The torque remainder must follow the rounding of the predicted current
/// (its staircase) by at least this held-out shrink, %, or the smoothed
/// rounding does not reach the channel.
pub const STAIRCASE_MIN_PCT: f64 = 2.0;

/// The lattice a column's values sit on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// Its step and one of its points (the column's unit).
    pub step: f64,
    pub offset: f64,
    /// Agreement of the samples' phase on it, 0…1.
    pub score: f64,
    /// The column's range in steps.
    pub levels: f64,
}

/// Agreement of the phase `2π (v − a)/q` across the finite samples, 0…1.
fn phase_agreement(v: &[f64], a: f64, q: f64) -> f64 {
    let (mut c, mut s, mut n) = (0.0, 0.0, 0.0);
    for x in v.iter().filter(|x| x.is_finite()) {
        let ph = std::f64::consts::TAU * (x - a) / q;
        c += ph.cos();
        s += ph.sin();
        n += 1.0;
    }
    if n == 0.0 {
        0.0
    } else {
        (c * c + s * s).sqrt() / n
    }
}

/// The lattice the values sit on, if they sit on one. The step is first
/// read from the smallest changes between samples (a quantised signal at
/// low speed moves one step at a time), then refined by least squares of
/// the values on their step numbers; a column that never moves by a single
/// step is tried at a half, third and quarter of that change.
pub fn lattice(v: &[f64]) -> Option<Lattice> {
    let fin: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if fin.len() < 50 {
        return None;
    }
    let (lo, hi) = fin.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
    let range = hi - lo;
    if range <= 0.0 {
        return None;
    }
    let mut d: Vec<f64> = fin.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|x| *x > 1e-9 * range).collect();
    if d.len() < 20 {
        return None;
    }
    d.sort_by(f64::total_cmp);
    let q0 = d[d.len() / 100];
    (1..=4).find_map(|m| {
        let mut q = q0 / m as f64;
        // The step numbers from the first value, then the step that fits
        // them best; twice, as a first step off by a rounding of the
        // logged values drifts over many steps.
        for _ in 0..2 {
            let k: Vec<f64> = fin.iter().map(|x| ((x - fin[0]) / q).round()).collect();
            let n = k.len() as f64;
            let (mk, mv) = (k.iter().sum::<f64>() / n, fin.iter().sum::<f64>() / n);
            let skk: f64 = k.iter().map(|x| (x - mk).powi(2)).sum();
            let skv: f64 = k.iter().zip(&fin).map(|(a, b)| (a - mk) * (b - mv)).sum();
            if skk <= 0.0 {
                return None;
            }
            q = skv / skk;
        }
        let score = phase_agreement(&fin, fin[0], q);
        let levels = range / q;
        (score >= LATTICE_MIN && levels >= MIN_LEVELS).then_some(Lattice { step: q, offset: fin[0], score, levels })
    })
}

/// The column a quantised sensor logs, the rig file's resolution of it, and
/// what it adds to its channel given the nominal's view of its true value.
#[derive(Clone, Copy)]
enum Column {
    MotorAngle,
    Scale,
    Current,
}

/// The rounding error of a lattice, in steps, at `u` steps from one of its
/// points, for a sensor that switches at `switch` of a cell (0 a floor,
/// ½ the nearest), less its mean (a constant is an offset, not a step);
/// `blur`: the nominal's uncertainty of the true value, in steps — the
/// error expected given the prediction, its sawtooth's harmonics damped by
/// `e^{−2π² n² blur²}`.
fn sawtooth(u: f64, switch: f64, blur: f64) -> f64 {
    if blur <= 0.0 {
        return (u + switch).floor() - u - (switch - 0.5);
    }
    let ph = std::f64::consts::TAU * (u + switch - 0.5);
    (1..=HARMONICS)
        .map(|n| {
            let nf = n as f64;
            let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            sign / (std::f64::consts::PI * nf) * (nf * ph).sin() * (-2.0 * std::f64::consts::PI.powi(2) * nf * nf * blur * blur).exp()
        })
        .sum()
}

impl Column {
    fn name(self) -> &'static str {
        match self {
            Column::MotorAngle => "motor_angle_rad",
            Column::Scale => "terminal_position_m",
            Column::Current => "current_q_a",
        }
    }
    fn channel(self) -> usize {
        match self {
            Column::MotorAngle | Column::Scale => POSITION,
            Column::Current => TORQUE,
        }
    }
    fn expected(self, p: &Physics) -> f64 {
        match self {
            Column::MotorAngle => p.encoder_step_rad,
            Column::Scale => p.scale_step_m,
            Column::Current => p.current_step_a,
        }
    }
    fn logged(self, s: &Segment) -> &[f64] {
        match self {
            Column::MotorAngle => &s.theta_logged,
            Column::Scale => &s.scale_logged,
            Column::Current => &s.iq_logged,
        }
    }
    /// The rounding error the channel carries, from the nominal's view of
    /// the column's true value (`r`: the channel's remainder): the scale
    /// as the motor side and the load predict it, the angle as the scale
    /// sees it, the current as the motion and the load need it.
    fn regressor(self, s: &Segment, r: &[f64], p: &Physics, lat: &Lattice, switch: f64, blur: f64) -> Vec<f64> {
        let e = |x: f64| lat.step * sawtooth((x - lat.offset) / lat.step, switch, blur);
        match self {
            Column::Scale => s.scale_logged.iter().zip(r).map(|(v, r)| e(v - r)).collect(),
            Column::MotorAngle => s.theta_logged.iter().zip(r).map(|(v, r)| -p.k * e(v + r / p.k)).collect(),
            Column::Current => {
                let e: Vec<f64> = s.iq.iter().zip(r).map(|(v, r)| e(v - r / p.kt)).collect();
                sg_smooth(&e, s.sg_m).into_iter().map(|x| p.kt * x).collect()
            }
        }
    }
}

/// The quantisation class on channel `c`: one fit per logged column on a
/// lattice coarser than the rig file's resolution (none where no column
/// is). `nominal_rms_h`: the nominal's held-out RMS on `c`.
pub fn fit(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, nominal: &Nominal, c: usize, nominal_rms_h: f64) -> Vec<GenericFit> {
    let Nominal::Physics(p) = nominal else { return Vec::new() };
    [Column::MotorAngle, Column::Scale, Column::Current]
        .into_iter()
        .filter(|col| col.channel() == c)
        .filter_map(|col| fit_column(train, rem_t, held, rem_h, p, col, nominal_rms_h))
        .collect()
}

#[allow(clippy::too_many_arguments)] // the two parts and their remainders, as everywhere here
fn fit_column(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, p: &Physics, col: Column, nominal_rms_h: f64) -> Option<GenericFit> {
    let c = col.channel();
    let complete = |segs: &[&Segment], rem: &Remainder| segs.iter().zip(rem).all(|(s, r)| r[c].is_some() && col.logged(s).len() == s.len());
    if held.is_empty() || !complete(train, rem_t) || !complete(held, rem_h) {
        return None;
    }
    // The held-out log's own evidence decides; the training log's lattice
    // is reported beside it.
    let values = |segs: &[&Segment]| segs.iter().flat_map(|s| col.logged(s).iter().copied()).collect::<Vec<f64>>();
    let lat = lattice(&values(held))?;
    let expected = col.expected(p);
    if !(expected > 0.0 && lat.step >= COARSER * expected) {
        return None;
    }
    let basis = |segs: &[&Segment], rem: &Remainder, switch: f64, blur: f64| -> Vec<Vec<Vec<f64>>> {
        segs.iter()
            .zip(rem)
            .map(|(s, r)| col.regressor(s, r[c].as_deref().unwrap_or(&[]), p, &lat, switch, blur).into_iter().map(|x| vec![x]).collect())
            .collect()
    };
    // The staircase: the remainder against the rounding of the predicted
    // value, where the sensor switches and how sharp the prediction is
    // chosen on training.
    let (base_t, base_h) = (rms(train, rem_t, c, None), rms(held, rem_h, c, None));
    let (switch, blur, b, after_t) = (0..SWITCH_GRID)
        .flat_map(|j| BLUR_GRID.iter().map(move |bl| (j as f64 / SWITCH_GRID as f64, *bl)))
        .map(|(switch, blur)| {
            let xt = basis(train, rem_t, switch, blur);
            let b = lsq(train, rem_t, c, &xt);
            let after = rms(train, rem_t, c, Some((&xt, &b)));
            (switch, blur, b, after)
        })
        .min_by(|a, b| a.3.total_cmp(&b.3))?;
    let (xt, xh) = (basis(train, rem_t, switch, blur), basis(held, rem_h, switch, blur));
    let after_h = rms(held, rem_h, c, Some((&xh, &b)));
    let staircase_h = shrink(base_h, after_h);
    // What the rounding accounts for: its error's energy through the
    // channel (the sharp sawtooth of the predicted value: it is uniform
    // over a step wherever the signal crosses steps) as a share of the
    // remainder's, stated as the shrink its removal would give. Noise of
    // this kind is accounted for, not predicted sample by sample: the
    // staircase above is the evidence that it is in the channel.
    let accounts = |segs: &[&Segment], rem: &Remainder, base: f64| -> (f64, f64) {
        let e = mean_square(segs, rem, c, &basis(segs, rem, switch, 0.0));
        let share = if base > 0.0 { (e / (base * base)).min(1.0) } else { 0.0 };
        (100.0 * share, 100.0 * (1.0 - (1.0 - share).sqrt()))
    };
    let ((share_t, acc_t), (share_h, acc_h)) = (accounts(train, rem_t, base_t), accounts(held, rem_h, base_h));
    let refused = (c == TORQUE && staircase_h < STAIRCASE_MIN_PCT).then(|| {
        format!(
            "the {} remainder does not follow the rounding of the predicted `{}` ({staircase_h:.1} % of it on the held-out part, at least {STAIRCASE_MIN_PCT} %): the lattice does not reach this channel",
            CHANNELS[c],
            col.name()
        )
    });
    let left_h = (base_h * base_h * (1.0 - share_h / 100.0)).max(0.0).sqrt();
    let ok = refused.is_none();
    let mut g = GenericFit {
        class: "quantisation".into(),
        channel: CHANNELS[c].into(),
        column: Some(col.name().into()),
        primary_shrink_pct: if ok { shrink(nominal_rms_h, left_h) } else { 0.0 },
        remainder_shrink_pct: if ok { acc_h } else { 0.0 },
        train_shrink_pct: if ok { acc_t } else { 0.0 },
        refused,
        basis: Basis(Some((xt, xh))),
        ..Default::default()
    };
    let train_lattice = lattice(&values(train));
    for (k, v) in [
        ("step", lat.step),
        ("expected_step", expected),
        ("coarser_than_rig", lat.step / expected),
        ("lattice_agreement", lat.score),
        ("levels", lat.levels),
        ("switch_in_cell", switch),
        ("prediction_blur_steps", blur),
        ("staircase_amplitude", b.first().copied().unwrap_or(0.0)),
        ("staircase_shrink_pct", staircase_h),
        ("training_staircase_shrink_pct", shrink(base_t, after_t)),
        ("rounding_share_pct", share_h),
        ("training_rounding_share_pct", share_t),
    ] {
        g.params.insert(k.into(), v);
    }
    if let Some(l) = train_lattice {
        g.params.insert("training_step".into(), l.step);
    }
    if let Column::MotorAngle = col {
        g.params.insert("counts_per_rev".into(), std::f64::consts::TAU / lat.step);
    }
    Some(g)
}

/// Weighted mean square over the parts' samples of a one-regressor basis,
/// normalised as `rms` normalises the remainder.
fn mean_square(segs: &[&Segment], rem: &Remainder, c: usize, x: &[Vec<Vec<f64>>]) -> f64 {
    let (mut ss, mut n) = (0.0, 0usize);
    for ((s, r), xs) in segs.iter().zip(rem).zip(x) {
        if r[c].is_none() {
            continue;
        }
        for (i, v) in xs.iter().enumerate() {
            ss += (s.weight(c, i) * v.first().copied().unwrap_or(0.0)).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        ss / n as f64
    }
}
