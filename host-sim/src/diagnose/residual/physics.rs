//! The rig's nominal rigid-body model (from the simulator's `[plant]`):
//! the torque a motion needs, the compliance's deflection, the voltage the
//! motor needs. The residual compares the log with it; kept apart from the
//! segment builder so the model can be read and checked on its own.

use crate::config::RigConfig;
use crate::plant::Compliance;

/// The rig's nominal rigid-body model, from the simulator's `[plant]`.
#[derive(Clone, Debug)]
pub struct Physics {
    /// Torque constant `1.5 p ψ_f`, N·m/A.
    pub kt: f64,
    pub pole_pairs: f64,
    pub flux_wb: f64,
    pub r_ohm: f64,
    pub l_q_h: f64,
    /// Rotating inertia (rotor + coupling + screw), kg·m².
    pub j_rot: f64,
    /// Metres per radian, `L/2π`.
    pub k: f64,
    /// Moving mass (nut + rod + payload), kg.
    pub m_moving: f64,
    /// Viscous friction at the motor, rod viscous reflected, N·m·s/rad.
    pub b_rot: f64,
    /// Screw efficiency friction coefficient `(1−η)/η`.
    pub mu: f64,
    pub drag_n_m: f64,
    pub rod_coulomb_n: f64,
    pub rod_static_n: f64,
    /// Rod seal viscous friction (also inside `b_rot`), N·s/m.
    pub rod_viscous_n_s_m: f64,
    /// Structural damping across the axial compliance, N·s/m.
    pub axial_damping_n_s_m: f64,
    /// Screw inertia (inside `j_rot`), kg·m², and its bearings' viscous
    /// friction (inside `b_rot`), N·m·s/rad.
    pub j_screw: f64,
    pub b_screw: f64,
    pub stribeck_m_s: f64,
    pub gravity: f64,
    pub tilt_deg: f64,
    pub x0: f64,
    /// Sign regularisation of every friction law, rad/s at the motor.
    pub omega_eps: f64,
    pub compliance: Compliance,
    /// Contact preload of the nut (Hertz law), N.
    pub contact_preload_n: f64,
    /// The resolution the rig's sensors log at: one encoder count, rad; the
    /// scale's step, m; one current-ADC step, A. A logged column coarser
    /// than these is a quantisation the nominal does not expect.
    pub encoder_step_rad: f64,
    pub scale_step_m: f64,
    pub current_step_a: f64,
}

impl Physics {
    pub fn from_rig(rig: &RigConfig) -> Physics {
        let p = &rig.plant;
        let k = p.screw.lead_m / std::f64::consts::TAU;
        Physics {
            kt: 1.5 * f64::from(p.motor.pole_pairs) * p.motor.flux_linkage_wb,
            pole_pairs: f64::from(p.motor.pole_pairs),
            flux_wb: p.motor.flux_linkage_wb,
            r_ohm: p.motor.phase_resistance_ohm,
            l_q_h: p.motor.inductance_q_h,
            j_rot: p.motor.rotor_inertia_kg_m2 + p.coupling.inertia_kg_m2 + p.screw.inertia_kg_m2,
            k,
            m_moving: p.rod.nut_rod_mass_kg + p.rod.payload_mass_kg,
            b_rot: p.motor.viscous_friction_n_m_s_rad
                + p.screw.viscous_friction_n_m_s_rad
                + p.rod.viscous_friction_n_s_m * k * k,
            mu: (1.0 - p.screw.efficiency) / p.screw.efficiency,
            drag_n_m: p.screw.preload_drag_torque_n_m,
            rod_coulomb_n: p.rod.coulomb_friction_n,
            rod_static_n: p.rod.static_friction_n,
            rod_viscous_n_s_m: p.rod.viscous_friction_n_s_m,
            axial_damping_n_s_m: p.deformation.axial_damping_n_s_m,
            j_screw: p.screw.inertia_kg_m2,
            b_screw: p.screw.viscous_friction_n_m_s_rad,
            stribeck_m_s: p.rod.stribeck_velocity_m_s,
            gravity: p.load.gravity_m_s2,
            tilt_deg: p.load.initial_tilt_deg,
            x0: p.stroke.initial_position_m,
            omega_eps: 0.5,
            compliance: Compliance::new(p),
            contact_preload_n: p.deformation.contact.preload_n,
            encoder_step_rad: std::f64::consts::TAU / f64::from(p.sensors.encoder_counts_per_rev),
            scale_step_m: p.sensors.linear_scale_resolution_m,
            current_step_a: 2.0 * p.sensors.current_full_scale_a / 2f64.powi(p.sensors.adc_bits as i32),
        }
    }

