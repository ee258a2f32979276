//! A controlled stop the load is winning, on a drive whose motor is stronger
//! than its brake: a load beyond the rating (on a near-empty rod, a push
//! neither the motor nor the brake holds alone). Handing it to the brake
//! alone lets it slide; fighting on with the motor alone lets it run. Motor
//! and brake together hold it: the brake closes under the loops, which hold
//! on for the brake's engage time. Then the motor's share is ramped down
//! over one more engage time, and kept at nothing for a third, while the
//! rod is watched (near the ramp's end a slip has not yet moved the rod
//! far enough to be seen; the dwell sees it). A rod that slips
//! means the brake alone does not yet hold what the load asks: the motor
//! gets its whole share back and holds for another engage time before the
//! next try. A ramp that ends without a slip leaves the brake holding alone,
//! and the bridge goes off (the latched fault keeps the drive in `Fault`).
//! A load that never lets go ends with the I²t trip or the stroke
//! overtravel, which close the brake and switch off.

use super::Controller;
use crate::io::{PwmCommand, SensorSample};
use crate::protection::LimitFlags;
use crate::telemetry::Mode;

impl Controller {
    /// A controlled stop is already lost when the motor is at its limit,
    /// the rod runs away from the stop and, at its present acceleration,
    /// would pass within the brake's engage time the speed where the
    /// back-EMF and the reactance's drop at the current limit fill the
    /// bus's voltage circle: there the braking current escapes the current
    /// loop, the comparator trips and the brake, weaker than the load,
    /// slides. A light rod (little mass beyond the rotor's) gets there while
    /// the stop strays its error bound; called now, the brake closes on a
    /// slower rod. A rotor springing back off an obstacle is too slow.
    /// Called every position period of such a stop (the acceleration is
    /// the speed's change since the last one, or since the stop began).
    #[inline(never)]
    pub(super) fn stop_outruns_bus(&mut self, x: f32) -> bool {
        let w = self.speed_rad_s();
        let accel = (w - core::mem::replace(&mut self.speed_prev_rad_s, w)) / self.derived.position_period_s;
        let m = &self.params.motor;
        let i = self.derived.current_limit_a;
        let flux = crate::math::sqrt(m.flux_linkage_wb * m.flux_linkage_wb + m.inductance_q_h * m.inductance_q_h * i * i);
        let bus_speed =
            crate::foc::svpwm::linear_limit_v(self.bus_voltage_v) * self.params.limits.max_modulation / (flux * m.pole_pairs as f32);
        (self.position_command_m - x) * w < 0.0
            && w * accel > 0.0
            && (w + accel * self.params.brake.engage_time_s).abs() > bus_speed
            && self.limits.intersects(LimitFlags::CURRENT.union(LimitFlags::VOLTAGE))
    }

    /// The brake closes under a controlled stop the load is winning; the
    /// loops hold on with it, the stop anchored where the rod got to.
    #[inline(never)]
    pub(super) fn assist_stop_with_brake(&mut self) {
        self.stop_brake_assist = true;
        self.brake_periods = 0;
        self.anchor_assisted_stop();
        self.handover_anchor_m = self.motor_position_m();
        self.set_mode(Mode::Braking);
    }

    /// Under the brake's assist the stop holds wherever the rod is, every
    /// position period: the position loop must not drive the rod back
    /// through the closed brake, and the speed loop alone opposes motion.
    #[inline(never)]
    pub(super) fn anchor_assisted_stop(&mut self) {
        let x = self.motor_position_m();
        self.stop = crate::motion::StopRamp::new(x, 0.0, self.params.faults.stop_deceleration_m_s2);
        self.position_command_m = x;
    }

    /// `Braking` under the assist: hold with the brake for its engage time,
    /// ramp the motor's share down over one more, hold none for a third,
    /// watching for a slip throughout the last two.
    #[inline(never)]
    pub(super) fn assisted_braking_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        let engage = self.derived.brake_engage_periods.max(1);
        self.brake_periods = self.brake_periods.saturating_add(1);
        if position_tick {
            let x = self.motor_position_m();
            if self.brake_periods <= engage {
                self.handover_anchor_m = x;
            } else if (x - self.handover_anchor_m).abs() > self.params.brake.handover_slip_m {
                // The brake alone does not hold this load yet.
                self.brake_periods = 0;
                self.handover_anchor_m = x;
            }
        }
        let ramped = self.brake_periods.saturating_sub(engage);
        if ramped >= engage.saturating_mul(2) {
            // The motor's share is gone and the rod stayed through one more
            // engage time without it: the brake holds alone.
            self.hold_current_q_a = super::expected_load_current_q_a(&self.params);
            self.set_mode(if self.faults.is_empty() { Mode::Disabled } else { Mode::Fault });
            return self.bridge_off();
        }
        let share = crate::math::max(1.0 - ramped as f32 / engage as f32, 0.0);
        let mut out = self.run_period_capped(s, position_tick, speed_tick, share * self.derived.current_limit_a);
        out.brake_release = false;
        out
    }
}
