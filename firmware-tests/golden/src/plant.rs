//! A rigid drive train on a PMSM: the smallest plant that closes every loop
//! (d-q electrical model, one inertia, viscous friction, quantised encoder,
//! the duties of one period applied during the next). Independent of the
//! core's transforms: the formulas are written out here.
//!
//! `golden-gen` records a closed-loop sensor sequence with it on the host;
//! the cost benchmark closes the loop with it on the target so the
//! controller's branches are the ones a moving drive takes.

use core::f32::consts::PI;
use servo_core::{ControlParams, PwmCommand, SensorSample};

/// Plant state, motor side.
#[derive(Clone, Copy, Debug)]
pub struct RigidPlant {
    pub i_d: f32,
    pub i_q: f32,
    pub speed_rad_s: f32,
    pub angle_rad: f32,
    pub bus_voltage_v: f32,
    p: ControlParams,
}

impl RigidPlant {
    /// Integration sub-steps per PWM period (explicit Euler).
    pub const SUBSTEPS: u32 = 10;

    pub fn new(p: ControlParams, bus_voltage_v: f32) -> Self {
        Self {
            i_d: 0.0,
            i_q: 0.0,
            speed_rad_s: 0.0,
            angle_rad: 0.0,
            bus_voltage_v,
            p,
        }
    }

    /// The sensors at the PWM centre: phase currents, 16-bit encoder counter.
    pub fn sample(&self) -> SensorSample {
        let pp = self.p.motor.pole_pairs as f32;
        let (s, c) = libm::sincosf(pp * self.angle_rad);
        let i_alpha = self.i_d * c - self.i_q * s;
        let i_beta = self.i_d * s + self.i_q * c;
        let h = 0.5 * libm::sqrtf(3.0);
        let counts =
            libm::floorf(self.angle_rad / (2.0 * PI) * self.p.encoder.counts_per_rev as f32) as i32;
        SensorSample {
            phase_current_a: [
                i_alpha,
                -0.5 * i_alpha + h * i_beta,
                -0.5 * i_alpha - h * i_beta,
            ],
            encoder_count: counts as u16,
            bus_voltage_v: self.bus_voltage_v,
            terminal_position_m: None,
            load_cell_force_n: None,
            home_switch: None,
            power_stage_temperature_c: None,
        }
    }

    /// Advances one PWM period under `out`.
    pub fn advance(&mut self, out: &PwmCommand) {
        let m = self.p.motor;
        let pp = m.pole_pairs as f32;
        let j = self.p.reflected_inertia_kg_m2();
        let b = self.p.drive_train.viscous_friction_n_m_s_rad;
        let dt = self.p.pwm_period_s() / Self::SUBSTEPS as f32;
        let bus = self.bus_voltage_v;
        let [da, db, dc] = if out.enable { out.duty } else { [0.5; 3] };
        let (va, vb, vc) = (da * bus, db * bus, dc * bus);
        let v_alpha = (2.0 * va - vb - vc) / 3.0;
        let v_beta = (vb - vc) / libm::sqrtf(3.0);
        for _ in 0..Self::SUBSTEPS {
            let (s, c) = libm::sincosf(pp * self.angle_rad);
            let v_d = v_alpha * c + v_beta * s;
            let v_q = -v_alpha * s + v_beta * c;
            let we = pp * self.speed_rad_s;
            let did = (v_d - m.phase_resistance_ohm * self.i_d + we * m.inductance_q_h * self.i_q)
                / m.inductance_d_h;
            let diq = (v_q
                - m.phase_resistance_ohm * self.i_q
                - we * (m.inductance_d_h * self.i_d + m.flux_linkage_wb))
                / m.inductance_q_h;
            let torque = 1.5 * pp * m.flux_linkage_wb * self.i_q;
            self.i_d += did * dt;
            self.i_q += diq * dt;
            self.speed_rad_s += (torque - b * self.speed_rad_s) / j * dt;
            self.angle_rad += self.speed_rad_s * dt;
        }
    }
}

/// A deterministic noise source (xorshift32) for ADC-like noise on recorded
/// samples: the same sequence on every machine.
#[derive(Clone, Copy, Debug)]
pub struct Noise(u32);

impl Noise {
    pub const fn new(seed: u32) -> Self {
        Self(if seed == 0 { 0x9E37_79B9 } else { seed })
    }

    /// Uniform in [−1, 1).
    pub fn next(&mut self) -> f32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        (x >> 8) as f32 * (2.0 / 16_777_216.0) - 1.0
    }
}
