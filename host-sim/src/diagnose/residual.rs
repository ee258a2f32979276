//! The nominal model and the inverse-dynamics residual.
//!
//! From the measured motion (motor angle, or the linear scale when no encoder
//! is logged) Savitzky–Golay differentiation gives ω and α; the nominal model
//! gives the torque the motion needs, compared with the torque from current
//! (torque channel); the rod position the nominal compliance predicts,
//! compared with the scale (position channel); the q-axis voltage the nominal
//! motor needs, compared with the logged command (voltage channel). No
//! simulation, so no drift: friction, load and inertia gaps show directly.

use super::log::Log;
use crate::config::RigConfig;
use crate::plant::Compliance;
use anyhow::{bail, Result};

pub const TORQUE: usize = 0;
pub const POSITION: usize = 1;
pub const VOLTAGE: usize = 2;
pub const NCH: usize = 3;
pub const CHANNELS: [&str; NCH] = ["torque", "position", "voltage"];

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

/// The nominal model a log is compared with.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // one per diagnosis; boxing buys nothing
pub enum Nominal {
    /// The rig's physical model (`[plant]` of the rig TOML).
    Physics(Physics),
    /// A linear-in-parameters model of current and tracking error fitted on
    /// reference (healthy) runs: for rigs whose physical parameters are not
    /// known (the Cranfield stepper rig).
    Regression(Regression),
}

/// Nominal regression: `current ≈ Σ a_j f_j`, `tracking error ≈ Σ b_j g_j`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Regression {
    pub v_eps: f64,
    pub torque_coef: Vec<f64>,
    pub position_coef: Vec<f64>,
}

/// Regression features: a constant, the reference speed's sign, the
/// reference speed now and 2, 4, 8 and 12 samples ago (the drive's lag),
/// the reference acceleration, the load and the load × sign.
pub const REG_FEATURES: [&str; 10] = [
    "1",
    "sgn(v)",
    "v",
    "v[-2]",
    "v[-4]",
    "v[-8]",
    "v[-12]",
    "a",
    "F",
    "F·sgn(v)",
];
pub const NREG: usize = REG_FEATURES.len();

fn reg_features(seg: &Segment, i: usize, f: f64, v_eps: f64) -> [f64; NREG] {
    let v = seg.v_ref[i];
    let lag = |k: usize| seg.v_ref[i.saturating_sub(k)];
    let s = (v / v_eps).tanh();
    [
        1.0,
        s,
        v,
        lag(2),
        lag(4),
        lag(8),
        lag(12),
        seg.a_ref[i],
        f / 1000.0,
        f / 1000.0 * s,
    ]
}

/// A contiguous stretch of samples with its kinematics and residuals.
#[derive(Clone, Debug, Default)]
pub struct Segment {
    pub run: usize,
    pub heldout: bool,
    /// Log row (0-based) of the first sample kept.
    pub first_row: usize,
    pub t: Vec<f64>,
    /// Time from the start of the segment.
    pub t_rel: Vec<f64>,
    pub theta: Vec<f64>,
    pub omega: Vec<f64>,
    pub alpha: Vec<f64>,
    /// Rod position (scale if logged, else motor side), m; speed, accel.
    pub x: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    /// Reference speed and acceleration (measured ones without a reference).
    pub v_ref: Vec<f64>,
    pub a_ref: Vec<f64>,
    /// The rod's acceleration (and so its inertial force in `f_ax`) is the
    /// scale's, not the motor side's: the rod mode and any ripple the
    /// drive train passes on are measured, not modelled.
    pub rod_from_scale: bool,
    /// Gravity + external load, N; nut force (load, rod inertia, seal), N.
    pub f_load: Vec<f64>,
    pub f_ax: Vec<f64>,
    pub iq: Vec<f64>,
    /// Direction of motion with hysteresis (±1), and samples since reversal.
    pub dir: Vec<f64>,
    pub since_reversal_s: Vec<f64>,
    pub c_loc: Vec<f64>,
    /// Input for the residual–input cross-correlation (reference or current).
    pub input: Vec<f64>,
    pub y: [Option<Vec<f64>>; NCH],
    pub r: [Option<Vec<f64>>; NCH],
    /// Motor angle is from an encoder (not derived from the scale).
    pub encoder: bool,
    /// Play (backlash) operator outputs minus input, divided by the play,
    /// for every play of `BACKLASH_GRID_M`, driven by the motor side (or the
    /// reference, or the scale). Regression nominal only.
    pub play: Vec<Vec<f64>>,
    /// Physics nominal: `−½ flank`, the flank (±1) the rod rests on in a
    /// lost motion, set by the sign of the nut force with a hold band
    /// (see `flank_deviation`).
    pub flank: Vec<f64>,
    /// Weight of each sample in the torque and position channels (empty:
    /// all 1). Physics nominal: near standstill the seal and screw hold
    /// whatever friction the last motion left (statically indeterminate,
    /// anything up to breakaway), which no friction law predicts; it sets
    /// both the motor torque and the nut force that deflects the drive
    /// train. Those samples are faded out of fitting and scoring:
    /// `1 − e^{−(ω/ω_rest)²}`.
    pub motion_weight: Vec<f64>,
    /// Savitzky–Golay half width and sample step of the differentiation.
    pub sg_m: usize,
    pub dt: f64,
}

