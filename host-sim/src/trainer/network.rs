//! The observer network (paper §4.1), in `f64`: normalised inputs, one hidden
//! layer of Gaussian units `φ_k = exp(−‖z − c_k‖² / 2σ_k²)`, linear output
//! `y = b + Σ w_k φ_k (+ Σ a_j z_j)`; loss `MSE + λ·Σ w_k²`; analytic gradient.
//!
//! The optional linear skip term `Σ a_j z_j` (not in the paper) carries the
//! global trend of the target, which the Gaussians then need not build out of
//! bumps: it is what makes the length model (length ≈ displacement + error)
//! learnable at all, and it extrapolates the trend gently past the data.
//!
//! Parameters live in one flat vector (what IBAS searches and back-propagation
//! updates), laid out as
//! `[c_1 (N values) … c_H, s_1 … s_H, w_1 … w_H, (a_1 … a_N), b]` with
//! `σ_k = exp(s_k)` (the log keeps every width positive whatever the search
//! does) and `N` the inputs the network uses: the paper's four, or five with
//! the direction of travel. Input arrays always have the five slots; a
//! four-input network reads the first four, and its normalisation keeps
//! the fifth at the point 0 (unused, as the firmware runs it).

use super::dataset::{ModelKind, N_INPUTS, STATIC_INPUTS};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// Input min/max normalisation to `[-1, 1]` and target standardisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Normaliser {
    /// Trained input range; inputs outside it are clamped to it. A
    /// `model.json` of four inputs (written before the fifth slot) reads
    /// with the fifth at `[0, 0]`.
    #[serde(deserialize_with = "slots")]
    pub input_min: [f64; N_INPUTS],
    #[serde(deserialize_with = "slots")]
    pub input_max: [f64; N_INPUTS],
    /// Network output 0 maps to `output_offset`, 1 to `output_offset + output_scale` (metres).
    pub output_offset: f64,
    pub output_scale: f64,
}

/// Four or five values into the five input slots (the rest 0).
fn slots<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; N_INPUTS], D::Error> {
    let v: Vec<f64> = Vec::deserialize(d)?;
    if v.len() != STATIC_INPUTS && v.len() != N_INPUTS {
        return Err(serde::de::Error::custom(format!("{} inputs; a model has {STATIC_INPUTS} or {N_INPUTS}", v.len())));
    }
    let mut a = [0.0; N_INPUTS];
    a[..v.len()].copy_from_slice(&v);
    Ok(a)
}

impl Normaliser {
    /// Range of the inputs, mean and standard deviation of the targets.
    pub fn fit(inputs: &[[f64; N_INPUTS]], targets: &[f64]) -> Normaliser {
        let mut input_min = [f64::INFINITY; N_INPUTS];
        let mut input_max = [f64::NEG_INFINITY; N_INPUTS];
        for x in inputs {
            for j in 0..N_INPUTS {
                input_min[j] = input_min[j].min(x[j]);
                input_max[j] = input_max[j].max(x[j]);
            }
        }
        let n = targets.len().max(1) as f64;
        let mean = targets.iter().sum::<f64>() / n;
        let var = targets.iter().map(|t| (t - mean) * (t - mean)).sum::<f64>() / n;
        let sd = var.sqrt();
        // A constant target still gets a usable scale.
        let output_scale = if sd > 1e-12 * (1.0 + mean.abs()) { sd } else { 1.0 };
        Normaliser { input_min, input_max, output_offset: mean, output_scale }
    }

    /// `2 / (max − min)`, or 0 for an input that was constant in training.
    pub fn input_scale(&self) -> [f64; N_INPUTS] {
        let mut s = [0.0; N_INPUTS];
        for j in 0..N_INPUTS {
            let span = self.input_max[j] - self.input_min[j];
            s[j] = if span > 0.0 { 2.0 / span } else { 0.0 };
        }
        s
    }

