//! INTERIM copy of the hosttool branch's `tool/analysis.rs` until it is on
//! main; replaced by `crate::tool::analysis` at the merge.
//! Step and frequency-response figures of a captured test.

use crate::diagnose::spectrum::fft;

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StepFigures {
    pub amplitude: f64,
    pub initial: f64,
    pub final_value: f64,
    /// 10 % → 90 % of the final change, seconds from the step.
    pub rise_time_s: Option<f64>,
    /// Peak beyond the final value, percent of the change.
    pub overshoot_pct: f64,
    /// Last time the response is outside ±2 % of the change around its
    /// final value, seconds from the step.
    pub settling_time_s: Option<f64>,
}

/// `t0`: step instant; `y` sampled at `dt` from `t = 0`.
pub fn step_figures(y: &[f64], dt: f64, t0: f64, amplitude: f64) -> StepFigures {
    let k0 = ((t0 / dt).round() as usize).min(y.len());
    let before = &y[..k0.max(1).min(y.len())];
    let initial = before.iter().sum::<f64>() / before.len().max(1) as f64;
    let tail = &y[y.len() - (y.len() - k0).max(1) / 10 - 1..];
    let final_value = tail.iter().sum::<f64>() / tail.len() as f64;
    let change = final_value - initial;
    let mut f = StepFigures { amplitude, initial, final_value, ..Default::default() };
    if change.abs() < 1e-12 {
        return f;
    }
    let frac = |v: f64| (v - initial) / change;
    let after = &y[k0..];
    let t10 = after.iter().position(|v| frac(*v) >= 0.1);
    let t90 = after.iter().position(|v| frac(*v) >= 0.9);
    if let (Some(a), Some(b)) = (t10, t90) {
        f.rise_time_s = Some((b as f64 - a as f64) * dt);
    }
    let peak = after.iter().map(|v| frac(*v)).fold(f64::MIN, f64::max);
    f.overshoot_pct = ((peak - 1.0) * 100.0).max(0.0);
    let last_out = after.iter().rposition(|v| (frac(*v) - 1.0).abs() > 0.02);
    f.settling_time_s = match last_out {
        Some(k) if k + 1 < after.len() => Some((k + 1) as f64 * dt),
        Some(_) => None,
        None => Some(0.0),
    };
    f
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Frf {
    pub freq_hz: Vec<f64>,
    pub gain_db: Vec<f64>,
    pub phase_deg: Vec<f64>,
    pub coherence: Vec<f64>,
}

/// H1 estimate `S_xy / S_xx` by Welch (Hann, 50 % overlap, `nfft` a power of
/// two), with the magnitude-squared coherence.
pub fn h1(x: &[f64], y: &[f64], dt: f64, nfft: usize) -> Frf {
    let n = x.len().min(y.len());
    let nfft = nfft.min(n.next_power_of_two() / 2).max(8);
    let win: Vec<f64> = (0..nfft).map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / nfft as f64).cos()).collect();
    let half = nfft / 2;
    let (mut sxx, mut syy) = (vec![0.0; half], vec![0.0; half]);
    let (mut sxy_re, mut sxy_im) = (vec![0.0; half], vec![0.0; half]);
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let mut start = 0;
    while start + nfft <= n {
        let mut xr: Vec<f64> = (0..nfft).map(|i| (x[start + i] - mx) * win[i]).collect();
        let mut xi = vec![0.0; nfft];
        let mut yr: Vec<f64> = (0..nfft).map(|i| (y[start + i] - my) * win[i]).collect();
        let mut yi = vec![0.0; nfft];
        fft(&mut xr, &mut xi);
        fft(&mut yr, &mut yi);
        for k in 0..half {
            sxx[k] += xr[k] * xr[k] + xi[k] * xi[k];
            syy[k] += yr[k] * yr[k] + yi[k] * yi[k];
            // conj(X) Y
            sxy_re[k] += xr[k] * yr[k] + xi[k] * yi[k];
            sxy_im[k] += xr[k] * yi[k] - xi[k] * yr[k];
        }
        start += half;
    }
    let mut f = Frf::default();
    for k in 1..half {
        let h_re = sxy_re[k] / sxx[k];
        let h_im = sxy_im[k] / sxx[k];
        f.freq_hz.push(k as f64 / (nfft as f64 * dt));
        f.gain_db.push(10.0 * (h_re * h_re + h_im * h_im).log10());
        f.phase_deg.push(h_im.atan2(h_re).to_degrees());
        f.coherence.push((sxy_re[k].powi(2) + sxy_im[k].powi(2)) / (sxx[k] * syy[k]));
    }
    f
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrfFigures {
    /// First frequency where the closed-loop gain falls 3 dB below its
    /// low-frequency value.
    pub bandwidth_3db_hz: Option<f64>,
    /// Of the open loop `L = T / (1 − T)` from the closed loop `T`.
    pub gain_margin_db: Option<f64>,
    pub phase_crossover_hz: Option<f64>,
    pub phase_margin_deg: Option<f64>,
    pub gain_crossover_hz: Option<f64>,
    /// Points used (inside the chirp's band, coherence ≥ 0.8).
    pub points: usize,
}