    /// Rotor-referred inertia including the moving mass, kg·m².
    pub fn j_eq(&self) -> f64 {
        self.j_rot + self.m_moving * self.k * self.k
    }

    pub fn sgn(&self, omega: f64) -> f64 {
        (omega / self.omega_eps).tanh()
    }

    /// Axial load from gravity and the external force, N.
    pub fn load_n(&self, f_ext: f64, tilt_deg: f64) -> f64 {
        self.m_moving * self.gravity * tilt_deg.to_radians().sin() + f_ext
    }

    /// Nominal friction torque at the motor.
    pub fn friction(&self, omega: f64, f_ax: f64) -> f64 {
        let v = self.k * omega;
        let rod = self.rod_coulomb_n
            + (self.rod_static_n - self.rod_coulomb_n) * (-(v / self.stribeck_m_s).powi(2)).exp();
        self.b_rot * omega
            + self.sgn(omega) * (self.drag_n_m + self.k * rod + self.mu * self.k * f_ax.abs())
    }

    /// The torsional path (coupling + screw twist to the nut) carries, on
    /// top of the thread's `(L/2π) F` that `deflection` includes, the torque
    /// that accelerates the screw and the nut's friction torque; its wind-up
    /// puts the nut behind by `(L/2π) C_rot(x) (J_s α + T_f)`, m. `dir`: the
    /// last direction of motion, holding the friction at rest (as the seal).
    pub fn screw_wind_up_m(&self, omega: f64, alpha: f64, f_nut: f64, x: f64, dir: f64) -> f64 {
        let moving = (omega / self.omega_eps).abs().tanh();
        let s = moving * omega.signum() + (1.0 - moving) * dir;
        let t_f = self.b_screw * omega + s * (self.drag_n_m + self.mu * self.k * f_nut.abs());
        self.k * self.compliance.torsional_compliance_rad_per_n_m(x) * (self.j_screw * alpha + t_f)
    }

    /// Damping ratio of the rod's axial mode at local compliance `c` (m/N).
    pub fn rod_damping_ratio(&self, c: f64) -> f64 {
        0.5 * self.axial_damping_n_s_m * (c / self.m_moving).sqrt()
    }

    /// The rod seal's friction force at rod speed `v`, which the nut
    /// carries on top of load and inertia (so it deflects the drive train).
    /// At rest the seal holds the force the last motion (`dir`, ±1) left
    /// in it; moving, it is the nominal law. Returns (force, weight of the
    /// moving law in [0, 1]).
    pub fn rod_friction_n(&self, v: f64, dir: f64) -> (f64, f64) {
        let moving = (v / (self.k * self.omega_eps)).abs().tanh();
        let s = moving * v.signum() + (1.0 - moving) * dir;
        let stribeck =
            (self.rod_static_n - self.rod_coulomb_n) * (-(v / self.stribeck_m_s).powi(2)).exp();
        (
            self.rod_viscous_n_s_m * v + s * self.rod_coulomb_n + moving * v.signum() * stribeck,
            moving,
        )
    }

    /// Motor torque the nominal model needs for (ω, α) with the nut carrying
    /// `f_nut` (load + the rod's own inertia + seal friction): rotor and
    /// screw inertia, the thread, bearing viscous friction, the nut's drag
    /// and its load-proportional (efficiency) friction.
    pub fn required_torque_nut(&self, omega: f64, alpha: f64, f_nut: f64) -> f64 {
        let b_bearings = self.b_rot - self.rod_viscous_n_s_m * self.k * self.k;
        self.j_rot * alpha
            + self.k * f_nut
            + b_bearings * omega
            + self.sgn(omega) * (self.drag_n_m + self.mu * self.k * f_nut.abs())
    }

    /// Motor torque the nominal model needs for (ω, α) under load `f_load`.
    pub fn required_torque(&self, omega: f64, alpha: f64, f_load: f64) -> f64 {
        let f_ax = f_load + self.m_moving * self.k * alpha;
        self.j_rot * alpha + self.k * f_ax + self.friction(omega, f_ax)
    }

    /// Nominal static deflection (motor side minus terminal), m.
    pub fn deflection(&self, f_ax: f64, x: f64) -> f64 {
        self.compliance
            .static_deflection(f_ax, x)
            .terminal_total_m()
    }

    /// Local compliance `d deflection / dF`, m/N.
    pub fn local_compliance(&self, f_ax: f64, x: f64) -> f64 {
        (self.deflection(f_ax + 1.0, x) - self.deflection(f_ax - 1.0, x)) / 2.0
    }
}
