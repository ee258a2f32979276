//! Fitting effects on the training part, scoring on the held-out part.
//!
//! Every channel is weighted by the RMS of its nominal residual on the
//! training part, so channels in different units count alike. The gap of a
//! part is the weighted RMS residual; `shrink = 1 − gap_after/gap_before`.

use super::effects::{Effect, MAXP};
use super::residual::{Nominal, Segment, NCH};
use nalgebra::{DMatrix, DVector};

/// An effect's (or the nominal's) value on every residual channel of a
/// segment (`None`: channel absent).
pub type ChannelPred = [Option<Vec<f64>>; NCH];

/// One effect with its shape parameter fixed.
#[derive(Clone, Copy, Debug)]
pub struct Term {
    pub effect: Effect,
    pub hyper: f64,
}

/// Weights `1/s_c` from the training residuals (0 for absent channels).
pub fn channel_weights(train: &[&Segment]) -> [f64; NCH] {
    let mut w = [0.0; NCH];
    for (c, wc) in w.iter_mut().enumerate() {
        let (mut ss, mut n) = (0.0, 0usize);
        for s in train {
            if let Some(r) = &s.r[c] {
                ss += r
                    .iter()
                    .enumerate()
                    .map(|(i, x)| (s.weight(c, i) * x).powi(2))
                    .sum::<f64>();
                n += r.len();
            }
        }
        if n > 0 && ss > 0.0 {
            *wc = 1.0 / (ss / n as f64).sqrt();
        }
    }
    w
}

fn nparams(terms: &[Term]) -> usize {
    terms.iter().map(|t| t.effect.params().len()).sum()
}

/// Fills `phi[c][j]` for all terms at sample i.
fn row(terms: &[Term], seg: &Segment, i: usize, nominal: &Nominal, phi: &mut Vec<[f64; NCH]>) {
    phi.clear();
    let mut buf = [[0.0; NCH]; MAXP];
    for t in terms {
        t.effect.regressors(t.hyper, seg, i, nominal, &mut buf);
        phi.extend_from_slice(&buf[..t.effect.params().len()]);
    }
}

/// Least squares result.
pub enum Solved {
    Ok(Vec<f64>),
    /// Why not: rank deficiency, unexcited regressor, non-finite.
    Failed(String),
}

/// Weighted least squares of the terms on the segments.
pub fn solve(terms: &[Term], segs: &[&Segment], nominal: &Nominal, w: &[f64; NCH]) -> Solved {
    let p = nparams(terms);
    let mut ata = DMatrix::<f64>::zeros(p, p);
    let mut atb = DVector::<f64>::zeros(p);
    let mut phi = Vec::with_capacity(p);
    for s in segs {
        for i in 0..s.len() {
            row(terms, s, i, nominal, &mut phi);
            for c in 0..NCH {
                let Some(r) = &s.r[c] else { continue };
                let wc2 = (w[c] * s.weight(c, i)).powi(2);
                if wc2 == 0.0 {
                    continue;
                }
                for a in 0..p {
                    let fa = phi[a][c];
                    if fa == 0.0 {
                        continue;
                    }
                    atb[a] += wc2 * fa * r[i];
                    for b in 0..p {
                        ata[(a, b)] += wc2 * fa * phi[b][c];
                    }
                }
            }
        }
    }
    let names: Vec<&str> = terms
        .iter()
        .flat_map(|t| t.effect.params().iter().copied())
        .collect();
    let d: Vec<f64> = (0..p).map(|a| ata[(a, a)]).collect();
    if let Some(a) = (0..p).find(|&a| d[a].is_nan() || d[a] <= 0.0 || !d[a].is_finite()) {
        return Solved::Failed(format!(
            "parameter `{}` is not excited by the data (its regressor is zero)",
            names[a]
        ));
    }
    let mut norm = ata.clone();
    for a in 0..p {
        for b in 0..p {
            norm[(a, b)] /= (d[a] * d[b]).sqrt();
        }
    }
    let eig = norm.clone().symmetric_eigen().eigenvalues;
    let (lo, hi) = eig
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), e| (l.min(*e), h.max(*e)));
    if lo <= 1e-9 * hi {
        return Solved::Failed(format!(
            "ill-conditioned least squares (normalised eigenvalue ratio {:.1e})",
            lo / hi
        ));
    }
    match ata.cholesky() {
        Some(ch) => {
            let x = ch.solve(&atb);
            if x.iter().all(|v| v.is_finite()) {
                Solved::Ok(x.iter().copied().collect())
            } else {
                Solved::Failed("non-finite parameters".into())
            }
        }
        None => Solved::Failed("normal equations not positive definite".into()),
    }
}

/// The terms' prediction on every channel of a segment.
pub fn predict(terms: &[Term], params: &[f64], seg: &Segment, nominal: &Nominal) -> ChannelPred {
    let mut out: ChannelPred =
        std::array::from_fn(|c| seg.r[c].as_ref().map(|_| vec![0.0; seg.len()]));
    let mut phi = Vec::new();
    for i in 0..seg.len() {
        row(terms, seg, i, nominal, &mut phi);
        for (c, o) in out.iter_mut().enumerate() {
            if let Some(o) = o {
                o[i] = phi.iter().zip(params).map(|(f, p)| f[c] * p).sum();
            }
        }
    }
    out
}

