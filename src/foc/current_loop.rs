//! The d-q current loop: runs every PWM period, in the ADC interrupt.

use super::svpwm::{linear_limit_v, svpwm};
use super::transforms::{clarke, inverse_park, park, Dq, SinCos};
use crate::params::ControlParams;
use crate::pi::Pi;

/// Two PI regulators with decoupling and back-EMF feedforward.
#[derive(Clone, Copy, Debug, Default)]
pub struct CurrentLoop {
    pi_d: Pi,
    pi_q: Pi,
}

/// What one current-loop period produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLoopOutput {
    pub duty: [f32; 3],
    pub current_dq: Dq,
    pub voltage_dq: Dq,
    /// The voltage circle limited u_d or u_q this period.
    pub voltage_limited: bool,
}

/// The loop's timing, derived from the PWM rate once (at parameter apply)
/// instead of a division every period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentTiming {
    /// One PWM period: the PI regulators' time step.
    pub period_s: f32,
    /// How far ahead the applied voltage vector must point: the duties act
    /// from the next period on, on average half a period later still, so
    /// 1.5 periods of electrical travel.
    pub advance_s: f32,
}

impl CurrentTiming {
    pub fn of(p: &ControlParams) -> Self {
        let period_s = p.pwm_period_s();
        Self { period_s, advance_s: 1.5 * period_s }
    }
}

/// Everything about the rotor the current loop needs this period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorState {
    /// Electrical angle at the ADC sample instant.
    pub electrical_angle_rad: f32,
    pub electrical_speed_rad_s: f32,
}

impl CurrentLoop {
    pub const fn new() -> Self {
        Self { pi_d: Pi::new(), pi_q: Pi::new() }
    }

    pub fn reset(&mut self) {
        self.pi_d.reset();
        self.pi_q.reset();
    }

    /// A proportional gain change, bumpless for the last current error
    /// (reference − measured, d and q).
    pub fn retune(&mut self, kp_old: f32, kp_new: f32, error: Dq) {
        self.pi_d.retune(kp_old, kp_new, error.d);
        self.pi_q.retune(kp_old, kp_new, error.q);
    }

    #[inline]
    pub fn step(
        &mut self,
        p: &ControlParams,
        timing: CurrentTiming,
        phase_current_a: [f32; 3],
        reference: Dq,
        rotor: RotorState,
        bus_voltage_v: f32,
    ) -> CurrentLoopOutput {
        let dt = timing.period_s;
        let m = &p.motor;
        let sc = SinCos::of(rotor.electrical_angle_rad);
        let current = park(clarke(phase_current_a), sc);
        let w = rotor.electrical_speed_rad_s;

        // Feedforward from the references rather than the measured currents:
        // same steady state, without injecting ADC noise into the voltages.
        let ff_d = -w * m.inductance_q_h * reference.q;
        let ff_q = w * (m.inductance_d_h * reference.d + m.flux_linkage_wb);

        // d-axis first: it holds the flux; q gets what is left of the circle.
        let v_max = linear_limit_v(bus_voltage_v) * p.limits.max_modulation;
        let ud = self.pi_d.update(&p.current_pi, reference.d - current.d, ff_d, -v_max, v_max, dt);
        let uq_max = crate::math::sqrt_non_negative(v_max * v_max - ud.value * ud.value);
        let uq = self.pi_q.update(&p.current_pi, reference.q - current.q, ff_q, -uq_max, uq_max, dt);
        let voltage_dq = Dq { d: ud.value, q: uq.value };

        // Rotated ahead so the applied vector sits where the rotor will be
        // while it acts (see `CurrentTiming::advance_s`).
        let out = svpwm(inverse_park(voltage_dq, sc.advanced_by(timing.advance_s * w)), bus_voltage_v);
        CurrentLoopOutput {
            duty: out.duty,
            current_dq: current,
            voltage_dq,
            voltage_limited: ud.saturated || uq.saturated || out.limited,
        }
    }
}
