//! The cylinder's axial compliance against the rig file's, from a test the
//! drive can run on its own: a q-current step above the hold current with
//! the speed and position loops suspended, so that the load is thrown up
//! for a moment and the drive train rings at its axial mode. The motor
//! speed's ringing frequency goes as `√(k / m)`: compared with the same test
//! on the rig file's design, at the payload the hold current says, it gives
//! the stiffness ratio and so the compliance ratio `c = k₀ / k`.
//!
//! The observer's deformation is static (docs/observer-figures.md, "Where the rest
//! of the error is"), so weights trained at the design's stiffness scaled
//! by `c` predict a softer or stiffer cylinder's deformation.
//!
//! A speed-loop chirp does not resolve the mode (the closed loop and the
//! screw's friction hide it). A step below the hold current lets the load
//! fall for the whole step: when the speed loop takes over again it is far
//! from its reference and latches `speed_following`.
//!
//! This file is the analysis of the captures and the ratio with its
//! uncertainty; `tool::stiffness` runs the probe on a drive through the
//! protocol (a board, or a simulated drive for the design and the bench).

use crate::config::RigConfig;
use anyhow::{bail, Result};
use servo_core::observer::block::Weights;

/// The step from the hold current (A) and how long it lasts (s). It is
/// the step the simulator's probe took at the rig file's payload (the hold
/// current there less 6 A), where the ratio reads within 3.5 % on the
/// ±15 % stiffness rigs.
pub const STEP_A: f64 = 4.5;
pub const STEP_S: f64 = 0.08;
/// The edge's transient left out before the ringing is read (s).
const SKIP_S: f64 = 0.004;
/// A measured ratio this close to 1 is within the test's resolution: on
/// the development rigs (seed 6600) the rig file's own rig read 1.004, and
/// rigs of the same stiffness with 30 % more friction, ±10 % payload or a
/// lead error read 0.986–1.004 (friction shifts the ringing a little).
/// Within it the design's stiffness is kept.
pub const RESOLUTION: f64 = 0.02;
/// Where the axial mode is looked for (Hz).
pub const BAND_HZ: (f64, f64) = (15.0, 90.0);
/// Probes per identification: the spread of their frequencies is part of
/// the uncertainty.
pub const REPEATS: usize = 3;
/// The probe needs the load hanging on the rod: below this hold current
/// (A) there is no weight to lower (a horizontal or unloaded rod).
pub const HOLD_MIN_A: f64 = 1.0;
/// A ringing whose amplitude is below this many times the residual's RMS
/// is not read. The simulated rigs ring at about 3 times it (the residual
/// holds the ringing's decay, which a steady sinusoid does not fit); the
/// strongest line of white noise alone reaches a tenth of it.
pub const RING_TO_NOISE_MIN: f64 = 1.5;
/// Repeats whose frequencies spread more than this (relative standard
/// deviation) disagree: something else moved the mode.
pub const SPREAD_MAX: f64 = 0.03;
/// A ratio whose standard uncertainty is above this is not applied: the
/// shipped weights' stiffness bars allow ±15 % unscaled.
pub const RATIO_UNCERTAINTY_MAX: f64 = 0.05;
/// The method's own error on the ratio (relative), beside the noise: on
/// the simulated ±15 % stiffness rigs the probe reads the ratio 3.5–4 %
/// off the truth while its repeats agree within 0.5 % (the short, damped
/// window biases the peak). It is part of the stated uncertainty.
pub const METHOD_ERROR: f64 = 0.04;
/// Room the probe needs on either side of the rod, per repeat (m): the
/// load moves ≈ 7 mm on the rig file's rig, twice that is kept.
pub const DROP_ROOM_M: f64 = 0.015;

/// One probe's reading.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Ring {
    /// Ringing frequency of the motor speed (Hz).
    pub mode_hz: f64,
    /// Its standard uncertainty from the fit (the Cramér–Rao bound of a
    /// sinusoid's frequency in white noise at the measured amplitude and
    /// residual), Hz.
    pub fit_std_hz: f64,
    /// The ringing's amplitude and the residual's RMS (rad/s).
    pub ring_rad_s: f64,
    pub residual_rad_s: f64,
    /// Mean q current over the capture's record before the step (A).
    pub hold_a: f64,
}

/// Several probes on one unit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Rings {
    pub mode_hz: f64,
    /// Standard uncertainty of `mode_hz`: the larger of the repeats'
    /// standard error and the fits' own.
    pub std_hz: f64,
    /// Relative standard deviation of the repeats.
    pub spread: f64,
    pub hold_a: f64,
    pub probes: Vec<Ring>,
}

