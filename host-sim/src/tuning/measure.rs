//! What the tuning check measures on a captured test, and how (docs/tuning.md,
//! "Measurement"):
//!
//! - **Frequency response by the full-record DTFT ratio.** A chirp test starts
//!   and ends at rest (the capture's pre-trigger samples before it, ≥ 10 % of
//!   its length after it), so the captured reference `x` and response `y` are
//!   finite transients and `Y(f) = H(f) X(f)` holds exactly for a linear loop
//!   at every frequency, not only on FFT bins. `H(f) = Y(f)/X(f)` is evaluated
//!   on a log grid inside the chirp's band with no window (a Welch/Hann H1
//!   on a sweep weights the input and the delayed output differently and
//!   biases the gain; its bins are also coarse at the low end of a log sweep).
//! - **−3 dB against 0 dB**: every loop here has integral action (or sits
//!   round one), so its reference-to-output gain is 1 at DC; the first
//!   frequency where `|T|` falls below `1/√2`, interpolated in dB on the grid.
//! - **Margins from the open loop `L = C·P`**: the chirp also captures the
//!   controller's output `u`; `P = Y/U` is measured, `C` (the regulator as
//!   the core computes it, known exactly) multiplies it.
//! - **Steps**: the figures of `tool::analysis::step_figures` on the samples
//!   before the step ends (the capture's last samples see the step come off),
//!   after a 3-sample centred mean (sensor noise would otherwise add its peak
//!   to the overshoot).

use super::design::{margins_from_samples, Margins};
use crate::tool::analysis::{step_figures, StepFigures};
use nalgebra::Complex;
use std::f64::consts::{FRAC_1_SQRT_2, TAU};

type C = Complex<f64>;

/// `Σ v[k] e^{−j2πf k dt}` for each `f`, after removing `v`'s mean over
/// `rest` leading samples (the operating point the test started from).
pub fn dtft(v: &[f64], rest: usize, dt: f64, freqs_hz: &[f64]) -> Vec<C> {
    let rest = rest.clamp(1, v.len().max(1));
    let base = v[..rest].iter().sum::<f64>() / rest as f64;
    freqs_hz
        .iter()
        .map(|&f| {
            // Rotating phasor: one complex multiply per sample.
            let step = C::new((TAU * f * dt).cos(), -(TAU * f * dt).sin());
            let mut ph = C::new(1.0, 0.0);
            let mut acc = C::new(0.0, 0.0);
            for &s in v {
                acc += ph * (s - base);
                ph *= step;
            }
            acc
        })
        .collect()
}

/// `n` frequencies spaced logarithmically over `[f0, f1]`.
pub fn log_grid(f0: f64, f1: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| f0 * (f1 / f0).powf(k as f64 / (n - 1).max(1) as f64))
        .collect()
}

/// A measured frequency response on a grid.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Response {
    pub freq_hz: Vec<f64>,
    #[serde(skip)]
    pub h: Vec<C>,
}

impl Response {
    /// `Y/X` from a capture: `x`, `y` from the test's start, `rest` samples of
    /// the operating point before it.
    pub fn ratio(x: &[f64], y: &[f64], rest: usize, dt: f64, freqs_hz: Vec<f64>) -> Self {
        let (xf, yf) = (dtft(x, rest, dt, &freqs_hz), dtft(y, rest, dt, &freqs_hz));
        Response {
            h: yf.iter().zip(&xf).map(|(y, x)| y / x).collect(),
            freq_hz: freqs_hz,
        }
    }

    pub fn gain_db(&self) -> Vec<f64> {
        self.h.iter().map(|h| 20.0 * h.norm().log10()).collect()
    }

    /// First frequency where `|H|` falls 3 dB below `reference` (1 for a loop
    /// with integral action), interpolated in dB between grid points, on the
    /// gain smoothed over 1/6 octave (a mean in dB over the grid points within
    /// ±1/12 octave): friction and noise leave single-point dips that are not
    /// the loop's roll-off.
    pub fn bandwidth_3db_hz(&self, reference: f64) -> Option<f64> {
        let lim = 20.0 * (reference * FRAC_1_SQRT_2).log10();
        let g = smoothed(&self.freq_hz, &self.gain_db(), 1.0 / 12.0);
        (1..g.len()).find(|&k| g[k] < lim && g[k - 1] >= lim).map(|k| {
            let s = (g[k - 1] - lim) / (g[k - 1] - g[k]);
            let (a, b) = (self.freq_hz[k - 1].ln(), self.freq_hz[k].ln());
            (a + s * (b - a)).exp()
        })
    }

