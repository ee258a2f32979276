//! Physical plausibility of a fitted effect. A least-squares fit will bend
//! any regressor to soak up part of a residual it has nothing to do with;
//! the parameters then say so. Fits outside these bounds are reported
//! (`implausible`), never ranked, and they feed the "log does not match the
//! rig's physics" gate.

use super::effects::Effect;
use super::residual::{Nominal, Segment, TORQUE};

/// Opposite-signed Coulomb (or viscous) terms whose smaller part exceeds
/// this share of the larger make mostly a constant offset (or a `|ω|`
/// law), not friction: friction that changes opposes the motion in both
/// directions (both terms the same sign), and a real one-sided change
/// leaves the other term near zero. The closed-world suite's one-sided
/// truths fit the small term at under 15 % of the large one.
pub const FRICTION_OFFSET_SHARE: f64 = 0.3;

/// Cumulative lead error, m/m. ISO 3408-3 / JIS B 1192 transport grade
/// C10, the loosest, allows 210 µm per 300 mm (7e-4); a fit beyond 1e-3
/// is no screw, it is a wrong lead in the rig file (or another effect).
pub const MAX_LEAD_ERROR_M_PER_M: f64 = 1e-3;

/// Once-per-revolution lead error (wobble) amplitude, m. Even C10 screws
/// hold the per-revolution variation to tens of µm.
pub const MAX_LEAD_PER_REV_M: f64 = 50e-6;

/// Lost motion, m. A worn, non-preloaded ball nut has a few 0.1 mm of
/// axial play; beyond 2 mm the balls would fall out of the track.
pub const MAX_BACKLASH_M: f64 = 2e-3;

/// Thermal strain accumulated over the log, 1/1: steel expands
/// 11.7e-6 per K, so 1e-3 is an 85 K warm-up of the whole screw.
pub const MAX_THERMAL_STRAIN: f64 = 1e-3;

/// Current-sensor gain error, 1/1. A shunt amplifier is calibrated to a
/// few %; 15 % is a broken part or a wrong torque constant in the rig file.
pub const MAX_CURRENT_GAIN_ERROR: f64 = 0.15;

/// Encoder eccentricity, rad: 0.05 rad (≈ 3°) of disc run-out would put
/// the read head off the track.
pub const MAX_ENCODER_ECCENTRICITY_RAD: f64 = 0.05;

/// Cogging or Stribeck torque against the largest torque the log carries:
/// a ripple or breakaway bigger than half the peak torque would dominate
/// every move and would not be "unmodelled".
pub const MAX_TORQUE_SHARE_OF_PEAK: f64 = 0.5;

/// Whether the torque-channel signal is an unsigned magnitude (a stepper
/// drive's current, e.g. Cranfield): then an "asymmetric" law with
/// opposite signs is a symmetric magnitude change, not an offset.
pub fn torque_unsigned(train: &[&Segment]) -> bool {
    let (mut neg, mut n) = (0usize, 0usize);
    for s in train {
        if let Some(y) = &s.y[TORQUE] {
            neg += y.iter().filter(|v| **v < 0.0).count();
            n += y.len();
        }
    }
    n > 0 && (neg as f64) < 0.01 * n as f64
}

