//! Physical ranges: every numeric leaf has an upper bound on its size,
//! chosen by its unit (the suffix of its path, `_m_s`, `_a`, `_s`, …,
//! classified when the image is built, so no path string is in it) and,
//! where the rig gives one, taken from the set's own ratings: rod speeds
//! within the screw's and motor's speed rating, currents within the
//! inverter's peak, voltages within the bus rating. A protection's time or
//! distance bound may not be so large that it never acts. The loop gains
//! are bounded by the bandwidth of the loop inside them (`validate_gains`).

use super::leaves::{path, LEAVES, LEAF_COUNT};
use super::value::ValueKind;
use super::{ControlParams, ParamError};
use crate::reason::Reason;

/// A leaf's unit class, from its path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Unit {
    /// Checked elsewhere (gains, signs, flags, enums), or dimensionless.
    Free,
    Dimensionless,
    /// A protection's time: ≤ 1 s.
    ProtectionTime,
    Time,
    LongTime,
    /// A protection's distance: ≤ 50 mm.
    ProtectionLength,
    Length,
    RodSpeed,
    RodAcceleration,
    RodJerk,
    MotorSpeed,
    Current,
    Voltage,
    Frequency,
    Force,
    Torque,
    Power,
    Temperature,
    Angle,
    Counts,
    /// A `u32` count (pole pairs, dividers, periods).
    Integer,
    /// A rating itself: bounded by an absolute hardware figure.
    Rating,
    /// The PWM rate itself.
    PwmRate,
    /// An observer's rate gain (1/s): within the PWM's reach.
    RateGain,
    /// Its square-law gain (1/s²).
    RateGain2,
    /// Viscous friction (N·m·s/rad): at the rated speed within the peak
    /// torque.
    Damping,
}

const fn ends_with(s: &str, suffix: &str) -> bool {
    let (s, x) = (s.as_bytes(), suffix.as_bytes());
    if x.len() > s.len() {
        return false;
    }
    let mut i = 0;
    let off = s.len().wrapping_sub(x.len());
    while i < x.len() {
        if let (Some(a), Some(b)) = (s.split_at(off).1.split_at(i).1.first(), x.split_at(i).1.first()) {
            if *a != *b {
                return false;
            }
        }
        i = i.wrapping_add(1);
    }
    true
}

const fn starts_with(s: &str, prefix: &str) -> bool {
    let (s, x) = (s.as_bytes(), prefix.as_bytes());
    if x.len() > s.len() {
        return false;
    }
    let mut i = 0;
    while i < x.len() {
        if let (Some(a), Some(b)) = (s.split_at(i).1.first(), x.split_at(i).1.first()) {
            if *a != *b {
                return false;
            }
        }
        i = i.wrapping_add(1);
    }
    true
}

/// The unit class of the leaf at `p` (a `control.` path).
pub const fn classify(p: &str, kind: ValueKind) -> Unit {
    let protection = starts_with(p, "control.faults.")
        || starts_with(p, "control.stream.")
        || starts_with(p, "control.power_stage.")
        || ends_with(p, "watch_travel_m")
        || ends_with(p, "handover_slip_m");
    if starts_with(p, "control.ratings.") {
        return Unit::Rating;
    }
    if starts_with(p, "control.current_pi.") || starts_with(p, "control.speed_pi.") || ends_with(p, "position_kp_per_s") {
        return Unit::Free;
    }
    if matches!(kind, ValueKind::U32) {
        return Unit::Integer;
    }
    if !matches!(kind, ValueKind::F32) {
        return Unit::Free;
    }
    if ends_with(p, "pwm_frequency_hz") {
        Unit::PwmRate
    } else if ends_with(p, "time_constant_s") {
        Unit::LongTime
    } else if ends_with(p, "_m_s3") {
        Unit::RodJerk
    } else if ends_with(p, "_m_s2") {
        Unit::RodAcceleration
    } else if ends_with(p, "_m_s") {
        Unit::RodSpeed
    } else if ends_with(p, "_rad_s") {
        Unit::MotorSpeed
    } else if ends_with(p, "_per_s") {
        Unit::RateGain
    } else if ends_with(p, "_per_s2") {
        Unit::RateGain2
    } else if ends_with(p, "_n_m_s_rad") {
        Unit::Damping
    } else if ends_with(p, "_s") {
        if protection { Unit::ProtectionTime } else { Unit::Time }
    } else if ends_with(p, "_n_m") {
        Unit::Torque
    } else if ends_with(p, "_m") {
        if protection { Unit::ProtectionLength } else { Unit::Length }
    } else if ends_with(p, "_a") {
        Unit::Current
    } else if ends_with(p, "_v") {
        Unit::Voltage
    } else if ends_with(p, "_hz") {
        Unit::Frequency
    } else if ends_with(p, "_n") {
        Unit::Force
    } else if ends_with(p, "_w") {
        Unit::Power
    } else if ends_with(p, "_c") {
        Unit::Temperature
    } else if ends_with(p, "_rad") {
        Unit::Angle
    } else if ends_with(p, "_counts") {
        Unit::Counts
    } else {
        // Motor and plant constants, ratios, weights.
        Unit::Dimensionless
    }
}

