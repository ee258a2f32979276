//! `ControlParams::validate`: every field checked, the first bad one named.
//! A `const fn`, so the firmware's set is checked when the image is built.

use super::ControlParams;
use crate::leaf;
use crate::reason::Reason;

/// A parameter that cannot be used: its leaf index (`params::leaves`;
/// [`ParamError::field`] is its path in the TOML file) and why.
///
/// An index, not the path: the ≈ 100 paths the checks name cost ≈ 4 KB of
/// the image as strings. The drive's server turns the index into the path
/// through the tree (`protocol::params::name`), so a reply still names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    pub leaf: u16,
    pub reason: Reason,
}

impl ParamError {
    /// The field's path (`control.speed_pi.kp`), for the host and for
    /// compile-time messages (the drive names it through the tree instead:
    /// this table of paths is not in the image unless called there).
    pub const fn field(&self) -> &'static str {
        super::leaves::path(self.leaf as usize)
    }
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "parameter `{}`: {}", self.field(), self.reason)
    }
}

/// A parameter set that passed [`ControlParams::validate`]. A controller
/// built from one needs no check at run time: the firmware makes its set in
/// a `const`, so an invalid one is a compile error naming the field (and the
/// image carries neither the checks nor their messages).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidatedParams(ControlParams);

impl ValidatedParams {
    pub const fn new(p: ControlParams) -> Result<Self, ParamError> {
        match p.validate() {
            Ok(()) => Ok(Self(p)),
            Err(e) => Err(e),
        }
    }

    pub const fn get(&self) -> &ControlParams {
        &self.0
    }
}

/// A check of one leaf on its own (the checks between fields are code,
/// below). Most of `validate` is these, so they are a table walked by one
/// loop: as ≈ 100 calls they were ≈ 1.5 KB of the image, as rows 2 bytes
/// each.
#[derive(Clone, Copy, Debug)]
enum Check {
    /// An `f32` leaf, finite and > 0.
    Positive = 0,
    /// An `f32` leaf, finite and >= 0.
    NonNegative = 1,
    /// A `u32` leaf, >= 1.
    NonZero = 2,
}

/// One row, packed in 16 bits: the leaf's byte offset in words (bits
/// 0–6: every checked leaf is a 4-byte `f32`/`u32`, and the struct is
/// < 512 B), its index for the error (bits 7–13) and the check (bits
/// 14–15). The packing is checked per row at compile time.
#[derive(Clone, Copy, Debug)]
struct Rule(u16);

impl Rule {
    const fn new(offset: usize, leaf: u16, check: Check) -> Self {
        assert!(offset & 3 == 0 && offset < 512, "a checked leaf's offset does not fit a rule");
        assert!(leaf < 128, "leaf index beyond a rule's 7 bits");
        Self((offset as u16).wrapping_shr(2) | leaf.wrapping_shl(7) | (check as u16).wrapping_shl(14))
    }
    const fn offset(self) -> usize {
        ((self.0 & 0x7f) as usize).wrapping_shl(2)
    }
    const fn leaf(self) -> u16 {
        self.0.wrapping_shr(7) & 0x7f
    }
    const fn check(self) -> Check {
        match self.0.wrapping_shr(14) {
            0 => Check::Positive,
            1 => Check::NonNegative,
            _ => Check::NonZero,
        }
    }
}

/// A row; the `const _` makes the leaf's type the one the check reads.
macro_rules! rule {
    ($check:ident, $ty:ty, $($f:ident).+) => {{
        const _: $ty = ControlParams::DEFAULT.$($f).+;
        const R: Rule = Rule::new(core::mem::offset_of!(ControlParams, $($f).+), leaf!($($f).+), Check::$check);
        R
    }};
}
macro_rules! positive {
    ($($f:ident).+) => { rule!(Positive, f32, $($f).+) };
}
macro_rules! non_negative {
    ($($f:ident).+) => { rule!(NonNegative, f32, $($f).+) };
}
macro_rules! nonzero {
    ($($f:ident).+) => { rule!(NonZero, u32, $($f).+) };
}