/// Plays (lost motions) tried by the backlash effect, m: 2 µm … 4.6 mm.
pub fn backlash_grid_m() -> Vec<f64> {
    (0..24).map(|k| 2e-6 * 1.4f64.powi(k)).collect()
}

/// `(play_b(x) − x)/b` of the play operator `y = clamp(y, x − b/2, x + b/2)`
/// started centred.
pub fn play_deviation(x: &[f64], b: f64) -> Vec<f64> {
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&xi| {
            y = y.clamp(xi - 0.5 * b, xi + 0.5 * b);
            (y - xi) / b
        })
        .collect()
}

/// Lost motion with a known nut force: the rod rests on the flank the force
/// pushes it against, `−½ flank` of the gap behind the screw. The flank
/// turns when the force (load + inertia + the seal's sliding friction,
/// given with the weight `moving` of the sliding law) leaves a hold band:
/// at rest the seal's breakaway `f_hold` must be overcome to push the rod
/// across the gap; sliding, only the sign counts. Without a load the
/// force follows the motion and this is the play operator.
pub fn flank_deviation(force: &[(f64, f64)], f_hold: f64) -> Vec<f64> {
    let mut flank = force
        .first()
        .map_or(1.0, |f| if f.0 < 0.0 { -1.0 } else { 1.0 });
    force
        .iter()
        .map(|&(f, moving)| {
            let band = (1.0 - moving) * f_hold;
            if f > band {
                flank = 1.0;
            } else if f < -band {
                flank = -1.0;
            }
            -0.5 * flank
        })
        .collect()
}

/// Gain of the quadratic Savitzky–Golay smoother (half width m) on a
/// sinusoid advancing `phi` rad per sample.
pub fn sg_smooth_gain(m: usize, phi: f64) -> f64 {
    let mf = m as f64;
    let den = (2.0 * mf + 1.0) * (4.0 * mf * mf + 4.0 * mf - 3.0);
    (0..=2 * m)
        .map(|j| {
            let k = j as f64 - mf;
            (3.0 * (3.0 * mf * mf + 3.0 * mf - 1.0) - 15.0 * k * k) / den * (k * phi).cos()
        })
        .sum()
}

/// Gain of the Savitzky–Golay second derivative relative to the true one on
/// a sinusoid advancing `phi` rad per sample.
pub fn sg_second_gain(m: usize, phi: f64) -> f64 {
    if phi.abs() < 1e-6 {
        return 1.0;
    }
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let num: f64 = (0..=2 * m)
        .map(|j| 2.0 * ((j as f64 - mf).powi(2) - s2) / sq * ((j as f64 - mf) * phi).cos())
        .sum();
    -num / (phi * phi)
}

/// Below this motor speed the torque and position channels fade out (see
/// `Segment::motion_weight`), rad/s: 0.8 mm/s at the rod, under the nominal
/// Stribeck speed.
pub const STANDSTILL_RAD_S: f64 = 1.0;

