//! Back-propagation: full-batch minimisation with the analytic gradient.
//!
//! - [`Method::Gd`]: plain gradient descent `p ← p − η ∇L` (paper §4.1.1);
//! - [`Method::Adam`]: Adam (β1 0.9, β2 0.999) with the rate decaying
//!   geometrically from `learning_rate` to `learning_rate · lr_final_fraction`;
//! - [`Method::Lbfgs`]: L-BFGS (two-loop recursion, `lbfgs_memory` pairs) with
//!   a backtracking Armijo line search; no learning rate to tune.
//!
//! Every method keeps the best parameters seen (lowest validation loss when a
//! validation set is given, checked every `validate_every` epochs; lowest
//! training loss otherwise). A loss that turns NaN/∞ or exceeds
//! `divergence_factor` × the best training loss stops the run: the outcome
//! carries the last good parameters and says where and why it stopped.

use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Method {
    Gd,
    Adam,
    Lbfgs,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimOptions {
    pub method: Method,
    /// Maximum epochs (full-batch gradient steps; L-BFGS: iterations).
    pub epochs: usize,
    /// GD: η. Adam: initial α. L-BFGS: unused.
    pub learning_rate: f64,
    /// Adam: the rate ends at `learning_rate × lr_final_fraction`.
    pub lr_final_fraction: f64,
    pub lbfgs_memory: usize,
    /// Stop when every gradient component is below this.
    pub grad_tolerance: f64,
    /// Loss above this factor × the best loss so far counts as divergence.
    pub divergence_factor: f64,
    pub validate_every: usize,
}

impl Default for OptimOptions {
    fn default() -> Self {
        OptimOptions {
            method: Method::Lbfgs,
            epochs: 1500,
            learning_rate: 0.01,
            lr_final_fraction: 0.01,
            lbfgs_memory: 12,
            grad_tolerance: 1e-9,
            divergence_factor: 100.0,
            validate_every: 10,
        }
    }
}

impl OptimOptions {
    /// Defaults for `method` (GD: η = 0.1, 5000 epochs; Adam: α = 0.01, 4000).
    pub fn for_method(method: Method) -> Self {
        match method {
            Method::Gd => OptimOptions { method, learning_rate: 0.1, epochs: 5000, ..OptimOptions::default() },
            Method::Adam => OptimOptions { method, learning_rate: 0.01, epochs: 4000, ..OptimOptions::default() },
            Method::Lbfgs => OptimOptions { method, ..OptimOptions::default() },
        }
    }
}

/// Where and why training stopped on a blow-up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Divergence {
    pub epoch: usize,
    /// The offending loss (NaN/∞ are written as strings by serde_json: null).
    pub loss: f64,
    /// Best training loss before it (that of the parameters kept).
    pub last_good_loss: f64,
    pub reason: String,
}

#[derive(Clone, Debug, PartialEq)]
pub struct OptimOutcome {
    /// The parameters kept (see the module doc).
    pub params: Vec<f64>,
    /// Training loss at `params`.
    pub train_loss: f64,
    /// Validation loss at `params`, if validating.
    pub val_loss: Option<f64>,
    pub epochs: usize,
    pub evaluations: usize,
    pub diverged: Option<Divergence>,
    /// Why the run stopped (epochs exhausted, converged, diverged, …).
    pub stop_reason: String,
    /// (epoch, training loss) every `validate_every` epochs.
    pub history: Vec<(usize, f64)>,
}

/// Validation loss of a parameter vector.
pub type Validation<'a> = &'a mut dyn FnMut(&[f64]) -> f64;

