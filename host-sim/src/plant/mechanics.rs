//! The coupled electromechanical model: state layout, right-hand side,
//! static equilibrium and energy bookkeeping.
//!
//! Bodies and springs, from the inverter out:
//! ```text
//!  rotor+coupling hub J_m ──[torsion: coupling ∥ screw twist, C_rot(x); damping c_rot]── screw J_s
//!  screw ──(x_s = x0 + L θ_s/2π)──[axial compliance δ1..δ4(F, x); damping c_ax]── nut+rod+payload m
//!  rod ── friction, end stops, load F_L = m g sin(tilt) + F_ext
//! ```
//! Equations (r = L/2π):
//! - `J_m ω̇_m = T_e − T_c − B_m ω_m`, `T_c = (θ_m − θ_s)/C_rot(x) + c_rot (ω_m − ω_s)`
//! - `J_s ω̇_s = T_c − r F_ax − T_f(ω_s, F_ax)`, `F_ax = F(x_s − x_r, x) + c_ax (r ω_s − v)`
//! - `m v̇ = F_ax − F_L − F_f(v) + F_stop(x, v)`
//!
//! The screw inertia is lumped at the nut end of the torsional path, so the
//! whole rotor-to-nut twist (coupling + δθ5) is one spring.

use super::deformation::{AxialWarmStart, Compliance};
use super::effects::EffectDynamics;
use super::frames::{self, SinCosCache};
use super::friction::{RodFriction, ScrewFriction};
use super::inverter::{self, Drive};
use super::motor::Motor;
use super::params::PlantParams;

/// Number of states.
pub const N: usize = 8;
/// `[i_d, i_q, θ_m, ω_m, θ_s, ω_s, x_r, v_r]`.
pub type StateVec = [f64; N];
pub const I_D: usize = 0;
pub const I_Q: usize = 1;
pub const THETA_M: usize = 2;
pub const OMEGA_M: usize = 3;
pub const THETA_S: usize = 4;
pub const OMEGA_S: usize = 5;
pub const X_ROD: usize = 6;
pub const V_ROD: usize = 7;

/// What one right-hand-side evaluation leaves for the next (no effect on
/// the answer beyond rounding; see `Model::evaluate_warm`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WarmStart {
    pub axial: AxialWarmStart,
    pub angle: SinCosCache,
}

/// What is held constant through one RK4 step.
#[derive(Clone, Copy, Debug)]
pub struct Inputs {
    pub drive: Drive,
    pub bus_v: f64,
    /// Axial load on the rod, positive opposing extension.
    pub load_force_n: f64,
    /// A phase disconnected from the inverter (fault injection), if any.
    pub open_phase: Option<usize>,
    /// The holding brake on the motor shaft.
    pub brake: super::brake::BrakeTorque,
}

/// Everything one right-hand-side evaluation computes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Eval {
    pub deriv: StateVec,
    pub sin_e: f64,
    pub cos_e: f64,
    pub u_d: f64,
    pub u_q: f64,
    pub motor_torque: f64,
    /// Spring part of the rotor-to-nut torque.
    pub torsion_spring_torque: f64,
    /// Spring + damper.
    pub coupling_torque: f64,
    pub torsional_compliance: f64,
    pub axial_spring_force: f64,
    /// Spring + damper: the force the nut transmits.
    pub axial_force: f64,
    pub screw_friction_torque: f64,
    pub rod_friction_force: f64,
    pub stop_force: f64,
    /// Elastic part of the end-stop force.
    pub stop_elastic_force: f64,
    pub stop_penetration: f64,
    /// `x0 + L θ_s/2π`.
    pub screw_position: f64,
}

/// What `Model::state_terms` computes: the right-hand side's terms that
/// depend on the state alone (not on the step's `Inputs`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StateTerms {
    pub sin_e: f64,
    pub cos_e: f64,
    pub motor_torque: f64,
    pub cogging_torque: f64,
    pub torsion_spring_torque: f64,
    pub coupling_torque: f64,
    pub torsional_compliance: f64,
    /// dx_s/dθ_s.
    pub ratio: f64,
    pub axial_spring_force: f64,
    pub axial_force: f64,
    pub screw_friction_torque: f64,
    pub rod_friction_force: f64,
    pub stop_force: f64,
    pub stop_elastic_force: f64,
    pub stop_penetration: f64,
    pub screw_position: f64,
}

