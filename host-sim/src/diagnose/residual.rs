//! The nominal model and the inverse-dynamics residual.
//!
//! From the measured motion (motor angle, or the linear scale when no encoder
//! is logged) Savitzky–Golay differentiation gives ω and α; the nominal model
//! gives the torque the motion needs, compared with the torque from current
//! (torque channel); the rod position the nominal compliance predicts,
//! compared with the scale (position channel); the q-axis voltage the nominal
//! motor needs, compared with the logged command (voltage channel). No
//! simulation, so no drift: friction, load and inertia gaps show directly.
//!
//! The nominal model (`physics`, `regression`), the differentiation
//! (`savitzky_golay`) and the lost-motion shapes (`lost_motion`) live in
//! the submodules; this file holds the channels, the segment and its
//! builder.

mod lost_motion;
mod physics;
mod regression;
mod savitzky_golay;

pub use lost_motion::*;
pub use physics::*;
pub use regression::*;
use savitzky_golay::sg;
pub use savitzky_golay::*;

use super::log::Log;
use anyhow::{bail, Result};

pub const TORQUE: usize = 0;
pub const POSITION: usize = 1;
pub const VOLTAGE: usize = 2;
pub const NCH: usize = 3;
pub const CHANNELS: [&str; NCH] = ["torque", "position", "voltage"];

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
    /// The logged current, Savitzky–Golay smoothed (with the derivatives
    /// of the inverse dynamics) and as logged: smoothing over ±10 ms
    /// removes what drives a mode above ≈ 25 Hz.
    pub iq: Vec<f64>,
    pub iq_logged: Vec<f64>,
    /// The motor angle and the scale as logged (empty: not logged), where
    /// a sensor's own resolution shows.
    pub theta_logged: Vec<f64>,
    pub scale_logged: Vec<f64>,
    /// The logged motor temperature, °C (empty: not logged).
    pub temperature_c: Vec<f64>,
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
        let temperature = get("motor_temperature_c").map(|v| &v[s..e]);
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
            seg.iq_logged.push(iq_raw.as_ref().map_or(0.0, |v| v[i]));
            if encoder {
                seg.theta_logged.push(theta_raw[i]);
            }
            if let Some(sc) = scale {
                seg.scale_logged.push(sc[i]);
            }
            if let Some(tc) = temperature {
                seg.temperature_c.push(tc[i]);
            }
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