/// Every single-leaf check, in the order the fields are declared.
const RULES: &[Rule] = &[
    nonzero!(motor.pole_pairs),
    positive!(motor.phase_resistance_ohm),
    positive!(motor.inductance_d_h),
    positive!(motor.inductance_q_h),
    positive!(motor.flux_linkage_wb),
    positive!(drive_train.screw_lead_m),
    positive!(drive_train.screw_efficiency),
    positive!(drive_train.rotating_inertia_kg_m2),
    non_negative!(drive_train.moving_mass_kg),
    non_negative!(drive_train.viscous_friction_n_m_s_rad),
    non_negative!(drive_train.coulomb_friction_n_m),
    positive!(drive_train.friction_feedforward_speed_rad_s),
    non_negative!(drive_train.friction_feedforward_gain),
    positive!(rates.pwm_frequency_hz),
    nonzero!(rates.speed_loop_divider),
    nonzero!(rates.position_loop_divider),
    positive!(current_pi.kp),
    non_negative!(current_pi.ki),
    positive!(speed_pi.kp),
    non_negative!(speed_pi.ki),
    non_negative!(speed_setpoint_weight),
    non_negative!(torque_filter_hz),
    positive!(position_kp_per_s),
    nonzero!(encoder.counts_per_rev),
    positive!(encoder.pll_kp_per_s),
    positive!(encoder.pll_ki_per_s2),
    positive!(trajectory.max_velocity_m_s),
    positive!(trajectory.max_acceleration_m_s2),
    positive!(trajectory.max_jerk_m_s3),
    positive!(limits.current_max_a),
    positive!(limits.copper_power_max_w),
    positive!(limits.speed_max_rad_s),
    non_negative!(limits.stroke_min_m),
    positive!(limits.stroke_max_m),
    positive!(limits.max_modulation),
    positive!(faults.overcurrent_trip_a),
    positive!(faults.bus_overvoltage_v),
    positive!(faults.bus_undervoltage_v),
    nonzero!(faults.encoder_max_step_counts),
    positive!(faults.encoder_max_innovation_counts),
    positive!(faults.position_following_error_m),
    non_negative!(faults.stroke_overtravel_m),
    positive!(load_estimate.filter_hz),
    positive!(faults.speed_following_error_rad_s),
    positive!(faults.speed_following_time_s),
    positive!(faults.encoder_lost_speed_rad_s),
    positive!(faults.encoder_lost_time_s),
    non_negative!(faults.stroke_soft_margin_m),
    positive!(faults.stop_deceleration_m_s2),
    positive!(faults.observer_shift_max_m),
    positive!(faults.current_sum_max_a),
    nonzero!(faults.current_sum_periods),
    positive!(faults.stop_following_error_m),
    positive!(faults.open_phase_window_s),
    positive!(faults.open_phase_current_a),
    positive!(faults.open_phase_ratio),
    non_negative!(brake.release_time_s),
    non_negative!(brake.engage_time_s),
    non_negative!(brake.holding_torque_n_m),
    non_negative!(brake.preload_time_s),
    positive!(brake.torque_watch_travel_m),
    positive!(brake.handover_slip_m),
    positive!(compensation.shift_max_m),
    positive!(compensation.shift_rate_max_m_s),
    positive!(thermal.continuous_current_a),
    positive!(thermal.time_constant_s),
    positive!(thermal.foldback_start),
    positive!(ratings.motor_peak_current_a),
    positive!(ratings.inverter_peak_current_a),
    positive!(ratings.bus_max_voltage_v),
    positive!(ratings.speed_max_rad_s),
    positive!(calibration.duration_s),
    positive!(calibration.offset_max_a),
    positive!(calibration.noise_max_a),
    positive!(calibration.bus_ripple_max_v),
    positive!(commutation.test_current_a),
    positive!(commutation.ramp_s),
    positive!(commutation.sweep_s),
    positive!(commutation.settle_s),
    positive!(commutation.settle_speed_rad_s),
    positive!(commutation.settle_timeout_s),
    positive!(commutation.min_amplitude_counts),
    positive!(commutation.max_twist_rad),
    positive!(commutation.hold_current_d_a),
    positive!(commutation.check_angle_rad),
    positive!(commutation.check_time_s),
    positive!(commutation.ratio_tolerance),
    positive!(commutation.blocked_ratio),
    positive!(commutation.timeout_s),
    positive!(homing.speed_m_s),
    positive!(homing.current_max_a),
    positive!(homing.contact_following_m),
    positive!(homing.contact_speed_rad_s),
    positive!(homing.contact_time_s),
    non_negative!(homing.backoff_m),
    positive!(homing.travel_max_m),
    positive!(homing.jog_speed_max_m_s),
    positive!(power_stage.temperature_foldback_c),
    positive!(power_stage.regen_bus_start_v),
    non_negative!(power_stage.regen_power_max_w),
    positive!(power_stage.emf_speed_mismatch_rad_s),
    positive!(power_stage.emf_mismatch_time_s),
    positive!(stream.period_max_s),
    positive!(stream.velocity_mismatch_max_m_s),
];