/// The model's constants, prepared once from `PlantParams`.
#[derive(Clone, Debug)]
pub struct Model {
    pub motor: Motor,
    pub compliance: Compliance,
    pub rod_friction: RodFriction,
    pub screw_friction: ScrewFriction,
    /// `L/2π`.
    pub metres_per_rad: f64,
    /// Motor-side position at θ = 0.
    pub origin_m: f64,
    pub j_m: f64,
    pub j_s: f64,
    pub mass: f64,
    /// 1/J_m, 1/J_s, 1/m: the right-hand side multiplies.
    inv_j_m: f64,
    inv_j_s: f64,
    inv_mass: f64,
    pub payload_mass: f64,
    pub gravity: f64,
    pub b_m: f64,
    pub c_rot: f64,
    pub c_ax: f64,
    pub stop_lo: f64,
    pub stop_hi: f64,
    pub k_stop: f64,
    pub c_stop: f64,
    /// Unmodelled effects of a truth rig (`effects.rs`); none by default.
    pub fx: EffectDynamics,
}

impl Model {
    pub fn new(p: &PlantParams) -> Self {
        Self {
            motor: Motor::new(p),
            compliance: Compliance::new(p),
            rod_friction: RodFriction::new(p),
            screw_friction: ScrewFriction::new(p),
            metres_per_rad: p.metres_per_rad(),
            origin_m: p.stroke.initial_position_m,
            j_m: p.motor_side_inertia_kg_m2(),
            j_s: p.screw.inertia_kg_m2,
            mass: p.moving_mass_kg(),
            inv_j_m: 1.0 / p.motor_side_inertia_kg_m2(),
            inv_j_s: 1.0 / p.screw.inertia_kg_m2,
            inv_mass: 1.0 / p.moving_mass_kg(),
            payload_mass: p.rod.payload_mass_kg,
            gravity: p.load.gravity_m_s2,
            b_m: p.motor.viscous_friction_n_m_s_rad,
            c_rot: p.coupling.torsional_damping_n_m_s_rad,
            c_ax: p.deformation.axial_damping_n_s_m,
            stop_lo: p.stroke.retracted_stop_m,
            stop_hi: p.stroke.extended_stop_m,
            k_stop: p.stroke.stop_stiffness_n_m,
            c_stop: p.stroke.stop_damping_n_s_m,
            fx: EffectDynamics::default(),
        }
    }

    /// Axial load from gravity along the cylinder and an external force.
    pub fn load_force_n(&self, tilt_rad: f64, external_force_n: f64) -> f64 {
        self.load_force_from_sin(tilt_rad.sin(), external_force_n)
    }

    /// `load_force_n` with sin(tilt) given.
    #[inline]
    pub fn load_force_from_sin(&self, sin_tilt: f64, external_force_n: f64) -> f64 {
        self.mass * self.gravity * sin_tilt + external_force_n + self.fx.load_offset
    }

    /// Motor-side position `x0 + L θ_m/2π`.
    #[inline]
    pub fn motor_side_position_m(&self, theta_m: f64) -> f64 {
        self.origin_m + self.metres_per_rad * theta_m
    }

    /// Phase currents and PM back-EMF at a state (for the inverter's diodes).
    pub fn currents_and_emf(&self, s: &StateVec) -> ([f64; 3], [f64; 3]) {
        let (sin_e, cos_e) = (self.motor.pole_pairs * s[THETA_M]).sin_cos();
        (frames::dq_to_abc(s[I_D], s[I_Q], sin_e, cos_e), self.motor.back_emf_abc(s[OMEGA_M], sin_e, cos_e))
    }

