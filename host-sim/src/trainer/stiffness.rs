//! The cylinder's axial compliance against the rig file's, from a test the
//! drive can run on its own: a q-current step below the hold current with
//! the speed and position loops suspended, so that the load lowers freely
//! for a moment and the drive train rings at its axial mode. The motor
//! speed's ringing frequency goes as `√(k / m)`: compared with the same test
//! on the rig file's design, at the payload the hold current says, it gives
//! the stiffness ratio and so the compliance ratio `c = k₀ / k`.
//!
//! The observer's deformation is static (docs/observer.md, "Where the rest
//! of the error is"), so weights trained at the design's stiffness scaled
//! by `c` predict a softer or stiffer cylinder's deformation.
//!
//! A speed-loop chirp does not resolve the mode (the closed loop and the
//! screw's friction hide it), and a step above the hold current does not
//! break the screw's static friction: the lowering step does both.

use crate::config::RigConfig;
use crate::tuning::simcheck::{holding, run_test, Loop, TestSpec};
use crate::tuning::X0_M;
use anyhow::{bail, Context, Result};

/// The step below the hold current (A) and how long it lasts (s): the load
/// lowers ≈ 7 mm on the rig file's rig.
pub const STEP_BELOW_HOLD_A: f64 = 6.0;
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
const BAND_HZ: (f64, f64) = (15.0, 90.0);

/// One identification.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ComplianceId {
    /// Ringing of the cylinder and of the design at the same payload (Hz).
    pub mode_hz: f64,
    pub design_mode_hz: f64,
    /// Hold currents before the step: the cylinder's and the design's at
    /// its own payload (A).
    pub hold_a: f64,
    pub design_hold_a: f64,
    /// The design's payload scaled to match the hold current.
    pub payload_scale: f64,
    /// `k₀ / k = (f₀ / f)²`, as measured.
    pub measured_ratio: f64,
    /// What the drive applies: the measured ratio, or 1 within [`RESOLUTION`].
    pub compliance_ratio: f64,
}

/// The ringing frequency (Hz) and the hold current (A) of the lowering step
/// on `rig`.
fn ring(rig: &RigConfig, seed: u64) -> Result<(f64, f64)> {
    let mut cl = holding(rig, rig.control, X0_M, seed)?;
    let hold = f64::from(cl.controller.telemetry().current_q_a);
    let spec = TestSpec { decimation: 4, ..TestSpec::step(Loop::Current, hold - STEP_BELOW_HOLD_A, STEP_S) };
    let c = run_test(&mut cl, &spec).context("the lowering current step")?;
    let y = c.capture.get("speed").context("the capture has no speed")?;
    let dt = c.capture.dt_s;
    let from = c.trigger_index + (SKIP_S / dt) as usize;
    let to = (c.trigger_index + (STEP_S / dt) as usize).min(y.len());
    if to < from + 50 {
        bail!("the capture holds {} samples of the step; 50 are needed", to.saturating_sub(from));
    }
    let t: Vec<f64> = (from..to).map(|k| k as f64 * dt).collect();
    Ok((peak_hz(&t, &y[from..to]), hold))
}

/// The strongest frequency in `BAND_HZ` of `y` after a quadratic trend (the
/// rigid body's acceleration) is taken out, on a 0.02 Hz grid.
fn peak_hz(t: &[f64], y: &[f64]) -> f64 {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut aty = nalgebra::Vector3::<f64>::zeros();
    for (&ti, &yi) in t.iter().zip(y) {
        let v = nalgebra::Vector3::new(1.0, ti, ti * ti);
        ata += v * v.transpose();
        aty += v * yi;
    }
    let c = ata.try_inverse().map_or(nalgebra::Vector3::zeros(), |inv| inv * aty);
    let r: Vec<f64> = t.iter().zip(y).map(|(&ti, &yi)| yi - c[0] - c[1] * ti - c[2] * ti * ti).collect();
    let mut best = (BAND_HZ.0, 0.0);
    let steps = ((BAND_HZ.1 - BAND_HZ.0) / 0.02).round() as usize;
    for k in 0..=steps {
        let f = BAND_HZ.0 + 0.02 * k as f64;
        let w = std::f64::consts::TAU * f;
        let (mut a, mut b) = (0.0, 0.0);
        for (&ti, &ri) in t.iter().zip(&r) {
            a += ri * (w * ti).cos();
            b += ri * (w * ti).sin();
        }
        if a * a + b * b > best.1 {
            best = (f, a * a + b * b);
        }
    }
    best.0
}

/// The compliance of `rig` (a cylinder, with its own `[control]`) against
/// `design` (the rig file it was built to).
pub fn identify_compliance(rig: &RigConfig, design: &RigConfig, seed: u64) -> Result<ComplianceId> {
    let (mode_hz, hold_a) = ring(rig, seed).context("the cylinder")?;
    let (_, design_hold_a) = ring(design, seed.wrapping_add(1)).context("the design")?;
    // The hold current carries the moving mass's weight: the design's
    // payload is scaled so that its whole moving mass matches.
    let p = &design.plant;
    let (payload, rest) = (p.rod.payload_mass_kg, p.moving_mass_kg() - p.rod.payload_mass_kg);
    let payload_scale = ((hold_a / design_hold_a) * (payload + rest) - rest) / payload;
    if !(0.5..=1.5).contains(&payload_scale) {
        bail!("hold current {hold_a:.2} A against the design's {design_hold_a:.2} A: the payload is not within ±50 % of the rig file's");
    }
    let mut matched = design.clone();
    matched.plant.rod.payload_mass_kg *= payload_scale;
    let (design_mode_hz, _) = ring(&matched, seed.wrapping_add(2)).context("the design at the cylinder's payload")?;
    let measured_ratio = (design_mode_hz / mode_hz).powi(2);
    let compliance_ratio = if (measured_ratio - 1.0).abs() <= RESOLUTION { 1.0 } else { measured_ratio };
    Ok(ComplianceId { mode_hz, design_mode_hz, hold_a, design_hold_a, payload_scale, measured_ratio, compliance_ratio })
}
