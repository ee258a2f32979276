//! Gain design from the identified plant: frequency responses of the three
//! loops as the core computes them (sampled PIs, the torque filter's biquad,
//! holds, the encoder PLL) and the rules that place the gains.
//!
//! - Current PI: pole-zero cancellation, `kp = L ω_c`, `ki = R ω_c`, on the
//!   exact sampled loop (winding over one PWM period, one period of
//!   computation + the PWM's update): ω_c is solved so that the closed
//!   loop's −3 dB frequency is the one asked.
//! - Speed PI: loop shaping at crossover. For a crossover ω_c the plant's
//!   phase there (`K_t/(J s + B)`, the closed current loop, the torque
//!   filter, the speed loop's hold, the encoder PLL) fixes the PI zero that
//!   leaves the asked phase margin, `|L(jω_c)| = 1` fixes kp; ω_c is solved
//!   so that the closed loop's −3 dB frequency is the one asked.
//! - Position P: `L = K_p T_ω(s)/s` through the hold of the 1 kHz loop;
//!   K_p solved for the asked −3 dB frequency.

use nalgebra::Complex;
use servo_core::ControlParams;
use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};

type C = Complex<f64>;

fn cis(x: f64) -> C {
    C::new(x.cos(), x.sin())
}

/// What the design needs to know of the drive.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DesignPlant {
    pub r_ohm: f64,
    pub l_h: f64,
    pub kt_n_m_a: f64,
    pub inertia_kg_m2: f64,
    pub viscous_n_m_s_rad: f64,
    pub pwm_hz: f64,
    pub speed_div: f64,
    pub position_div: f64,
    pub torque_filter_hz: f64,
    pub pll_kp: f64,
    pub pll_ki: f64,
    /// Optional axial (load-on-spring) mode: the motor's speed sees
    /// `1/(J s) · (s²/ω_a² + 2ζ_a s/ω_a + 1)/(s²/ω_r² + 2ζ_r s/ω_r + 1)`.
    pub rod_mode: Option<RodMode>,
    /// The speed PI's setpoint weight `b` (`control.speed_setpoint_weight`):
    /// the gains' structure, kept here so that every response below uses it.
    pub speed_setpoint_weight: f64,
    /// The moving mass reflected to the motor, `m r²` (kg·m², part of
    /// `inertia_kg_m2`), and the screw's `μ = (1 − η)/η`: the nut's friction
    /// is `μ r |F_ax|`, so a motion that lifts the load (does work against
    /// it) drives the load's inertia through `r (1 + μ)` and one that lowers
    /// it through `r (1 − μ)`. A symmetric test (a chirp, the identification's
    /// ± steps) sees `inertia_kg_m2`; a one-way step sees
    /// `inertia_kg_m2 ± μ m r²` ([`DesignPlant::for_step`]). 0: none.
    #[serde(default)]
    pub load_inertia_kg_m2: f64,
    #[serde(default)]
    pub screw_mu: f64,
    /// The static load torque (N·m; +: it opposes positive motion, as
    /// gravity does on the bench), of which only the sign is used; 0 when
    /// unloaded.
    #[serde(default)]
    pub load_sign: f64,
    /// The friction a speed step meets and the drive's feedforward of it
    /// (`model::step_response`); None: frictionless.
    #[serde(default)]
    pub step_friction: Option<StepFriction>,
    /// The drive's speed limit (rad/s): with friction the step's response is
    /// not linear in its amplitude, and the check sizes its step from it.
    #[serde(default)]
    pub speed_max_rad_s: f64,
}

