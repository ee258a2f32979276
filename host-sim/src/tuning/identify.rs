//! Identification from captures: the rigid-body inverse dynamics at the
//! motor (`K_t i_q = J ω̇ + B ω + T_c sgn ω + T_load`, diagnose's nominal
//! model with its parameters free) by least squares, and the winding's R
//! and L (and ψ_f) from a q-current step.

use crate::diagnose::residual::Physics;
use anyhow::{bail, Context, Result};
use std::path::Path;

/// A capture as the host tool writes it: `t_s` (0 at the trigger) and one
/// column per signal, named as `host-sim drive capture` names them
/// (`current_q`, `speed`, `motor_position`, `voltage_q`, …).
#[derive(Clone, Debug)]
pub struct Capture {
    pub source: String,
    pub dt_s: f64,
    pub names: Vec<String>,
    pub columns: Vec<Vec<f64>>,
}

impl Capture {
    pub fn new(source: &str, dt_s: f64, names: Vec<String>, columns: Vec<Vec<f64>>) -> Self {
        Self { source: source.to_string(), dt_s, names, columns }
    }

    pub fn read_csv(path: &Path) -> Result<Self> {
        let mut r = csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
        let header: Vec<String> = r.headers()?.iter().map(|s| s.trim().to_string()).collect();
        let mut cols: Vec<Vec<f64>> = vec![Vec::new(); header.len()];
        for (row, rec) in r.records().enumerate() {
            let rec = rec?;
            for (c, cell) in rec.iter().enumerate().take(header.len()) {
                let v: f64 = cell.trim().parse().with_context(|| {
                    format!("{}:{}:{}: `{cell}` is not a number", path.display(), row + 1, header[c])
                })?;
                cols[c].push(v);
            }
        }
        let t_idx = header.iter().position(|h| h == "t_s" || h == "time_s").with_context(|| {
            format!("{}: no t_s column (the host tool's capture CSV starts with t_s)", path.display())
        })?;
        let t = &cols[t_idx];
        if t.len() < 16 {
            bail!("{}: {} samples, too few to identify from", path.display(), t.len());
        }
        let dt_s = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        if !(dt_s > 0.0) {
            bail!("{}: t_s does not increase", path.display());
        }
        let mut names = Vec::new();
        let mut columns = Vec::new();
        for (h, c) in header.into_iter().zip(cols) {
            if h != "t_s" && h != "time_s" {
                names.push(h);
                columns.push(c);
            }
        }
        Ok(Self::new(&path.display().to_string(), dt_s, names, columns))
    }

    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.names.iter().position(|n| n == name).map(|i| self.columns[i].as_slice())
    }

    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
        let mut h = vec!["t_s".to_string()];
        h.extend(self.names.iter().cloned());
        w.write_record(&h)?;
        for k in 0..self.len() {
            let mut r = vec![format!("{}", k as f64 * self.dt_s)];
            r.extend(self.columns.iter().map(|c| format!("{}", c[k])));
            w.write_record(&r)?;
        }
        w.flush()?;
        Ok(())
    }
}

/// Ordinary least squares `y ≈ X θ` with the parameters' standard errors.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LsFit {
    pub theta: Vec<f64>,
    /// `sqrt(σ² (XᵀX)⁻¹)_ii` with `σ²` the residual variance over `n − p`,
    /// scaled by `sqrt(correlation_length)`: the residual of filtered
    /// signals is correlated over about that many samples, so the samples
    /// are not independent.
    pub std_err: Vec<f64>,
    pub rms_residual: f64,
    /// `1 − Σr² / Σ(y − ȳ)²`.
    pub r2: f64,
    pub samples: usize,
    pub correlation_length: f64,
}