    /// Clamps `x` to the trained range and maps it to `[-1, 1]`; the flag
    /// says whether any input was clamped. Same arithmetic as the firmware.
    pub fn normalise(&self, x: &[f64; N_INPUTS]) -> ([f64; N_INPUTS], bool) {
        let scale = self.input_scale();
        let mut z = [0.0; N_INPUTS];
        let mut clamped = false;
        for j in 0..N_INPUTS {
            let (lo, hi) = (self.input_min[j], self.input_max[j]);
            let xc = if x[j] < lo {
                clamped = true;
                lo
            } else if x[j] > hi {
                clamped = true;
                hi
            } else {
                x[j]
            };
            z[j] = (xc - lo) * scale[j] - 1.0;
        }
        (z, clamped)
    }

    pub fn target_to_net(&self, t: f64) -> f64 {
        (t - self.output_offset) / self.output_scale
    }
    pub fn net_to_target(&self, y: f64) -> f64 {
        self.output_offset + self.output_scale * y
    }
}

/// Normalised training data: network inputs and targets.
#[derive(Clone, Debug, Default)]
pub struct Batch {
    pub z: Vec<[f64; N_INPUTS]>,
    pub t: Vec<f64>,
}

impl Batch {
    pub fn new(norm: &Normaliser, inputs: &[[f64; N_INPUTS]], targets: &[f64]) -> Batch {
        Batch {
            z: inputs.iter().map(|x| norm.normalise(x).0).collect(),
            t: targets.iter().map(|&t| norm.target_to_net(t)).collect(),
        }
    }
    pub fn len(&self) -> usize {
        self.t.len()
    }
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Shape of a network with `hidden` Gaussian units: indexes into the flat
/// parameter vector, forward pass, loss and gradient.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rbf {
    pub hidden: usize,
    /// With the linear skip term `Σ a_j z_j`.
    pub linear: bool,
    /// Inputs used: the first 4 or all 5 slots (a `model.json` written
    /// before the fifth slot has 4).
    #[serde(default = "static_inputs")]
    pub inputs: usize,
}

fn static_inputs() -> usize {
    STATIC_INPUTS
}