/// Friction at the motor shaft during a speed step, and what the drive feeds
/// forward against it (the core's `friction_feedforward_n_m` from the step's
/// reference, `viscous · ω_ref`). While the rotor turns one way the Coulomb
/// torque is a constant one opposing the motion; at rest it holds whatever
/// the net torque is, up to the breakaway level (static friction).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StepFriction {
    /// Coulomb torque while moving, under the static load (N·m): the
    /// identified `T_c` (drag, seal, and the screw's efficiency law under the
    /// load; the share under the step's inertial force is in
    /// [`DesignPlant::for_step`]'s inertia).
    pub coulomb_n_m: f64,
    /// The share of `coulomb_n_m` that acts on the load (the rod seal's, at
    /// the motor): with the rod's mode it drags the load, not the rotor.
    pub load_side_n_m: f64,
    /// Breakaway above Coulomb (static − Coulomb, N·m, the seal's: on the
    /// load side with the rod's mode), fading as `exp(−(ω/ω_s)²)`.
    pub breakaway_excess_n_m: f64,
    pub stribeck_rad_s: f64,
    /// The drive's Coulomb feedforward at full size (N·m), its direction
    /// ramped over `feedforward_ramp_rad_s` of the reference.
    pub feedforward_coulomb_n_m: f64,
    pub feedforward_ramp_rad_s: f64,
    /// The drive's viscous feedforward (N·m·s/rad on the reference).
    pub feedforward_viscous_n_m_s_rad: f64,
    /// Friction holding the rotor at rest before the step, in the step's
    /// direction (N·m): the hold current is short of the load by it.
    pub rest_n_m: f64,
}

/// The load mass on the drive train's axial stiffness, seen at the motor.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct RodMode {
    /// Anti-resonance (motor locked… the load on its spring), Hz.
    pub antiresonance_hz: f64,
    pub resonance_hz: f64,
    pub zeta_a: f64,
    pub zeta_r: f64,
}

impl RodMode {
    /// From the axial stiffness `k_ax` (N/m) and damping `c` (N·s/m), the
    /// moving mass `m`, the lead factor `k` (m/rad) and the total and
    /// rotating inertias.
    pub fn new(k_ax: f64, c: f64, m: f64, j_total: f64, j_motor: f64) -> Self {
        let wa = (k_ax / m).sqrt();
        let za = c / (2.0 * (k_ax * m).sqrt());
        let ratio = (j_total / j_motor).sqrt();
        RodMode { antiresonance_hz: wa / TAU, resonance_hz: wa * ratio / TAU, zeta_a: za, zeta_r: za * ratio }
    }
    /// The same spring and load seen by a drive train whose total inertia
    /// is `j_new` instead of `j_old` with the motor's share unchanged (the
    /// load's share scaled): the anti-resonance stays, the resonance moves.
    pub fn with_total_inertia(&self, j_old: f64, j_new: f64) -> Self {
        let jm = j_old * (self.antiresonance_hz / self.resonance_hz).powi(2);
        let ratio = (j_new / jm).sqrt();
        RodMode { resonance_hz: self.antiresonance_hz * ratio, zeta_r: self.zeta_a * ratio, ..*self }
    }
    fn factor(&self, s: C) -> C {
        let (wa, wr) = (TAU * self.antiresonance_hz, TAU * self.resonance_hz);
        (s * s / (wa * wa) + s * (2.0 * self.zeta_a / wa) + 1.0) / (s * s / (wr * wr) + s * (2.0 * self.zeta_r / wr) + 1.0)
    }
}

impl DesignPlant {
    pub fn from_params(p: &ControlParams, inertia: f64, viscous: f64) -> Self {
        DesignPlant {
            r_ohm: f64::from(p.motor.phase_resistance_ohm),
            l_h: f64::from(p.motor.inductance_q_h),
            kt_n_m_a: f64::from(p.torque_constant_n_m_a()),
            inertia_kg_m2: inertia,
            viscous_n_m_s_rad: viscous,
            pwm_hz: f64::from(p.rates.pwm_frequency_hz),
            speed_div: f64::from(p.rates.speed_loop_divider),
            position_div: f64::from(p.rates.position_loop_divider),
            torque_filter_hz: f64::from(p.torque_filter_hz),
            pll_kp: f64::from(p.encoder.pll_kp_per_s),
            pll_ki: f64::from(p.encoder.pll_ki_per_s2),
            rod_mode: None,
            speed_setpoint_weight: f64::from(p.speed_setpoint_weight),
            load_inertia_kg_m2: 0.0,
            screw_mu: 0.0,
            load_sign: 0.0,
            step_friction: None,
            speed_max_rad_s: f64::from(p.limits.speed_max_rad_s),
        }
    }