pub fn least_squares(x: &[Vec<f64>], y: &[f64], correlation_length: f64) -> Result<LsFit> {
    let p = x.first().map_or(0, Vec::len);
    let n = y.len();
    if n <= p + 2 {
        bail!("{n} samples for {p} parameters");
    }
    let a = nalgebra::DMatrix::from_fn(n, p, |i, j| x[i][j]);
    let b = nalgebra::DVector::from_column_slice(y);
    // Column scaling: the regressors span decades (α ~ 1e4, sgn ~ 1).
    let scale: Vec<f64> = (0..p).map(|j| a.column(j).norm().max(1e-300)).collect();
    let a_s = nalgebra::DMatrix::from_fn(n, p, |i, j| a[(i, j)] / scale[j]);
    let ata = a_s.transpose() * &a_s;
    let inv = ata.clone().try_inverse().context("regressors collinear: the capture does not excite every parameter")?;
    let cond = {
        let e = ata.symmetric_eigenvalues();
        e.max() / e.min().max(1e-300)
    };
    if cond > 1e12 {
        bail!("regressors nearly collinear (condition {cond:.1e})");
    }
    let th_s = &inv * a_s.transpose() * &b;
    let theta: Vec<f64> = (0..p).map(|j| th_s[j] / scale[j]).collect();
    let r = &b - &a * nalgebra::DVector::from_column_slice(&theta);
    let ss_r = r.norm_squared();
    let mean = y.iter().sum::<f64>() / n as f64;
    let ss_t: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    let sigma2 = ss_r / (n - p) as f64;
    let std_err = (0..p).map(|j| (sigma2 * inv[(j, j)] * correlation_length.max(1.0)).sqrt() / scale[j]).collect();
    Ok(LsFit {
        theta,
        std_err,
        rms_residual: (ss_r / n as f64).sqrt(),
        r2: if ss_t > 0.0 { 1.0 - ss_r / ss_t } else { 0.0 },
        samples: n,
        correlation_length: correlation_length.max(1.0),
    })
}

/// Zero-phase low-pass: a 2nd-order Butterworth forward and backward
/// (4th order, no delay), edges padded with the end values.
pub fn filtfilt(y: &[f64], corner_hz: f64, dt: f64) -> Vec<f64> {
    let n = y.len();
    if n == 0 || !(corner_hz > 0.0) || corner_hz >= 0.45 / dt {
        return y.to_vec();
    }
    let k = (std::f64::consts::PI * corner_hz * dt).tan();
    let q = std::f64::consts::FRAC_1_SQRT_2;
    let norm = 1.0 / (1.0 + k / q + k * k);
    let b0 = k * k * norm;
    let (b1, b2) = (2.0 * b0, b0);
    let a1 = 2.0 * (k * k - 1.0) * norm;
    let a2 = (1.0 - k / q + k * k) * norm;
    let pad = ((3.0 / (corner_hz * dt)).ceil() as usize).min(20 * n);
    let run = |x: &[f64]| -> Vec<f64> {
        let (mut z1, mut z2) = (x[0] * (1.0 - b0), x[0] * (b2 - a2));
        // Transposed direct form II, started settled at x[0].
        x.iter()
            .map(|&v| {
                let out = b0 * v + z1;
                z1 = b1 * v - a1 * out + z2;
                z2 = b2 * v - a2 * out;
                out
            })
            .collect()
    };
    let mut ext = Vec::with_capacity(n + 2 * pad);
    ext.extend(std::iter::repeat_n(y[0], pad));
    ext.extend_from_slice(y);
    ext.extend(std::iter::repeat_n(y[n - 1], pad));
    let mut f = run(&ext);
    f.reverse();
    let mut g = run(&f);
    g.reverse();
    g[pad..pad + n].to_vec()
}

/// First derivative by a quadratic Savitzky–Golay window of ±m samples
/// (the smoothing differentiator of diagnose's residual), one-sided
/// shrinking windows at the edges.
pub fn sg_derivative(y: &[f64], m: usize, dt: f64) -> Vec<f64> {
    let n = y.len();
    (0..n)
        .map(|i| {
            let h = m.min(i).min(n - 1 - i);
            if h == 0 {
                let (a, b) = if i + 1 < n { (i, i + 1) } else { (i.saturating_sub(1), i) };
                return if a == b { 0.0 } else { (y[b] - y[a]) / dt };
            }
            let s: f64 = (1..=h).map(|k| k as f64 * (y[i + k] - y[i - k])).sum();
            let d: f64 = (1..=h).map(|k| 2.0 * (k * k) as f64).sum();
            s / d / dt
        })
        .collect()
}

