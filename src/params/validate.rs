//! `ControlParams::validate`: every field checked, the first bad one named.
//! A `const fn`, so the firmware's set is checked when the image is built.

use super::ControlParams;
use crate::leaf;
use crate::protocol::Reason;

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

// Out of line: ≈ 100 call sites, each inlined copy costs flash (the
// run-time validation is not on any fast path).
#[inline(never)]
const fn positive(leaf: u16, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { leaf, reason: Reason::MustBeFinite })
    } else if v <= 0.0 {
        Err(ParamError { leaf, reason: Reason::MustBePositive })
    } else {
        Ok(())
    }
}

// Out of line: ≈ 100 call sites, each inlined copy costs flash (the
// run-time validation is not on any fast path).
#[inline(never)]
const fn non_negative(leaf: u16, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { leaf, reason: Reason::MustBeFinite })
    } else if v < 0.0 {
        Err(ParamError { leaf, reason: Reason::MustBeNonNegative })
    } else {
        Ok(())
    }
}

// Out of line: ≈ 100 call sites, each inlined copy costs flash (the
// run-time validation is not on any fast path).
#[inline(never)]
const fn nonzero(leaf: u16, v: u32) -> Result<(), ParamError> {
    if v == 0 { Err(ParamError { leaf, reason: Reason::MustBeAtLeastOne }) } else { Ok(()) }
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
        let m = &self.motor;
        check!(nonzero(leaf!(motor.pole_pairs), m.pole_pairs));
        check!(positive(leaf!(motor.phase_resistance_ohm), m.phase_resistance_ohm));
        check!(positive(leaf!(motor.inductance_d_h), m.inductance_d_h));
        check!(positive(leaf!(motor.inductance_q_h), m.inductance_q_h));
        check!(positive(leaf!(motor.flux_linkage_wb), m.flux_linkage_wb));
        let d = &self.drive_train;
        check!(positive(leaf!(drive_train.screw_lead_m), d.screw_lead_m));
        check!(positive(leaf!(drive_train.screw_efficiency), d.screw_efficiency));
        if d.screw_efficiency > 1.0 {
            return Err(ParamError { leaf: leaf!(drive_train.screw_efficiency), reason: Reason::MustBeAtMostOne });
        }
        check!(positive(leaf!(drive_train.rotating_inertia_kg_m2), d.rotating_inertia_kg_m2));
        check!(non_negative(leaf!(drive_train.moving_mass_kg), d.moving_mass_kg));
        check!(non_negative(leaf!(drive_train.viscous_friction_n_m_s_rad), d.viscous_friction_n_m_s_rad));
        check!(non_negative(leaf!(drive_train.coulomb_friction_n_m), d.coulomb_friction_n_m));
        check!(positive(leaf!(drive_train.friction_feedforward_speed_rad_s), d.friction_feedforward_speed_rad_s));
        check!(non_negative(leaf!(drive_train.friction_feedforward_gain), d.friction_feedforward_gain));
        if d.friction_feedforward_gain > 1.0 {
            // Above the modelled friction the feedforward drives the rod
            // ahead of its reference at every start.
            return Err(ParamError { leaf: leaf!(drive_train.friction_feedforward_gain), reason: Reason::MustBeAtMostOne });
        }
        check!(positive(leaf!(rates.pwm_frequency_hz), self.rates.pwm_frequency_hz));
        check!(nonzero(leaf!(rates.speed_loop_divider), self.rates.speed_loop_divider));
        check!(nonzero(leaf!(rates.position_loop_divider), self.rates.position_loop_divider));
        if !self.rates.position_loop_divider.is_multiple_of(self.rates.speed_loop_divider) {
            return Err(ParamError {
                leaf: leaf!(rates.position_loop_divider),
                reason: Reason::MultipleOfSpeedDivider,
            });
        }
        check!(positive(leaf!(current_pi.kp), self.current_pi.kp));
        check!(non_negative(leaf!(current_pi.ki), self.current_pi.ki));
        check!(positive(leaf!(speed_pi.kp), self.speed_pi.kp));
        check!(non_negative(leaf!(speed_pi.ki), self.speed_pi.ki));
        check!(non_negative(leaf!(torque_filter_hz), self.torque_filter_hz));
        check!(positive(leaf!(position_kp_per_s), self.position_kp_per_s));
        let e = &self.encoder;
        check!(nonzero(leaf!(encoder.counts_per_rev), e.counts_per_rev));
        if e.counts_per_rev > 32_768 {
            // The core unwraps a 16-bit counter: one revolution must fit in half its range.
            return Err(ParamError { leaf: leaf!(encoder.counts_per_rev), reason: Reason::CountsPerRevTooHigh });
        }
        if e.direction != 1 && e.direction != -1 {
            return Err(ParamError { leaf: leaf!(encoder.direction), reason: Reason::MustBeOneOrMinusOne });
        }
        if !e.electrical_offset_rad.is_finite() {
            return Err(ParamError { leaf: leaf!(encoder.electrical_offset_rad), reason: Reason::MustBeFinite });
        }
        check!(positive(leaf!(encoder.pll_kp_per_s), e.pll_kp_per_s));
        check!(positive(leaf!(encoder.pll_ki_per_s2), e.pll_ki_per_s2));
        let t = &self.trajectory;
        check!(positive(leaf!(trajectory.max_velocity_m_s), t.max_velocity_m_s));
        check!(positive(leaf!(trajectory.max_acceleration_m_s2), t.max_acceleration_m_s2));
        check!(positive(leaf!(trajectory.max_jerk_m_s3), t.max_jerk_m_s3));
        let l = &self.limits;
        check!(positive(leaf!(limits.current_max_a), l.current_max_a));
        check!(positive(leaf!(limits.copper_power_max_w), l.copper_power_max_w));
        check!(positive(leaf!(limits.speed_max_rad_s), l.speed_max_rad_s));
        check!(non_negative(leaf!(limits.stroke_min_m), l.stroke_min_m));
        check!(positive(leaf!(limits.stroke_max_m), l.stroke_max_m));
        if l.stroke_max_m <= l.stroke_min_m {
            return Err(ParamError { leaf: leaf!(limits.stroke_max_m), reason: Reason::MustExceedStrokeMin });
        }
        check!(positive(leaf!(limits.max_modulation), l.max_modulation));
        if l.max_modulation > 1.0 {
            return Err(ParamError { leaf: leaf!(limits.max_modulation), reason: Reason::MustBeAtMostOne });
        }
        let f = &self.faults;
        check!(positive(leaf!(faults.overcurrent_trip_a), f.overcurrent_trip_a));
        if f.overcurrent_trip_a < l.current_max_a {
            return Err(ParamError {
                leaf: leaf!(faults.overcurrent_trip_a),
                reason: Reason::TripBelowCurrentLimit,
            });
        }
        check!(positive(leaf!(faults.bus_overvoltage_v), f.bus_overvoltage_v));
        check!(positive(leaf!(faults.bus_undervoltage_v), f.bus_undervoltage_v));
        if f.bus_overvoltage_v <= f.bus_undervoltage_v {
            return Err(ParamError { leaf: leaf!(faults.bus_overvoltage_v), reason: Reason::MustExceedBusUndervoltage });
        }
        check!(nonzero(leaf!(faults.encoder_max_step_counts), f.encoder_max_step_counts));
        check!(positive(leaf!(faults.encoder_max_innovation_counts), f.encoder_max_innovation_counts));
        check!(positive(leaf!(faults.position_following_error_m), f.position_following_error_m));
        check!(non_negative(leaf!(faults.stroke_overtravel_m), f.stroke_overtravel_m));
        check!(positive(leaf!(load_estimate.filter_hz), self.load_estimate.filter_hz));
        check!(self.validate_lifecycle());
        check!(positive(leaf!(faults.speed_following_error_rad_s), f.speed_following_error_rad_s));
        check!(positive(leaf!(faults.speed_following_time_s), f.speed_following_time_s));
        check!(positive(leaf!(faults.encoder_lost_speed_rad_s), f.encoder_lost_speed_rad_s));
        check!(positive(leaf!(faults.encoder_lost_time_s), f.encoder_lost_time_s));
        check!(non_negative(leaf!(faults.stroke_soft_margin_m), f.stroke_soft_margin_m));
        if f.stroke_soft_margin_m >= f.stroke_overtravel_m {
            return Err(ParamError {
                leaf: leaf!(faults.stroke_soft_margin_m),
                reason: Reason::MarginNotBelowOvertravel,
            });
        }
        check!(positive(leaf!(faults.stop_deceleration_m_s2), f.stop_deceleration_m_s2));
        if f.stop_deceleration_m_s2 < self.trajectory.max_acceleration_m_s2 {
            return Err(ParamError {
                leaf: leaf!(faults.stop_deceleration_m_s2),
                reason: Reason::StopDecelerationTooLow,
            });
        }
        check!(positive(leaf!(faults.observer_shift_max_m), f.observer_shift_max_m));
        check!(positive(leaf!(faults.current_sum_max_a), f.current_sum_max_a));
        check!(nonzero(leaf!(faults.current_sum_periods), f.current_sum_periods));
        check!(positive(leaf!(faults.stop_following_error_m), f.stop_following_error_m));
        check!(positive(leaf!(faults.open_phase_window_s), f.open_phase_window_s));
        check!(positive(leaf!(faults.open_phase_current_a), f.open_phase_current_a));
        check!(positive(leaf!(faults.open_phase_ratio), f.open_phase_ratio));
        if f.open_phase_ratio >= 1.0 {
            return Err(ParamError { leaf: leaf!(faults.open_phase_ratio), reason: Reason::MustBeBelowOne });
        }
        let b = &self.brake;
        check!(non_negative(leaf!(brake.release_time_s), b.release_time_s));
        check!(non_negative(leaf!(brake.engage_time_s), b.engage_time_s));
        check!(non_negative(leaf!(brake.holding_torque_n_m), b.holding_torque_n_m));
        check!(non_negative(leaf!(brake.preload_time_s), b.preload_time_s));
        let c = &self.compensation;
        check!(positive(leaf!(compensation.shift_max_m), c.shift_max_m));
        if c.shift_max_m > f.observer_shift_max_m {
            return Err(ParamError {
                leaf: leaf!(compensation.shift_max_m),
                reason: Reason::AboveObserverShiftMax,
            });
        }
        check!(positive(leaf!(compensation.shift_rate_max_m_s), c.shift_rate_max_m_s));
        let th = &self.thermal;
        check!(positive(leaf!(thermal.continuous_current_a), th.continuous_current_a));
        if th.continuous_current_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(thermal.continuous_current_a), reason: Reason::AboveCurrentLimit });
        }
        check!(positive(leaf!(thermal.time_constant_s), th.time_constant_s));
        check!(positive(leaf!(thermal.foldback_start), th.foldback_start));
        if th.foldback_start >= 1.0 {
            return Err(ParamError { leaf: leaf!(thermal.foldback_start), reason: Reason::MustBeBelowOne });
        }
        if !(th.trip_level > 1.0) || !th.trip_level.is_finite() {
            return Err(ParamError { leaf: leaf!(thermal.trip_level), reason: Reason::MustBeFiniteAboveOne });
        }
        let r = &self.ratings;
        check!(positive(leaf!(ratings.motor_peak_current_a), r.motor_peak_current_a));
        check!(positive(leaf!(ratings.inverter_peak_current_a), r.inverter_peak_current_a));
        check!(positive(leaf!(ratings.bus_max_voltage_v), r.bus_max_voltage_v));
        check!(positive(leaf!(ratings.speed_max_rad_s), r.speed_max_rad_s));
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
        let c = &self.calibration;
        check!(positive(leaf!(calibration.duration_s), c.duration_s));
        check!(positive(leaf!(calibration.offset_max_a), c.offset_max_a));
        check!(positive(leaf!(calibration.noise_max_a), c.noise_max_a));
        check!(positive(leaf!(calibration.bus_ripple_max_v), c.bus_ripple_max_v));
        let m = &self.commutation;
        check!(positive(leaf!(commutation.test_current_a), m.test_current_a));
        if m.test_current_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(commutation.test_current_a), reason: Reason::AboveCurrentLimit });
        }
        check!(positive(leaf!(commutation.ramp_s), m.ramp_s));
        check!(positive(leaf!(commutation.sweep_s), m.sweep_s));
        check!(positive(leaf!(commutation.settle_s), m.settle_s));
        check!(positive(leaf!(commutation.settle_speed_rad_s), m.settle_speed_rad_s));
        check!(positive(leaf!(commutation.settle_timeout_s), m.settle_timeout_s));
        check!(positive(leaf!(commutation.min_amplitude_counts), m.min_amplitude_counts));
        check!(positive(leaf!(commutation.max_twist_rad), m.max_twist_rad));
        check!(positive(leaf!(commutation.hold_current_d_a), m.hold_current_d_a));
        if m.hold_current_d_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(commutation.hold_current_d_a), reason: Reason::AboveCurrentLimit });
        }
        check!(positive(leaf!(commutation.check_angle_rad), m.check_angle_rad));
        check!(positive(leaf!(commutation.check_time_s), m.check_time_s));
        check!(positive(leaf!(commutation.ratio_tolerance), m.ratio_tolerance));
        check!(positive(leaf!(commutation.blocked_ratio), m.blocked_ratio));
        if m.blocked_ratio >= 1.0 - m.ratio_tolerance {
            return Err(ParamError { leaf: leaf!(commutation.blocked_ratio), reason: Reason::BlockedRatioTooHigh });
        }
        check!(positive(leaf!(commutation.timeout_s), m.timeout_s));
        let h = &self.homing;
        if h.direction != 1 && h.direction != -1 {
            return Err(ParamError { leaf: leaf!(homing.direction), reason: Reason::MustBeOneOrMinusOne });
        }
        check!(positive(leaf!(homing.speed_m_s), h.speed_m_s));
        if h.speed_m_s > self.trajectory.max_velocity_m_s {
            return Err(ParamError { leaf: leaf!(homing.speed_m_s), reason: Reason::AboveTrajectoryVelocity });
        }
        check!(positive(leaf!(homing.current_max_a), h.current_max_a));
        if h.current_max_a > l.current_max_a {
            return Err(ParamError { leaf: leaf!(homing.current_max_a), reason: Reason::AboveCurrentLimit });
        }
        check!(positive(leaf!(homing.contact_following_m), h.contact_following_m));
        check!(positive(leaf!(homing.contact_speed_rad_s), h.contact_speed_rad_s));
        check!(positive(leaf!(homing.contact_time_s), h.contact_time_s));
        if !h.home_position_m.is_finite() {
            return Err(ParamError { leaf: leaf!(homing.home_position_m), reason: Reason::MustBeFinite });
        }
        check!(non_negative(leaf!(homing.backoff_m), h.backoff_m));
        check!(positive(leaf!(homing.travel_max_m), h.travel_max_m));
        check!(positive(leaf!(homing.jog_speed_max_m_s), h.jog_speed_max_m_s));
        let p = &self.power_stage;
        check!(positive(leaf!(power_stage.temperature_foldback_c), p.temperature_foldback_c));
        if p.temperature_trip_c <= p.temperature_foldback_c || !p.temperature_trip_c.is_finite() {
            return Err(ParamError { leaf: leaf!(power_stage.temperature_trip_c), reason: Reason::MustExceedTemperatureFoldback });
        }
        check!(positive(leaf!(power_stage.regen_bus_start_v), p.regen_bus_start_v));
        if p.regen_bus_max_v <= p.regen_bus_start_v || !p.regen_bus_max_v.is_finite() {
            return Err(ParamError { leaf: leaf!(power_stage.regen_bus_max_v), reason: Reason::MustExceedRegenStart });
        }
        if p.regen_bus_max_v > self.faults.bus_overvoltage_v {
            return Err(ParamError {
                leaf: leaf!(power_stage.regen_bus_max_v),
                reason: Reason::RegenAboveOvervoltage,
            });
        }
        check!(non_negative(leaf!(power_stage.regen_power_max_w), p.regen_power_max_w));
        check!(positive(leaf!(power_stage.emf_speed_mismatch_rad_s), p.emf_speed_mismatch_rad_s));
        check!(positive(leaf!(power_stage.emf_mismatch_time_s), p.emf_mismatch_time_s));
        check!(positive(leaf!(stream.period_max_s), self.stream.period_max_s));
        if self.stream.timeout_s < self.stream.period_max_s || !self.stream.timeout_s.is_finite() {
            return Err(ParamError { leaf: leaf!(stream.timeout_s), reason: Reason::TimeoutBelowPeriodMax });
        }
        if self.stream.leg_index >= crate::protocol::can::LEGS as u32 {
            return Err(ParamError { leaf: leaf!(stream.leg_index), reason: Reason::NoSuchLegSlot });
        }
        Ok(())
    }
}
