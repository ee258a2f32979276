//! Speed loop: PI on the tracked encoder speed, with acceleration and viscous
//! feedforward, producing the q-axis current reference.

use crate::filters::Biquad;
use crate::params::ControlParams;
use crate::pi::Pi;

#[derive(Clone, Copy, Debug, Default)]
pub struct SpeedLoop {
    pi: Pi,
    torque_filter: Biquad,
}

/// One speed-loop update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedLoopOutput {
    pub current_q_reference_a: f32,
    /// The q-current reference hit the Eq. 19 current bound.
    pub current_limited: bool,
}

impl SpeedLoop {
    pub fn new(p: &ControlParams) -> Self {
        let rate_hz = p.rates.pwm_frequency_hz / p.rates.speed_loop_divider as f32;
        Self { pi: Pi::new(), torque_filter: Biquad::low_pass(p.torque_filter_hz, rate_hz) }
    }

    pub fn reset(&mut self) {
        self.pi.reset();
        self.torque_filter.reset();
    }

    /// `current_limit_a` is the q-axis share of the current circle.
    pub fn step(
        &mut self,
        p: &ControlParams,
        speed_reference_rad_s: f32,
        acceleration_reference_rad_s2: f32,
        speed_measured_rad_s: f32,
        current_limit_a: f32,
    ) -> SpeedLoopOutput {
        let torque_ff = p.reflected_inertia_kg_m2() * acceleration_reference_rad_s2
            + p.drive_train.viscous_friction_n_m_s_rad * speed_reference_rad_s;
        let ff_a = torque_ff / p.torque_constant_n_m_a();
        let out = self.pi.update(
            &p.speed_pi,
            speed_reference_rad_s - speed_measured_rad_s,
            ff_a,
            -current_limit_a,
            current_limit_a,
            p.speed_period_s(),
        );
        // The filter sits after the limit, so its output can overshoot the
        // bound only by the filter's 4 % step overshoot; clamp that too.
        let filtered = crate::math::clamp(self.torque_filter.update(out.value), -current_limit_a, current_limit_a);
        SpeedLoopOutput { current_q_reference_a: filtered, current_limited: out.saturated }
    }
}