    /// The plant a step of sign `direction` meets: the load's reflected
    /// inertia through the screw's efficiency law, `J ± μ m r²` (+ lifting),
    /// the rod's mode moved with it.
    pub fn for_step(&self, direction: f64) -> DesignPlant {
        let sgn = |x: f64| if x > 0.0 { 1.0 } else if x < 0.0 { -1.0 } else { 0.0 };
        let s = sgn(direction) * sgn(self.load_sign);
        let extra = s * self.screw_mu * self.load_inertia_kg_m2;
        if extra == 0.0 || !extra.is_finite() {
            return self.clone();
        }
        let j = self.inertia_kg_m2 + extra;
        DesignPlant {
            inertia_kg_m2: j,
            rod_mode: self.rod_mode.map(|m| m.with_total_inertia(self.inertia_kg_m2, j)),
            ..self.clone()
        }
    }
    pub fn t_pwm(&self) -> f64 {
        1.0 / self.pwm_hz
    }
    pub fn t_speed(&self) -> f64 {
        self.speed_div / self.pwm_hz
    }
    pub fn t_position(&self) -> f64 {
        self.position_div / self.pwm_hz
    }

    /// Current loop open loop (q axis) at `w` rad/s: `C(z) W(z) z⁻¹/(1 + Q)`,
    /// `W = b/(z − a)` the winding over a held period, one period of
    /// computation; `Q = W p ψ K_t M(s) (z^{1/2} − z⁻¹ PLL(s))` the back-EMF
    /// the motion `ω = K_t M(s) i` induces (mid-period) less the feedforward
    /// the core subtracts (the PLL's speed, one period late). Q is what cut
    /// the q loop's gain by 0.3–1 dB at 100–450 Hz; 0 on the d axis.
    pub fn current_ol(&self, kp: f64, ki: f64, w: f64) -> C {
        let t = self.t_pwm();
        let z = cis(w * t);
        let a = (-self.r_ohm * t / self.l_h).exp();
        let b = (1.0 - a) / self.r_ohm;
        let c = C::from(kp) + z * (ki * t) / (z - 1.0);
        let wdg = b / (z - a);
        let p_psi = self.kt_n_m_a / 1.5;
        let q = wdg * p_psi * self.kt_n_m_a * self.mechanics(w) * (cis(0.5 * w * t) - self.pll(w) / z);
        c * wdg / (z * (q + 1.0))
    }
    pub fn current_cl(&self, kp: f64, ki: f64, w: f64) -> C {
        let l = self.current_ol(kp, ki, w);
        l / (l + 1.0)
    }

    /// The core's torque filter (bilinear 2nd-order Butterworth at the speed
    /// rate; off when 0 or beyond 0.45 of the rate).
    pub fn torque_filter(&self, w: f64) -> C {
        let rate = 1.0 / self.t_speed();
        let f = self.torque_filter_hz;
        if !(f > 0.0 && f < 0.45 * rate) {
            return C::from(1.0);
        }
        let k = (PI * f / rate).tan();
        let q = FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        let a1 = 2.0 * (k * k - 1.0) * norm;
        let a2 = (1.0 - k / q + k * k) * norm;
        let zi = cis(-w * self.t_speed());
        (zi * 2.0 * b0 + zi * zi * b0 + b0) / (zi * a1 + zi * zi * a2 + 1.0)
    }

    fn zoh(t: f64, w: f64) -> C {
        if w * t < 1e-9 {
            return C::from(1.0);
        }
        (C::from(1.0) - cis(-w * t)) / (C::new(0.0, w * t))
    }