/// One identification.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ComplianceId {
    /// Ringing of the cylinder and of the design at the same payload (Hz),
    /// with their standard uncertainties.
    pub mode_hz: f64,
    pub mode_std_hz: f64,
    pub design_mode_hz: f64,
    pub design_mode_std_hz: f64,
    /// Hold currents before the step: the cylinder's and the design's at
    /// its own payload (A).
    pub hold_a: f64,
    pub design_hold_a: f64,
    /// The design's payload scaled to match the hold current.
    pub payload_scale: f64,
    /// `k₀ / k = (f₀ / f)²`, as measured; the standard uncertainty from
    /// the noise (repeats and fits), and with the method's own error
    /// ([`METHOD_ERROR`]) added.
    pub measured_ratio: f64,
    pub ratio_std: f64,
    pub ratio_uncertainty: f64,
    /// What the drive applies: the measured ratio, or 1 within [`RESOLUTION`].
    pub compliance_ratio: f64,
}

/// Reads one probe's capture: `speed` (rad/s) and `current_q` (A) sampled
/// every `dt` s, the step at `trigger`. Refuses a capture that does not
/// show a readable axial mode, saying why.
pub fn ring_of(speed: &[f64], current_q: &[f64], dt: f64, trigger: usize) -> Result<Ring> {
    if trigger == 0 || trigger > current_q.len() {
        bail!("the capture has no record before the step (trigger at sample {trigger})");
    }
    let hold_a = current_q[..trigger].iter().sum::<f64>() / trigger as f64;
    let from = trigger + (SKIP_S / dt).round() as usize;
    let to = (trigger + (STEP_S / dt) as usize).min(speed.len());
    if to < from + 50 {
        bail!("the capture holds {} samples of the step; 50 are needed", to.saturating_sub(from));
    }
    let t: Vec<f64> = (from..to).map(|k| (k - from) as f64 * dt).collect();
    let r = detrended(&t, &speed[from..to]);
    let mode_hz = peak_hz(&t, &r);
    let edge = 0.5;
    if mode_hz <= BAND_HZ.0 + edge || mode_hz >= BAND_HZ.1 - edge {
        bail!(
            "the strongest ringing is at {mode_hz:.1} Hz, the edge of the {:.0}–{:.0} Hz band: no axial mode inside it",
            BAND_HZ.0,
            BAND_HZ.1
        );
    }
    let (amp, residual) = sinusoid_fit(&t, &r, mode_hz);
    if amp < RING_TO_NOISE_MIN * residual {
        bail!(
            "the ringing ({amp:.3} rad/s at {mode_hz:.1} Hz) is under {RING_TO_NOISE_MIN} times the residual ({residual:.3} rad/s RMS): too weak to read"
        );
    }
    // Cramér–Rao: var(ω) = 12 σ² / (A² N (N² − 1)) per sample² (ω in rad
    // per sample), σ the residual's RMS.
    let n = t.len() as f64;
    let fit_std_hz = (12.0 / (n * (n * n - 1.0))).sqrt() * residual / amp / (std::f64::consts::TAU * dt);
    Ok(Ring { mode_hz, fit_std_hz, ring_rad_s: amp, residual_rad_s: residual, hold_a })
}