/// Why the fitted `params` of `effect` are not physical, if so.
pub fn check(
    effect: Effect,
    params: &[f64],
    nominal: &Nominal,
    train: &[&Segment],
) -> Option<String> {
    let phys = matches!(nominal, Nominal::Physics(_));
    let signed = phys || !torque_unsigned(train);
    let duration = train
        .iter()
        .map(|s| s.t_rel.last().copied().unwrap_or(0.0))
        .fold(0.0, f64::max);
    let peak_torque = train
        .iter()
        .filter_map(|s| s.y[TORQUE].as_ref())
        .flat_map(|y| y.iter().map(|v| v.abs()))
        .fold(0.0f64, f64::max);
    let offset_like = |a: f64, b: f64, what: &str| {
        (signed && a * b < 0.0 && a.abs().min(b.abs()) > FRICTION_OFFSET_SHARE * a.abs().max(b.abs())).then(|| {
            format!(
                "opposite-signed {what} terms ({a:+.3e}, {b:+.3e}): together they make an offset, not friction (smaller part > {:.0} % of the larger)",
                100.0 * FRICTION_OFFSET_SHARE
            )
        })
    };
    match effect {
        Effect::CoulombAsym => offset_like(params[0], params[1], "Coulomb"),
        Effect::ViscousAsym => offset_like(params[0], params[1], "viscous"),
        Effect::LeadErrorCumulative if params[0].abs() > MAX_LEAD_ERROR_M_PER_M => Some(format!(
            "lead error {:.2e} m/m is beyond any screw grade (C10 allows 7e-4; bound {MAX_LEAD_ERROR_M_PER_M:.0e}): a wrong lead in the rig file, or another effect",
            params[0]
        )),
        Effect::LeadErrorPerRev if params[0].hypot(params[1]) > MAX_LEAD_PER_REV_M => Some(format!(
            "once-per-revolution lead error {:.1} µm is beyond any screw grade (bound {:.0} µm)",
            1e6 * params[0].hypot(params[1]),
            1e6 * MAX_LEAD_PER_REV_M
        )),
        Effect::Backlash if params[0] > MAX_BACKLASH_M => {
            Some(format!("lost motion {:.2} mm is beyond a ball nut's (bound {:.0} mm)", 1e3 * params[0], 1e3 * MAX_BACKLASH_M))
        }
        Effect::ThermalDrift if (params[0] * duration).abs() > MAX_THERMAL_STRAIN => Some(format!(
            "thermal strain {:.1e} over the {duration:.1} s log is an implausible warm-up (bound {MAX_THERMAL_STRAIN:.0e})",
            params[0] * duration
        )),
        Effect::CurrentSensor if params[0].abs() > MAX_CURRENT_GAIN_ERROR => Some(format!(
            "current-sensor gain error {:+.1} % is beyond a calibrated sensor (bound ±{:.0} %): a wrong torque constant in the rig file?",
            100.0 * params[0],
            100.0 * MAX_CURRENT_GAIN_ERROR
        )),
        Effect::EncoderEccentricity if params[0].hypot(params[1]) > MAX_ENCODER_ECCENTRICITY_RAD => Some(format!(
            "encoder eccentricity {:.3} rad is beyond a readable disc (bound {MAX_ENCODER_ECCENTRICITY_RAD} rad)",
            params[0].hypot(params[1])
        )),
        Effect::Cogging | Effect::Stribeck if phys => {
            let amp = if effect == Effect::Cogging { params[0].hypot(params[1]) } else { params[0].abs() };
            (peak_torque > 0.0 && amp > MAX_TORQUE_SHARE_OF_PEAK * peak_torque).then(|| {
                format!(
                    "{} amplitude {amp:.3e} N·m exceeds {:.0} % of the log's peak torque {peak_torque:.3e} N·m",
                    effect.name(),
                    100.0 * MAX_TORQUE_SHARE_OF_PEAK
                )
            })
        }
        _ => None,
    }
}

/// The implausible fits (`names`) that stay implausible *and* matter once
/// the library stack is in the model: each refitted on what the stack
/// leaves on the training part, counted only if it is still implausible
/// and still removes `MIN_FINDING_PCT` of that remainder's gap. An effect
/// bent out of shape to reach the stack's signature (a lead error soaking
/// up a load offset's deflection) fits plausibly, or to nothing, once that
/// signature is gone; one still bent and still explaining a share says
/// the gap holds something the stack does not explain either. (An
/// opposite-signed friction pair fits any trace of an offset with a ratio
/// of one: its ratio alone says nothing once the offset is a few per cent
/// of the floor — on a closed-world load offset of 94 % shrink it did.)
pub fn still_implausible(
    names: &[String],
    stack: (&[super::fit::Term], &[f64]),
    train: &[&Segment],
    nominal: &Nominal,
    w: &[f64; super::residual::NCH],
) -> Vec<String> {
    let rest: Vec<Segment> = train
        .iter()
        .map(|s| {
            let p = super::fit::predict(stack.0, stack.1, s, nominal);
            let mut s = super::slice_segment(s, 0, s.len(), s.heldout);
            for (r, p) in s.r.iter_mut().zip(&p) {
                if let (Some(r), Some(p)) = (r.as_mut(), p) {
                    r.iter_mut().zip(p).for_each(|(a, b)| *a -= b);
                }
            }
            s
        })
        .collect();
    let refs: Vec<&Segment> = rest.iter().collect();
    let before = super::fit::gap(&refs, None, w);
    names
        .iter()
        .filter(|n| {
            let Some(e) = super::effects::by_name(n) else {
                return false;
            };
            super::fit::fit_effect(e, &refs, nominal, w).is_ok_and(|f| {
                check(e, &f.params, nominal, &refs).is_some()
                    && super::figures::shrink(before, f.train_gap) >= super::MIN_FINDING_PCT
            })
        })
        .cloned()
        .collect()
}