    /// The encoder PLL's speed over the true speed.
    pub fn pll(&self, w: f64) -> C {
        let s = C::new(0.0, w);
        (s * self.pll_kp + self.pll_ki) / (s * s + s * self.pll_kp + self.pll_ki)
    }

    /// Mechanics: true speed per torque.
    pub fn mechanics(&self, w: f64) -> C {
        let s = C::new(0.0, w);
        let rigid = C::from(1.0) / (s * self.inertia_kg_m2 + self.viscous_n_m_s_rad);
        match &self.rod_mode {
            Some(m) => rigid * m.factor(s),
            None => rigid,
        }
    }

    /// Speed PI output (A) to true speed (rad/s): torque filter, hold of the
    /// speed period, closed current loop, torque constant, mechanics.
    pub fn speed_forward(&self, cur: (f64, f64), w: f64) -> C {
        self.torque_filter(w) * Self::zoh(self.t_speed(), w) * self.current_cl(cur.0, cur.1, w) * self.kt_n_m_a * self.mechanics(w)
    }
    /// The speed PI (backward Euler integral, as `Pi::update`).
    pub fn speed_pi(&self, kp: f64, ki: f64, w: f64) -> C {
        let z = cis(w * self.t_speed());
        C::from(kp) + z * (ki * self.t_speed()) / (z - 1.0)
    }
    pub fn speed_ol(&self, cur: (f64, f64), spd: (f64, f64), w: f64) -> C {
        self.speed_pi(spd.0, spd.1, w) * self.speed_forward(cur, w) * self.pll(w)
    }
    /// The speed PI from the reference: `kp b + ki T z/(z − 1)`.
    pub fn speed_pi_reference(&self, kp: f64, ki: f64, w: f64) -> C {
        self.speed_pi(kp * self.speed_setpoint_weight, ki, w)
    }
    /// Measured (PLL) speed over the speed reference: what a speed chirp's
    /// FRF measures.
    pub fn speed_cl(&self, cur: (f64, f64), spd: (f64, f64), w: f64) -> C {
        let f = self.speed_pi_reference(spd.0, spd.1, w) * self.speed_forward(cur, w) * self.pll(w);
        f / (self.speed_ol(cur, spd, w) + 1.0)
    }
    /// True speed over the speed reference.
    pub fn speed_cl_true(&self, cur: (f64, f64), spd: (f64, f64), w: f64) -> C {
        let f = self.speed_pi_reference(spd.0, spd.1, w) * self.speed_forward(cur, w);
        f / (self.speed_ol(cur, spd, w) + 1.0)
    }
    pub fn position_ol(&self, cur: (f64, f64), spd: (f64, f64), kp: f64, w: f64) -> C {
        let s = C::new(0.0, w);
        self.speed_cl_true(cur, spd, w) * Self::zoh(self.t_position(), w) * kp / s
    }
    pub fn position_cl(&self, cur: (f64, f64), spd: (f64, f64), kp: f64, w: f64) -> C {
        let l = self.position_ol(cur, spd, kp, w);
        l / (l + 1.0)
    }
}

/// First frequency (Hz) at which `|t|` falls 3 dB below its value at `f0`,
/// searched up to `f1`.
pub fn bandwidth_hz(t: impl Fn(f64) -> C, f0: f64, f1: f64) -> Option<f64> {
    let g0 = t(TAU * f0).norm();
    let n = 2000;
    let mut prev = f0;
    for k in 1..=n {
        let f = f0 * (f1 / f0).powf(k as f64 / n as f64);
        if t(TAU * f).norm() < g0 * FRAC_1_SQRT_2 {
            let (mut lo, mut hi) = (prev, f);
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if t(TAU * mid).norm() < g0 * FRAC_1_SQRT_2 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return Some(0.5 * (lo + hi));
        }
        prev = f;
    }
    None
}