impl Segment {
    /// Weight of sample i in channel c (fitting and scoring).
    #[inline]
    pub fn weight(&self, c: usize, i: usize) -> f64 {
        if c == TORQUE || c == POSITION {
            self.motion_weight.get(i).copied().unwrap_or(1.0)
        } else {
            1.0
        }
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Quadratic Savitzky–Golay value, first and second derivative at sample i
/// (half width m, step h).
fn sg(y: &[f64], i: usize, m: usize, h: f64) -> (f64, f64, f64) {
    let mf = m as f64;
    let s2 = mf * (mf + 1.0) / 3.0;
    let sk2: f64 = (1..=m).map(|k| 2.0 * (k as f64).powi(2)).sum();
    let sq: f64 = (0..=2 * m)
        .map(|j| ((j as f64 - mf).powi(2) - s2).powi(2))
        .sum();
    let (mut a1, mut a2) = (0.0, 0.0);
    let mean: f64 = y[i - m..=i + m].iter().sum::<f64>() / (2.0 * mf + 1.0);
    for j in 0..=2 * m {
        let kk = j as f64 - mf;
        let v = y[i - m + j];
        a1 += kk * v;
        a2 += (kk * kk - s2) * v;
    }
    let c2 = a2 / sq;
    (mean - c2 * s2, a1 / sk2 / h, 2.0 * c2 / (h * h))
}

/// Half width of the differentiation window for a sample step: ±10 ms, at
/// least 2 samples.
pub fn half_width(dt: f64) -> usize {
    ((0.010 / dt).round() as usize).clamp(2, 50)
}

/// Builds the segments of `log` with the nominal residuals. The `m` samples
/// at each segment edge feed the differentiation only (reported).
pub fn build_segments(log: &Log, nominal: &Nominal, tilt_default_deg: f64) -> Result<Vec<Segment>> {
    let mut out = Vec::new();
    let get = |n: &str| log.get(n);
    let phys = match nominal {
        Nominal::Physics(p) => Some(p),
        Nominal::Regression(_) => None,
    };
    for (run_idx, (s, e)) in log.segments().into_iter().enumerate() {
        let t = &get("time_s").unwrap()[s..e];
        let n = t.len();
        if n < 12 {
            continue;
        }
        let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
        let m = half_width(dt);
        if n < 2 * m + 5 {
            continue;
        }
        let scale = get("terminal_position_m").map(|v| &v[s..e]);
        let k = phys.map_or(0.005 / std::f64::consts::TAU, |p| p.k);
        let x0 = phys.map_or(0.0, |p| p.x0);
        let (theta_raw, encoder): (Vec<f64>, bool) = match (get("motor_angle_rad"), scale) {
            (Some(th), _) => (th[s..e].to_vec(), true),
            (None, Some(x)) => (x.iter().map(|x| (x - x0) / k).collect(), false),
            (None, None) => {
                bail!(
                    "{}: neither motor_angle_rad nor terminal_position_m: no motion to analyse",
                    log.source
                )
            }
        };
        let mut iq_raw: Option<Vec<f64>> = get("current_q_a").map(|v| v[s..e].to_vec());
        if iq_raw.is_none() {
            if let (Some(ia), Some(ib), Some(p)) = (get("current_a_a"), get("current_b_a"), phys) {
                if encoder {
                    iq_raw = Some(
                        (s..e)
                            .map(|i| {
                                let th = p.pole_pairs * theta_raw[i - s];
                                let (al, be) = (ia[i], (ia[i] + 2.0 * ib[i]) / 3f64.sqrt());
                                -al * th.sin() + be * th.cos()
                            })
                            .collect(),
                    );
                }
            }
        }
        let uq = get("voltage_q_v").map(|v| &v[s..e]);
        let reference = get("position_reference_m").map(|v| &v[s..e]);
        let f_ext = get("load_force_n").map(|v| &v[s..e]);
        let tilt = get("tilt_deg").map(|v| &v[s..e]);
        let x_motor: Vec<f64> = theta_raw.iter().map(|th| x0 + k * th).collect();
        let xs: &[f64] = scale.unwrap_or(&x_motor);
        let rod_from_scale = phys.is_some() && scale.is_some() && encoder;
        let mut seg = Segment {
            run: run_idx,
            first_row: s + m,
            encoder,
            rod_from_scale,
            sg_m: m,
            dt,
            ..Default::default()
        };
        let omega_max = (m..n - m)
            .map(|i| sg(&theta_raw, i, m, dt).1.abs())
            .fold(0.0, f64::max);
        let omega_th = (0.05 * omega_max).max(1e-9);
        let mut dir = 1.0;
        let mut last_rev = t[0];
        let mut yt = Vec::new();
        let mut yp = Vec::new();
        let mut yv = Vec::new();
        let mut rt = Vec::new();
        let mut rp = Vec::new();
        let mut rv = Vec::new();
        let mut first = true;
        let mut flank_force = Vec::new();
        for i in m..n - m {
            let (th, om, al) = sg(&theta_raw, i, m, dt);
            let (x, v, a) = if encoder || phys.is_some() {
                (x0 + k * th, k * om, k * al)
            } else {
                sg(xs, i, m, dt)
            };
            let (x, v, a) = if scale.is_some() && !encoder {
                sg(xs, i, m, dt)
            } else {
                (x, v, a)
            };
            let newdir = if om > omega_th {
                1.0
            } else if om < -omega_th {
                -1.0
            } else {
                dir
            };
            if first {
                dir = newdir;
                first = false;
            } else if newdir != dir {
                dir = newdir;
                last_rev = t[i];
            }
            let tilt_i = tilt.map_or(tilt_default_deg, |v| v[i]);
            let fext = f_ext.map_or(0.0, |v| v[i]);
            // The rod's acceleration from the scale when it is logged next
            // to an encoder (two bodies measured), else the motor side's.
            let a_rod = match (phys, scale) {
                (Some(_), Some(sc)) if encoder => sg(sc, i, m, dt).2,
                _ => a,
            };
            let (f_load, f_ax, c_loc) = match phys {
                Some(p) => {
                    let fl = p.load_n(fext, tilt_i);
                    let (f_seal, moving) = p.rod_friction_n(v, dir);
                    let fa = fl + p.m_moving * a_rod + f_seal;
                    // The flank is decided by the force without the seal's
                    // held (static) part: a gap is crossed when load and
                    // inertia beat the seal's breakaway (`flank_deviation`).
                    flank_force.push((fl + p.m_moving * a_rod + moving * f_seal, moving));
                    (fl, fa, p.local_compliance(fa, x))
                }
                None => (fext, fext, 0.0),
            };
            let iq = iq_raw.as_ref().map(|v| sg(v, i, m, dt));
            seg.t.push(t[i]);
            seg.t_rel.push(t[i] - t[m]);
            seg.theta.push(th);
            seg.omega.push(om);
            seg.alpha.push(al);
            seg.x.push(x);
            seg.v.push(v);
            seg.a.push(a);
            let (vr, ar) = match reference {
                Some(re) => {
                    let q = sg(re, i, m, dt);
                    (q.1, q.2)
                }
                None => (v, a),
            };
            seg.v_ref.push(vr);
            seg.a_ref.push(ar);
            seg.f_load.push(f_load);
            seg.f_ax.push(f_ax);
            seg.c_loc.push(c_loc);
            seg.dir.push(dir);
            seg.since_reversal_s.push(t[i] - last_rev);
            seg.iq.push(iq.map_or(0.0, |q| q.0));
            seg.input.push(match (reference, &iq) {
                (Some(r), _) => r[i],
                (None, Some(q)) => q.0,
                (None, None) => 0.0,
            });
            match (nominal, &iq) {
                (Nominal::Physics(p), Some(q)) => {
                    let y = p.kt * q.0;
                    yt.push(y);
                    rt.push(y - p.required_torque_nut(om, al, f_ax));
                }
                (Nominal::Regression(r), Some(q)) => {
                    let f = reg_features(&seg, seg.v_ref.len() - 1, fext, r.v_eps);
                    yt.push(q.0);
                    rt.push(
                        q.0 - f
                            .iter()
                            .zip(&r.torque_coef)
                            .map(|(a, b)| a * b)
                            .sum::<f64>(),
                    );
                }
                _ => {}
            }
            match (nominal, scale) {
                (Nominal::Physics(p), Some(sc)) if encoder => {
                    let y = sc[i] - x_motor[i];
                    yp.push(y);
                    rp.push(y + p.deflection(f_ax, x) + p.screw_wind_up_m(om, al, f_ax, x, dir));
                }
                (Nominal::Regression(r), Some(sc)) => {
                    let Some(re) = reference else { continue };
                    let y = sc[i] - re[i];
                    let g = reg_features(&seg, seg.v_ref.len() - 1, fext, r.v_eps);
                    yp.push(y);
                    rp.push(
                        y - g
                            .iter()
                            .zip(&r.position_coef)
                            .map(|(a, b)| a * b)
                            .sum::<f64>(),
                    );
                }
                _ => {}
            }
            if let (Nominal::Physics(p), Some(u), Some(q)) = (nominal, uq, &iq) {
                let y = u[i];
                yv.push(y);
                rv.push(y - (p.r_ohm * q.0 + p.l_q_h * q.1 + p.pole_pairs * om * p.flux_wb));
            }
        }
        let nn = seg.t.len();
        // The play is driven by the motor side (encoder), else the reference
        // (an open-loop drive follows it), else the scale.
        let drive: Vec<f64> = (m..n - m)
            .map(|i| {
                if encoder {
                    x_motor[i]
                } else if let Some(r) = reference {
                    r[i]
                } else {
                    xs[i]
                }
            })
            .collect();
        match phys {
            Some(p) => {
                seg.flank = flank_deviation(&flank_force, p.rod_static_n);
                seg.motion_weight = seg
                    .omega
                    .iter()
                    .map(|w| 1.0 - (-(w / STANDSTILL_RAD_S).powi(2)).exp())
                    .collect();
            }
            None => {
                seg.play = backlash_grid_m()
                    .into_iter()
                    .map(|b| play_deviation(&drive, b))
                    .collect()
            }
        }
        for (c, (y, r)) in [(yt, rt), (yp, rp), (yv, rv)].into_iter().enumerate() {
            if y.len() == nn && nn > 0 {
                seg.y[c] = Some(y);
                seg.r[c] = Some(r);
            }
        }
        out.push(seg);
    }
    Ok(out)
}

/// Fits the regression nominal on reference segments (built with a zero
/// regression, which leaves the kinematics intact).
pub fn fit_regression(log: &Log) -> Result<Regression> {
    let zero = Regression {
        v_eps: 1e-3,
        torque_coef: vec![0.0; NREG],
        position_coef: vec![0.0; NREG],
    };
    let segs = build_segments(log, &Nominal::Regression(zero.clone()), 0.0)?;
    let vmax = segs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let v_eps = (0.05 * vmax).max(1e-6);
    let solve = |ch: usize, feats: &dyn Fn(&Segment, usize) -> Vec<f64>, p: usize| -> Vec<f64> {
        let mut ata = nalgebra::DMatrix::<f64>::zeros(p, p);
        let mut atb = nalgebra::DVector::<f64>::zeros(p);
        for s in &segs {
            let Some(y) = &s.y[ch] else { continue };
            for (i, yi) in y.iter().enumerate() {
                let f = feats(s, i);
                for a in 0..p {
                    atb[a] += f[a] * yi;
                    for b in 0..p {
                        ata[(a, b)] += f[a] * f[b];
                    }
                }
            }
        }
        ata.svd(true, true)
            .solve(&atb, 1e-12)
            .map(|v| v.iter().copied().collect())
            .unwrap_or_else(|_| vec![0.0; p])
    };
    let fext = |s: &Segment, i: usize| s.f_load[i];
    let tc = solve(
        TORQUE,
        &|s, i| reg_features(s, i, fext(s, i), v_eps).to_vec(),
        NREG,
    );
    let pc = solve(
        POSITION,
        &|s, i| reg_features(s, i, fext(s, i), v_eps).to_vec(),
        NREG,
    );
    Ok(Regression {
        v_eps,
        torque_coef: tc,
        position_coef: pc,
    })
}
