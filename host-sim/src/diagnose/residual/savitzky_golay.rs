//! Savitzky–Golay differentiation (quadratic, ±10 ms): the value, speed and
//! acceleration the residual is built from, and the smoother's gains on a
//! sinusoid (what the differentiation does to a periodic error).

/// Gain of the quadratic Savitzky–Golay smoother (half width m) on a
/// sinusoid advancing `phi` rad per sample.
pub fn sg_smooth_gain(m: usize, phi: f64) -> f64 {
    let mf = m as f64;
    let den = (2.0 * mf + 1.0) * (4.0 * mf * mf + 4.0 * mf - 3.0);
    (0..=2 * m)
        .map(|j| {
            let k = j as f64 - mf;
            (3.0 * (3.0 * mf * mf + 3.0 * mf - 1.0) - 15.0 * k * k) / den * (k * phi).cos()
        })
        .sum()
}

/// Gain of the Savitzky–Golay second derivative relative to the true one on
/// a sinusoid advancing `phi` rad per sample.
pub fn sg_second_gain(m: usize, phi: f64) -> f64 {
    if phi.abs() < 1e-6 {
        return 1.0;
    }
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let num: f64 = (0..=2 * m)
        .map(|j| 2.0 * ((j as f64 - mf).powi(2) - s2) / sq * ((j as f64 - mf) * phi).cos())
        .sum();
    -num / (phi * phi)
}

/// Quadratic Savitzky–Golay value, first and second derivative at sample i
/// (half width m, step h).
pub(super) fn sg(y: &[f64], i: usize, m: usize, h: f64) -> (f64, f64, f64) {
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sk2: f64 = (1..=m).map(|k| 2.0 * (k as f64).powi(2)).sum();
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let (mut a1, mut a2) = (0.0, 0.0);
    let mean: f64 = y[i - m..=i + m].iter().sum::<f64>() / (2.0 * mf + 1.0);
    for j in 0..=2 * m {
        let kk = j as f64 - mf;
        let v = y[i - m + j];
        a1 += kk * v;
        a2 += (kk * kk - s2) * v;
    }
    let c2 = a2 / sq;
    (mean - c2 * s2, a1 / sk2 / h, 2.0 * c2 / (h * h))
}

/// Half width of the differentiation window for a sample step: ±10 ms, at
/// least 2 samples.
pub fn half_width(dt: f64) -> usize {
    ((0.010 / dt).round() as usize).clamp(2, 50)
}

/// Quadratic Savitzky–Golay smoothing (value) over ±m samples, the filter
/// the torque channel's current goes through, for a prediction to be
/// smoothed alike; the ends are left as they are.
pub fn sg_smooth(y: &[f64], m: usize) -> Vec<f64> {
    let n = y.len();
    if m == 0 || n < 2 * m + 1 {
        return y.to_vec();
    }
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let coef: Vec<f64> = (0..=2 * m)
        .map(|j| 1.0 / (2.0 * mf + 1.0) - ((j as f64 - mf).powi(2) - s2) * s2 / sq)
        .collect();
    let mut out = y.to_vec();
    for (i, o) in out.iter_mut().enumerate().take(n - m).skip(m) {
        *o = coef.iter().zip(&y[i - m..=i + m]).map(|(a, b)| a * b).sum();
    }
    out
}

/// Quadratic Savitzky–Golay second derivative over ±m samples (step h) of
/// a whole series, the operator the rod's acceleration from the scale goes
/// through, for a prediction of what reaches the torque channel to be
/// differentiated alike; zero within m samples of the ends, where the
/// window does not fit.
pub fn sg_second(y: &[f64], m: usize, h: f64) -> Vec<f64> {
    let n = y.len();
    let mut out = vec![0.0; n];
    if m == 0 || n < 2 * m + 1 {
        return out;
    }
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let coef: Vec<f64> = (0..=2 * m)
        .map(|j| 2.0 * ((j as f64 - mf).powi(2) - s2) / sq / (h * h))
        .collect();
    for (i, o) in out.iter_mut().enumerate().take(n - m).skip(m) {
        *o = coef.iter().zip(&y[i - m..=i + m]).map(|(a, b)| a * b).sum();
    }
    out
}

/// The smoother the second derivative implies: the kernel `g` (half width
/// m − 1, summing to 1) with `sg(·).2 = Δ²(g ∗ y)/h²`, Δ² the central
/// second difference. A torque balanced against accelerations from `sg`
/// is compared like for like only if the current is smoothed by `g` too:
/// the quadratic fit's value has another frequency response, which
/// differs by tens of percent at the rod's axial mode and so leaves every
/// move start's transient in the residual.
pub fn accel_smoother(m: usize) -> Vec<f64> {
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sq: f64 = (0..=2 * m).map(|j| ((j as f64 - mf).powi(2) - s2).powi(2)).sum();
    let c: Vec<f64> = (0..=2 * m).map(|j| 2.0 * ((j as f64 - mf).powi(2) - s2) / sq).collect();
    // g_j = Σ_{i<j} (j − i) c_i, for j = −(m−1) … m−1 (index j + m − 1).
    (1..2 * m)
        .map(|j| (0..j).map(|i| (j - i) as f64 * c[i]).sum())
        .collect()
}

/// `y` smoothed at sample i by a kernel of `accel_smoother` (the ends,
/// where the kernel does not fit, left as they are).
pub fn smooth_with(y: &[f64], i: usize, g: &[f64]) -> f64 {
    let h = g.len() / 2;
    if i < h || i + h >= y.len() {
        return y[i];
    }
    g.iter().enumerate().map(|(j, w)| w * y[i + j - h]).sum()
}