/// Margins of an open loop: the first gain crossover (phase margin) and the
/// first phase crossover after it (gain margin), on a log grid.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Margins {
    pub crossover_hz: Option<f64>,
    pub phase_margin_deg: Option<f64>,
    pub phase_crossover_hz: Option<f64>,
    pub gain_margin_db: Option<f64>,
    /// Largest |1/(1 + L)| (sensitivity peak), dB.
    pub sensitivity_peak_db: f64,
}

pub fn margins(l: impl Fn(f64) -> C, f0: f64, f1: f64) -> Margins {
    let n = 4000;
    let f: Vec<f64> = (0..=n).map(|k| f0 * (f1 / f0).powf(k as f64 / n as f64)).collect();
    let v: Vec<C> = f.iter().map(|&f| l(TAU * f)).collect();
    margins_from_samples(&f, &v)
}

/// [`margins`] of an open loop given at the frequencies `f` (Hz, rising).
pub fn margins_from_samples(f: &[f64], l: &[C]) -> Margins {
    let mut out = Margins::default();
    let mut ms = 0.0f64;
    for k in 0..f.len().min(l.len()) {
        let v = l[k];
        ms = ms.max(1.0 / (v + 1.0).norm());
        if k == 0 {
            continue;
        }
        let (fp, vp, f) = (f[k - 1], l[k - 1], f[k]);
        if out.crossover_hz.is_none() && vp.norm() >= 1.0 && v.norm() < 1.0 {
            let a = (vp.norm().ln()) / (vp.norm().ln() - v.norm().ln());
            let x = vp + (v - vp) * a;
            out.crossover_hz = Some(fp + a * (f - fp));
            out.phase_margin_deg = Some(180.0 + (-(-x.arg().to_degrees()).rem_euclid(360.0)));
        }
        if out.phase_crossover_hz.is_none() && (vp.im < 0.0) != (v.im < 0.0) && v.re < 0.0 && vp.re < 0.0 {
            let a = vp.im / (vp.im - v.im);
            let x = vp + (v - vp) * a;
            out.phase_crossover_hz = Some(fp + a * (f - fp));
            out.gain_margin_db = Some(-20.0 * x.norm().log10());
        }
    }
    out.sensitivity_peak_db = 20.0 * ms.log10();
    out
}