/// Options of the mechanical identification.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MechOptions {
    /// Zero-phase low-pass corner applied alike to the torque and to every
    /// regressor (the model is linear in them, so the relation holds
    /// filtered): it keeps the rigid-body band and cuts the rod's axial mode
    /// (≈ 29 Hz) the rigid model does not have.
    pub filter_hz: f64,
    /// A direction counts as excited once the filtered speed passes this.
    pub min_speed_rad_s: f64,
    /// Below this (raw) speed a sample is at rest: the friction there is
    /// one unknown per capture, not the Coulomb law.
    pub rest_speed_rad_s: f64,
    /// Sign regularisation `tanh(ω/ε)` of the Coulomb term (as diagnose).
    pub sign_eps_rad_s: f64,
}

impl Default for MechOptions {
    fn default() -> Self {
        Self { filter_hz: 8.0, min_speed_rad_s: 5.0, rest_speed_rad_s: 1.0, sign_eps_rad_s: 0.5 }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Estimate {
    pub value: f64,
    pub std_err: f64,
}

/// The mechanics as identified, at the motor shaft.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MechId {
    /// Torque constant used to turn current into torque (from the
    /// parameters, or identified from a current step).
    pub kt_n_m_a: f64,
    pub inertia_kg_m2: Estimate,
    pub viscous_n_m_s_rad: Estimate,
    /// `None` when every capture moved one way only: Coulomb friction and a
    /// constant load are then the same regressor (the constant holds both).
    pub coulomb_n_m: Option<Estimate>,
    /// Constant torque: gravity load (+ Coulomb friction when it is not
    /// separable).
    pub load_n_m: Estimate,
    pub fit: LsFit,
    pub options: MechOptions,
    pub captures: Vec<String>,
    pub note: String,
}

/// Speed of a capture: `speed`, else the derivative of `motor_position`
/// (m, through `metres_per_rad`).
fn speed_of(c: &Capture, metres_per_rad: f64) -> Result<Vec<f64>> {
    if let Some(w) = c.get("speed") {
        return Ok(w.to_vec());
    }
    if let Some(x) = c.get("motor_position") {
        let th: Vec<f64> = x.iter().map(|v| v / metres_per_rad).collect();
        let m = ((0.002 / c.dt_s).round() as usize).max(1);
        return Ok(sg_derivative(&th, m, c.dt_s));
    }
    bail!("{}: neither `speed` nor `motor_position`", c.source)
}

/// `K_t i_q = J ω̇ + B ω + T_c sgn ω + T_load` over the captures jointly.
///
/// Every signal and regressor goes through the same zero-phase low-pass
/// (the relation is linear in them, so it holds filtered). At rest the
/// friction holds whatever torque the last motion left (statically
/// indeterminate, anything up to breakaway): no law predicts it, and the
/// filter would smear that error into the motion that follows, where the
/// acceleration is largest (it biased J by −11 % at an 8 Hz corner). So
/// each capture's rest samples get their own unknown torque (a filtered
/// rest indicator per capture), and the Coulomb law acts only while moving.
pub fn identify_mechanics(caps: &[Capture], kt: f64, metres_per_rad: f64, o: &MechOptions) -> Result<MechId> {
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut y = Vec::new();
    let mut any_pos = false;
    let mut any_neg = false;
    let mut corr = 1.0f64;
    let nc = caps.len();
    for (ci, c) in caps.iter().enumerate() {
        let iq = c.get("current_q").with_context(|| format!("{}: no `current_q` column", c.source))?;
        let w = speed_of(c, metres_per_rad)?;
        let dt = c.dt_s;
        let torque = filtfilt(&iq.iter().map(|i| kt * i).collect::<Vec<_>>(), o.filter_hz, dt);
        let wf = filtfilt(&w, o.filter_hz, dt);
        // The derivative of the filtered speed: the filter is the smoothing,
        // the central difference over ±1 sample adds no further lag.
        let alpha = sg_derivative(&wf, 1, dt);
        let moving: Vec<f64> = w.iter().map(|v| if v.abs() >= o.rest_speed_rad_s { 1.0 } else { 0.0 }).collect();
        let sgn = filtfilt(&w.iter().zip(&moving).map(|(v, m)| m * (v / o.sign_eps_rad_s).tanh()).collect::<Vec<_>>(), o.filter_hz, dt);
        let rest = filtfilt(&moving.iter().map(|m| 1.0 - m).collect::<Vec<_>>(), o.filter_hz, dt);
        corr = corr.max(1.0 / (2.0 * o.filter_hz * dt));
        for k in 0..c.len() {
            if wf[k].abs() >= o.min_speed_rad_s {
                any_pos |= wf[k] > 0.0;
                any_neg |= wf[k] < 0.0;
            }
            let mut r = vec![alpha[k], wf[k], sgn[k], 1.0];
            r.extend((0..nc).map(|j| if j == ci { rest[k] } else { 0.0 }));
            rows.push(r);
            y.push(torque[k]);
        }
    }
    let moving_samples = rows.iter().filter(|r| r[1].abs() >= o.min_speed_rad_s).count();
    if moving_samples < 20 {
        bail!("{moving_samples} samples faster than {} rad/s: nothing moved enough to identify from", o.min_speed_rad_s);
    }
    let both = any_pos && any_neg;
    if !both {
        for r in &mut rows {
            r.remove(2);
        }
    }
    let fit = least_squares(&rows, &y, corr)?;
    let est = |j: usize| Estimate { value: fit.theta[j], std_err: fit.std_err[j] };
    let (coulomb, load) = if both { (Some(est(2)), est(3)) } else { (None, est(2)) };
    let note = if both {
        "both directions: Coulomb friction and the constant load separate".to_string()
    } else {
        "one direction only: Coulomb friction is inside the constant (capture a step each way to separate them)"
            .to_string()
    };
    Ok(MechId {
        kt_n_m_a: kt,
        inertia_kg_m2: est(0),
        viscous_n_m_s_rad: est(1),
        coulomb_n_m: coulomb,
        load_n_m: load,
        fit,
        options: o.clone(),
        captures: caps.iter().map(|c| c.source.clone()).collect(),
        note,
    })
}

/// The winding as identified from a current step.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ElecId {
    pub resistance_ohm: Estimate,
    pub inductance_h: Estimate,
    /// From the back-EMF term when the rotor turned during a q step.
    pub flux_linkage_wb: Option<Estimate>,
    pub fit: LsFit,
    pub source: String,
    /// `d` or `q`: the axis the step ran on.
    pub axis: String,
    /// How R was found, and what to trust it for.
    pub note: String,
}

