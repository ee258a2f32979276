//! Which coefficient changes of a regression re-fit are real, judged by
//! group with their joint uncertainty.
//!
//! The regression's lagged speeds (`v`, `v[-2]` … `v[-12]`) are nearly
//! collinear: a re-fit can move one far up and its neighbour far down and
//! predict almost the same. Judged one by one, each such coefficient looks
//! changed by many times the nominal's RMS while their combined effect —
//! the static gain from speed to the channel, their sum — did not move.
//! So the lagged speeds are one parameter, their sum, and every change
//! counts only when it is large (its held-out effect against the nominal's
//! prediction) *and* beyond its own uncertainty (the least-squares
//! covariance, widened for the residual's serial correlation: a smooth
//! residual at 1 kHz holds far fewer independent samples than it has).

use super::residual::{reg_features, Regression, Segment, CHANNELS, NREG, REG_FEATURES};

/// Regressors judged together: the lagged speeds as one static gain, every
/// other regressor alone.
pub const GROUPS: [&[usize]; 6] = [&[0], &[1], &[2, 3, 4, 5, 6], &[7], &[8], &[9]];
/// A change counts only beyond this many standard errors.
pub const CHANGE_SIGMAS: f64 = 3.0;

/// One group's change: its name, the file's and the log's value (the sum
/// of its coefficients), its held-out effect (RMS), its standard error.
pub struct GroupChange {
    pub name: String,
    pub base: f64,
    pub refit: f64,
    pub effect_rms: f64,
    pub sd: f64,
}

fn group_name(c: usize, g: &[usize]) -> String {
    match g {
        [j] => format!("{}[{}]", CHANNELS[c], REG_FEATURES[*j]),
        _ => format!(
            "{}[Σ {}…{}]",
            CHANNELS[c],
            REG_FEATURES[g[0]],
            REG_FEATURES[g[g.len() - 1]]
        ),
    }
}

/// Covariance of channel `c`'s re-fit coefficients `dc` on `train`
/// (`σ² (AᵀWA)⁻¹`, σ² from the weighted residual, times the AR(1)
/// variance factor `(1 + ρ) / (1 − ρ)` of the residual's lag-one
/// correlation ρ).
fn covariance(train: &[&Segment], r: &Regression, c: usize, dc: &[f64]) -> nalgebra::DMatrix<f64> {
    let mut ata = nalgebra::DMatrix::<f64>::zeros(NREG, NREG);
    let (mut ss, mut n, mut lag1, mut lag0) = (0.0, 0.0, 0.0, 0.0);
    for s in train {
        let Some(res) = &s.r[c] else { continue };
        let mut prev: Option<f64> = None;
        for (i, ri) in res.iter().enumerate() {
            let w2 = s.weight(c, i).powi(2);
            let f = reg_features(s, i, s.f_load[i], r.v_eps);
            let e = ri - f.iter().zip(dc).map(|(a, b)| a * b).sum::<f64>();
            let we = s.weight(c, i) * e;
            ss += we * we;
            n += 1.0;
            if let Some(p) = prev {
                lag1 += p * we;
                lag0 += p * p;
            }
            prev = Some(we);
            for a in 0..NREG {
                for b in 0..NREG {
                    ata[(a, b)] += w2 * f[a] * f[b];
                }
            }
        }
    }
    let rho = if lag0 > 0.0 { (lag1 / lag0).clamp(0.0, 0.999) } else { 0.0 };
    let sigma2 = ss / (n - NREG as f64).max(1.0) * (1.0 + rho) / (1.0 - rho);
    let d = ata.diagonal().map(|v| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 });
    let dm = nalgebra::DMatrix::from_diagonal(&d);
    let inv = (&dm * &ata * &dm)
        .pseudo_inverse(1e-12)
        .unwrap_or_else(|_| nalgebra::DMatrix::zeros(NREG, NREG));
    (&dm * inv * &dm) * sigma2
}