fn solve_increasing(target: f64, mut lo: f64, mut hi: f64, g: impl Fn(f64) -> Option<f64>) -> Option<f64> {
    // Geometric bisection of an increasing g.
    let (glo, ghi) = (g(lo)?, g(hi)?);
    if !(glo <= target && target <= ghi) {
        return None;
    }
    for _ in 0..80 {
        let mid = (lo * hi).sqrt();
        match g(mid) {
            Some(v) if v < target => lo = mid,
            _ => hi = mid,
        }
    }
    Some((lo * hi).sqrt())
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct LoopDesign {
    pub kp: f64,
    pub ki: f64,
    pub asked_bandwidth_hz: f64,
    pub asked_phase_margin_deg: Option<f64>,
    /// The design model's closed-loop −3 dB frequency.
    pub model_bandwidth_hz: f64,
    pub margins: Margins,
    /// What the user asked (None: whatever the plain design gives).
    pub asked_overshoot_pct: Option<f64>,
    /// Overshoot of the design model's step response (`model::step_response`).
    pub model_overshoot_pct: f64,
    pub rule: String,
}

/// Current PI by pole-zero cancellation on the sampled loop.
pub fn design_current(p: &DesignPlant, bw_hz: f64) -> anyhow::Result<(f64, f64, Margins, f64)> {
    let gains = |wc: f64| (p.l_h * wc, p.r_ohm * wc);
    let bw = |wc: f64| {
        let (kp, ki) = gains(wc);
        bandwidth_hz(|w| p.current_cl(kp, ki, w), 1.0, 0.5 * p.pwm_hz)
    };
    // ω_c up to where the phase margin would fall below 30°: a quarter of
    // the PWM rate in ω_c·1.5 T.
    let wc_max = (PI / 3.0) / (1.5 * p.t_pwm());
    let wc = solve_increasing(bw_hz, TAU * 1.0, wc_max, bw).ok_or_else(|| {
        anyhow::anyhow!(
            "current-loop bandwidth {bw_hz} Hz is not reachable with at least 30° of phase margin at {} Hz PWM (at most {:.0} Hz)",
            p.pwm_hz,
            bw(wc_max).unwrap_or(f64::NAN)
        )
    })?;
    let (kp, ki) = gains(wc);
    let m = margins(|w| p.current_ol(kp, ki, w), 1.0, 0.5 * p.pwm_hz);
    Ok((kp, ki, m, bw(wc).unwrap_or(f64::NAN)))
}

/// The speed PI that leaves `pm_deg` at crossover `wc`: `(kp, ki)`, or
/// `None` if the lags already eat the margin.
pub fn speed_pi_at(p: &DesignPlant, cur: (f64, f64), wc: f64, pm_deg: f64) -> Option<(f64, f64)> {
    let g = p.speed_forward(cur, wc) * p.pll(wc);
    let need = (-180.0 + pm_deg).to_radians() - g.arg();
    // Wrapped to (−π, π].
    let need = (need + PI).rem_euclid(TAU) - PI;
    // The PI is kp (1 + r D), D = T z/(z − 1): its phase runs from 0 (r = 0)
    // towards ∠D (≈ −90°) as r grows.
    let z = cis(wc * p.t_speed());
    let d = z * p.t_speed() / (z - 1.0);
    if need > 0.0 || need <= d.arg() {
        return None;
    }
    let tn = need.tan();
    let r = tn / (d.im - d.re * tn);
    if !(r >= 0.0) {
        return None;
    }
    let kp = 1.0 / ((C::from(1.0) + d * r) * g).norm();
    Some((kp, r * kp))
}

pub fn design_speed(p: &DesignPlant, cur: (f64, f64), bw_hz: f64, pm_deg: f64) -> anyhow::Result<(f64, f64, Margins, f64)> {
    let bw = |wc: f64| {
        let (kp, ki) = speed_pi_at(p, cur, wc, pm_deg)?;
        bandwidth_hz(|w| p.speed_cl(cur, (kp, ki), w), 0.5, 0.25 / p.t_speed())
    };
    // The largest crossover at which the PI can still leave the margin.
    let mut wc_hi = TAU * 1.0;
    while wc_hi < TAU * 0.2 / p.t_speed() && speed_pi_at(p, cur, wc_hi * 1.05, pm_deg).is_some() {
        wc_hi *= 1.05;
    }
    let wc = solve_increasing(bw_hz, TAU * 0.5, wc_hi, bw).ok_or_else(|| {
        anyhow::anyhow!(
            "speed-loop bandwidth {bw_hz} Hz with {pm_deg}° of phase margin is not reachable: the current loop, torque filter, hold and PLL lags allow at most {:.1} Hz at that margin",
            bw(wc_hi).unwrap_or(f64::NAN)
        )
    })?;
    let (kp, ki) = speed_pi_at(p, cur, wc, pm_deg).expect("inside the feasible range");
    let m = margins(|w| p.speed_ol(cur, (kp, ki), w), 0.5, 0.5 / p.t_speed());
    Ok((kp, ki, m, bw(wc).unwrap_or(f64::NAN)))
}

pub fn design_position(p: &DesignPlant, cur: (f64, f64), spd: (f64, f64), bw_hz: f64) -> anyhow::Result<(f64, Margins, f64)> {
    let bw = |kp: f64| bandwidth_hz(|w| p.position_cl(cur, spd, kp, w), 0.05, 0.5 / p.t_position());
    let k = solve_increasing(bw_hz, 0.1, 2000.0, bw)
        .ok_or_else(|| anyhow::anyhow!("position-loop bandwidth {bw_hz} Hz is not reachable with this speed loop"))?;
    let m = margins(|w| p.position_ol(cur, spd, k, w), 0.05, 0.5 / p.t_position());
    Ok((k, m, bw(k).unwrap_or(f64::NAN)))
}