/// Figures of a closed-loop FRF measured over `[from, to]` Hz.
pub fn frf_figures(frf: &Frf, from_hz: f64, to_hz: f64) -> FrfFigures {
    let idx: Vec<usize> = (0..frf.freq_hz.len())
        .filter(|&k| frf.freq_hz[k] >= from_hz && frf.freq_hz[k] <= to_hz && frf.coherence[k] >= 0.8)
        .collect();
    let mut out = FrfFigures { points: idx.len(), ..Default::default() };
    let Some(&first) = idx.first() else { return out };
    let g0 = frf.gain_db[first];
    out.bandwidth_3db_hz = idx.iter().find(|&&k| frf.gain_db[k] < g0 - 3.0).map(|&k| frf.freq_hz[k]);
    // Open loop from closed loop, unity feedback: L = T / (1 − T). Phases
    // are taken wrapped to (−360°, 0°] at the crossings (no unwrapping over
    // the band: where |L| is large its phase is noisy and an unwrap drifts
    // by whole turns); the phase crossover is where L crosses the negative
    // real axis.
    let mut prev: Option<(f64, f64, f64, f64)> = None; // (f, |L| dB, Re L, Im L)
    let wrap = |deg: f64| -((-deg).rem_euclid(360.0));
    for &k in &idx {
        let (m, p) = (10f64.powf(frf.gain_db[k] / 20.0), frf.phase_deg[k].to_radians());
        let (tr, ti) = (m * p.cos(), m * p.sin());
        let (dr, di) = (1.0 - tr, -ti);
        let den = dr * dr + di * di;
        let (lr, li) = ((tr * dr + ti * di) / den, (ti * dr - tr * di) / den);
        let ldb = 10.0 * (lr * lr + li * li).log10();
        let f = frf.freq_hz[k];
        if let Some((f0, l0, r0, i0)) = prev {
            if out.gain_crossover_hz.is_none() && l0 >= 0.0 && ldb < 0.0 {
                let a = l0 / (l0 - ldb);
                out.gain_crossover_hz = Some(f0 + a * (f - f0));
                let (xr, xi) = (r0 + a * (lr - r0), i0 + a * (li - i0));
                out.phase_margin_deg = Some(180.0 + wrap(xi.atan2(xr).to_degrees()));
            }
            if out.phase_crossover_hz.is_none() && (i0 < 0.0) != (li < 0.0) && r0 < 0.0 && lr < 0.0 {
                let a = i0 / (i0 - li);
                out.phase_crossover_hz = Some(f0 + a * (f - f0));
                out.gain_margin_db = Some(-(l0 + a * (ldb - l0)));
            }
        }
        prev = Some((f, ldb, lr, li));
    }
    out
}
