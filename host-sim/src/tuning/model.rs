//! The design model in the time domain: the three loops as the core runs
//! them (the current PI every PWM period on the winding, its voltage acting
//! one period later; the speed PI + torque filter every speed period; the
//! position P every position period; the encoder PLL), on the rigid (or
//! two-mass) mechanics, no friction, no load. Gives the step responses the
//! design predicts.

use super::design::DesignPlant;
use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum StepKind {
    Current,
    Speed,
    Position,
}

#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Gains {
    pub current: (f64, f64),
    pub speed: (f64, f64),
    pub position_kp: f64,
}

struct Biquad {
    b0: f64,
    a1: f64,
    a2: f64,
    z1: f64,
    z2: f64,
    pass: bool,
}

impl Biquad {
    /// Settled at `x` (unity gain at DC).
    fn preset(&mut self, x: f64) {
        if !self.pass {
            self.z1 = x * (1.0 - self.b0);
            self.z2 = x * (self.b0 - self.a2);
        }
    }
    fn new(f: f64, rate: f64) -> Self {
        if !(f > 0.0 && f < 0.45 * rate) {
            return Biquad { b0: 1.0, a1: 0.0, a2: 0.0, z1: 0.0, z2: 0.0, pass: true };
        }
        let k = (PI * f / rate).tan();
        let q = FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        Biquad { b0: k * k * norm, a1: 2.0 * (k * k - 1.0) * norm, a2: (1.0 - k / q + k * k) * norm, z1: 0.0, z2: 0.0, pass: false }
    }
    fn update(&mut self, x: f64) -> f64 {
        if self.pass {
            return x;
        }
        let y = self.b0 * x + self.z1;
        self.z1 = 2.0 * self.b0 * x - self.a1 * y + self.z2;
        self.z2 = self.b0 * x - self.a2 * y;
        y
    }
}

/// Response to a step of `amplitude` (A, rad/s or rad at the motor) at
/// t = 0, sampled every PWM period for `duration_s`: the measured signal
/// (q current, PLL speed, or motor angle).
///
/// The mechanics are those the step's direction meets
/// ([`DesignPlant::for_step`]: a step that lifts the load drives its inertia
/// through the screw's efficiency).
pub fn step_response(p: &DesignPlant, g: &Gains, kind: StepKind, amplitude: f64, duration_s: f64) -> Vec<f64> {
    let p = &p.for_step(amplitude);
    let t = p.t_pwm();
    let n = (duration_s / t).round() as usize;
    let (sd, pd) = (p.speed_div.round() as usize, p.position_div.round() as usize);
    let ts = p.t_speed();
    // Two-mass split (rigid when no mode is given).
    let (jm, jl, kax, cax) = match &p.rod_mode {
        Some(m) => {
            let (wa, wr) = (TAU * m.antiresonance_hz, TAU * m.resonance_hz);
            let jm = p.inertia_kg_m2 * wa * wa / (wr * wr);
            let jl = p.inertia_kg_m2 - jm;
            let k = jl * wa * wa;
            (jm, jl, k, 2.0 * m.zeta_a * (k * jl).sqrt())
        }
        None => (p.inertia_kg_m2, 0.0, 0.0, 0.0),
    };
    // Friction on a speed step only (the position step's plan is a hold:
    // nothing is fed forward, and its figures are not designed on it). In
    // the step's direction `dir`; the load and the hold current that
    // carries it cancel, but for the share friction carried at rest.
    let fr = if kind == StepKind::Speed { p.step_friction } else { None };
    let dir = if amplitude < 0.0 { -1.0 } else { 1.0 };
    let i0 = fr.map_or(0.0, |f| -dir * f.rest_n_m / p.kt_n_m_a);
    let (mut i, mut th, mut w, mut thl, mut wl) = (i0, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut th_est, mut w_est) = (0.0f64, 0.0f64);
    let (mut int_i, mut int_w) = (p.r_ohm * i0, i0);
    let mut u_prev = p.r_ohm * i0;
    let mut w_ref = 0.0;
    let mut i_ref = i0;
    let mut tf = Biquad::new(p.torque_filter_hz, 1.0 / ts);
    tf.preset(i0);
    let mut out = Vec::with_capacity(n);
    let sub = 20;
    let h = t / sub as f64;
    let ah = (-p.r_ohm * h / p.l_h).exp();
    let p_psi = if kind == StepKind::Current { 0.0 } else { p.kt_n_m_a / 1.5 };
    let mut ff_prev = 0.0f64;
    for k in 0..n {
        // Sample.
        th_est += w_est * t;
        let err = th - th_est;
        th_est += p.pll_kp * err * t;
        w_est += p.pll_ki * err * t;
        let (speed_tick, position_tick) = (k % sd == 0, k % pd == 0);
        match kind {
            StepKind::Current => i_ref = amplitude,
            StepKind::Speed => {
                w_ref = amplitude;
            }
            StepKind::Position => {
                if position_tick {
                    w_ref = g.position_kp * (amplitude - th);
                }
            }
        }
        if kind != StepKind::Current && speed_tick {
            let e = w_ref - w_est;
            int_w += g.speed.1 * e * ts;
            let ff = fr.map_or(0.0, |f| {
                let ramp = if f.feedforward_ramp_rad_s > 0.0 { (w_ref / f.feedforward_ramp_rad_s).clamp(-1.0, 1.0) } else { w_ref.signum() };
                (f.feedforward_viscous_n_m_s_rad * w_ref + f.feedforward_coulomb_n_m * ramp) / p.kt_n_m_a
            });
            i_ref = tf.update(g.speed.0 * (p.speed_setpoint_weight * w_ref - w_est) + int_w + ff);
        }
        let e = i_ref - i;
        int_i += g.current.1 * e * t;
        let u = g.current.0 * e + int_i;
        out.push(match kind {
            StepKind::Current => i,
            StepKind::Speed => w_est,
            StepKind::Position => th,
        });
        // The period: last period's voltage on the winding with the back-EMF
        // `p ψ ω` the motion induces, less the core's feedforward of it (the
        // PLL's speed at the sample that computed the voltage), as the
        // design's `current_ol` (`Q`); the current along the exact
        // exponential of each sub-step, the mechanics from it.
        let mut i_s = i;
        for _ in 1..=sub {
            let i_inf = (u_prev + p_psi * (ff_prev - w)) / p.r_ohm;
            let i_next = i_inf + (i_s - i_inf) * ah;
            // Mean current over the sub-step.
            let i_mid = i_inf + (i_s - i_inf) * (1.0 - ah) * p.l_h / (p.r_ohm * h);
            i_s = i_next;
            let torque = p.kt_n_m_a * i_mid;
            let spring = if jl > 0.0 { kax * (th - thl) + cax * (w - wl) } else { 0.0 };
            let net = torque - p.viscous_n_m_s_rad * w - spring;
            // The seal's share (and its breakaway) acts on the load where the
            // rod's mode separates it from the rotor, the rest on the rotor.
            let (motor_fr, load_fr) = fr.map_or((0.0, 0.0), |f| {
                if jl > 0.0 {
                    let seal = f.load_side_n_m.clamp(0.0, f.coulomb_n_m);
                    (friction_torque(f.coulomb_n_m - seal, 0.0, 0.0, w, net), friction_torque(seal, f.breakaway_excess_n_m, f.stribeck_rad_s, wl, spring))
                } else {
                    (friction_torque(f.coulomb_n_m, f.breakaway_excess_n_m, f.stribeck_rad_s, w, net), 0.0)
                }
            });
            let friction = motor_fr;
            if jl > 0.0 {
                w += h * (net - friction) / jm;
                wl += h * (spring - load_fr) / jl;
                th += h * w;
                thl += h * wl;
            } else {
                w += h * (net - friction) / jm;
                th += h * w;
            }
        }
        i = i_s;
        ff_prev = w_est;
        u_prev = u;
        let _ = (speed_tick, position_tick);
    }
    out
}