    /// Right-hand side. `force_guess` warm-starts the axial-force inversion
    /// and is updated with its answer.
    #[inline]
    pub fn evaluate(&self, s: &StateVec, inp: &Inputs, force_guess: &mut f64) -> Eval {
        let mut warm = WarmStart { axial: AxialWarmStart::from_force(*force_guess), ..WarmStart::default() };
        let e = self.evaluate_warm(s, inp, &mut warm);
        *force_guess = warm.axial.force_n;
        e
    }

    /// `evaluate`, carrying from one call to the next what makes the next
    /// cheaper: the axial-force inversion's tangent (see
    /// `Compliance::axial_force_warm`) and the electrical angle's sin/cos.
    #[inline]
    pub fn evaluate_warm(&self, s: &StateVec, inp: &Inputs, warm: &mut WarmStart) -> Eval {
        let t = self.state_terms(s, warm);
        self.finish(s, &t, inp)
    }

    /// The part of the right-hand side that depends on the state alone:
    /// everything but the inverter voltages, the brake and the load, which
    /// are held through a step and may change between periods. Split out
    /// so the state record's evaluation at a period's end can serve as the
    /// next step's first stage (`finish` with the new inputs), the force
    /// inversion and friction laws not repeated.
    #[inline(always)]
    pub fn state_terms(&self, s: &StateVec, warm: &mut WarmStart) -> StateTerms {
        let (th_m, w_m, th_s, w_s, x, v) = (s[THETA_M], s[OMEGA_M], s[THETA_S], s[OMEGA_S], s[X_ROD], s[V_ROD]);
        let (sin_e, cos_e) = warm.angle.sin_cos(self.motor.pole_pairs * th_m);
        let motor_torque = self.motor.torque_n_m(s[I_D], s[I_Q]);

        let torsional_compliance = self.compliance.torsional_compliance_rad_per_n_m(x);
        let torsion_spring_torque = (th_m - th_s) / torsional_compliance;
        let coupling_torque = torsion_spring_torque + self.c_rot * (w_m - w_s);

        // `ratio` = dx_s/dθ_s: L/2π, unless a lead error bends the thread.
        let (screw_position, ratio) =
            self.fx.thread(self.origin_m + self.metres_per_rad * th_s, self.metres_per_rad, th_s);
        let axial_spring_force = match self.fx.engaged_deflection(screw_position - x) {
            Some(d) => self.compliance.axial_force_warm(d, x, &mut warm.axial),
            None => {
                warm.axial = AxialWarmStart::default();
                0.0
            }
        };
        let mut axial_force = axial_spring_force + self.c_ax * (ratio * w_s - v);
        if self.fx.has_gap() {
            axial_force = self.fx.contact_force(axial_spring_force, axial_force);
        }

        let screw_friction_torque = self.screw_friction.torque_n_m(w_s, axial_force) + self.fx.screw_friction_n_m(w_s);
        let rod_friction_force = self.rod_friction.force_n(v);
        let (stop_force, stop_elastic_force, stop_penetration) = self.stop_force(x, v);
        StateTerms {
            sin_e,
            cos_e,
            motor_torque,
            cogging_torque: self.fx.cogging_n_m(th_m),
            torsion_spring_torque,
            coupling_torque,
            torsional_compliance,
            ratio,
            axial_spring_force,
            axial_force,
            screw_friction_torque,
            rod_friction_force,
            stop_force,
            stop_elastic_force,
            stop_penetration,
            screw_position,
        }
    }

    /// `evaluate_warm`'s derivative alone, for the RK4 stages: none of the
    /// rest of `Eval` is assembled.
    #[inline(always)]
    pub fn deriv_warm(&self, s: &StateVec, inp: &Inputs, warm: &mut WarmStart) -> StateVec {
        let t = self.state_terms(s, warm);
        self.deriv_from(s, &t, inp)
    }

    /// The derivative at state `s` from its `state_terms` and the inputs
    /// held through the step.
    #[inline(always)]
    pub fn deriv_from(&self, s: &StateVec, t: &StateTerms, inp: &Inputs) -> StateVec {
        let (u_d, u_q) = self.dq_voltages(s, t, inp);
        self.derivative(s, t, u_d, u_q, inp)
    }

