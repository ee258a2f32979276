//! Frequency content and statistics of a residual: Welch spectrum and band
//! energies, the time windows with the most residual energy, whiteness and
//! the residual–input cross-correlation.

use super::residual::Segment;

/// In-place radix-2 FFT (`re`, `im` of a power-of-two length).
pub fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -std::f64::consts::TAU / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (s, c) = (ang * k as f64).sin_cos();
                let (a, b) = (start + k, start + k + len / 2);
                let (xr, xi) = (re[b] * c - im[b] * s, re[b] * s + im[b] * c);
                re[b] = re[a] - xr;
                im[b] = im[a] - xi;
                re[a] += xr;
                im[a] += xi;
            }
        }
        len <<= 1;
    }
}

/// Welch power spectrum (Hann, 50 % overlap) of the residual over segments:
/// (frequencies Hz, PSD units²/Hz).
pub fn welch(segs: &[&Segment], ch: usize) -> (Vec<f64>, Vec<f64>) {
    let dt = segs
        .iter()
        .find(|s| s.len() > 1)
        .map_or(1e-3, |s| (s.t[s.len() - 1] - s.t[0]) / (s.len() - 1) as f64);
    let min_len = segs
        .iter()
        .filter(|s| s.r[ch].is_some())
        .map(|s| s.len())
        .min()
        .unwrap_or(0);
    let mut nfft = 1024usize;
    while nfft > 16 && nfft > min_len {
        nfft /= 2;
    }
    let win: Vec<f64> = (0..nfft)
        .map(|k| 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / nfft as f64).cos())
        .collect();
    let wss: f64 = win.iter().map(|w| w * w).sum();
    let mut psd = vec![0.0; nfft / 2 + 1];
    let mut count = 0usize;
    for s in segs {
        let Some(r) = &s.r[ch] else { continue };
        let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
        let mut start = 0;
        while start + nfft <= r.len() {
            let mut re: Vec<f64> = (0..nfft).map(|k| (r[start + k] - mean) * win[k]).collect();
            let mut im = vec![0.0; nfft];
            fft(&mut re, &mut im);
            for (k, p) in psd.iter_mut().enumerate() {
                let scale = if k == 0 || k == nfft / 2 { 1.0 } else { 2.0 };
                *p += scale * (re[k] * re[k] + im[k] * im[k]) * dt / wss;
            }
            count += 1;
            start += nfft / 2;
        }
    }
    if count > 0 {
        psd.iter_mut().for_each(|p| *p /= count as f64);
    }
    let freqs = (0..psd.len())
        .map(|k| k as f64 / (nfft as f64 * dt))
        .collect();
    (freqs, psd)
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Band {
    pub lo_hz: f64,
    pub hi_hz: f64,
    pub energy_pct: f64,
}

