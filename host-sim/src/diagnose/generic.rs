//! Generic structures for what no library effect explains: a pure delay,
//! a lightly damped resonance, a gain drifting with time, a constant
//! unmeasured force, counts lost once, a column quantised coarser than the
//! rig file expects. Each is a shape with one or two
//! parameters on a grid and a linear amplitude, fitted on the training
//! remainder of the primary channel and scored on the held-out remainder,
//! like the library (the drifting gain and a count loss, states of each
//! run, are fitted within each part: `drift`, `count_loss`). None is built
//! from the channel's own measured output: the delay and the drift act on
//! the channel's *nominal* prediction (from the motion and the load), the
//! resonance is the rod side's ringing under the motor's thrust from the
//! logged current (`resonance`); quantisation is gated on the logged
//! column's own lattice and explains the rounding of the nominal's
//! prediction of it (`quantise`).

mod count_loss;
mod drift;
mod overlap;
mod quantise;
mod resonance;

pub use overlap::Basis;
pub use quantise::{lattice, Lattice};

use resonance::rod_mode;

use super::effects::{Effect, MAXP};
use super::events::Remainder;
use super::figures::shrink;
use super::residual::{Nominal, Segment, NCH, POSITION, TORQUE, VOLTAGE};

/// A generic structure names the remainder when it removes at least this
/// share of what the stack leaves on its channel, held-out and on training — a
/// quarter, the bar the remainder's character uses for a structure — and
/// leads every other class: it removes at least `GENERIC_LEAD` times what
/// the other removes, or, fitted together with it on the same channel, it
/// explains what the other does not (`overlap`).
pub const GENERIC_MIN_PCT: f64 = 25.0;
pub const GENERIC_LEAD: f64 = 1.5;

/// The generic structure that names the remainder, if one does.
pub fn named(fits: &[GenericFit]) -> Option<&GenericFit> {
    let best = fits.first()?;
    let leads = fits
        .iter()
        .filter(|g| g.class != best.class)
        .all(|g| best.remainder_shrink_pct >= GENERIC_LEAD * g.remainder_shrink_pct || (g.channel == best.channel && overlap::leads_beyond(best, &g.class)));
    // Counts lost once are an event of the log they happen in: the
    // training log need not show one (it is often the healthy reference),
    // and the held-out one carries its own evidence (`count_loss`).
    let trained = best.train_shrink_pct >= GENERIC_MIN_PCT || best.class == "count_loss";
    (best.refused.is_none() && best.remainder_shrink_pct >= GENERIC_MIN_PCT && trained && leads).then_some(best)
}

/// One generic structure fitted and scored.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GenericFit {
    /// `delay`, `resonance`, `gain_drift`, `constant_force`, `count_loss`,
    /// `quantisation`.
    pub class: String,
    /// The channel it is fitted and scored on.
    pub channel: String,
    /// The logged column it is read from, where it is one column's
    /// (`quantisation`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub column: Option<String>,
    /// The parameters with their units in the names (`delay_ms`,
    /// `frequency_hz`, `damping_ratio`, `drift_per_s`, `level_n`, …).
    pub params: std::collections::BTreeMap<String, f64>,
    /// Held-out shrink of its channel's gap against the nominal, %.
    pub primary_shrink_pct: f64,
    /// Held-out shrink of what the stack leaves on its channel (what it
    /// explains of the remainder), %, and the same on training.
    pub remainder_shrink_pct: f64,
    pub train_shrink_pct: f64,
    /// Why this fit cannot name the remainder whatever its share (a gain
    /// that does not drift), if it cannot.
    pub refused: Option<String>,
    /// For each other class fitted on the same channel, fitted together
    /// with this one: what this one and what the other explain of the
    /// held-out remainder's energy beyond each other, % (`overlap`).
    pub beyond_pct: std::collections::BTreeMap<String, [f64; 2]>,
    /// The fit's regressors on training and held out, while the classes of
    /// a channel are compared.
    #[serde(skip)]
    pub basis: Basis,
}

/// The channel's nominal prediction (logged signal minus residual).
fn nominal_pred(s: &Segment, c: usize) -> Vec<f64> {
    match (&s.y[c], &s.r[c]) {
        (Some(y), Some(r)) => y.iter().zip(r).map(|(y, r)| y - r).collect(),
        _ => vec![0.0; s.len()],
    }
}

/// Regressors (one or two per sample) of a class at a grid point.
type Shape = dyn Fn(&Segment) -> Vec<Vec<f64>>;

