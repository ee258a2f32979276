//! Improved beetle antennae search (paper §4.1.2) over a flat parameter vector.
//!
//! Paper's rule, per iteration `t` of `T`: draw a random unit vector `b`, smell
//! at the antennae `X_l = X + b·d/2`, `X_r = X − b·d/2`, move
//! `X ← X − δ_t · b · sign(f(X_l) − f(X_r))` (towards the better antenna).
//!
//! Step schedule (`t = 0 … T−1`, so the first step is `δ_start` and the last
//! `δ_end`):
//! - [`StepDecay::Linear`]: `δ_t = δ_start − (δ_start − δ_end) · t/(T−1)`;
//! - [`StepDecay::Geometric`] (default): `δ_t = δ_start · (δ_end/δ_start)^(t/(T−1))`,
//!   the same end points but an equal share of iterations per decade of step,
//!   which matters when the two ends are two orders of magnitude apart.
//!
//! Improvements over the paper (each can be switched off; [`IbasOptions::paper`]
//! switches them all off):
//! - several beetles from independent random starts, the best one wins
//!   (one beetle in a space of a few hundred parameters is at the mercy of its start);
//! - keep-best: every point smelt (antennae and positions) is a candidate and
//!   the best one is returned, so the result is never worse than the start;
//! - adaptive step: a move that does not lower `f` is refused and the step
//!   multiplier `ρ` shrinks (×0.9); a move that does grows it (×1.5, at most
//!   2): a 1/5-success-style rule. The antenna length follows the step,
//!   `d = d0 · ρ δ_t/δ_start`, so the antennae resolve the slope at the scale
//!   of the move.
//!
//! Defaults come from measurement (docs/observer.md): on the observer loss,
//! at an equal budget of fitness evaluations, the geometric decay matters
//! most; several beetles and the adaptive step did not lower the loss
//! further, so the default is one beetle, geometric decay, keep-best, and
//! [`IbasOptions::swarm`] turns the rest on.

use indicatif::ProgressBar;
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

const RHO_UP: f64 = 1.5;
const RHO_DOWN: f64 = 0.9;
const RHO_MAX: f64 = 2.0;

/// How the step decays from `step_start` to `step_end`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StepDecay {
    Linear,
    Geometric,
}

/// IBAS settings. Distances are in parameter units (the network's parameters
/// are in normalised units, so one scale fits all of them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IbasOptions {
    /// Beetles, each from its own random start.
    pub beetles: usize,
    /// Iterations `T` per beetle.
    pub iterations: usize,
    /// Antenna length `d0` (distance between the two antennae).
    pub antenna_d0: f64,
    pub step_start: f64,
    pub step_end: f64,
    pub decay: StepDecay,
    pub keep_best: bool,
    pub adaptive: bool,
    /// The fitness is the training loss on at most this many samples (spread
    /// evenly over the training runs); 0 = all.
    pub max_samples: usize,
}

impl Default for IbasOptions {
    fn default() -> Self {
        IbasOptions {
            beetles: 1,
            iterations: 1200,
            antenna_d0: 0.1,
            step_start: 0.5,
            step_end: 0.005,
            decay: StepDecay::Geometric,
            keep_best: true,
            adaptive: false,
            max_samples: 1000,
        }
    }
}

impl IbasOptions {
    /// The paper's algorithm as written: one beetle, fixed antennae, linear
    /// decay, every move taken, the last position returned.
    pub fn paper() -> Self {
        IbasOptions { beetles: 1, decay: StepDecay::Linear, keep_best: false, adaptive: false, ..IbasOptions::default() }
    }

    /// Every improvement on: 4 beetles × 300 iterations (same evaluation
    /// budget as the default), adaptive step, keep-best, geometric decay.
    pub fn swarm() -> Self {
        IbasOptions { beetles: 4, iterations: 300, adaptive: true, ..IbasOptions::default() }
    }

    /// Step `δ_t` of iteration `t` (0-based) of `T`.
    pub fn step(&self, t: usize) -> f64 {
        let frac = if self.iterations > 1 { t as f64 / (self.iterations - 1) as f64 } else { 0.0 };
        match self.decay {
            StepDecay::Linear => self.step_start - (self.step_start - self.step_end) * frac,
            StepDecay::Geometric => self.step_start * (self.step_end / self.step_start).powf(frac),
        }
    }
}