const fn build_units() -> [Unit; LEAF_COUNT] {
    let mut units = [Unit::Free; LEAF_COUNT];
    let mut slots: &mut [Unit] = &mut units;
    let mut leaves: &[super::leaves::Leaf] = &LEAVES;
    let mut i = 0;
    while let ([slot, rest @ ..], [leaf, more @ ..]) = (slots, leaves) {
        *slot = classify(path(i), leaf.kind);
        slots = rest;
        leaves = more;
        i = i.wrapping_add(1);
    }
    units
}

/// Every leaf's unit class, in index order (built when the image is).
pub const UNITS: [Unit; LEAF_COUNT] = build_units();

/// The largest size a leaf of this unit may have in set `p`.
pub const fn bound(unit: Unit, p: &ControlParams) -> f32 {
    let r = &p.ratings;
    match unit {
        Unit::Free => f32::INFINITY,
        Unit::Dimensionless => 1.0e4,
        Unit::ProtectionTime => 1.0,
        Unit::Time => 60.0,
        Unit::LongTime => 3600.0,
        Unit::ProtectionLength => 0.05,
        Unit::Length => 2.0,
        // The screw's and motor's speed rating at the rod.
        Unit::RodSpeed => r.speed_max_rad_s * p.metres_per_rad(),
        Unit::RodAcceleration => 100.0,
        Unit::RodJerk => 1.0e5,
        Unit::MotorSpeed => r.speed_max_rad_s,
        Unit::Current => r.inverter_peak_current_a,
        Unit::Voltage => r.bus_max_voltage_v,
        Unit::Frequency => p.rates.pwm_frequency_hz * 0.5,
        Unit::Force => 10.0 * p.thrust_peak_n(),
        Unit::Torque => 10.0 * p.torque_constant_n_m_a() * r.motor_peak_current_a,
        Unit::Power => r.bus_max_voltage_v * r.inverter_peak_current_a,
        Unit::Temperature => 200.0,
        Unit::Angle => 100.0,
        Unit::Counts => 1.0e6,
        Unit::Integer => 1.0e6,
        // Absolute: what any drive of this family could carry.
        Unit::Rating => 1.0e4,
        // What the gate drivers and the current sampling reach.
        Unit::PwmRate => 100.0e3,
        Unit::RateGain => core::f32::consts::PI * p.rates.pwm_frequency_hz,
        Unit::Damping => p.torque_constant_n_m_a() * r.motor_peak_current_a / r.speed_max_rad_s,
        Unit::RateGain2 => {
            let w = core::f32::consts::PI * p.rates.pwm_frequency_hz;
            w * w
        }
    }
}

/// The largest size the leaf `index` may have in `p`.
pub fn leaf_bound(index: usize, p: &ControlParams) -> Option<f32> {
    UNITS.get(index).map(|u| bound(*u, p))
}

