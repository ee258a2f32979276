//! Which parameters may change while the bridge is on.
//!
//! Live (applied between two periods, the loops keep their states, gains
//! bumplessly): the loop gains, the torque filter, the trajectory and
//! stream limits, the compensation's bounds, the current, power and speed
//! limits and the modulation depth, the feedforward model (inertia, mass,
//! friction) and the load-estimate filter.
//!
//! Bridge off only: what the loops' structure, the position frame or the
//! protection rests on: rates, motor, screw lead, encoder, stroke, fault
//! thresholds, brake, thermal model, ratings, the start-up steps and the
//! power stage. Changing these under a turning motor would move the frame
//! the rod is held in or a trip threshold mid-motion. Also the speed loop's
//! setpoint weight: a change would step the q current by `kp Δb ω_ref`.

use super::ControlParams;

/// Path prefixes of the parameters that change live (a trailing `.` is a
/// whole group).
const LIVE: &[&str] = &[
    "control.current_pi.",
    "control.speed_pi.",
    "control.torque_filter_hz",
    "control.position_kp_per_s",
    "control.trajectory.",
    "control.stream.",
    "control.compensation.",
    "control.limits.current_max_a",
    "control.limits.copper_power_max_w",
    "control.limits.speed_max_rad_s",
    "control.limits.max_modulation",
    "control.drive_train.screw_efficiency",
    "control.drive_train.rotating_inertia_kg_m2",
    "control.drive_train.moving_mass_kg",
    "control.drive_train.viscous_friction_n_m_s_rad",
    "control.drive_train.coulomb_friction_n_m",
    "control.drive_train.friction_feedforward_speed_rad_s",
    "control.drive_train.friction_feedforward_gain",
    "control.load_estimate.",
];

/// `a != b` as a `return Some(name)`.
macro_rules! off {
    ($a:expr, $b:expr, $name:literal) => {
        if $a != $b {
            return Some($name);
        }
    };
}

impl ControlParams {
    /// True if the parameter at `path` may change with the bridge on.
    pub fn is_live_path(path: &str) -> bool {
        LIVE.iter().any(|p| if p.ends_with('.') { path.starts_with(p) } else { path == *p })
    }

    /// The first field (or group) that differs between `self` and `new` and
    /// changes only with the bridge off; `None` if every difference is live.
    /// The same split as [`ControlParams::is_live_path`] (a test walks every
    /// leaf).
    pub fn bridge_off_change(&self, new: &Self) -> Option<&'static str> {
        off!(self.motor, new.motor, "control.motor");
        off!(self.drive_train.screw_lead_m, new.drive_train.screw_lead_m, "control.drive_train.screw_lead_m");
        off!(self.rates, new.rates, "control.rates");
        off!(self.encoder, new.encoder, "control.encoder");
        off!(self.limits.stroke_min_m, new.limits.stroke_min_m, "control.limits.stroke_min_m");
        off!(self.limits.stroke_max_m, new.limits.stroke_max_m, "control.limits.stroke_max_m");
        off!(self.faults, new.faults, "control.faults");
        off!(self.startup, new.startup, "control.startup");
        off!(self.calibration, new.calibration, "control.calibration");
        off!(self.commutation, new.commutation, "control.commutation");
        off!(self.homing, new.homing, "control.homing");
        off!(self.power_stage, new.power_stage, "control.power_stage");
        off!(self.thermal, new.thermal, "control.thermal");
        off!(self.ratings, new.ratings, "control.ratings");
        off!(self.brake, new.brake, "control.brake");
        off!(self.speed_setpoint_weight, new.speed_setpoint_weight, "control.speed_setpoint_weight");
        None
    }
}