/// The groups of channel `c` (nominal coefficients `base`, re-fit
/// changes `dc`): their change, held-out effect and standard error.
pub fn group_changes(train: &[&Segment], held: &[&Segment], r: &Regression, c: usize, base: &[f64], dc: &[f64]) -> Vec<GroupChange> {
    let cov = covariance(train, r, c, dc);
    GROUPS
        .iter()
        .map(|g| {
            let (mut ss, mut n) = (0.0, 0.0);
            for s in held {
                for i in 0..s.len() {
                    let f = reg_features(s, i, s.f_load[i], r.v_eps);
                    // A group's effect is its static part: the summed change
                    // times the group's mean regressor (for the lagged
                    // speeds, the speed itself).
                    let x = g.iter().map(|j| f[*j]).sum::<f64>() / g.len() as f64;
                    ss += (x * g.iter().map(|j| dc[*j]).sum::<f64>()).powi(2);
                    n += 1.0;
                }
            }
            let var: f64 = g.iter().flat_map(|a| g.iter().map(move |b| (*a, *b))).map(|(a, b)| cov[(a, b)]).sum();
            GroupChange {
                name: group_name(c, g),
                base: g.iter().map(|j| base[*j]).sum(),
                refit: g.iter().map(|j| base[*j] + dc[*j]).sum(),
                effect_rms: (ss / f64::max(n, 1.0)).sqrt(),
                sd: var.max(0.0).sqrt(),
            }
        })
        .collect()
}

impl GroupChange {
    /// Changed: its effect reaches `share` of the nominal's RMS `nom` and
    /// the change is beyond `CHANGE_SIGMAS` standard errors.
    pub fn changed(&self, nom: f64, share: f64) -> bool {
        nom > 0.0 && self.effect_rms >= share * nom && (self.refit - self.base).abs() > CHANGE_SIGMAS * self.sd
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::residual::TORQUE;

    /// A 4 s segment whose reference speed is two sinusoids, its torque
    /// residual `dc · features` plus white noise of 0.01.
    fn segment(dc: &[f64], r: &Regression) -> Segment {
        let (n, dt) = (4000, 1e-3);
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let v_ref: Vec<f64> = t.iter().map(|t| 0.1 * (2.0 * t).sin() + 0.03 * (9.0 * t).sin()).collect();
        let mut s = Segment { t, v_ref, a_ref: vec![0.0; n], f_load: vec![0.0; n], dt, ..Default::default() };
        // A deterministic white-ish sequence (a fixed LCG), zero mean.
        let mut x: u64 = 12345;
        let res = (0..n)
            .map(|i| {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let noise = 0.01 * ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt();
                reg_features(&s, i, 0.0, r.v_eps).iter().zip(dc).map(|(a, b)| a * b).sum::<f64>() + noise
            })
            .collect();
        s.r[TORQUE] = Some(res);
        s
    }

    fn regression() -> Regression {
        let mut c = vec![0.0; NREG];
        c[2] = 10.0; // 10 A per m/s: the nominal's RMS ≈ 0.74 A
        Regression { v_eps: 0.005, torque_coef: c.clone(), position_coef: c }
    }

    /// Two neighbouring lags moved ±500 each: one by one both look changed
    /// by hundreds of times the nominal's RMS, together (the static gain)
    /// nothing changed.
    #[test]
    fn cancelling_lags_are_no_change() {
        let r = regression();
        let mut dc = vec![0.0; NREG];
        dc[3] = 500.0;
        dc[4] = -500.0;
        let s = segment(&dc, &r);
        let nom = 10.0 * (s.v_ref.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt();
        let g = group_changes(&[&s], &[&s], &r, TORQUE, &r.torque_coef, &dc);
        let speeds = g.iter().find(|g| g.name.contains('Σ')).expect("the speed group");
        assert!(speeds.effect_rms < 1e-9 && !speeds.changed(nom, 0.1), "effect {}", speeds.effect_rms);
        // Alone, either lag's effect is far beyond the share.
        let alone = 500.0 * (s.v_ref.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt();
        assert!(alone > 10.0 * nom);
        assert!(g.iter().all(|g| !g.changed(nom, 0.1)), "{:?}", g.iter().map(|g| &g.name).collect::<Vec<_>>());
    }

    /// A static gain 30 % higher, spread over two lags, is a change, with
    /// the summed value reported.
    #[test]
    fn a_static_gain_change_counts() {
        let r = regression();
        let mut dc = vec![0.0; NREG];
        dc[2] = 2.0;
        dc[5] = 1.0;
        let s = segment(&dc, &r);
        let nom = 10.0 * (s.v_ref.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt();
        let g = group_changes(&[&s], &[&s], &r, TORQUE, &r.torque_coef, &dc);
        let speeds = g.iter().find(|g| g.name.contains('Σ')).expect("the speed group");
        assert!((speeds.refit - 13.0).abs() < 1e-12 && (speeds.base - 10.0).abs() < 1e-12);
        assert!(speeds.changed(nom, 0.1), "effect {} of {nom}, sd {}", speeds.effect_rms, speeds.sd);
        assert!(g.iter().filter(|g| g.changed(nom, 0.1)).count() == 1);
    }
}
