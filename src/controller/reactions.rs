//! What the drive does with the bridge and the brake when it stops driving:
//! a fault (bridge off, short circuit while the brake closes), a `Disable`
//! (hold while the brake closes, then off), and the brake bookkeeping while
//! driving (`Enable`'s preload, the release wait).

use super::Controller;
use crate::foc::Dq;
use crate::io::{PwmCommand, SensorSample};
use crate::protection::FaultSet;
use crate::telemetry::Mode;

/// Controlled-stop faults after which the drive does not hold on the motor:
/// with a phase open, two phases leave angles with no torque, so once at
/// rest the brake takes the load and the bridge goes off (a stop category 1,
/// where the others hold under control, category 2). Without a brake the
/// drive keeps holding: that beats dropping the load.
const SAFE_STOP_THEN_BRAKE: FaultSet = FaultSet::OPEN_PHASE.union(FaultSet::HOMING_FAILED);

impl Controller {
    /// True while the brake is (being) held closed or opening: a planned
    /// move waits for `brake.preload_time_s + brake.release_time_s` after
    /// `Enable`.
    pub(super) fn brake_opening(&self) -> bool {
        self.params.brake.fitted
            && matches!(self.mode, Mode::Running | Mode::Homing | Mode::Preloading)
            && self.brake_periods < self.derived.brake_preload_periods.saturating_add(self.derived.brake_release_periods)
    }

    /// Brake bookkeeping at the position rate while driving: the preload
    /// and release wait after `Enable`, and the hand-over to the brake after
    /// an open-phase stop came to rest.
    #[inline(never)]
    pub(super) fn brake_tick(&mut self) {
        self.homing_tick();
        self.brake_periods = self.brake_periods.saturating_add(self.params.rates.position_loop_divider);
        // The hold current builds with the brake closed; then it lets go.
        if self.mode == Mode::Preloading && self.brake_periods >= self.derived.brake_preload_periods {
            self.set_mode(Mode::Running);
        }
        if self.mode == Mode::Stopping
            && self.params.brake.fitted
            && self.stop.at_rest()
            && self.faults.intersects(SAFE_STOP_THEN_BRAKE)
        {
            // A degraded motor should not be left holding: once the stop is
            // at rest, hand the load to the brake and switch off.
            self.brake_periods = 0;
            self.set_mode(Mode::Braking);
        }
    }

    /// `Preloading`: the loops hold, the brake stays closed.
    #[inline(never)]
    pub(super) fn preload_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        if position_tick {
            self.brake_tick();
        }
        let mut out = self.run_period(s, position_tick, speed_tick);
        out.brake_release = false;
        out
    }

    /// `Braking`: the loops hold while the brake closes, then the bridge
    /// goes off. The load held at that moment is kept as the next
    /// `Enable`'s preload.
    #[inline(never)]
    pub(super) fn braking_period(&mut self, s: &SensorSample, position_tick: bool, speed_tick: bool) -> PwmCommand {
        if self.stop_brake_assist {
            return self.assisted_braking_period(s, position_tick, speed_tick);
        }
        if self.stop.at_rest() {
            self.brake_periods = self.brake_periods.saturating_add(1);
        }
        if self.brake_periods > self.derived.brake_engage_periods {
            // The preload is what held the load. At rest any torque within
            // the friction band around the low-passed load estimate holds,
            // so a quiet hold's own q current stands. One outside it is not
            // a static hold but a sample of a swing: a hold that still rings
            // (the rod's axial mode, ±30 A at 90 Hz on a light rod near the
            // retracted end after homing). Then the load estimate is the
            // preload: one that far from the load leaves the brake carrying
            // the difference until it lets go, and the rod sags until the
            // loops catch it.
            let slow_n = self.load.slow_force_n();
            let load_a = super::load_current_q_a(&self.params, slow_n);
            let band_a = super::friction_band_q_a(&self.params, &self.load);
            let q = self.current_reference.q;
            let held = if (q - load_a).abs() <= band_a { q } else { load_a };
            if held.is_finite() {
                self.hold_current_q_a = held;
            } else if q.is_finite() {
                self.hold_current_q_a = q;
            }
            self.set_mode(if self.faults.is_empty() { Mode::Disabled } else { Mode::Fault });
            return self.bridge_off();
        }
        let mut out = self.run_period(s, position_tick, speed_tick);
        // Closing starts once the stop ramp is at rest.
        out.brake_release = !(self.params.brake.fitted && self.stop.at_rest());
        out
    }

    /// Active short circuit (all low-side switches on) while the brake closes
    /// after a bridge-off fault: the motor brakes itself through its winding
    /// resistance, no sensor or loop needed, so a vertical load sinks at a
    /// few mm/s instead of falling. Only entered below the speed whose
    /// short-circuit current stays inside `limits.current_max_a` (≈89 rad/s,
    /// 70 mm/s of rod, for the default motor), and still ended for good if a
    /// phase reads above that limit.
    #[inline(never)]
    pub(super) fn short_circuit(&mut self, s: &SensorSample) -> PwmCommand {
        self.short_circuit_periods = self.short_circuit_periods.saturating_sub(1);
        let limit = self.params.limits.current_max_a;
        let [a, b, c] = s.phase_current_a;
        // NaN compares false: `!(x <= limit)` ends the short circuit too.
        let bounded = a.abs() <= limit && b.abs() <= limit && c.abs() <= limit;
        let off = self.bridge_off();
        if !bounded {
            self.short_circuit_periods = 0;
            return off;
        }
        PwmCommand { duty: [0.0; 3], enable: true, brake_release: false }
    }

    /// Bridge off: loops reset, the command follows the rod.
    #[inline(never)]
    pub(super) fn bridge_off(&mut self) -> PwmCommand {
        // A hold on the half-turned angle ends here: the user's offset back.
        if self.torque_watch.turned() {
            self.params.encoder.electrical_offset_rad = self.torque_watch.end_turn();
        }
        self.hold_here();
        self.stop_brake_assist = false;
        self.stream.stop();
        self.reset_loops();
        // No current flows with the bridge off: the I²t model cools.
        self.current_dq = Dq::default();
        PwmCommand::OFF
    }
}