/// The repeats of one unit, refused when they disagree.
pub fn combine(probes: Vec<Ring>) -> Result<Rings> {
    let n = probes.len();
    if n == 0 {
        bail!("no probe was read");
    }
    let mean = probes.iter().map(|r| r.mode_hz).sum::<f64>() / n as f64;
    let sd = if n > 1 { (probes.iter().map(|r| (r.mode_hz - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt() } else { 0.0 };
    let spread = sd / mean;
    if spread > SPREAD_MAX {
        let list: Vec<String> = probes.iter().map(|r| format!("{:.2}", r.mode_hz)).collect();
        bail!(
            "the probes disagree: {} Hz spread {:.1} % (at most {:.0} %): the mode moved between them (the rod's position, the load or a contact changed)",
            list.join(", "),
            100.0 * spread,
            100.0 * SPREAD_MAX
        );
    }
    let fit = (probes.iter().map(|r| r.fit_std_hz.powi(2)).sum::<f64>()).sqrt() / n as f64;
    let std_hz = (sd / (n as f64).sqrt()).max(fit);
    let hold_a = probes.iter().map(|r| r.hold_a).sum::<f64>() / n as f64;
    Ok(Rings { mode_hz: mean, std_hz, spread, hold_a, probes })
}

/// The design's payload scale whose moving mass the cylinder's hold
/// current `hold_a` carries, against the design's own `design_hold_a`.
pub fn payload_scale(design: &RigConfig, hold_a: f64, design_hold_a: f64) -> Result<f64> {
    if hold_a < HOLD_MIN_A {
        bail!("the hold current is {hold_a:.2} A (at least {HOLD_MIN_A} A): the probe needs the load hanging on the rod, rod vertical with its payload");
    }
    let p = &design.plant;
    let (payload, rest) = (p.rod.payload_mass_kg, p.moving_mass_kg() - p.rod.payload_mass_kg);
    let s = ((hold_a / design_hold_a) * (payload + rest) - rest) / payload;
    if !(0.5..=1.5).contains(&s) {
        bail!("hold current {hold_a:.2} A against the design's {design_hold_a:.2} A: the payload is not within ±50 % of the rig file's");
    }
    Ok(s)
}

/// The ratio from the cylinder's rings and the design's at the matched
/// payload; refused when its uncertainty is beyond [`RATIO_UNCERTAINTY_MAX`].
pub fn compliance(cylinder: &Rings, design_hold_a: f64, payload_scale: f64, design: &Rings) -> Result<ComplianceId> {
    let measured_ratio = (design.mode_hz / cylinder.mode_hz).powi(2);
    let ratio_std = 2.0 * measured_ratio * ((cylinder.std_hz / cylinder.mode_hz).powi(2) + (design.std_hz / design.mode_hz).powi(2)).sqrt();
    if ratio_std > RATIO_UNCERTAINTY_MAX {
        bail!(
            "the compliance ratio {measured_ratio:.3} is uncertain by ±{ratio_std:.3} (at most ±{RATIO_UNCERTAINTY_MAX}): the ringing is too noisy to scale the weights by"
        );
    }
    let compliance_ratio = if (measured_ratio - 1.0).abs() <= RESOLUTION { 1.0 } else { measured_ratio };
    let ratio_uncertainty = ratio_std.hypot(METHOD_ERROR * measured_ratio);
    Ok(ComplianceId {
        mode_hz: cylinder.mode_hz,
        mode_std_hz: cylinder.std_hz,
        design_mode_hz: design.mode_hz,
        design_mode_std_hz: design.std_hz,
        hold_a: cylinder.hold_a,
        design_hold_a,
        payload_scale,
        measured_ratio,
        ratio_std,
        ratio_uncertainty,
        compliance_ratio,
    })
}

/// `w` with its prediction scaled by `k` (output scale and offset): the
/// static deformation it predicts goes with the compliance.
pub fn scaled_weights(w: &Weights, k: f64) -> Weights {
    let mut s = *w;
    s.output_scale = (f64::from(s.output_scale) * k) as f32;
    s.output_offset = (f64::from(s.output_offset) * k) as f32;
    s
}

/// The compliance of `rig` (a cylinder, with its own `[control]`) against
/// `design` (the rig file it was built to), both probed on simulated drives
/// through the host tool's own probe (`tool::stiffness`).
pub fn identify_compliance(rig: &RigConfig, design: &RigConfig, seed: u64) -> Result<ComplianceId> {
    crate::tool::stiffness::identify_simulated(rig, design, seed)
}

/// `y` less its quadratic trend in `t` (the rigid body's acceleration).
fn detrended(t: &[f64], y: &[f64]) -> Vec<f64> {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut aty = nalgebra::Vector3::<f64>::zeros();
    for (&ti, &yi) in t.iter().zip(y) {
        let v = nalgebra::Vector3::new(1.0, ti, ti * ti);
        ata += v * v.transpose();
        aty += v * yi;
    }
    let c = ata.try_inverse().map_or(nalgebra::Vector3::zeros(), |inv| inv * aty);
    t.iter().zip(y).map(|(&ti, &yi)| yi - c[0] - c[1] * ti - c[2] * ti * ti).collect()
}

/// The strongest frequency in `BAND_HZ` of `r`, on a 0.02 Hz grid.
fn peak_hz(t: &[f64], r: &[f64]) -> f64 {
    let mut best = (BAND_HZ.0, 0.0);
    let steps = ((BAND_HZ.1 - BAND_HZ.0) / 0.02).round() as usize;
    for k in 0..=steps {
        let f = BAND_HZ.0 + 0.02 * k as f64;
        let w = std::f64::consts::TAU * f;
        let (mut a, mut b) = (0.0, 0.0);
        for (&ti, &ri) in t.iter().zip(r) {
            a += ri * (w * ti).cos();
            b += ri * (w * ti).sin();
        }
        if a * a + b * b > best.1 {
            best = (f, a * a + b * b);
        }
    }
    best.0
}

/// Least-squares amplitude of a sinusoid at `f_hz` in `r`, and the RMS of
/// what it leaves.
fn sinusoid_fit(t: &[f64], r: &[f64], f_hz: f64) -> (f64, f64) {
    let w = std::f64::consts::TAU * f_hz;
    let mut ata = nalgebra::Matrix2::<f64>::zeros();
    let mut aty = nalgebra::Vector2::<f64>::zeros();
    for (&ti, &ri) in t.iter().zip(r) {
        let v = nalgebra::Vector2::new((w * ti).cos(), (w * ti).sin());
        ata += v * v.transpose();
        aty += v * ri;
    }
    let c = ata.try_inverse().map_or(nalgebra::Vector2::zeros(), |inv| inv * aty);
    let ss: f64 = t.iter().zip(r).map(|(&ti, &ri)| (ri - c[0] * (w * ti).cos() - c[1] * (w * ti).sin()).powi(2)).sum();
    (c.norm(), (ss / t.len() as f64).sqrt())
}
