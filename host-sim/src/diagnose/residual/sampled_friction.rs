//! The nominal's friction evaluated sample by sample, then smoothed by the
//! same filter as the logged current (`accel_smoother`).
//!
//! Friction switches with the direction of motion within a fraction of a
//! millisecond (the rig's own sign regularisation), and the logged current
//! that balances it is smoothed over ±10 ms. A friction law evaluated on
//! the ±10 ms smoothed speed switches over the whole window instead (and
//! the smoothing leaks the coming motion into the samples before it
//! starts), so the nominal would switch the friction differently from the
//! current it is compared with. Smoothing the law's sample-by-sample value
//! (`smooth(f(ω))`, not `f(smooth(ω))`) with the current's filter treats
//! the friction as the current is treated.

use super::savitzky_golay::{accel_smoother, sg, smooth_with};
use super::Physics;

/// Half width of the speed the friction laws see, s: short enough to
/// resolve a breakaway, long enough to average a few encoder counts.
pub const SAMPLED_SPEED_HALF_WIDTH_S: f64 = 0.002;

/// The friction terms of one run, on the run's raw sample index (valid on
/// `m..n−m`, where the residual is built).
pub struct SampledFriction {
    /// The rod seal's force (the nut carries it), N, smoothed.
    pub seal_n: Vec<f64>,
    /// The screw–nut friction torque (bearings' viscous, drag, load-
    /// proportional Coulomb) under the nut force, N·m, smoothed.
    pub screw_n_m: Vec<f64>,
    /// The friction's sign (`tanh(ω/ω_ε)` at the rig's regularisation),
    /// smoothed: the regressor a re-fitted drag must use to match.
    pub sign: Vec<f64>,
}

/// Evaluates the friction per sample on the motor angle `theta` (rad; the
/// motor-side speed over ±`SAMPLED_SPEED_HALF_WIDTH_S`) with the nut force
/// `f_base` (load and rod inertia, without the seal, N, per raw sample)
/// and smooths each term over ±`m` samples. `dir_threshold_rad_s`: the
/// speed beyond which the direction the seal holds at rest is updated.
pub fn sampled_friction(p: &Physics, theta: &[f64], f_base: &[f64], m: usize, dt: f64, dir_threshold_rad_s: f64) -> SampledFriction {
    let n = theta.len();
    let mf = ((SAMPLED_SPEED_HALF_WIDTH_S / dt).round() as usize).clamp(1, m.max(1));
    let omega_eps = p.omega_eps_sampled;
    let mut seal = Vec::with_capacity(n);
    let mut screw = Vec::with_capacity(n);
    let mut sign = Vec::with_capacity(n);
    let mut dir = 0.0;
    for j in 0..n {
        let jj = j.clamp(mf, n.saturating_sub(mf + 1).max(mf));
        let om = if n > 2 * mf { sg(theta, jj, mf, dt).1 } else { 0.0 };
        if om > dir_threshold_rad_s {
            dir = 1.0;
        } else if om < -dir_threshold_rad_s {
            dir = -1.0;
        } else if dir == 0.0 {
            dir = om.signum();
        }
        let f_seal = p.rod_friction_eps_n(p.k * om, dir, p.k * omega_eps);
        let f_nut = f_base[j] + f_seal;
        let s = (om / omega_eps).tanh();
        seal.push(f_seal);
        screw.push(p.b_screw * om + s * (p.drag_n_m + p.mu * p.k * f_nut.abs()));
        sign.push(s);
    }
    let g = accel_smoother(m);
    let smooth = |y: &[f64]| -> Vec<f64> { (0..n).map(|i| smooth_with(y, i, &g)).collect() };
    SampledFriction {
        seal_n: smooth(&seal),
        screw_n_m: smooth(&screw),
        sign: smooth(&sign),
    }
}
