//! The PI regulator every loop uses, with feedforward and anti-windup.

use crate::params::PiGains;

/// Integrator state of one PI regulator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pi {
    integral: f32,
}

/// One regulator update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiOutput {
    pub value: f32,
    /// The unclamped output lay outside `[lo, hi]`.
    pub saturated: bool,
}

impl Pi {
    pub const fn new() -> Self {
        Self { integral: 0.0 }
    }

    pub fn reset(&mut self) {
        self.integral = 0.0;
    }

    /// Starts the integrator at `value` (bumpless start on a known load).
    pub fn preset(&mut self, value: f32) {
        self.integral = value;
    }

    /// A proportional gain change from `kp_old` to `kp_new` that leaves the
    /// output for `error` where it was (bumpless transfer): the integrator
    /// takes up the difference. An integral gain change needs nothing: the
    /// integrator holds `∫ki·e dt`, not `∫e dt`, so a new `ki` acts only on
    /// the error still to come.
    pub fn retune(&mut self, kp_old: f32, kp_new: f32, error: f32) {
        let shift = (kp_old - kp_new) * error;
        if shift.is_finite() {
            self.integral += shift;
        }
    }

    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// `u = kp·e + ∫ki·e dt + ff`, clamped to `[lo, hi]`.
    ///
    /// Anti-windup by conditional integration: while the output is pinned at a
    /// limit the integrator only moves in the direction that leaves it, and it
    /// is held inside `[lo − ff, hi − ff]` so that, when the limits shrink (the
    /// q-axis voltage limit depends on u_d), recovery is immediate.
    #[inline]
    pub fn update(&mut self, gains: &PiGains, error: f32, feedforward: f32, lo: f32, hi: f32, dt_s: f32) -> PiOutput {
        let candidate = self.integral + gains.ki * error * dt_s;
        let proportional = gains.kp * error;
        let unclamped = proportional + candidate + feedforward;
        let (value, saturated) = if unclamped > hi {
            if error < 0.0 {
                self.integral = candidate;
            }
            (hi, true)
        } else if unclamped < lo {
            if error > 0.0 {
                self.integral = candidate;
            }
            (lo, true)
        } else {
            self.integral = candidate;
            (unclamped, false)
        };
        let i_lo = lo - feedforward;
        let i_hi = hi - feedforward;
        if i_lo <= i_hi {
            self.integral = crate::math::clamp(self.integral, i_lo, i_hi);
        }
        PiOutput { value, saturated }
    }
}
