//! Terminal-error compensation (paper §4.2, Eq. 42): each position period the
//! IBAS-BPNN observer predicts the terminal error δ̂ (terminal − motor side)
//! from what the drive measures, and the position command becomes the
//! reference minus δ̂, so the piston rod rather than the motor lands on target.
//!
//! The paper writes the update recursively, `x*(k+1) = x*(k) + δ̂(k)`. Read
//! literally that integrates δ̂ every period, and δ̂ is the *whole* predicted
//! error, not an increment: a constant 0.3 mm sag would walk the command away
//! by 0.3 mm per millisecond. We apply it as a shift of the reference,
//! `x*(k) = x_ref(k) − δ̂(k)`, which is what the recursion means once x*(k) is
//! read as "the reference at k" (the counter in the paper's pulse-train drive
//! is reset to the reference each period).
//!
//! The shift is bounded (the paper's largest compensation, 1.5 mm) and
//! rate-limited so a jump in the load estimate cannot kick the rod. A
//! non-finite prediction or one beyond `faults.observer_shift_max_m` is a
//! fault (controlled stop); inputs outside the trained range are clamped by
//! the forward pass and flagged.

use crate::observer::{self, block::Weights, model, ModelKind, NETWORK_INPUTS};
use crate::params::ControlParams;

/// What one compensation update produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompensationOutput {
    /// Shift added to the reference this period (m).
    pub shift_m: f32,
    /// How fast the prediction moved the shift this period (m/s), fed
    /// forward as part of the commanded velocity; 0 while the rate limit
    /// acts (the shift ramping in after enable, or out when switched off),
    /// which the position loop follows as a move of its own.
    pub rate_m_s: f32,
    /// The bound or the rate limit acted.
    pub limited: bool,
    /// An observer input lay outside the trained range (clamped).
    pub input_clamped: bool,
    /// The prediction was unusable (non-finite, or beyond the fault bound).
    pub out_of_bounds: bool,
}

/// The compensation state: on/off, the shift last applied, and the weights
/// the observer runs (the compiled model unless a block was uploaded; a
/// reference, so an uploaded block costs no RAM of the controller's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compensator {
    enabled: bool,
    shift_m: f32,
    model: &'static Weights,
    /// Sign of the last nonzero planned velocity (+1 elongation, −1
    /// contraction; 0 before the first planned move): the observer's fifth
    /// input, held at rest because the screw's and the seal's friction stay
    /// turned the way the last move left them.
    travel_direction: f32,
}

impl Default for Compensator {
    fn default() -> Self {
        Self::new(false)
    }
}

impl Compensator {
    pub const fn new(enabled: bool) -> Self {
        Self { enabled, shift_m: 0.0, model: &observer::block::COMPILED, travel_direction: 0.0 }
    }

    /// The direction of travel after a period whose planned velocity is
    /// `planned_velocity_m_s`: its sign, or the last one while the plan is
    /// at rest. Range `[-1, 1]` (0 only before the first planned move).
    pub fn travel_direction(&mut self, planned_velocity_m_s: f32) -> f32 {
        if planned_velocity_m_s > 0.0 {
            self.travel_direction = 1.0;
        } else if planned_velocity_m_s < 0.0 {
            self.travel_direction = -1.0;
        }
        self.travel_direction
    }

    /// The weights the observer runs from the next period on. The shift
    /// moves to the new prediction at the rate limit.
    pub fn set_model(&mut self, model: &'static Weights) {
        self.model = model;
    }

    pub fn model(&self) -> &'static Weights {
        self.model
    }

    /// Whether the observer runs the compiled weights.
    pub fn model_is_compiled(&self) -> bool {
        core::ptr::eq(self.model, &observer::block::COMPILED)
    }

    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Switching off ramps nothing: the shift returns to zero at the rate
    /// limit through `update`, so the rod does not jump.
    pub fn set_enabled(&mut self, on: bool) {
        self.enabled = on;
    }

    pub fn reset(&mut self) {
        self.shift_m = 0.0;
    }

    /// The observer's inputs, in the order the network takes them, from the
    /// drive's own signals: encoder speed, nut speed and displacement through
    /// the lead, the load force (estimate or load cell), and the direction
    /// of travel ([`Self::travel_direction`]; a four-input model leaves it
    /// unused).
    pub fn inputs(
        p: &ControlParams,
        speed_rad_s: f32,
        motor_position_m: f32,
        load_force_n: f32,
        travel_direction: f32,
    ) -> [f32; NETWORK_INPUTS] {
        [speed_rad_s, speed_rad_s * p.metres_per_rad(), motor_position_m, load_force_n, travel_direction]
    }

    /// One position period.
    pub fn update(&mut self, p: &ControlParams, inputs: [f32; NETWORK_INPUTS], dt_s: f32) -> CompensationOutput {
        let c = &p.compensation;
        let mut out = CompensationOutput::default();
        let target = if self.enabled && model::META.kind == ModelKind::Error {
            let pred = observer::evaluate(self.model, inputs);
            out.input_clamped = pred.clamped;
            if !pred.valid || pred.value_m.abs() > p.faults.observer_shift_max_m {
                out.out_of_bounds = true;
                0.0
            } else {
                // δ̂ is terminal − motor side: command the motor that much the
                // other way.
                let wanted = -pred.value_m;
                let bounded = crate::math::clamp(wanted, -c.shift_max_m, c.shift_max_m);
                out.limited = bounded != wanted;
                bounded
            }
        } else {
            0.0
        };
        let step_max = c.shift_rate_max_m_s * dt_s;
        let step = crate::math::clamp(target - self.shift_m, -step_max, step_max);
        let ramping = step != target - self.shift_m;
        out.limited |= ramping && self.enabled;
        self.shift_m += step;
        out.shift_m = self.shift_m;
        out.rate_m_s = if ramping || dt_s <= 0.0 { 0.0 } else { step / dt_s };
        out
    }
}
