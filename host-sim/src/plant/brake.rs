//! The spring-applied holding brake on the motor shaft.
//!
//! Power opens it: with the coil off, springs press the friction disc and the
//! shaft is held up to the brake's holding torque. The disc is modelled as
//! an elasto-plastic contact (a bristle): once engaged at angle `θ_a`, it
//! gives `k (θ_a − θ) − c ω`, bounded by the holding torque; beyond the
//! bound the anchor slides with the shaft (the brake slips at its holding
//! torque). Unlike `tanh(ω/ω_ε)` friction, a held load does not creep.
//!
//! Engaging and releasing take the catalogue times after the coil changes
//! (armature travel, flux decay); a command that flips back before then
//! restarts the count.

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BrakeParams {
    /// False: no brake on the rig; the command is ignored.
    pub fitted: bool,
    pub holding_torque_n_m: f64,
    /// Coil on → disc free.
    pub release_time_s: f64,
    /// Coil off → disc holding.
    pub engage_time_s: f64,
    /// Tangential stiffness of the engaged disc, at the shaft.
    pub stiffness_n_m_rad: f64,
    pub damping_n_m_s_rad: f64,
}

impl Default for BrakeParams {
    /// See `params/rig.toml` [plant.brake].
    fn default() -> Self {
        Self {
            fitted: true,
            holding_torque_n_m: 2.5,
            release_time_s: 0.04,
            engage_time_s: 0.025,
            stiffness_n_m_rad: 200.0,
            damping_n_m_s_rad: 0.05,
        }
    }
}

/// What the right-hand side needs: the engaged disc's torque law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BrakeTorque {
    engaged: bool,
    anchor_rad: f64,
    stiffness: f64,
    damping: f64,
    holding: f64,
}

impl BrakeTorque {
    /// Torque on the motor shaft at angle `θ` and speed `ω`.
    #[inline]
    pub fn torque_n_m(&self, theta_rad: f64, omega_rad_s: f64) -> f64 {
        if !self.engaged {
            return 0.0;
        }
        (self.stiffness * (self.anchor_rad - theta_rad) - self.damping * omega_rad_s).clamp(-self.holding, self.holding)
    }
}

/// The brake's state: coil command, time since it changed, disc engaged.
#[derive(Clone, Debug)]
pub struct Brake {
    p: BrakeParams,
    coil_on: bool,
    since_change_s: f64,
    engaged: bool,
    anchor_rad: f64,
}

impl Brake {
    /// A brake held open (coil on), as under a drive that is holding.
    pub fn new(p: &BrakeParams) -> Self {
        Self { p: p.clone(), coil_on: true, since_change_s: f64::INFINITY, engaged: false, anchor_rad: 0.0 }
    }

    pub fn engaged(&self) -> bool {
        self.engaged
    }

    /// Coil off and the disc already holding at `theta_rad` (a drive found
    /// switched off, its load hanging on the brake).
    pub fn engage_now(&mut self, theta_rad: f64) {
        self.coil_on = false;
        self.since_change_s = f64::INFINITY;
        self.engaged = self.p.fitted;
        self.anchor_rad = theta_rad;
    }

    /// The drive's brake output for the coming period.
    pub fn command(&mut self, coil_on: bool) {
        if coil_on != self.coil_on {
            self.coil_on = coil_on;
            self.since_change_s = 0.0;
        }
    }

    pub fn torque_law(&self) -> BrakeTorque {
        BrakeTorque {
            engaged: self.engaged,
            anchor_rad: self.anchor_rad,
            stiffness: self.p.stiffness_n_m_rad,
            damping: self.p.damping_n_m_s_rad,
            holding: self.p.holding_torque_n_m,
        }
    }

    /// After an integration step of `h` ending at shaft angle `θ`: the coil
    /// delays run, and an engaged disc loaded beyond its holding torque
    /// slides its anchor along.
    pub fn after_step(&mut self, h: f64, theta_rad: f64) {
        if !self.p.fitted {
            return;
        }
        self.since_change_s += h;
        if self.coil_on && self.engaged && self.since_change_s >= self.p.release_time_s {
            self.engaged = false;
        } else if !self.coil_on && !self.engaged && self.since_change_s >= self.p.engage_time_s {
            self.engaged = true;
            self.anchor_rad = theta_rad;
        }
        if self.engaged {
            let slip_limit = self.p.holding_torque_n_m / self.p.stiffness_n_m_rad;
            let stretch = self.anchor_rad - theta_rad;
            if stretch.abs() > slip_limit {
                self.anchor_rad = theta_rad + slip_limit.copysign(stretch);
            }
        }
    }
}