impl Rbf {
    /// The paper's network (no linear term, four inputs).
    pub fn new(hidden: usize) -> Rbf {
        Rbf { hidden, linear: false, inputs: STATIC_INPUTS }
    }
    pub fn with_linear(hidden: usize, linear: bool) -> Rbf {
        Rbf { hidden, linear, inputs: STATIC_INPUTS }
    }
    /// The same network on the first `inputs` input slots (4 or 5).
    pub fn with_inputs(self, inputs: usize) -> Rbf {
        Rbf { inputs: inputs.clamp(1, N_INPUTS), ..self }
    }
    pub fn n_params(&self) -> usize {
        self.b_at() + 1
    }
    fn n_linear(&self) -> usize {
        if self.linear {
            self.inputs
        } else {
            0
        }
    }
    fn a_at(&self) -> usize {
        self.hidden * self.inputs + 2 * self.hidden
    }
    fn s_at(&self) -> usize {
        self.hidden * self.inputs
    }
    fn w_at(&self) -> usize {
        self.hidden * self.inputs + self.hidden
    }
    fn b_at(&self) -> usize {
        self.a_at() + self.n_linear()
    }
    pub fn centre<'a>(&self, p: &'a [f64], k: usize) -> &'a [f64] {
        &p[k * self.inputs..(k + 1) * self.inputs]
    }
    pub fn log_widths<'a>(&self, p: &'a [f64]) -> &'a [f64] {
        &p[self.s_at()..self.w_at()]
    }
    pub fn weights<'a>(&self, p: &'a [f64]) -> &'a [f64] {
        &p[self.w_at()..self.a_at()]
    }
    /// Linear-term coefficients `a_j` (all zero without the term, and in
    /// unused slots).
    pub fn linear_coefficients(&self, p: &[f64]) -> [f64; N_INPUTS] {
        let mut a = [0.0; N_INPUTS];
        if self.linear {
            a[..self.inputs].copy_from_slice(&p[self.a_at()..self.b_at()]);
        }
        a
    }
    pub fn bias(&self, p: &[f64]) -> f64 {
        p[self.b_at()]
    }

    /// Random start (what plain BP starts from and IBAS starts searching at):
    /// centres uniform in `[-1, 1]^N`, every width `σ0 = 2 / H^(1/N)` (about
    /// the spacing of H points in the box), output weights `N(0, 0.5²)`,
    /// linear coefficients and bias 0.
    pub fn init_random(&self, rng: &mut impl Rng) -> Vec<f64> {
        let mut p = vec![0.0; self.n_params()];
        let sigma0 = 2.0 / (self.hidden.max(1) as f64).powf(1.0 / self.inputs as f64);
        for v in &mut p[..self.s_at()] {
            *v = rng.random_range(-1.0..1.0);
        }
        for v in &mut p[self.s_at()..self.w_at()] {
            *v = sigma0.ln();
        }
        for v in &mut p[self.w_at()..self.a_at()] {
            let u: f64 = rng.sample(StandardNormal);
            *v = 0.5 * u;
        }
        p
    }

    /// Network output (normalised units) for normalised input `z`.
    pub fn forward(&self, p: &[f64], z: &[f64; N_INPUTS]) -> f64 {
        let (c, rest) = p.split_at(self.s_at());
        let (s, rest) = rest.split_at(self.hidden);
        let (w, rest) = rest.split_at(self.hidden);
        let (a, b) = rest.split_at(self.n_linear());
        let mut y = b[0];
        for (aj, zj) in a.iter().zip(z) {
            y += aj * zj;
        }
        for ((ck, &sk), &wk) in c.chunks_exact(self.inputs).zip(s).zip(w) {
            let d2 = dist2(z, ck);
            y += wk * (-d2 * 0.5 * (-2.0 * sk).exp()).exp();
        }
        y
    }

    /// `(1/n) Σ (y − t)² + λ Σ w_k²`.
    pub fn loss(&self, p: &[f64], batch: &Batch, lambda: f64) -> f64 {
        let n = batch.len().max(1) as f64;
        let sse: f64 = batch.z.iter().zip(&batch.t).map(|(z, &t)| (self.forward(p, z) - t).powi(2)).sum();
        sse / n + lambda * self.weights(p).iter().map(|w| w * w).sum::<f64>()
    }

    /// Loss and its analytic gradient (written into `grad`).
    ///
    /// With `r = y − t`, `g_k = 1/(2σ_k²)`, `φ_k = exp(−d_k² g_k)`:
    /// `∂L/∂b = (2/n) Σ r`, `∂L/∂w_k = (2/n) Σ r φ_k + 2λ w_k`,
    /// `∂L/∂c_kj = (2/n) Σ r w_k φ_k · 2 g_k (z_j − c_kj)`,
    /// `∂L/∂s_k = (2/n) Σ r w_k φ_k · 2 g_k d_k²`, `∂L/∂a_j = (2/n) Σ r z_j`.
    pub fn loss_grad(&self, p: &[f64], batch: &Batch, lambda: f64, grad: &mut [f64]) -> f64 {
        let h = self.hidden;
        assert_eq!(p.len(), self.n_params());
        assert_eq!(grad.len(), self.n_params());
        grad.fill(0.0);
        let n = batch.len().max(1) as f64;
        let (c, rest) = p.split_at(self.s_at());
        let (s, rest) = rest.split_at(h);
        let (w, rest) = rest.split_at(h);
        let (a, b) = rest.split_at(self.n_linear());
        let g: Vec<f64> = s.iter().map(|&sk| 0.5 * (-2.0 * sk).exp()).collect();
        let mut phi = vec![0.0; h];
        let mut d2 = vec![0.0; h];
        let mut sse = 0.0;
        {
            let (gc, grest) = grad.split_at_mut(self.s_at());
            let (gs, grest) = grest.split_at_mut(h);
            let (gw, grest) = grest.split_at_mut(h);
            let (ga, gb) = grest.split_at_mut(self.n_linear());
            for (z, &t) in batch.z.iter().zip(&batch.t) {
                let mut y = b[0];
                for (aj, zj) in a.iter().zip(z) {
                    y += aj * zj;
                }
                for k in 0..h {
                    let dk = dist2(z, &c[k * self.inputs..(k + 1) * self.inputs]);
                    d2[k] = dk;
                    phi[k] = (-dk * g[k]).exp();
                    y += w[k] * phi[k];
                }
                let r = y - t;
                sse += r * r;
                let e = 2.0 * r / n;
                gb[0] += e;
                for (gaj, zj) in ga.iter_mut().zip(z) {
                    *gaj += e * zj;
                }
                for k in 0..h {
                    gw[k] += e * phi[k];
                    let a = e * w[k] * phi[k] * 2.0 * g[k];
                    if a == 0.0 {
                        continue;
                    }
                    gs[k] += a * d2[k];
                    let ck = &c[k * self.inputs..(k + 1) * self.inputs];
                    let gck = &mut gc[k * self.inputs..(k + 1) * self.inputs];
                    for j in 0..self.inputs {
                        gck[j] += a * (z[j] - ck[j]);
                    }
                }
            }
            for (gwk, &wk) in gw.iter_mut().zip(w) {
                *gwk += 2.0 * lambda * wk;
            }
        }
        sse / n + lambda * w.iter().map(|w| w * w).sum::<f64>()
    }
}