/// Weighted RMS gap of segments after subtracting `pred` (per segment).
pub fn gap(segs: &[&Segment], pred: Option<&[ChannelPred]>, w: &[f64; NCH]) -> f64 {
    let (mut ss, mut n) = (0.0, 0usize);
    for (k, s) in segs.iter().enumerate() {
        for c in 0..NCH {
            let Some(r) = &s.r[c] else { continue };
            if w[c] == 0.0 {
                continue;
            }
            let p = pred.and_then(|p| p[k][c].as_ref());
            for i in 0..r.len() {
                let e = r[i] - p.map_or(0.0, |p| p[i]);
                ss += (w[c] * s.weight(c, i) * e).powi(2);
            }
            n += r.len();
        }
    }
    if n == 0 {
        0.0
    } else {
        (ss / n as f64).sqrt()
    }
}

/// Fit % = 100·(1 − ‖r‖/‖y − ȳ‖) per channel, over segments.
pub fn fit_pct(segs: &[&Segment], pred: Option<&[ChannelPred]>) -> [Option<f64>; NCH] {
    std::array::from_fn(|c| {
        let (mut sr, mut sy, mut my, mut n) = (0.0, 0.0, 0.0, 0usize);
        for s in segs {
            if let Some(y) = &s.y[c] {
                my += y.iter().sum::<f64>();
                n += y.len();
            }
        }
        if n == 0 {
            return None;
        }
        my /= n as f64;
        for (k, s) in segs.iter().enumerate() {
            let (Some(y), Some(r)) = (&s.y[c], &s.r[c]) else {
                continue;
            };
            let p = pred.and_then(|p| p[k][c].as_ref());
            for i in 0..y.len() {
                sr += (r[i] - p.map_or(0.0, |p| p[i])).powi(2);
                sy += (y[i] - my).powi(2);
            }
        }
        (sy > 0.0).then(|| 100.0 * (1.0 - (sr / sy).sqrt()))
    })
}

/// Fit of one effect: grid over its shape parameter on the training part.
pub struct EffectFit {
    pub terms: Vec<Term>,
    pub params: Vec<f64>,
    pub train_gap: f64,
}

pub fn fit_effect(
    effect: Effect,
    train: &[&Segment],
    nominal: &Nominal,
    w: &[f64; NCH],
) -> Result<EffectFit, String> {
    let grid = effect.grid_for(nominal).map_or(vec![0.0], |g| g.1);
    let mut best: Option<(usize, EffectFit)> = None;
    let mut last_err = String::new();
    for (gi, h) in grid.iter().enumerate() {
        let terms = vec![Term { effect, hyper: *h }];
        match solve(&terms, train, nominal, w) {
            Solved::Ok(params) => {
                let pred: Vec<_> = train
                    .iter()
                    .map(|s| predict(&terms, &params, s, nominal))
                    .collect();
                let g = gap(train, Some(&pred), w);
                if best.as_ref().is_none_or(|(_, b)| g < b.train_gap) {
                    best = Some((
                        gi,
                        EffectFit {
                            terms,
                            params,
                            train_gap: g,
                        },
                    ));
                }
            }
            Solved::Failed(e) => last_err = e,
        }
    }
    match best {
        None => Err(last_err),
        Some((gi, fit)) => {
            if effect == Effect::Backlash && fit.params[0] < 0.0 {
                Err(format!(
                    "fitted lost motion {:.3e} m is negative (unphysical)",
                    fit.params[0]
                ))
            } else if effect == Effect::Stribeck && fit.params[0] < 0.0 {
                // Breakaway friction exceeds the sliding one by definition;
                // less friction at low speed than the nominal is not this
                // effect (it is what smoothing the onset of motion leaves).
                Err(format!(
                    "fitted Stribeck torque {:.3e} N·m is negative (unphysical)",
                    fit.params[0]
                ))
            } else if grid.len() > 2 && (gi == 0 || gi == grid.len() - 1) {
                let (name, _) = effect.grid_for(nominal).expect("grid");
                Err(format!(
                    "shape parameter `{name}` optimum {} at the grid edge",
                    grid[gi]
                ))
            } else {
                Ok(fit)
            }
        }
    }
}

/// A parameter whose regressor (weighted, all channels) carries under 1 %
/// of its held-out energy on the training part cannot be identified there:
/// returns its name.
pub fn unexcited(
    terms: &[Term],
    train: &[&Segment],
    held: &[&Segment],
    nominal: &Nominal,
    w: &[f64; NCH],
) -> Option<String> {
    let p = nparams(terms);
    let energy = |segs: &[&Segment]| {
        let mut e = vec![0.0; p];
        let mut n = 0usize;
        let mut phi = Vec::new();
        for s in segs {
            for i in 0..s.len() {
                row(terms, s, i, nominal, &mut phi);
                for (a, ea) in e.iter_mut().enumerate() {
                    *ea += (0..NCH)
                        .filter(|c| s.r[*c].is_some())
                        .map(|c| (w[c] * s.weight(c, i) * phi[a][c]).powi(2))
                        .sum::<f64>();
                }
            }
            n += s.len();
        }
        e.iter().map(|x| x / n.max(1) as f64).collect::<Vec<_>>()
    };
    let (et, eh) = (energy(train), energy(held));
    let names: Vec<&str> = terms
        .iter()
        .flat_map(|t| t.effect.params().iter().copied())
        .collect();
    (0..p)
        .find(|&a| et[a] < 0.01 * eh[a])
        .map(|a| names[a].to_string())
}

/// Joint fit of several terms (shape parameters fixed).
pub fn fit_terms(
    terms: &[Term],
    train: &[&Segment],
    nominal: &Nominal,
    w: &[f64; NCH],
) -> Result<Vec<f64>, String> {
    match solve(terms, train, nominal, w) {
        Solved::Ok(p) => Ok(p),
        Solved::Failed(e) => Err(e),
    }
}