/// `power_stage.emf_speed_mismatch_rad_s` at most this part of the rated
/// speed (a quarter, the scale of `faults.speed_following_error_rad_s`).
pub const EMF_MISMATCH_PART_OF_RATED_SPEED: f32 = 0.25;

/// Runs [`RULES`] over `p`: the first leaf that fails, and why.
const fn check_rules(p: &ControlParams) -> Result<(), ParamError> {
    let base = (p as *const ControlParams).cast::<u8>();
    let mut rest = RULES;
    while let [rule, tail @ ..] = rest {
        let at = base.wrapping_add(rule.offset());
        let leaf = rule.leaf();
        let check = rule.check();
        // SAFETY: `offset()` is `offset_of!` of a field of `ControlParams`
        // (packed and unpacked exactly: `Rule::new` checks it)
        // whose type the `rule!` row checked to be the one read here (`f32`
        // for the float checks, `u32` for `NonZero`): an initialised,
        // aligned value inside `*p`.
        let bad = match check {
            Check::Positive | Check::NonNegative => {
                let v = unsafe { *at.cast::<f32>() };
                if !v.is_finite() {
                    Some(Reason::MustBeFinite)
                } else if matches!(check, Check::Positive) && v <= 0.0 {
                    Some(Reason::MustBePositive)
                } else if v < 0.0 {
                    Some(Reason::MustBeNonNegative)
                } else {
                    None
                }
            }
            Check::NonZero => {
                if unsafe { *at.cast::<u32>() } == 0 {
                    Some(Reason::MustBeAtLeastOne)
                } else {
                    None
                }
            }
        };
        if let Some(reason) = bad {
            return Err(ParamError { leaf, reason });
        }
        rest = tail;
    }
    Ok(())
}

/// `?` for `const fn`s (the trait-based `?` is not const).
macro_rules! check {
    ($e:expr) => {
        if let Err(e) = $e {
            return Err(e);
        }
    };
}