/// Below this speed (rad/s, mean over the pre-trigger share) a rotor
/// counts as standing: the back-EMF `p ψ ω` is then under 0.5 % of the
/// resistive drop of a 1 A hold current on the shipped motor; the PLL's
/// sample-to-sample noise is larger than this and averages out.
const STANDING_MEAN_SPEED_RAD_S: f64 = 0.5;

/// From a current step sampled every PWM period. The voltage computed at
/// sample n acts over period n+1 (computation, then the PWM's update), so
/// `v_{n−1} = R (i_n + i_{n+1})/2 + L (i_{n+1} − i_n)/T (+ p ψ ω_n on q)`.
///
/// - **d axis** (`current_d`, `voltage_d`; `host-sim drive step current-d`):
///   no torque, so the rotor stands and no back-EMF enters; R and L are
///   fitted jointly with a constant (a fixed voltage error of the inverter or
///   the sensing), R from the plateau against the rest before the step.
/// - **q axis** (`current_q`, `voltage_q`): the step accelerates the rotor;
///   R comes from the standstill before it (`v = R i` under a hold current
///   of ≥ 1 A), else from a joint fit with ψ, which trades R against ψ while
///   the rotor accelerates (+10 % on the nominal rig, +24 % on a rig holding
///   a 6 kg payload): the note says so.
pub fn identify_electrical(c: &Capture, pole_pairs: f64, pwm_period_s: f64, filter_hz: f64) -> Result<ElecId> {
    if (c.dt_s - pwm_period_s).abs() > 0.01 * pwm_period_s {
        bail!(
            "{}: sampled every {:.1} µs; R and L need every PWM period ({:.1} µs, decimation 1)",
            c.source,
            c.dt_s * 1e6,
            pwm_period_s * 1e6
        );
    }
    let axis_d = c.get("current_d").is_some() && c.get("voltage_d").is_some();
    let (i, v) = if axis_d {
        (c.get("current_d").unwrap_or_default(), c.get("voltage_d").unwrap_or_default())
    } else {
        (
            c.get("current_q").with_context(|| format!("{}: neither `current_d` and `voltage_d` nor `current_q`", c.source))?,
            c.get("voltage_q").with_context(|| format!("{}: no `voltage_q`", c.source))?,
        )
    };
    let dt = c.dt_s;
    let n = c.len();
    let w = c.get("speed").map(<[f64]>::to_vec).unwrap_or_else(|| vec![0.0; n]);
    let turned = {
        let (lo, hi) = w.iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
        hi - lo > 5.0
    };
    if axis_d && turned {
        bail!(
            "{}: the rotor turned during the d-axis step (speed spans more than 5 rad/s): hold it still (brake closed or the position loop holding) and capture again",
            c.source
        );
    }
    // The relation holds sample by sample between sequences; the same
    // zero-phase low-pass on each keeps it and takes the current sensor's
    // noise out of the difference regressor (noise in a regressor biases
    // its coefficient towards zero).
    let y = filtfilt(&(1..n - 1).map(|k| v[k - 1]).collect::<Vec<_>>(), filter_hz, dt);
    let x1 = filtfilt(&(1..n - 1).map(|k| 0.5 * (i[k] + i[k + 1])).collect::<Vec<_>>(), filter_hz, dt);
    let x2 = filtfilt(&(1..n - 1).map(|k| (i[k + 1] - i[k]) / dt).collect::<Vec<_>>(), filter_hz, dt);
    let x3 = filtfilt(&(1..n - 1).map(|k| pole_pairs * w[k]).collect::<Vec<_>>(), filter_hz, dt);
    let corr = 1.0 / (2.0 * filter_hz * dt);
    if axis_d {
        let rows: Vec<Vec<f64>> = (0..y.len()).map(|k| vec![x1[k], x2[k], 1.0]).collect();
        let fit = least_squares(&rows, &y, corr)?;
        let est = |j: usize| Estimate { value: fit.theta[j], std_err: fit.std_err[j] };
        return Ok(ElecId {
            resistance_ohm: est(0),
            inductance_h: est(1),
            flux_linkage_wb: None,
            fit,
            source: c.source.clone(),
            axis: "d".into(),
            note: "d-axis step at standstill: R and L with a constant voltage error, no back-EMF".into(),
        });
    }
    // R from the standstill before the step, where `v = R i` holds alone
    // (no di/dt, no back-EMF): the pre-trigger share of the capture (its
    // first 1/12), if the rotor stood and a hold current flowed.
    let rest = n / 12;
    let mean_w = w[..rest.max(1)].iter().sum::<f64>() / rest.max(1) as f64;
    let standing = rest > 8 && mean_w.abs() < STANDING_MEAN_SPEED_RAD_S;
    let (si, sv) = (i[..rest].iter().sum::<f64>(), v[..rest].iter().sum::<f64>());
    let static_r = (standing && (si / rest as f64).abs() > 1.0).then(|| {
        let r = sv / si;
        let scatter = (v[..rest].iter().zip(&i[..rest]).map(|(v, i)| (v - r * i).powi(2)).sum::<f64>() / rest as f64).sqrt();
        Estimate { value: r, std_err: scatter / (si.abs() / (rest as f64).sqrt()) }
    });
    let fixed_r = static_r.as_ref().map_or(0.0, |e| e.value);
    let y: Vec<f64> = if static_r.is_some() { y.iter().zip(&x1).map(|(y, x)| y - fixed_r * x).collect() } else { y };
    let rows: Vec<Vec<f64>> = (0..y.len())
        .map(|k| {
            let mut r = if static_r.is_some() { vec![] } else { vec![x1[k]] };
            r.push(x2[k]);
            if turned {
                r.push(x3[k]);
            }
            r
        })
        .collect();
    let fit = least_squares(&rows, &y, corr)?;
    let est = |j: usize| Estimate { value: fit.theta[j], std_err: fit.std_err[j] };
    let o = usize::from(static_r.is_none());
    let note = if static_r.is_some() {
        "q-axis step: R from the hold current at standstill before the step".to_string()
    } else {
        "q-axis step without a standing hold current of ≥ 1 A: R fitted jointly with ψ while the rotor accelerated, biased high (capture `drive step current-d` instead)".to_string()
    };
    Ok(ElecId {
        resistance_ohm: static_r.unwrap_or_else(|| est(0)),
        inductance_h: est(o),
        flux_linkage_wb: if turned { Some(est(o + 1)) } else { None },
        fit,
        source: c.source.clone(),
        axis: "q".into(),
        note,
    })
}