/// Below this speed (rad/s) the rotor is at rest for the friction law.
const STICK_RAD_S: f64 = 1e-3;

/// Friction torque (Coulomb `coulomb`, breakaway `coulomb + excess` fading
/// over the Stribeck speed `stribeck`) opposing a body at speed `w` under the
/// net driving torque `net`: at rest it holds `net` up to the breakaway
/// level (and the body stays), moving it opposes the motion.
fn friction_torque(coulomb: f64, excess: f64, stribeck: f64, w: f64, net: f64) -> f64 {
    if w.abs() < STICK_RAD_S {
        let breakaway = coulomb + excess;
        return if net.abs() <= breakaway { net } else { breakaway.copysign(net) };
    }
    let fade = if stribeck > 0.0 { (-(w / stribeck).powi(2)).exp() } else { 0.0 };
    (coulomb + excess * fade).copysign(w)
}

/// Overshoot (%) of a response to a step of `amplitude` that settles there.
pub fn overshoot_pct(y: &[f64], amplitude: f64) -> f64 {
    let peak = y.iter().map(|v| v / amplitude).fold(f64::MIN, f64::max);
    ((peak - 1.0) * 100.0).max(0.0)
}

/// The speed step the check runs (rad/s): as large as a 10 A swing of the
/// PI's proportional term allows, so that Coulomb friction stays a small part
/// of the response, within 10–100 rad/s and 30 % of the speed limit. The
/// model steps by the same amount: with friction its response is not linear
/// in the amplitude.
pub fn speed_step_amplitude_rad_s(kp: f64, speed_max_rad_s: f64) -> f64 {
    (10.0 / kp).clamp(10.0, 100.0).min(0.3 * speed_max_rad_s)
}

/// The overshoot (%) of the design model's step as the check runs it: a
/// speed step at [`speed_step_amplitude_rad_s`] (friction makes its
/// overshoot depend on the size), the others at unit amplitude (linear).
pub fn design_overshoot_pct(p: &DesignPlant, g: &Gains, kind: StepKind, duration_s: f64) -> f64 {
    let a = if kind == StepKind::Speed && p.step_friction.is_some() { speed_step_amplitude_rad_s(g.speed.0, p.speed_max_rad_s) } else { 1.0 };
    overshoot_pct(&step_response(p, g, kind, a, duration_s), a)
}

/// How long the speed step (test and model) lasts for an asked bandwidth:
/// long enough to settle.
pub fn speed_step_duration_s(bw_hz: f64) -> f64 {
    (3.0 / bw_hz).clamp(0.25, 0.6)
}

pub fn position_step_duration_s(bw_hz: f64) -> f64 {
    (3.0 / bw_hz).clamp(0.5, 2.0)
}