/// Share of the residual's (zero-mean) energy per band.
pub fn bands(freqs: &[f64], psd: &[f64]) -> Vec<Band> {
    let nyq = freqs.last().copied().unwrap_or(0.0);
    let mut edges = vec![0.0];
    for e in [0.5, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0] {
        if e < nyq {
            edges.push(e);
        }
    }
    edges.push(nyq + 1e-9);
    let total: f64 = psd.iter().sum();
    edges
        .windows(2)
        .map(|w| {
            let e: f64 = freqs
                .iter()
                .zip(psd)
                .filter(|(f, _)| **f >= w[0] && **f < w[1])
                .map(|(_, p)| p)
                .sum();
            Band {
                lo_hz: w[0],
                hi_hz: w[1].min(nyq),
                energy_pct: if total > 0.0 { 100.0 * e / total } else { 0.0 },
            }
        })
        .collect()
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Window {
    pub run: usize,
    pub t_start_s: f64,
    pub t_end_s: f64,
    pub log_row: usize,
    pub energy_pct: f64,
    pub rms: f64,
}

/// The `k` windows (`width_s` wide, not overlapping) with the most energy.
pub fn top_windows(segs: &[&Segment], ch: usize, width_s: f64, k: usize) -> Vec<Window> {
    let mut all = Vec::new();
    let mut total = 0.0;
    for s in segs {
        let Some(r) = &s.r[ch] else { continue };
        let mut i = 0;
        while i < r.len() {
            let mut j = i;
            let mut ss = 0.0;
            while j < r.len() && s.t[j] - s.t[i] < width_s {
                ss += r[j] * r[j];
                j += 1;
            }
            total += ss;
            all.push(Window {
                run: s.run,
                t_start_s: s.t[i],
                t_end_s: s.t[j - 1],
                log_row: s.first_row + i + 1,
                energy_pct: ss,
                rms: (ss / (j - i) as f64).sqrt(),
            });
            i = j;
        }
    }
    all.sort_by(|a, b| b.energy_pct.total_cmp(&a.energy_pct));
    all.truncate(k);
    for w in &mut all {
        w.energy_pct = if total > 0.0 {
            100.0 * w.energy_pct / total
        } else {
            0.0
        };
    }
    all
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Correlation {
    /// Lags (samples) 1..=max_lag with |ρ| beyond the 95 % band ±1.96/√N, %.
    pub autocorr_outside_pct: f64,
    pub autocorr_lag1: f64,
    pub white: bool,
    /// Residual vs input (reference or current): the largest |ρ| and its lag
    /// in samples (negative: the residual leads the input, i.e. feedback).
    pub xcorr_max: f64,
    pub xcorr_lag: i64,
    pub xcorr_negative_lag_max: f64,
    pub xcorr_positive_lag_max: f64,
}

pub fn correlation(segs: &[&Segment], ch: usize, max_lag: usize) -> Correlation {
    let mut acf = vec![0.0; max_lag + 1];
    let mut xc = vec![0.0; 2 * max_lag + 1];
    let (mut n, mut sr, mut su) = (0usize, 0.0, 0.0);
    for s in segs {
        let Some(r) = &s.r[ch] else { continue };
        let mr = r.iter().sum::<f64>() / r.len() as f64;
        // Input as its increments (a reference is non-stationary).
        let du: Vec<f64> = (0..r.len())
            .map(|i| {
                if i == 0 {
                    0.0
                } else {
                    s.input[i] - s.input[i - 1]
                }
            })
            .collect();
        let mu = du.iter().sum::<f64>() / du.len() as f64;
        let rc: Vec<f64> = r.iter().map(|x| x - mr).collect();
        let uc: Vec<f64> = du.iter().map(|x| x - mu).collect();
        for lag in 0..=max_lag {
            acf[lag] += (lag..rc.len()).map(|i| rc[i] * rc[i - lag]).sum::<f64>();
        }
        for (li, lag) in (-(max_lag as i64)..=max_lag as i64).enumerate() {
            // ρ(lag) = Σ r[i] u[i − lag]: positive lag, input leads.
            let sum: f64 = (0..rc.len())
                .filter_map(|i| {
                    let j = i as i64 - lag;
                    (j >= 0 && (j as usize) < uc.len()).then(|| rc[i] * uc[j as usize])
                })
                .sum();
            xc[li] += sum;
        }
        n += rc.len();
        sr += rc.iter().map(|x| x * x).sum::<f64>();
        su += uc.iter().map(|x| x * x).sum::<f64>();
    }
    let bound = 1.96 / (n.max(1) as f64).sqrt();
    let rho: Vec<f64> = acf
        .iter()
        .map(|a| if acf[0] > 0.0 { a / acf[0] } else { 0.0 })
        .collect();
    let outside = rho[1..].iter().filter(|r| r.abs() > bound).count();
    let norm = (sr * su).sqrt();
    let xr: Vec<f64> = xc
        .iter()
        .map(|x| if norm > 0.0 { x / norm } else { 0.0 })
        .collect();
    let (imax, xmax) = xr.iter().enumerate().fold((0, 0.0f64), |(bi, bv), (i, v)| {
        if v.abs() > bv.abs() {
            (i, *v)
        } else {
            (bi, bv)
        }
    });
    let neg = xr[..max_lag].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let pos = xr[max_lag + 1..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    Correlation {
        autocorr_outside_pct: 100.0 * outside as f64 / max_lag as f64,
        autocorr_lag1: rho.get(1).copied().unwrap_or(0.0),
        white: (outside as f64) <= 0.05 * max_lag as f64 + 1.0,
        xcorr_max: xmax,
        xcorr_lag: imax as i64 - max_lag as i64,
        xcorr_negative_lag_max: neg,
        xcorr_positive_lag_max: pos,
    }
}