impl ControlParams {
    /// Refuses a parameter set the loops cannot run with, naming the field.
    pub const fn validate(&self) -> Result<(), ParamError> {
        check!(check_rules(self));
        check!(super::ranges::validate_ranges(self));
        check!(super::ranges::validate_gains(self));
        let d = &self.drive_train;
        if d.screw_efficiency > 1.0 {
            return Err(ParamError { leaf: leaf!(drive_train.screw_efficiency), reason: Reason::MustBeAtMostOne });
        }
        if d.friction_feedforward_gain > 1.0 {
            // Above the modelled friction the feedforward drives the rod
            // ahead of its reference at every start.
            return Err(ParamError { leaf: leaf!(drive_train.friction_feedforward_gain), reason: Reason::MustBeAtMostOne });
        }
        if self.speed_setpoint_weight > 2.0 {
            // Beyond 2 the proportional path alone overshoots more than the
            // tuner's widest ask; the weight shapes overshoot, it is not a gain.
            return Err(ParamError { leaf: leaf!(speed_setpoint_weight), reason: Reason::MustBeAtMostTwo });
        }
        if !self.rates.position_loop_divider.is_multiple_of(self.rates.speed_loop_divider) {
            return Err(ParamError {
                leaf: leaf!(rates.position_loop_divider),
                reason: Reason::MultipleOfSpeedDivider,
            });
        }
        let e = &self.encoder;
        if e.counts_per_rev > 32_768 {
            // The core unwraps a 16-bit counter: one revolution must fit in half its range.
            return Err(ParamError { leaf: leaf!(encoder.counts_per_rev), reason: Reason::CountsPerRevTooHigh });
        }
        // A jump of half a turn or more in one period cannot be told from
        // the other way round: a bound that wide checks nothing.
        let half_turn = e.counts_per_rev >> 1;
        if self.faults.encoder_max_step_counts >= half_turn {
            return Err(ParamError { leaf: leaf!(faults.encoder_max_step_counts), reason: Reason::EncoderBoundNotBelowHalfTurn });
        }
        if !(self.faults.encoder_max_innovation_counts < half_turn as f32) {
            return Err(ParamError { leaf: leaf!(faults.encoder_max_innovation_counts), reason: Reason::EncoderBoundNotBelowHalfTurn });
        }
        if e.direction != 1 && e.direction != -1 {
            return Err(ParamError { leaf: leaf!(encoder.direction), reason: Reason::MustBeOneOrMinusOne });
        }
        if !e.electrical_offset_rad.is_finite() {
            return Err(ParamError { leaf: leaf!(encoder.electrical_offset_rad), reason: Reason::MustBeFinite });
        }
        let l = &self.limits;
        if l.stroke_max_m <= l.stroke_min_m {
            return Err(ParamError { leaf: leaf!(limits.stroke_max_m), reason: Reason::MustExceedStrokeMin });
        }
        if l.max_modulation > 1.0 {
            return Err(ParamError { leaf: leaf!(limits.max_modulation), reason: Reason::MustBeAtMostOne });
        }
        let f = &self.faults;
        if f.overcurrent_trip_a < l.current_max_a {
            return Err(ParamError {
                leaf: leaf!(faults.overcurrent_trip_a),
                reason: Reason::TripBelowCurrentLimit,
            });
        }
        if f.bus_overvoltage_v <= f.bus_undervoltage_v {
            return Err(ParamError { leaf: leaf!(faults.bus_overvoltage_v), reason: Reason::MustExceedBusUndervoltage });
        }
        check!(self.validate_lifecycle());
        if f.stroke_soft_margin_m >= f.stroke_overtravel_m {
            return Err(ParamError {
                leaf: leaf!(faults.stroke_soft_margin_m),
                reason: Reason::MarginNotBelowOvertravel,
            });
        }
        if f.stop_deceleration_m_s2 < self.trajectory.max_acceleration_m_s2 {
            return Err(ParamError {
                leaf: leaf!(faults.stop_deceleration_m_s2),
                reason: Reason::StopDecelerationTooLow,
            });
        }
        if f.open_phase_ratio >= 1.0 {
            return Err(ParamError { leaf: leaf!(faults.open_phase_ratio), reason: Reason::MustBeBelowOne });
        }
        let c = &self.compensation;
        if c.shift_max_m > f.observer_shift_max_m {
            return Err(ParamError {
                leaf: leaf!(compensation.shift_max_m),
                reason: Reason::AboveObserverShiftMax,
            });
        }
        let th = &self.thermal;
        if th.continuous_current_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(thermal.continuous_current_a), reason: Reason::AboveCurrentLimit });
        }
        if th.foldback_start >= 1.0 {
            return Err(ParamError { leaf: leaf!(thermal.foldback_start), reason: Reason::MustBeBelowOne });
        }
        if !(th.trip_level > 1.0) || !th.trip_level.is_finite() {
            return Err(ParamError { leaf: leaf!(thermal.trip_level), reason: Reason::MustBeFiniteAboveOne });
        }
        let r = &self.ratings;
        if l.current_max_a > r.motor_peak_current_a || l.current_max_a > r.inverter_peak_current_a {
            return Err(ParamError {
                leaf: leaf!(limits.current_max_a),
                reason: Reason::AbovePeakRating,
            });
        }
        if f.overcurrent_trip_a > r.inverter_peak_current_a {
            return Err(ParamError {
                leaf: leaf!(faults.overcurrent_trip_a),
                reason: Reason::AboveInverterPeakRating,
            });
        }
        if f.bus_overvoltage_v > r.bus_max_voltage_v {
            return Err(ParamError { leaf: leaf!(faults.bus_overvoltage_v), reason: Reason::AboveBusRating });
        }
        if l.speed_max_rad_s > r.speed_max_rad_s {
            return Err(ParamError { leaf: leaf!(limits.speed_max_rad_s), reason: Reason::AboveSpeedRating });
        }
        Ok(())
    }
}

