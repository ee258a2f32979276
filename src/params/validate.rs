//! `ControlParams::validate`: every field checked, the first bad one named.
//! A `const fn`, so the firmware's set is checked when the image is built.

use super::ControlParams;

/// A parameter that cannot be used, named by its path in the TOML file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    pub field: &'static str,
    pub reason: &'static str,
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "parameter `{}`: {}", self.field, self.reason)
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
const fn positive(field: &'static str, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { field, reason: "must be finite" })
    } else if v <= 0.0 {
        Err(ParamError { field, reason: "must be > 0" })
    } else {
        Ok(())
    }
}

// Out of line: ≈ 100 call sites, each inlined copy costs flash (the
// run-time validation is not on any fast path).
#[inline(never)]
const fn non_negative(field: &'static str, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { field, reason: "must be finite" })
    } else if v < 0.0 {
        Err(ParamError { field, reason: "must be >= 0" })
    } else {
        Ok(())
    }
}

// Out of line: ≈ 100 call sites, each inlined copy costs flash (the
// run-time validation is not on any fast path).
#[inline(never)]
const fn nonzero(field: &'static str, v: u32) -> Result<(), ParamError> {
    if v == 0 { Err(ParamError { field, reason: "must be >= 1" }) } else { Ok(()) }
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
        check!(nonzero("control.motor.pole_pairs", m.pole_pairs));
        check!(positive("control.motor.phase_resistance_ohm", m.phase_resistance_ohm));
        check!(positive("control.motor.inductance_d_h", m.inductance_d_h));
        check!(positive("control.motor.inductance_q_h", m.inductance_q_h));
        check!(positive("control.motor.flux_linkage_wb", m.flux_linkage_wb));
        let d = &self.drive_train;
        check!(positive("control.drive_train.screw_lead_m", d.screw_lead_m));
        check!(positive("control.drive_train.screw_efficiency", d.screw_efficiency));
        if d.screw_efficiency > 1.0 {
            return Err(ParamError { field: "control.drive_train.screw_efficiency", reason: "must be <= 1" });
        }
        check!(positive("control.drive_train.rotating_inertia_kg_m2", d.rotating_inertia_kg_m2));
        check!(non_negative("control.drive_train.moving_mass_kg", d.moving_mass_kg));
        check!(non_negative("control.drive_train.viscous_friction_n_m_s_rad", d.viscous_friction_n_m_s_rad));
        check!(non_negative("control.drive_train.coulomb_friction_n_m", d.coulomb_friction_n_m));
        check!(positive("control.drive_train.friction_feedforward_speed_rad_s", d.friction_feedforward_speed_rad_s));
        check!(non_negative("control.drive_train.friction_feedforward_gain", d.friction_feedforward_gain));
        if d.friction_feedforward_gain > 1.0 {
            // Above the modelled friction the feedforward drives the rod
            // ahead of its reference at every start.
            return Err(ParamError { field: "control.drive_train.friction_feedforward_gain", reason: "must be <= 1" });
        }
        check!(positive("control.rates.pwm_frequency_hz", self.rates.pwm_frequency_hz));
        check!(nonzero("control.rates.speed_loop_divider", self.rates.speed_loop_divider));
        check!(nonzero("control.rates.position_loop_divider", self.rates.position_loop_divider));
        if !self.rates.position_loop_divider.is_multiple_of(self.rates.speed_loop_divider) {
            return Err(ParamError {
                field: "control.rates.position_loop_divider",
                reason: "must be a multiple of speed_loop_divider",
            });
        }
        check!(positive("control.current_pi.kp", self.current_pi.kp));
        check!(non_negative("control.current_pi.ki", self.current_pi.ki));
        check!(positive("control.speed_pi.kp", self.speed_pi.kp));
        check!(non_negative("control.speed_pi.ki", self.speed_pi.ki));
        check!(non_negative("control.speed_setpoint_weight", self.speed_setpoint_weight));
        if self.speed_setpoint_weight > 2.0 {
            return Err(ParamError { field: "control.speed_setpoint_weight", reason: "must be <= 2" });
        }
        check!(non_negative("control.torque_filter_hz", self.torque_filter_hz));
        check!(positive("control.position_kp_per_s", self.position_kp_per_s));
        let e = &self.encoder;
        check!(nonzero("control.encoder.counts_per_rev", e.counts_per_rev));
        if e.counts_per_rev > 32_768 {
            // The core unwraps a 16-bit counter: one revolution must fit in half its range.
            return Err(ParamError { field: "control.encoder.counts_per_rev", reason: "must be <= 32768" });
        }
        if e.direction != 1 && e.direction != -1 {
            return Err(ParamError { field: "control.encoder.direction", reason: "must be 1 or -1" });
        }
        if !e.electrical_offset_rad.is_finite() {
            return Err(ParamError { field: "control.encoder.electrical_offset_rad", reason: "must be finite" });
        }
        check!(positive("control.encoder.pll_kp_per_s", e.pll_kp_per_s));
        check!(positive("control.encoder.pll_ki_per_s2", e.pll_ki_per_s2));
        let t = &self.trajectory;
        check!(positive("control.trajectory.max_velocity_m_s", t.max_velocity_m_s));
        check!(positive("control.trajectory.max_acceleration_m_s2", t.max_acceleration_m_s2));
        check!(positive("control.trajectory.max_jerk_m_s3", t.max_jerk_m_s3));
        let l = &self.limits;
        check!(positive("control.limits.current_max_a", l.current_max_a));
        check!(positive("control.limits.copper_power_max_w", l.copper_power_max_w));
        check!(positive("control.limits.speed_max_rad_s", l.speed_max_rad_s));
        check!(non_negative("control.limits.stroke_min_m", l.stroke_min_m));
        check!(positive("control.limits.stroke_max_m", l.stroke_max_m));
        if l.stroke_max_m <= l.stroke_min_m {
            return Err(ParamError { field: "control.limits.stroke_max_m", reason: "must exceed stroke_min_m" });
        }
        check!(positive("control.limits.max_modulation", l.max_modulation));
        if l.max_modulation > 1.0 {
            return Err(ParamError { field: "control.limits.max_modulation", reason: "must be <= 1" });
        }
        let f = &self.faults;
        check!(positive("control.faults.overcurrent_trip_a", f.overcurrent_trip_a));
        if f.overcurrent_trip_a < l.current_max_a {
            return Err(ParamError {
                field: "control.faults.overcurrent_trip_a",
                reason: "must be >= limits.current_max_a, or normal operation trips",
            });
        }
        check!(positive("control.faults.bus_overvoltage_v", f.bus_overvoltage_v));
        check!(positive("control.faults.bus_undervoltage_v", f.bus_undervoltage_v));
        if f.bus_overvoltage_v <= f.bus_undervoltage_v {
            return Err(ParamError { field: "control.faults.bus_overvoltage_v", reason: "must exceed bus_undervoltage_v" });
        }
        check!(nonzero("control.faults.encoder_max_step_counts", f.encoder_max_step_counts));
        check!(positive("control.faults.encoder_max_innovation_counts", f.encoder_max_innovation_counts));
        check!(positive("control.faults.position_following_error_m", f.position_following_error_m));
        check!(non_negative("control.faults.stroke_overtravel_m", f.stroke_overtravel_m));
        check!(positive("control.load_estimate.filter_hz", self.load_estimate.filter_hz));
        check!(self.validate_lifecycle());
        check!(positive("control.faults.speed_following_error_rad_s", f.speed_following_error_rad_s));
        check!(positive("control.faults.speed_following_time_s", f.speed_following_time_s));
        check!(positive("control.faults.encoder_lost_speed_rad_s", f.encoder_lost_speed_rad_s));
        check!(positive("control.faults.encoder_lost_time_s", f.encoder_lost_time_s));
        check!(non_negative("control.faults.stroke_soft_margin_m", f.stroke_soft_margin_m));
        if f.stroke_soft_margin_m >= f.stroke_overtravel_m {
            return Err(ParamError {
                field: "control.faults.stroke_soft_margin_m",
                reason: "must be below stroke_overtravel_m, or a controlled stop ends in a trip",
            });
        }
        check!(positive("control.faults.stop_deceleration_m_s2", f.stop_deceleration_m_s2));
        if f.stop_deceleration_m_s2 < self.trajectory.max_acceleration_m_s2 {
            return Err(ParamError {
                field: "control.faults.stop_deceleration_m_s2",
                reason: "must be >= trajectory.max_acceleration_m_s2, or planned moves trip the soft limits",
            });
        }
        check!(positive("control.faults.observer_shift_max_m", f.observer_shift_max_m));
        check!(positive("control.faults.current_sum_max_a", f.current_sum_max_a));
        check!(nonzero("control.faults.current_sum_periods", f.current_sum_periods));
        check!(positive("control.faults.stop_following_error_m", f.stop_following_error_m));
        check!(positive("control.faults.open_phase_window_s", f.open_phase_window_s));
        check!(positive("control.faults.open_phase_current_a", f.open_phase_current_a));
        check!(positive("control.faults.open_phase_ratio", f.open_phase_ratio));
        if f.open_phase_ratio >= 1.0 {
            return Err(ParamError { field: "control.faults.open_phase_ratio", reason: "must be < 1" });
        }
        let b = &self.brake;
        check!(non_negative("control.brake.release_time_s", b.release_time_s));
        check!(non_negative("control.brake.engage_time_s", b.engage_time_s));
        check!(non_negative("control.brake.holding_torque_n_m", b.holding_torque_n_m));
        check!(non_negative("control.brake.preload_time_s", b.preload_time_s));
        let c = &self.compensation;
        check!(positive("control.compensation.shift_max_m", c.shift_max_m));
        if c.shift_max_m > f.observer_shift_max_m {
            return Err(ParamError {
                field: "control.compensation.shift_max_m",
                reason: "must be <= faults.observer_shift_max_m",
            });
        }
        check!(positive("control.compensation.shift_rate_max_m_s", c.shift_rate_max_m_s));
        let th = &self.thermal;
        check!(positive("control.thermal.continuous_current_a", th.continuous_current_a));
        if th.continuous_current_a > l.current_max_a {
            return Err(ParamError { field: "control.thermal.continuous_current_a", reason: "must be <= limits.current_max_a" });
        }
        check!(positive("control.thermal.time_constant_s", th.time_constant_s));
        check!(positive("control.thermal.foldback_start", th.foldback_start));
        if th.foldback_start >= 1.0 {
            return Err(ParamError { field: "control.thermal.foldback_start", reason: "must be < 1" });
        }
        if !(th.trip_level > 1.0) || !th.trip_level.is_finite() {
            return Err(ParamError { field: "control.thermal.trip_level", reason: "must be finite and > 1" });
        }
        let r = &self.ratings;
        check!(positive("control.ratings.motor_peak_current_a", r.motor_peak_current_a));
        check!(positive("control.ratings.inverter_peak_current_a", r.inverter_peak_current_a));
        check!(positive("control.ratings.bus_max_voltage_v", r.bus_max_voltage_v));
        check!(positive("control.ratings.speed_max_rad_s", r.speed_max_rad_s));
        if l.current_max_a > r.motor_peak_current_a || l.current_max_a > r.inverter_peak_current_a {
            return Err(ParamError {
                field: "control.limits.current_max_a",
                reason: "above the motor or inverter peak rating (control.ratings)",
            });
        }
        if f.overcurrent_trip_a > r.inverter_peak_current_a {
            return Err(ParamError {
                field: "control.faults.overcurrent_trip_a",
                reason: "above control.ratings.inverter_peak_current_a",
            });
        }
        if f.bus_overvoltage_v > r.bus_max_voltage_v {
            return Err(ParamError { field: "control.faults.bus_overvoltage_v", reason: "above control.ratings.bus_max_voltage_v" });
        }
        if l.speed_max_rad_s > r.speed_max_rad_s {
            return Err(ParamError { field: "control.limits.speed_max_rad_s", reason: "above control.ratings.speed_max_rad_s" });
        }
        Ok(())
    }
}