/// What a search found.
#[derive(Clone, Debug, PartialEq)]
pub struct IbasOutcome {
    pub x: Vec<f64>,
    pub f: f64,
    /// Fitness of the best starting point.
    pub start_f: f64,
    /// Fitness evaluations spent.
    pub evaluations: usize,
    /// Best fitness so far after each iteration of each beetle, beetle after beetle.
    pub trace: Vec<f64>,
}

/// Runs the search from `starts` (one beetle per start). NaN fitness counts
/// as +∞. Deterministic for the state of `rng`.
pub fn search(
    starts: Vec<Vec<f64>>,
    mut f: impl FnMut(&[f64]) -> f64,
    opts: &IbasOptions,
    rng: &mut impl Rng,
    progress: &ProgressBar,
) -> IbasOutcome {
    let mut fit = |x: &[f64], evals: &mut usize| -> f64 {
        *evals += 1;
        let v = f(x);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let mut evals = 0usize;
    let mut best: Option<(Vec<f64>, f64)> = None;
    let mut start_f = f64::INFINITY;
    let mut trace = Vec::with_capacity(starts.len() * opts.iterations);
    let dim = starts.first().map_or(0, Vec::len);
    let (mut xl, mut xr, mut xn) = (vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]);
    let mut b = vec![0.0; dim];
    for mut x in starts {
        let mut fx = fit(&x, &mut evals);
        start_f = start_f.min(fx);
        let mut beetle_best = (x.clone(), fx);
        let mut rho = 1.0;
        for t in 0..opts.iterations {
            progress.inc(1);
            random_unit(rng, &mut b);
            let delta = opts.step(t) * rho;
            let d = if opts.adaptive { opts.antenna_d0 * delta / opts.step_start } else { opts.antenna_d0 };
            for i in 0..dim {
                xl[i] = x[i] + b[i] * d / 2.0;
                xr[i] = x[i] - b[i] * d / 2.0;
            }
            let (fl, fr) = (fit(&xl, &mut evals), fit(&xr, &mut evals));
            if opts.keep_best {
                if fl < beetle_best.1 {
                    beetle_best = (xl.clone(), fl);
                }
                if fr < beetle_best.1 {
                    beetle_best = (xr.clone(), fr);
                }
            }
            // X ← X − δ b sign(f_l − f_r): towards the antenna that smells better.
            let sign = if fl < fr {
                -1.0
            } else if fr < fl {
                1.0
            } else {
                0.0
            };
            if sign != 0.0 {
                for i in 0..dim {
                    xn[i] = x[i] - delta * b[i] * sign;
                }
                let fnew = fit(&xn, &mut evals);
                if opts.adaptive && !(fnew < fx) {
                    rho *= RHO_DOWN;
                } else {
                    if opts.adaptive {
                        rho = (rho * RHO_UP).min(RHO_MAX);
                    }
                    std::mem::swap(&mut x, &mut xn);
                    fx = fnew;
                }
            } else if opts.adaptive {
                rho *= RHO_DOWN;
            }
            if opts.keep_best && fx < beetle_best.1 {
                beetle_best = (x.clone(), fx);
            }
            let so_far = best.as_ref().map_or(f64::INFINITY, |b| b.1).min(if opts.keep_best { beetle_best.1 } else { fx });
            trace.push(so_far);
        }
        let (bx, bf) = if opts.keep_best { beetle_best } else { (x, fx) };
        if best.as_ref().is_none_or(|b| bf < b.1) {
            best = Some((bx, bf));
        }
    }
    let (x, f) = best.unwrap_or((Vec::new(), f64::INFINITY));
    IbasOutcome { x, f, start_f, evaluations: evals, trace }
}

fn random_unit(rng: &mut impl Rng, b: &mut [f64]) {
    loop {
        let mut n2 = 0.0;
        for v in b.iter_mut() {
            *v = rng.sample(StandardNormal);
            n2 += *v * *v;
        }
        if n2 > 1e-300 || b.is_empty() {
            let inv = 1.0 / n2.sqrt();
            b.iter_mut().for_each(|v| *v *= inv);
            return;
        }
    }
}