/// Minimises `objective` (loss, writing the gradient into its second
/// argument) from `p0`.
pub fn minimise(
    p0: Vec<f64>,
    mut objective: impl FnMut(&[f64], &mut [f64]) -> f64,
    mut validation: Option<Validation<'_>>,
    opts: &OptimOptions,
    progress: &ProgressBar,
) -> OptimOutcome {
    let dim = p0.len();
    let mut p = p0;
    let mut g = vec![0.0; dim];
    let mut evals = 0usize;
    let mut best_train: (Vec<f64>, f64) = (p.clone(), f64::INFINITY);
    let mut best_val: Option<(Vec<f64>, f64, f64)> = None; // (params, val, train)
    let mut diverged = None;
    let mut history = Vec::new();
    let every = opts.validate_every.max(1);
    let mut stop_reason = format!("{} epochs done", opts.epochs);

    // Adam state.
    let (mut m, mut v) = (vec![0.0; dim], vec![0.0; dim]);
    // L-BFGS state.
    let mut mem: Vec<(Vec<f64>, Vec<f64>, f64)> = Vec::new();
    let mut loss = objective(&p, &mut g);
    evals += 1;
    let mut epoch = 0usize;
    loop {
        // Bookkeeping at the current point (loss and g are those of p).
        if !loss.is_finite() || (best_train.1.is_finite() && loss > opts.divergence_factor * best_train.1) {
            let why = if loss.is_finite() {
                format!("loss {:.3e} exceeded {} × the best {:.3e}", loss, opts.divergence_factor, best_train.1)
            } else {
                "loss became NaN or infinite".to_string()
            };
            diverged = Some(Divergence { epoch, loss, last_good_loss: best_train.1, reason: why.clone() });
            stop_reason = format!("diverged at epoch {epoch}: {why}; kept the last good weights");
            break;
        }
        if loss < best_train.1 {
            best_train = (p.clone(), loss);
        }
        if epoch.is_multiple_of(every) || epoch == opts.epochs {
            history.push((epoch, loss));
            if let Some(val) = validation.as_mut() {
                let vl = val(&p);
                if vl.is_finite() && best_val.as_ref().is_none_or(|b| vl < b.1) {
                    best_val = Some((p.clone(), vl, loss));
                }
            }
        }
        if epoch >= opts.epochs {
            break;
        }
        if g.iter().all(|x| x.abs() < opts.grad_tolerance) {
            stop_reason = format!("converged at epoch {epoch} (gradient below {:e})", opts.grad_tolerance);
            break;
        }
        progress.inc(1);
        epoch += 1;
        match opts.method {
            Method::Gd => {
                for (pi, gi) in p.iter_mut().zip(&g) {
                    *pi -= opts.learning_rate * gi;
                }
                loss = objective(&p, &mut g);
                evals += 1;
            }
            Method::Adam => {
                let (b1, b2, eps): (f64, f64, f64) = (0.9, 0.999, 1e-8);
                let frac = epoch as f64 / opts.epochs.max(1) as f64;
                let lr = opts.learning_rate * opts.lr_final_fraction.powf(frac);
                let (c1, c2) = (1.0 - b1.powi(epoch as i32), 1.0 - b2.powi(epoch as i32));
                for i in 0..dim {
                    m[i] = b1 * m[i] + (1.0 - b1) * g[i];
                    v[i] = b2 * v[i] + (1.0 - b2) * g[i] * g[i];
                    p[i] -= lr * (m[i] / c1) / ((v[i] / c2).sqrt() + eps);
                }
                loss = objective(&p, &mut g);
                evals += 1;
            }
            Method::Lbfgs => {
                let mut d = lbfgs_direction(&g, &mem);
                let mut slope: f64 = d.iter().zip(&g).map(|(a, b)| a * b).sum();
                if !(slope < 0.0) {
                    mem.clear();
                    d = g.iter().map(|x| -x).collect();
                    slope = d.iter().zip(&g).map(|(a, b)| a * b).sum();
                }
                let gnorm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
                let mut alpha = if mem.is_empty() { (1.0 / gnorm.max(1e-300)).min(1.0) } else { 1.0 };
                let mut g_new = vec![0.0; dim];
                let mut p_new = vec![0.0; dim];
                let mut accepted = None;
                for _ in 0..40 {
                    for i in 0..dim {
                        p_new[i] = p[i] + alpha * d[i];
                    }
                    let f_new = objective(&p_new, &mut g_new);
                    evals += 1;
                    if f_new.is_finite() && f_new <= loss + 1e-4 * alpha * slope {
                        accepted = Some(f_new);
                        break;
                    }
                    alpha *= 0.5;
                }
                let Some(f_new) = accepted else {
                    stop_reason = format!("converged at epoch {epoch} (line search found no lower loss)");
                    break;
                };
                let s: Vec<f64> = p_new.iter().zip(&p).map(|(a, b)| a - b).collect();
                let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
                let sy: f64 = s.iter().zip(&y).map(|(a, b)| a * b).sum();
                if sy > 1e-16 {
                    if mem.len() == opts.lbfgs_memory.max(1) {
                        mem.remove(0);
                    }
                    mem.push((s, y, 1.0 / sy));
                }
                p = p_new;
                g = g_new;
                loss = f_new;
            }
        }
    }
    let (params, train_loss, val_loss) = match (validation.is_some(), best_val) {
        (true, Some((bp, bv, bt))) => (bp, bt, Some(bv)),
        _ => (best_train.0, best_train.1, None),
    };
    OptimOutcome { params, train_loss, val_loss, epochs: epoch, evaluations: evals, diverged, stop_reason, history }
}

/// `−H g` by the two-loop recursion over the stored `(s, y, 1/(s·y))` pairs.
fn lbfgs_direction(g: &[f64], mem: &[(Vec<f64>, Vec<f64>, f64)]) -> Vec<f64> {
    let mut q: Vec<f64> = g.to_vec();
    let mut alphas = vec![0.0; mem.len()];
    for (k, (s, y, rho)) in mem.iter().enumerate().rev() {
        let a = rho * s.iter().zip(&q).map(|(a, b)| a * b).sum::<f64>();
        alphas[k] = a;
        q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
    }
    if let Some((s, y, _)) = mem.last() {
        let sy: f64 = s.iter().zip(y).map(|(a, b)| a * b).sum();
        let yy: f64 = y.iter().map(|a| a * a).sum();
        let gamma = sy / yy.max(1e-300);
        q.iter_mut().for_each(|x| *x *= gamma);
    }
    for (k, (s, y, rho)) in mem.iter().enumerate() {
        let beta = rho * y.iter().zip(&q).map(|(a, b)| a * b).sum::<f64>();
        q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (alphas[k] - beta) * si);
    }
    q.iter_mut().for_each(|x| *x = -*x);
    q
}