    /// Margins of `self` taken as an open loop.
    pub fn margins(&self) -> Margins {
        margins_from_samples(&self.freq_hz, &self.h)
    }
}

/// `v` averaged over the points of `f` within ±`half_octaves` of each.
pub fn smoothed(f: &[f64], v: &[f64], half_octaves: f64) -> Vec<f64> {
    let k = 2f64.powf(half_octaves);
    (0..v.len())
        .map(|i| {
            let (lo, hi) = (f[i] / k, f[i] * k);
            let w: Vec<f64> = (0..v.len()).filter(|&j| f[j] >= lo && f[j] <= hi).map(|j| v[j]).collect();
            w.iter().sum::<f64>() / w.len() as f64
        })
        .collect()
}

/// Step figures on the samples before the step comes off (`duration_s`
/// after `t0`), smoothed by a 3-sample centred mean.
pub fn step_figures_in(
    y: &[f64],
    dt: f64,
    t0: f64,
    duration_s: f64,
    amplitude: f64,
) -> StepFigures {
    let end = (((t0 + duration_s) / dt).floor() as usize)
        .saturating_sub(1)
        .min(y.len());
    let y = &y[..end];
    let s: Vec<f64> = (0..y.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(y.len() - 1));
            y[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
        })
        .collect();
    step_figures(&s, dt, t0, amplitude)
}

/// What sensor noise alone adds to a step's overshoot figure, %: the
/// scatter of the 3-sample-mean response over the step's second half
/// (settled: the loops here settle well inside half their step) times the
/// expected largest of `n` normal draws, `√(2 ln n)`, over the samples the
/// peak is sought in, against the amplitude. A perfect step reads this much
/// overshoot; an ask below it cannot be resolved by the capture.
pub fn overshoot_noise_floor_pct(y: &[f64], dt: f64, t0: f64, duration_s: f64, amplitude: f64) -> f64 {
    let start = (t0 / dt).ceil() as usize;
    let end = ((((t0 + duration_s) / dt).floor() as usize).saturating_sub(1)).min(y.len());
    if end < start + 16 || amplitude == 0.0 {
        return f64::NAN;
    }
    let mid = start + (end - start) / 2;
    let s: Vec<f64> = (mid.max(1)..end.saturating_sub(1)).map(|k| (y[k - 1] + y[k] + y[k + 1]) / 3.0).collect();
    let mean = s.iter().sum::<f64>() / s.len() as f64;
    // A slow settling tail would count as noise: take the scatter about a
    // straight line through the half.
    let n = s.len() as f64;
    let xm = (n - 1.0) / 2.0;
    let sxx: f64 = (0..s.len()).map(|k| (k as f64 - xm).powi(2)).sum();
    let slope = (0..s.len()).map(|k| (k as f64 - xm) * (s[k] - mean)).sum::<f64>() / sxx;
    let var = (0..s.len()).map(|k| (s[k] - mean - slope * (k as f64 - xm)).powi(2)).sum::<f64>() / (n - 2.0);
    let samples = (end - start) as f64;
    100.0 * var.sqrt() * (2.0 * samples.ln()).sqrt() / amplitude.abs()
}

/// The figure's rule: the bandwidth within ±20 % of the ask; the overshoot
/// within ±20 % of the ask for asks ≥ 5 %, within ±1 percentage point
/// (20 % of 5 %) below that (a 0 % ask passes up to 1 %).
pub fn bandwidth_ok(asked_hz: f64, got_hz: Option<f64>) -> bool {
    got_hz.is_some_and(|g| (g - asked_hz).abs() <= 0.2 * asked_hz)
}

pub fn overshoot_tolerance_pct(asked_pct: f64) -> f64 {
    0.2 * asked_pct.max(5.0)
}

pub fn overshoot_ok(asked_pct: f64, got_pct: f64) -> bool {
    (got_pct - asked_pct).abs() <= overshoot_tolerance_pct(asked_pct)
}