/// `‖z − c‖²` over the inputs `c` has (the network's).
#[inline]
fn dist2(z: &[f64; N_INPUTS], c: &[f64]) -> f64 {
    let mut d = 0.0;
    for (zj, cj) in z.iter().zip(c) {
        let e = zj - cj;
        d += e * e;
    }
    d
}

/// A trained observer: shape, parameters, normalisation, what it predicts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainedModel {
    pub kind: ModelKind,
    pub rbf: Rbf,
    pub params: Vec<f64>,
    pub norm: Normaliser,
    /// The force the observer read in the training data: the weights run
    /// only on that force input (the drive checks it through the structure
    /// hash). `None` in a file written before the trainer recorded it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_source: Option<super::dataset::ForceSource>,
}

impl TrainedModel {
    /// Prediction in metres for raw inputs (clamped to the trained range, as
    /// in the firmware), and whether any input was clamped.
    pub fn predict(&self, x: &[f64; N_INPUTS]) -> (f64, bool) {
        // Slots the network does not use carry nothing (as in the firmware).
        let mut x = *x;
        for v in x.iter_mut().skip(self.rbf.inputs) {
            *v = 0.0;
        }
        let (z, clamped) = self.norm.normalise(&x);
        (self.norm.net_to_target(self.rbf.forward(&self.params, &z)), clamped)
    }
    pub fn hidden(&self) -> usize {
        self.rbf.hidden
    }
    /// Centres in the five slots; an unused slot's coordinate is −1, where
    /// its normalised input sits (`servo_core::observer::lift`).
    pub fn centres(&self) -> Vec<[f64; N_INPUTS]> {
        (0..self.rbf.hidden)
            .map(|k| {
                let mut c = [-1.0; N_INPUTS];
                c[..self.rbf.inputs].copy_from_slice(self.rbf.centre(&self.params, k));
                c
            })
            .collect()
    }
    /// Inputs the model uses (4 or 5).
    pub fn inputs(&self) -> usize {
        self.rbf.inputs
    }
    /// σ_k (normalised input units).
    pub fn widths(&self) -> Vec<f64> {
        self.rbf.log_widths(&self.params).iter().map(|s| s.exp()).collect()
    }
    pub fn weights(&self) -> &[f64] {
        self.rbf.weights(&self.params)
    }
    pub fn bias(&self) -> f64 {
        self.rbf.bias(&self.params)
    }
    pub fn linear_coefficients(&self) -> [f64; N_INPUTS] {
        self.rbf.linear_coefficients(&self.params)
    }
}