impl ControlParams {
    /// The start-up steps and the power stage's limits.
    const fn validate_lifecycle(&self) -> Result<(), ParamError> {
        let l = &self.limits;
        if !self.startup.expected_load_force_n.is_finite() {
            return Err(ParamError { field: "control.startup.expected_load_force_n", reason: "must be finite" });
        }
        let c = &self.calibration;
        check!(positive("control.calibration.duration_s", c.duration_s));
        check!(positive("control.calibration.offset_max_a", c.offset_max_a));
        check!(positive("control.calibration.noise_max_a", c.noise_max_a));
        check!(positive("control.calibration.bus_ripple_max_v", c.bus_ripple_max_v));
        let m = &self.commutation;
        check!(positive("control.commutation.test_current_a", m.test_current_a));
        if m.test_current_a > l.current_max_a {
            return Err(ParamError { field: "control.commutation.test_current_a", reason: "must be <= limits.current_max_a" });
        }
        check!(positive("control.commutation.ramp_s", m.ramp_s));
        check!(positive("control.commutation.sweep_s", m.sweep_s));
        check!(positive("control.commutation.settle_s", m.settle_s));
        check!(positive("control.commutation.settle_speed_rad_s", m.settle_speed_rad_s));
        check!(positive("control.commutation.settle_timeout_s", m.settle_timeout_s));
        check!(positive("control.commutation.min_amplitude_counts", m.min_amplitude_counts));
        check!(positive("control.commutation.max_twist_rad", m.max_twist_rad));
        check!(positive("control.commutation.hold_current_d_a", m.hold_current_d_a));
        if m.hold_current_d_a > l.current_max_a {
            return Err(ParamError { field: "control.commutation.hold_current_d_a", reason: "must be <= limits.current_max_a" });
        }
        check!(positive("control.commutation.check_angle_rad", m.check_angle_rad));
        check!(positive("control.commutation.check_time_s", m.check_time_s));
        check!(positive("control.commutation.ratio_tolerance", m.ratio_tolerance));
        check!(positive("control.commutation.blocked_ratio", m.blocked_ratio));
        if m.blocked_ratio >= 1.0 - m.ratio_tolerance {
            return Err(ParamError { field: "control.commutation.blocked_ratio", reason: "must be below 1 - ratio_tolerance" });
        }
        check!(positive("control.commutation.timeout_s", m.timeout_s));
        let h = &self.homing;
        if h.direction != 1 && h.direction != -1 {
            return Err(ParamError { field: "control.homing.direction", reason: "must be 1 or -1" });
        }
        check!(positive("control.homing.speed_m_s", h.speed_m_s));
        if h.speed_m_s > self.trajectory.max_velocity_m_s {
            return Err(ParamError { field: "control.homing.speed_m_s", reason: "must be <= trajectory.max_velocity_m_s" });
        }
        check!(positive("control.homing.current_max_a", h.current_max_a));
        if h.current_max_a > l.current_max_a {
            return Err(ParamError { field: "control.homing.current_max_a", reason: "must be <= limits.current_max_a" });
        }
        check!(positive("control.homing.contact_following_m", h.contact_following_m));
        check!(positive("control.homing.contact_speed_rad_s", h.contact_speed_rad_s));
        check!(positive("control.homing.contact_time_s", h.contact_time_s));
        if !h.home_position_m.is_finite() {
            return Err(ParamError { field: "control.homing.home_position_m", reason: "must be finite" });
        }
        check!(non_negative("control.homing.backoff_m", h.backoff_m));
        check!(positive("control.homing.travel_max_m", h.travel_max_m));
        check!(positive("control.homing.jog_speed_max_m_s", h.jog_speed_max_m_s));
        let p = &self.power_stage;
        check!(positive("control.power_stage.temperature_foldback_c", p.temperature_foldback_c));
        if p.temperature_trip_c <= p.temperature_foldback_c || !p.temperature_trip_c.is_finite() {
            return Err(ParamError { field: "control.power_stage.temperature_trip_c", reason: "must exceed temperature_foldback_c" });
        }
        check!(positive("control.power_stage.regen_bus_start_v", p.regen_bus_start_v));
        if p.regen_bus_max_v <= p.regen_bus_start_v || !p.regen_bus_max_v.is_finite() {
            return Err(ParamError { field: "control.power_stage.regen_bus_max_v", reason: "must exceed regen_bus_start_v" });
        }
        if p.regen_bus_max_v > self.faults.bus_overvoltage_v {
            return Err(ParamError {
                field: "control.power_stage.regen_bus_max_v",
                reason: "must be <= faults.bus_overvoltage_v, or regeneration trips the drive first",
            });
        }
        check!(non_negative("control.power_stage.regen_power_max_w", p.regen_power_max_w));
        check!(positive("control.power_stage.emf_speed_mismatch_rad_s", p.emf_speed_mismatch_rad_s));
        check!(positive("control.power_stage.emf_mismatch_time_s", p.emf_mismatch_time_s));
        check!(positive("control.stream.period_max_s", self.stream.period_max_s));
        if self.stream.timeout_s < self.stream.period_max_s || !self.stream.timeout_s.is_finite() {
            return Err(ParamError { field: "control.stream.timeout_s", reason: "must be >= stream.period_max_s" });
        }
        if self.stream.leg_index >= crate::protocol::can::LEGS as u32 {
            return Err(ParamError { field: "control.stream.leg_index", reason: "must be 0..=5 (a slot of the CAN setpoint frame)" });
        }
        Ok(())
    }
}