impl ControlParams {
    /// The start-up steps and the power stage's limits.
    const fn validate_lifecycle(&self) -> Result<(), ParamError> {
        let l = &self.limits;
        if !self.startup.expected_load_force_n.is_finite() {
            return Err(ParamError { leaf: leaf!(startup.expected_load_force_n), reason: Reason::MustBeFinite });
        }
        let m = &self.commutation;
        if m.test_current_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(commutation.test_current_a), reason: Reason::AboveCurrentLimit });
        }
        if m.hold_current_d_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(commutation.hold_current_d_a), reason: Reason::AboveCurrentLimit });
        }
        if m.blocked_ratio >= 1.0 - m.ratio_tolerance {
            return Err(ParamError { leaf: leaf!(commutation.blocked_ratio), reason: Reason::BlockedRatioTooHigh });
        }
        let h = &self.homing;
        if h.direction != 1 && h.direction != -1 {
            return Err(ParamError { leaf: leaf!(homing.direction), reason: Reason::MustBeOneOrMinusOne });
        }
        if h.speed_m_s > self.trajectory.max_velocity_m_s {
            return Err(ParamError { leaf: leaf!(homing.speed_m_s), reason: Reason::AboveTrajectoryVelocity });
        }
        if h.current_max_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(homing.current_max_a), reason: Reason::AboveCurrentLimit });
        }
        if !h.home_position_m.is_finite() {
            return Err(ParamError { leaf: leaf!(homing.home_position_m), reason: Reason::MustBeFinite });
        }
        let p = &self.power_stage;
        if p.temperature_trip_c <= p.temperature_foldback_c || !p.temperature_trip_c.is_finite() {
            return Err(ParamError { leaf: leaf!(power_stage.temperature_trip_c), reason: Reason::MustExceedTemperatureFoldback });
        }
        if p.regen_bus_max_v <= p.regen_bus_start_v || !p.regen_bus_max_v.is_finite() {
            return Err(ParamError { leaf: leaf!(power_stage.regen_bus_max_v), reason: Reason::MustExceedRegenStart });
        }
        if p.regen_bus_max_v > self.faults.bus_overvoltage_v {
            return Err(ParamError {
                leaf: leaf!(power_stage.regen_bus_max_v),
                reason: Reason::RegenAboveOvervoltage,
            });
        }
        // Beyond this a frozen encoder under a load that slips the rotor at
        // standstill is never told from the back-EMF.
        if !(p.emf_speed_mismatch_rad_s <= EMF_MISMATCH_PART_OF_RATED_SPEED * self.ratings.speed_max_rad_s) {
            return Err(ParamError { leaf: leaf!(power_stage.emf_speed_mismatch_rad_s), reason: Reason::EmfMismatchAboveQuarterRating });
        }
        if self.stream.timeout_s < self.stream.period_max_s || !self.stream.timeout_s.is_finite() {
            return Err(ParamError { leaf: leaf!(stream.timeout_s), reason: Reason::TimeoutBelowPeriodMax });
        }
        if !(self.stream.velocity_mismatch_max_m_s <= 0.5 * self.trajectory.max_velocity_m_s) {
            return Err(ParamError { leaf: leaf!(stream.velocity_mismatch_max_m_s), reason: Reason::MismatchAboveHalfVelocity });
        }
        if self.stream.leg_index >= super::stream::LEGS as u32 {
            return Err(ParamError { leaf: leaf!(stream.leg_index), reason: Reason::NoSuchLegSlot });
        }
        Ok(())
    }
}