    /// The right-hand side at state `s` from its `state_terms` and the
    /// inputs held through the step.
    #[inline]
    pub fn finish(&self, s: &StateVec, t: &StateTerms, inp: &Inputs) -> Eval {
        let (u_d, u_q) = self.dq_voltages(s, t, inp);
        Eval {
            deriv: self.derivative(s, t, u_d, u_q, inp),
            sin_e: t.sin_e,
            cos_e: t.cos_e,
            u_d,
            u_q,
            motor_torque: t.motor_torque,
            torsion_spring_torque: t.torsion_spring_torque,
            coupling_torque: t.coupling_torque,
            torsional_compliance: t.torsional_compliance,
            axial_spring_force: t.axial_spring_force,
            axial_force: t.axial_force,
            screw_friction_torque: t.screw_friction_torque,
            rod_friction_force: t.rod_friction_force,
            stop_force: t.stop_force,
            stop_elastic_force: t.stop_elastic_force,
            stop_penetration: t.stop_penetration,
            screw_position: t.screw_position,
        }
    }

    /// The inverter's dq voltages at the state (PWM, a phase open, or the
    /// diodes conducting).
    #[inline(always)]
    fn dq_voltages(&self, s: &StateVec, t: &StateTerms, inp: &Inputs) -> (f64, f64) {
        let (i_d, i_q, w_m) = (s[I_D], s[I_Q], s[OMEGA_M]);
        let (sin_e, cos_e) = (t.sin_e, t.cos_e);
        match (inp.drive, inp.open_phase) {
            (Drive::Pwm(duty), None) => {
                let u = inverter::pwm_phase_voltages(duty, inp.bus_v);
                frames::abc_to_dq(self.fx.dead_time(u, i_d, i_q, sin_e, cos_e, inp.bus_v), sin_e, cos_e)
            }
            (Drive::Pwm(duty), Some(k)) => {
                let e_abc = self.motor.back_emf_abc(w_m, sin_e, cos_e);
                frames::abc_to_dq(inverter::pwm_phase_voltages_open(duty, inp.bus_v, e_abc, k), sin_e, cos_e)
            }
            (Drive::Diodes(_), _) => {
                let e_abc = self.motor.back_emf_abc(w_m, sin_e, cos_e);
                inverter::dq_voltages(&inp.drive, inp.bus_v, e_abc, sin_e, cos_e)
            }
        }
    }

    #[inline(always)]
    fn derivative(&self, s: &StateVec, t: &StateTerms, u_d: f64, u_q: f64, inp: &Inputs) -> StateVec {
        let (i_d, i_q, th_m, w_m, w_s, v) = (s[I_D], s[I_Q], s[THETA_M], s[OMEGA_M], s[OMEGA_S], s[V_ROD]);
        let (di_d, di_q) = self.motor.current_derivatives(u_d, u_q, i_d, i_q, w_m);
        [
            di_d,
            di_q,
            w_m,
            (t.motor_torque - t.coupling_torque - self.b_m * w_m - t.cogging_torque + inp.brake.torque_n_m(th_m, w_m))
                * self.inv_j_m,
            w_s,
            (t.coupling_torque - t.ratio * t.axial_force - t.screw_friction_torque) * self.inv_j_s,
            v,
            (t.axial_force - inp.load_force_n - t.rod_friction_force + t.stop_force) * self.inv_mass,
        ]
    }

    /// End stops: a stiff spring-damper that can only push the rod back into
    /// the stroke (damping never pulls it onto the stop).
    /// Returns (total force on rod, elastic part, signed penetration).
    #[inline]
    fn stop_force(&self, x: f64, v: f64) -> (f64, f64, f64) {
        if x < self.stop_lo {
            let pen = self.stop_lo - x;
            ((self.k_stop * pen - self.c_stop * v).max(0.0), self.k_stop * pen, pen)
        } else if x > self.stop_hi {
            let pen = x - self.stop_hi;
            (-(self.k_stop * pen + self.c_stop * v).max(0.0), -self.k_stop * pen, -pen)
        } else {
            (0.0, 0.0, 0.0)
        }
    }

