//! Speed loop: PI on the tracked encoder speed, with acceleration, viscous
//! and Coulomb-friction feedforward, producing the q-axis current reference.

use crate::filters::Biquad;
use crate::params::ControlParams;
use crate::pi::Pi;

/// Share of each new speed error in the mean a gain change transfers
/// (0.1 at 5 kHz: ≈ 80 Hz, a 2 ms window).
const ERROR_MEAN_SHARE: f32 = 0.1;

#[derive(Clone, Copy, Debug, Default)]
pub struct SpeedLoop {
    pi: Pi,
    torque_filter: Biquad,
    /// The P term's error (`b r − y`), low-passed over ≈ 2 ms (for a
    /// bumpless gain change: its noise passes the P term once, only its
    /// mean would stay).
    error_mean_rad_s: f32,
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
        Self { pi: Pi::new(), torque_filter: Biquad::low_pass(p.torque_filter_hz, rate_hz), error_mean_rad_s: 0.0 }
    }

    /// New gains and torque-filter corner between two updates, the states
    /// kept: the PI's output for the last error stays where it was (see
    /// [`Pi::retune`]) and a new filter starts settled at `current_q_a`,
    /// the reference it delivered last.
    pub fn retune(&mut self, old: &ControlParams, new: &ControlParams, current_q_a: f32) {
        self.pi.retune(old.speed_pi.kp, new.speed_pi.kp, self.error_mean_rad_s);
        if old.torque_filter_hz != new.torque_filter_hz {
            let rate_hz = new.rates.pwm_frequency_hz / new.rates.speed_loop_divider as f32;
            self.torque_filter = Biquad::low_pass(new.torque_filter_hz, rate_hz);
            self.torque_filter.preset(current_q_a);
        }
    }

    pub fn reset(&mut self) {
        self.pi.reset();
        self.torque_filter.reset();
    }

    /// Starts the loop already delivering `current_q_a` at rest: the hold
    /// current is there before the brake lets go.
    pub fn preload(&mut self, current_q_a: f32) {
        self.pi.preset(current_q_a);
        self.torque_filter.preset(current_q_a);
    }

    /// `[current_min_a, current_max_a]` is the q-axis share of the current
    /// circle, narrowed where regeneration or homing bound one side;
    /// `friction_ff_n_m` comes from [`friction_feedforward_n_m`].
    pub fn step(
        &mut self,
        p: &ControlParams,
        speed_reference_rad_s: f32,
        acceleration_reference_rad_s2: f32,
        friction_ff_n_m: f32,
        speed_measured_rad_s: f32,
        (current_min_a, current_max_a): (f32, f32),
    ) -> SpeedLoopOutput {
        let torque_ff = p.reflected_inertia_kg_m2() * acceleration_reference_rad_s2
            + p.drive_train.viscous_friction_n_m_s_rad * speed_reference_rad_s
            + friction_ff_n_m;
        let mut ff_a = torque_ff / p.torque_constant_n_m_a();
        let b = p.speed_setpoint_weight;
        if b != 1.0 {
            // Setpoint weighting: kp (b r − y) = kp (r − y) − kp (1 − b) r;
            // the second term rides with the feedforward (skipped at 1, so
            // the plain PI is bit for bit what it was).
            ff_a -= p.speed_pi.kp * (1.0 - b) * speed_reference_rad_s;
        }
        let error = speed_reference_rad_s - speed_measured_rad_s;
        // What the P term multiplies: `b r − y`. A live kp change must carry
        // the weighted error's mean into the integrator, or the `kp (1 − b) r`
        // riding with the feedforward steps by `Δkp (1 − b) r` (b itself
        // changes only with the bridge off).
        let p_error = if b != 1.0 { error - (1.0 - b) * speed_reference_rad_s } else { error };
        self.error_mean_rad_s += ERROR_MEAN_SHARE * (p_error - self.error_mean_rad_s);
        let out = self.pi.update(
            &p.speed_pi,
            error,
            ff_a,
            current_min_a,
            current_max_a,
            p.speed_period_s(),
        );
        // The filter sits after the limit, so its output can overshoot the
        // bound only by the filter's 4 % step overshoot; clamp that too.
        let filtered = crate::math::clamp(self.torque_filter.update(out.value), current_min_a, current_max_a);
        SpeedLoopOutput { current_q_reference_a: filtered, current_limited: out.saturated }
    }
}

/// The Coulomb friction a move meets, fed forward so the speed PI does not
/// have to wind it up at every start: that wind-up is the motor's lag in the
/// first tens of milliseconds of a move, and it adds straight to the rod's
/// terminal error. The screw's share grows with the axial load as
/// `(L/2π)·μ·|F|`, `μ = (1 − η)/η`, the law behind the forward efficiency η;
/// `load_force_n` is the slow load estimate (weight and tilt). The sign
/// follows the planned velocity, never the measured one, so the feedforward
/// cannot close a loop around stick-slip.
pub fn friction_feedforward_n_m(p: &ControlParams, velocity_reference_m_s: f32, load_force_n: f32) -> f32 {
    p.drive_train.friction_feedforward_gain * friction_direction(p, velocity_reference_m_s) * coulomb_friction_n_m(p, load_force_n)
}

/// Direction of the friction for a planned velocity, −1 to 1: ramped over
/// `friction_feedforward_speed_rad_s`, since a hard sign would chatter at
/// standstill, where the friction can take any value within its size.
pub fn friction_direction(p: &ControlParams, velocity_reference_m_s: f32) -> f32 {
    let omega = velocity_reference_m_s / p.metres_per_rad();
    crate::math::clamp(omega / p.drive_train.friction_feedforward_speed_rad_s, -1.0, 1.0)
}

/// Size of the whole modelled Coulomb friction at the motor shaft (the
/// feedforward before its gain and sign): load-independent drag plus the
/// screw's share of the axial load.
pub fn coulomb_friction_n_m(p: &ControlParams, load_force_n: f32) -> f32 {
    let d = &p.drive_train;
    let mu = (1.0 - d.screw_efficiency) / d.screw_efficiency;
    let load = if load_force_n.is_finite() { load_force_n.abs() } else { 0.0 };
    d.coulomb_friction_n_m + p.metres_per_rad() * mu * load
}