/// Least squares of the weighted remainder on the regressors; returns the
/// coefficients.
fn lsq(segs: &[&Segment], rem: &Remainder, c: usize, x: &[Vec<Vec<f64>>]) -> Vec<f64> {
    let p = x.iter().flat_map(|v| v.first()).map(Vec::len).next().unwrap_or(0);
    if p == 0 {
        return Vec::new();
    }
    let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
    let mut atb = nalgebra::DVector::<f64>::zeros(p);
    for ((s, r), xs) in segs.iter().zip(rem).zip(x) {
        let Some(y) = &r[c] else { continue };
        for i in 0..s.len() {
            let w2 = s.weight(c, i).powi(2);
            for a in 0..p {
                atb[a] += w2 * xs[i][a] * y[i];
                for b in 0..p {
                    ata[(a, b)] += w2 * xs[i][a] * xs[i][b];
                }
            }
        }
    }
    ata.svd(true, true)
        .solve(&atb, 1e-12)
        .map(|v| v.iter().copied().collect())
        .unwrap_or_else(|_| vec![0.0; p])
}

/// Weighted RMS of channel `c` of a remainder minus an optional prediction.
fn rms(segs: &[&Segment], rem: &Remainder, c: usize, x: Option<(&[Vec<Vec<f64>>], &[f64])>) -> f64 {
    let (mut ss, mut n) = (0.0, 0usize);
    for (k, (s, r)) in segs.iter().zip(rem).enumerate() {
        let Some(y) = &r[c] else { continue };
        for i in 0..s.len() {
            let p = x.map_or(0.0, |(xs, b)| xs[k][i].iter().zip(b).map(|(a, b)| a * b).sum());
            ss += (s.weight(c, i) * (y[i] - p)).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (ss / n as f64).sqrt()
    }
}

/// Fits a class on channel `c`: the grid point (parameters, shape) chosen on
/// training by what it leaves there, the amplitude fitted there too, then
/// scored on the held-out remainder; `scale` turns the amplitudes into
/// named parameters.
#[allow(clippy::too_many_arguments)] // the two parts and their remainders, as everywhere here
fn fit_grid(
    train: &[&Segment],
    rem_t: &Remainder,
    held: &[&Segment],
    rem_h: &Remainder,
    c: usize,
    nominal_rms_h: f64,
    class: &str,
    grid: Vec<(Vec<(&'static str, f64)>, Box<Shape>)>,
    scale: &dyn Fn(&[f64]) -> Vec<(&'static str, f64)>,
) -> Option<GenericFit> {
    let base_t = rms(train, rem_t, c, None);
    let (params, shape, b, after_t) = grid
        .into_iter()
        .map(|(params, shape)| {
            let xt: Vec<Vec<Vec<f64>>> = train.iter().map(|s| shape(s)).collect();
            let b = lsq(train, rem_t, c, &xt);
            let after = rms(train, rem_t, c, Some((&xt, &b)));
            (params, shape, b, after)
        })
        .min_by(|a, b| a.3.total_cmp(&b.3))?;
    let xh: Vec<Vec<Vec<f64>>> = held.iter().map(|s| shape(s)).collect();
    let after_h = rms(held, rem_h, c, Some((&xh, &b)));
    let mut g = GenericFit {
        class: class.into(),
        channel: super::residual::CHANNELS[c].into(),
        primary_shrink_pct: shrink(nominal_rms_h, after_h),
        remainder_shrink_pct: shrink(rms(held, rem_h, c, None), after_h),
        train_shrink_pct: shrink(base_t, after_t),
        ..Default::default()
    };
    for (k, v) in params.into_iter().chain(scale(&b)) {
        g.params.insert(k.into(), v);
    }
    let xt: Vec<Vec<Vec<f64>>> = train.iter().map(|s| shape(s)).collect();
    g.basis = Basis(Some((xt, xh)));
    Some(g)
}

/// Fits every generic class on the torque and position channels of the
/// training remainder and scores each on the held-out remainder against
/// the nominal's held-out RMS of its channel. Best first.
pub fn fit_all(
    train: &[&Segment],
    rem_t: &Remainder,
    held: &[&Segment],
    rem_h: &Remainder,
    nominal: &Nominal,
) -> Vec<GenericFit> {
    let mut out: Vec<GenericFit> = [TORQUE, POSITION]
        .into_iter()
        .flat_map(|c| {
            let mut wc = [0.0; NCH];
            wc[c] = 1.0;
            let before = super::fit::gap(held, None, &wc);
            match (c == POSITION).then(|| rod_mode(train, rem_t, held, rem_h, nominal)).flatten() {
                Some((rt, rh)) => fit(train, &rt, held, &rh, nominal, c, before),
                None => fit(train, rem_t, held, rem_h, nominal, c, before),
            }
        })
        .collect();
    out.sort_by(|a, b| b.remainder_shrink_pct.total_cmp(&a.remainder_shrink_pct));
    out
}

/// Fits every generic class on channel `c` of the training remainder and
/// scores it on the held-out remainder; `nominal_rms_h`: the nominal's
/// held-out RMS on `c` (the shrink's reference). Best first.
pub fn fit(
    train: &[&Segment],
    rem_t: &Remainder,
    held: &[&Segment],
    rem_h: &Remainder,
    nominal: &Nominal,
    c: usize,
    nominal_rms_h: f64,
) -> Vec<GenericFit> {
    if c == VOLTAGE || !train.iter().any(|s| s.r[c].is_some()) {
        return Vec::new();
    }
    let dt = train.first().map_or(1e-3, |s| s.dt);
    let mut out = Vec::new();
    let try_class = |class: &str, grid: Vec<(Vec<(&'static str, f64)>, Box<Shape>)>, scale: &dyn Fn(&[f64]) -> Vec<(&'static str, f64)>| {
        fit_grid(train, rem_t, held, rem_h, c, nominal_rms_h, class, grid, scale)
    };
    // A pure delay: the channel's logged output early (k > 0) or late
    // against the motion by k samples: N(t + k dt) − N(t), amplitude ≈ 1.
    let kmax = ((0.02 / dt).round() as i64).max(2);
    let delay_grid: Vec<(Vec<(&'static str, f64)>, Box<Shape>)> = (-kmax..=kmax)
        .filter(|k| *k != 0)
        .map(|k| {
            let shape: Box<Shape> = Box::new(move |s: &Segment| {
                let nv = nominal_pred(s, c);
                let n = nv.len() as i64;
                (0..n)
                    .map(|i| vec![nv[(i + k).clamp(0, n - 1) as usize] - nv[i as usize]])
                    .collect()
            });
            (vec![("delay_ms", 1e3 * k as f64 * dt)], shape)
        })
        .collect();
    // The delay is fitted on the nominal's own residual, not on what the
    // library stack leaves: a delay's residual `N(t) − N(t − τ)` carries
    // the friction's step at each reversal shifted by τ, which a friction
    // effect of the stack (Stribeck) takes in part, so on the stack's
    // remainder the shift and amplitude read short (a 5 ms delay read as
    // 8 ms × 0.36). It is scored against what the stack leaves: the delay
    // in place of the stack, which it must beat to name the remainder.
    let own = |segs: &[&Segment]| -> Remainder { segs.iter().map(|s| s.r.clone()).collect() };
    let (own_t, own_h) = (own(train), own(held));
    if let Some(mut g) = fit_grid(train, &own_t, held, &own_h, c, nominal_rms_h, "delay", delay_grid, &|b| vec![("amplitude", b.first().copied().unwrap_or(0.0))]) {
        let after_h = nominal_rms_h * (1.0 - g.primary_shrink_pct / 100.0);
        let after_t = rms(train, &own_t, c, None) * (1.0 - g.train_shrink_pct / 100.0);
        g.remainder_shrink_pct = shrink(rms(held, rem_h, c, None), after_h);
        g.train_shrink_pct = shrink(rms(train, rem_t, c, None), after_t);
        out.push(g);
    }
    // A lightly damped resonance, up to a fifth of the sampling rate.
    out.extend(resonance::fit(train, rem_t, held, rem_h, nominal, c, nominal_rms_h));
    // A constant unmeasured force: the load offset's regressors on `c`.
    if matches!(nominal, Nominal::Physics(_)) && (c == TORQUE || c == POSITION) {
        let nominal = nominal.clone();
        let cf: Vec<(Vec<(&'static str, f64)>, Box<Shape>)> = vec![(
            Vec::new(),
            Box::new(move |s: &Segment| {
                let mut buf = [[0.0; NCH]; MAXP];
                (0..s.len())
                    .map(|i| {
                        Effect::LoadOffset.regressors(0.0, s, i, &nominal, &mut buf);
                        vec![buf[0][c]]
                    })
                    .collect()
            }),
        )];
        out.extend(try_class("constant_force", cf, &|b| vec![("level_n", b.first().copied().unwrap_or(0.0))]));
    }
    // A gain drifting with time.
    out.extend(drift::fit(train, rem_t, held, rem_h, c, nominal_rms_h));
    // A column quantised coarser than the rig file expects.
    out.extend(quantise::fit(train, rem_t, held, rem_h, nominal, c, nominal_rms_h));
    // Counts lost once: an offset of the scale − motor difference.
    if c == POSITION {
        out.extend(count_loss::fit(train, rem_t, held, rem_h, nominal, nominal_rms_h));
    }
    // A delay short against the motion's time scale is identified by the
    // product of amplitude and shift (`N(t + τ) − N(t) ≈ τ N'`): the grid's
    // shift alone trades against the amplitude, so the delay reported is
    // the product, the grid point kept as `shape_delay_ms`.
    for g in out.iter_mut().filter(|g| g.class == "delay") {
        let (tau, a) = (g.params["delay_ms"], g.params["amplitude"]);
        g.params.insert("shape_delay_ms".into(), tau);
        g.params.insert("delay_ms".into(), a * tau);
    }
    overlap::compare(train, rem_t, held, rem_h, c, &mut out);
    out.sort_by(|a, b| b.primary_shrink_pct.total_cmp(&a.primary_shrink_pct));
    out
}