    /// Static equilibrium at rest with motor angle `θ_m` under axial load
    /// `F_L`: the drive train carries `F_L` (friction is zero at rest), the
    /// torsional path is wound by `T = r F_L`, the rod sits `δ_ax` behind the
    /// screw, and the motor holds `T` with `i_q = T/(1.5 p ψ_f)`, `i_d = 0`.
    /// End stops are ignored (start inside the stroke).
    pub fn equilibrium(&self, theta_m: f64, load_force_n: f64) -> StateVec {
        // The thread's slope dx_s/dθ_s (L/2π without a lead error).
        let (_, ratio) = self.fx.thread(0.0, self.metres_per_rad, theta_m);
        let torque = ratio * load_force_n;
        let mut x = self.motor_side_position_m(theta_m);
        let mut theta_s = theta_m;
        // The stroke-dependent terms depend on x itself; the map contracts by
        // ~F/(E A) ≈ 1e-4 per pass, so a few passes reach machine precision.
        for _ in 0..8 {
            theta_s = theta_m - torque * self.compliance.torsional_compliance_rad_per_n_m(x);
            let (x_s, _) = self.fx.thread(self.origin_m + self.metres_per_rad * theta_s, self.metres_per_rad, theta_s);
            x = x_s - self.compliance.axial_deflection_m(load_force_n, x) - self.fx.gap_offset_m(load_force_n);
        }
        let i_q = torque / (1.5 * self.motor.pole_pairs * self.motor.flux_wb);
        [0.0, i_q, theta_m, 0.0, theta_s, 0.0, x, 0.0]
    }

    /// Energy stored in the plant and the power flows at one state, for
    /// checking that the model neither creates nor loses energy.
    pub fn energy_audit(&self, s: &StateVec, e: &Eval, load_force_n: f64) -> EnergyAudit {
        let (i_d, i_q, w_m, w_s, x, v) = (s[I_D], s[I_Q], s[OMEGA_M], s[OMEGA_S], s[X_ROD], s[V_ROD]);
        let kinetic = 0.5 * (self.j_m * w_m * w_m + self.j_s * w_s * w_s + self.mass * v * v);
        let springs = self.compliance.axial_energy_j(e.axial_spring_force, x)
            + 0.5 * e.torsion_spring_torque * e.torsion_spring_torque * e.torsional_compliance
            + 0.5 * self.k_stop * e.stop_penetration * e.stop_penetration;
        let stored_j = kinetic + springs + self.motor.magnetic_energy_j(i_d, i_q);

        let rel_w = w_m - w_s;
        let rel_v = self.metres_per_rad * w_s - v;
        // Power the rod pushes into a stop minus what the stop's spring stores.
        let stop_loss = -e.stop_force * v + e.stop_elastic_force * v;
        let dissipation_w = self.motor.copper_loss_w(i_d, i_q)
            + self.b_m * w_m * w_m
            + self.c_rot * rel_w * rel_w
            + e.screw_friction_torque * w_s
            + self.c_ax * rel_v * rel_v
            + e.rod_friction_force * v
            + stop_loss;
        EnergyAudit {
            stored_j,
            electrical_input_w: Motor::electrical_power_w(e.u_d, e.u_q, i_d, i_q),
            load_input_w: -load_force_n * v,
            dissipation_w,
            parametric_w: self.compliance.parametric_power_w(e.axial_spring_force, e.torsion_spring_torque, x, v),
        }
    }
}

/// Energy stored and power flows:
/// `d stored/dt = electrical_input + load_input − dissipation + parametric`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyAudit {
    pub stored_j: f64,
    /// Into the motor terminals.
    pub electrical_input_w: f64,
    /// Done on the rod by gravity and the external force.
    pub load_input_w: f64,
    /// Copper, viscous, Coulomb, structural damping and end-stop losses.
    pub dissipation_w: f64,
    /// `∂V/∂x · v`: the springs' energy change as the loaded screw length
    /// changes under them. The model takes the spring forces from the
    /// present stiffness and neglects the small axial force this would
    /// imply (≈ ½F²/(E_s A_s) ≈ 0.2 N at rated load), so this term is the
    /// model's only non-conservation; it is milliwatts.
    pub parametric_w: f64,
}
