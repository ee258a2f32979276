//! Periodicity and whiteness: the remainder's autocorrelation
//! (for its dominant time period and the Ljung–Box whiteness test) and its
//! periodicity in the motor angle at the kinematic periods known before the
//! data are seen (screw revolution, electrical period). A disturbance tied
//! to the angle (cogging, eccentricity) repeats with position, not time.

use super::{cv_regress, Remainder, SLOW_S};
use crate::diagnose::residual::Segment;
use crate::diagnose::spectrum::fft;

/// Autocorrelation (lags 0..=max_lag) of the weighted remainder, by FFT.
pub(super) fn acf(segs: &[&Segment], rem: &Remainder, c: usize, max_lag: usize) -> Vec<f64> {
    let mut acc = vec![0.0; max_lag + 1];
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let n = x.len();
        let mut nfft = 1;
        while nfft < 2 * n {
            nfft <<= 1;
        }
        let mean = (0..n).map(|i| s.weight(c, i) * x[i]).sum::<f64>() / n.max(1) as f64;
        let mut re: Vec<f64> = (0..nfft)
            .map(|i| {
                if i < n {
                    s.weight(c, i) * x[i] - mean
                } else {
                    0.0
                }
            })
            .collect();
        let mut im = vec![0.0; nfft];
        fft(&mut re, &mut im);
        let mut p: Vec<f64> = re.iter().zip(&im).map(|(a, b)| a * a + b * b).collect();
        let mut q = vec![0.0; nfft];
        fft(&mut p, &mut q);
        for (l, a) in acc.iter_mut().enumerate().take(max_lag.min(n - 1) + 1) {
            *a += p[l] / nfft as f64;
        }
    }
    let a0 = acc[0];
    acc.iter()
        .map(|a| if a0 > 0.0 { a / a0 } else { 0.0 })
        .collect()
}

/// Complementary error function (Abramowitz & Stegun 7.1.26, |ε| < 1.5e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let y = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let r = y * (-z * z).exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Upper tail of χ² with `k` degrees of freedom (Wilson–Hilferty).
pub fn chi2_sf(q: f64, k: usize) -> f64 {
    let k = k as f64;
    let z = ((q / k).powf(1.0 / 3.0) - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Ljung–Box Q over `h` lags of a series, with its p-value.
pub fn ljung_box(x: &[f64], h: usize) -> (f64, f64) {
    let n = x.len();
    if n <= h + 2 {
        return (0.0, 1.0);
    }
    let m = x.iter().sum::<f64>() / n as f64;
    let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    if c0 <= 0.0 {
        return (0.0, 1.0);
    }
    let q: f64 = (1..=h)
        .map(|k| {
            let rho = (k..n).map(|i| (x[i] - m) * (x[i - k] - m)).sum::<f64>() / c0;
            rho * rho / (n - k) as f64
        })
        .sum::<f64>()
        * (n * (n + 2)) as f64;
    (q, chi2_sf(q, h))
}

/// Periods per motor revolution of the kinematic-period test, known before
/// the data are seen (no search): the screw's revolution (the motor drives
/// it directly: encoder eccentricity, once-per-revolution lead error) and
/// its second harmonic, and with the rig's pole pairs `p` the electrical
/// period `p` and `2p` (current-sensor offsets and gain mismatch).
pub fn kinematic_periods(pole_pairs: Option<u32>) -> Vec<u32> {
    let mut v = vec![1, 2];
    if let Some(p) = pole_pairs.filter(|p| *p > 0) {
        v.extend([p, 2 * p]);
    }
    v.sort_unstable();
    v.dedup();
    v
}

/// Features of a remainder periodic in the motor angle with `n` periods per
/// revolution: `sin nθ`, `cos nθ` (an error on the angle or the force) and
/// their second time derivatives `n(α cos nθ − n ω² sin nθ)`, … (the same
/// error seen through the differentiation into acceleration), and 1.
pub fn angle_features(s: &Segment, n: f64) -> Vec<Vec<f64>> {
    (0..s.len())
        .map(|i| {
            let (sn, cs) = (n * s.theta[i]).sin_cos();
            let (om, al) = (
                s.omega.get(i).copied().unwrap_or(0.0),
                s.alpha.get(i).copied().unwrap_or(0.0),
            );
            vec![
                1.0,
                sn,
                cs,
                n * (al * cs - n * om * om * sn),
                -n * (al * sn + n * om * om * cs),
            ]
        })
        .collect()
}

/// The best of the kinematic periods (periods per revolution) and its
/// cross-validated share of the remainder's fast part (faster than
/// `SLOW_S`), %.
pub fn angle_periodic(
    segs: &[&Segment],
    rem: &Remainder,
    c: usize,
    periods: &[u32],
) -> (u32, f64, Vec<Vec<f64>>) {
    let mut best = (0, 0.0, segs.iter().map(|_| Vec::new()).collect());
    if segs.iter().all(|s| {
        s.theta
            .iter()
            .all(|t| *t == s.theta.first().copied().unwrap_or(0.0))
    }) {
        return best;
    }
    // Fast parts only (each signal minus its `SLOW_S` moving average): an
    // angle period shows while the angle sweeps; at rest a sinusoid of the
    // angle is a constant that would fit the rest levels of a slow
    // remainder (an offset, a step) through the positions the rod rests at.
    let hp = |x: &[f64], s: &Segment| -> Vec<f64> {
        let n = x.len();
        let half = ((0.5 * SLOW_S / s.dt) as usize).max(1);
        let mut pre = vec![0.0; n + 1];
        for (i, v) in x.iter().enumerate() {
            pre[i + 1] = pre[i] + v;
        }
        (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
                x[i] - (pre[b] - pre[a]) / (b - a) as f64
            })
            .collect()
    };
    let fast: Remainder = segs
        .iter()
        .zip(rem)
        .map(|(s, r)| {
            std::array::from_fn(|k| {
                if k == c {
                    r[k].as_ref().map(|x| hp(x, s))
                } else {
                    None
                }
            })
        })
        .collect();
    for &n in periods {
        let feats: Vec<Vec<Vec<f64>>> = segs
            .iter()
            .map(|s| {
                let f = angle_features(s, f64::from(n));
                let cols: Vec<Vec<f64>> = (1..5)
                    .map(|j| hp(&f.iter().map(|r| r[j]).collect::<Vec<_>>(), s))
                    .collect();
                (0..s.len())
                    .map(|i| vec![1.0, cols[0][i], cols[1][i], cols[2][i], cols[3][i]])
                    .collect()
            })
            .collect();
        let (r2, pred) = cv_regress(segs, &fast, c, &feats);
        if r2 > best.1 {
            best = (n, r2, pred);
        }
    }
    best
}