/// Below this speed (rad/s) a speed-step sample does not enter the flux
/// fit: the back-EMF there is under 2.5 % of the hold current's resistive
/// drop's scatter, and the PLL's noise dominates.
const FLUX_MIN_SPEED_RAD_S: f64 = 10.0;

/// The magnet flux linkage from motion captures that carry `voltage_q`,
/// `current_q` and `speed` (the identification's speed steps), with the
/// winding's R and L known (the d-axis step): `v_q − R i_q − L di_q/dt =
/// p ψ ω` on every sample faster than 10 rad/s, one coefficient by least
/// squares. The drive's own belief of ψ sets its torque constant
/// (`1.5 p ψ`) and its back-EMF feedforward; a unit whose magnets carry less
/// flux (hot, or a weaker batch) is then driven with both wrong. `None`
/// when no capture has the columns or nothing moved.
pub fn identify_flux(caps: &[Capture], pole_pairs: f64, r_ohm: f64, l_h: f64) -> Result<Option<Estimate>> {
    let mut rows = Vec::new();
    let mut y = Vec::new();
    for c in caps {
        let (Some(v), Some(i), Some(w)) = (c.get("voltage_q"), c.get("current_q"), c.get("speed")) else {
            continue;
        };
        let di = sg_derivative(i, 2, c.dt_s);
        for k in 0..c.len() {
            if w[k].abs() >= FLUX_MIN_SPEED_RAD_S {
                rows.push(vec![pole_pairs * w[k]]);
                y.push(v[k] - r_ohm * i[k] - l_h * di[k]);
            }
        }
    }
    if rows.len() < 20 {
        return Ok(None);
    }
    let fit = least_squares(&rows, &y, 1.0)?;
    Ok(Some(Estimate { value: fit.theta[0], std_err: fit.std_err[0] }))
}

/// The nominal values diagnose's model holds for the same quantities (the
/// rig's `[plant]`), for a check.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NominalMech {
    pub inertia_kg_m2: f64,
    pub viscous_n_m_s_rad: f64,
    /// Drag + seal + screw efficiency friction under `load_n`.
    pub coulomb_n_m: f64,
    pub load_n_m: f64,
}

pub fn nominal_mech(ph: &Physics, load_n: f64) -> NominalMech {
    NominalMech {
        inertia_kg_m2: ph.j_eq(),
        viscous_n_m_s_rad: ph.b_rot,
        coulomb_n_m: ph.drag_n_m + ph.k * ph.rod_coulomb_n + ph.mu * ph.k * load_n.abs(),
        load_n_m: ph.k * load_n,
    }
}