/// Every leaf within its unit's bound; the first one beyond is named.
pub(super) const fn validate_ranges(p: &ControlParams) -> Result<(), ParamError> {
    let base = (p as *const ControlParams).cast::<u8>();
    let mut leaves: &[super::leaves::Leaf] = &LEAVES;
    let mut units: &[Unit] = &UNITS;
    let mut index: u16 = 0;
    while let ([leaf, more @ ..], [unit, rest @ ..]) = (leaves, units) {
        leaves = more;
        units = rest;
        let this = index;
        index = index.wrapping_add(1);
        let limit = bound(*unit, p);
        let at = base.wrapping_add(leaf.offset as usize);
        // SAFETY: `leaf.offset` is `offset_of!` of a field of
        // `ControlParams` whose type is `leaf.kind` (the leaf table is
        // checked leaf by leaf against the tree): an initialised, aligned
        // value inside `*p`.
        let size = match leaf.kind {
            ValueKind::F32 => unsafe { *at.cast::<f32>() }.abs(),
            ValueKind::U32 => (unsafe { *at.cast::<u32>() }) as f32,
            _ => continue,
        };
        // NaN compares false: refused here too.
        if !(size <= limit) {
            let reason = match unit {
                Unit::RodSpeed => Reason::BeyondScrewSpeedRating,
                Unit::MotorSpeed => Reason::AboveSpeedRating,
                Unit::Current => Reason::AboveInverterPeakRating,
                Unit::Voltage => Reason::AboveBusRating,
                Unit::ProtectionTime => Reason::ProtectionTimeTooLong,
                Unit::ProtectionLength => Reason::ProtectionLengthTooLong,
                Unit::Frequency => Reason::AboveNyquist,
                _ => Reason::BeyondPhysicalRange,
            };
            return Err(ParamError { leaf: this, reason });
        }
    }
    Ok(())
}

/// Current-loop crossover at most this part of the PWM rate (the sampling
/// and PWM delay; the shipped loop: 1/20).
pub const CURRENT_BANDWIDTH_PART_OF_PWM: f32 = 0.125;
/// The speed loop's crossover at most this part of the current loop's (the
/// cascade's separation; the shipped loops: 1/25).
pub const CASCADE_SEPARATION: f32 = 0.3;
/// The speed loop's crossover at most this part of the torque filter's
/// corner (the filter's lag sits inside the speed loop).
pub const SPEED_PART_OF_TORQUE_FILTER: f32 = 1.0;
/// The position loop's crossover at most the speed loop's (the shipped
/// loops: a quarter; a halved speed gain must still be settable).
pub const POSITION_PART_OF_SPEED: f32 = 1.0;

/// A PI's integral corner (`ki/kp`) at most this times its loop's
/// crossover: beyond, the integral's phase lag dominates at the crossover
/// (the shipped loops: 1/4; a halved `kp` with `ki` kept must be settable).
pub const INTEGRAL_CORNER_PART: f32 = 2.0;

/// The crossovers the gains set (rad/s): current `kp/L_q`, speed
/// `kp·K_t/J`, position `kp`.
pub const fn crossovers_rad_s(p: &ControlParams) -> (f32, f32, f32) {
    let current = p.current_pi.kp / p.motor.inductance_q_h;
    let speed = p.speed_pi.kp * p.torque_constant_n_m_a() / p.reflected_inertia_kg_m2();
    (current, speed, p.position_kp_per_s)
}

/// Each loop's gains within what the loop inside it can carry: the current
/// loop below the PWM's reach, speed below current, position below speed,
/// and every integral corner (`ki/kp`) below its loop's crossover.
pub(super) const fn validate_gains(p: &ControlParams) -> Result<(), ParamError> {
    let (wc, ws, wp) = crossovers_rad_s(p);
    let w_pwm = 2.0 * core::f32::consts::PI * p.rates.pwm_frequency_hz;
    if !(wc <= CURRENT_BANDWIDTH_PART_OF_PWM * w_pwm) {
        return Err(ParamError { leaf: crate::leaf!(current_pi.kp), reason: Reason::GainAboveInnerBandwidth });
    }
    if !(p.current_pi.ki <= INTEGRAL_CORNER_PART * p.current_pi.kp * wc) {
        return Err(ParamError { leaf: crate::leaf!(current_pi.ki), reason: Reason::IntegralAboveCrossover });
    }
    let w_filter = 2.0 * core::f32::consts::PI * p.torque_filter_hz;
    if !(ws <= CASCADE_SEPARATION * wc) || (p.torque_filter_hz > 0.0 && !(ws <= SPEED_PART_OF_TORQUE_FILTER * w_filter)) {
        return Err(ParamError { leaf: crate::leaf!(speed_pi.kp), reason: Reason::GainAboveInnerBandwidth });
    }
    if !(p.speed_pi.ki <= INTEGRAL_CORNER_PART * p.speed_pi.kp * ws) {
        return Err(ParamError { leaf: crate::leaf!(speed_pi.ki), reason: Reason::IntegralAboveCrossover });
    }
    if !(wp <= POSITION_PART_OF_SPEED * ws) {
        return Err(ParamError { leaf: crate::leaf!(position_kp_per_s), reason: Reason::GainAboveInnerBandwidth });
    }
    Ok(())
}
