//! A lightly damped resonance: a mode of a few tens of hertz ringing under
//! the motor's thrust, fitted where it shows. Its frequency and damping
//! are searched on a coarse grid (frequency in 4 % steps: a mode with
//! ζ = 0.02 is 4 % wide), then refined around the best point; its
//! amplitude is linear. The rig's own axial mode (`rod_mode`) belongs to
//! the nominal's floor and is taken out of the position channel first.

use super::super::events::Remainder;
use super::super::residual::{sg_second, Nominal, Segment, POSITION};
use super::{fit_grid, lsq, nominal_pred, rms, GenericFit, Shape};

/// Damping ratios of the coarse search: light modes (0.015–0.04) to a
/// well-damped one.
const COARSE_ZETA: [f64; 4] = [0.015, 0.04, 0.1, 0.3];
/// The refinement around the coarse best: frequency steps of 1 % over
/// ±3 % (the coarse step is 4 %), damping steps of ×1.25 over ×/÷ 1.95
/// (the coarse steps are ×2.5–3).
const FINE_F_STEP: f64 = 0.01;
const FINE_ZETA_STEP: f64 = 1.25;
const FINE_STEPS: i32 = 3;

/// The resonance on channel `c`, fitted on training and scored on the
/// held-out remainder (`nominal_rms_h`: the nominal's held-out RMS on `c`).
pub fn fit(
    train: &[&Segment],
    rem_t: &Remainder,
    held: &[&Segment],
    rem_h: &Remainder,
    nominal: &Nominal,
    c: usize,
    nominal_rms_h: f64,
) -> Option<GenericFit> {
    let dt = train.first().map_or(1e-3, |s| s.dt);
    let f_max = (0.2 / dt).min(150.0);
    if f_max <= 6.0 {
        return None;
    }
    let two_mass = matches!(nominal, Nominal::Physics(_)) && train.iter().all(|s| s.rod_from_scale);
    let point = |f: f64, zeta: f64| -> (Vec<(&'static str, f64)>, Box<Shape>) {
        let nominal = nominal.clone();
        let shape: Box<Shape> = Box::new(move |s: &Segment| mode_shape(s, c, &nominal, f, zeta).into_iter().map(|v| vec![v]).collect());
        (vec![("frequency_hz", f), ("damping_ratio", zeta)], shape)
    };
    let nf = ((f_max / 5.0f64).ln() / 1.04f64.ln()).ceil() as usize + 1;
    let coarse: Vec<(f64, f64)> = (0..nf)
        .map(|j| 5.0 * (f_max / 5.0f64).powf(j as f64 / (nf - 1) as f64))
        .flat_map(|f| COARSE_ZETA.into_iter().map(move |z| (f, z)))
        .collect();
    let (f0, z0) = coarse
        .into_iter()
        .map(|(f, z)| {
            let (_, shape) = point(f, z);
            let xt: Vec<Vec<Vec<f64>>> = train.iter().map(|s| shape(s)).collect();
            let b = lsq(train, rem_t, c, &xt);
            (f, z, rms(train, rem_t, c, Some((&xt, &b))))
        })
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(f, z, _)| (f, z))?;
    let fine: Vec<_> = (-FINE_STEPS..=FINE_STEPS)
        .flat_map(|i| (-FINE_STEPS..=FINE_STEPS).map(move |j| (i, j)))
        .map(|(i, j)| ((f0 * (1.0 + FINE_F_STEP * i as f64)).min(f_max), z0 * FINE_ZETA_STEP.powi(j)))
        .map(|(f, z)| point(f, z))
        .collect();
    // The gain is the mode's static compliance (m/N) where the shape is
    // the two-mass one; its stiffness is reported with it.
    fit_grid(train, rem_t, held, rem_h, c, nominal_rms_h, "resonance", fine, &|b| {
        let g = b.first().copied().unwrap_or(0.0);
        let mut v = vec![("gain", g)];
        if g > 0.0 && two_mass {
            v.push(("stiffness_n_per_um", 1e-6 / g));
        }
        v
    })
}

/// What drives a resonance seen on channel `c`: the thrust on the screw.
fn thrust(s: &Segment, c: usize, nominal: &Nominal) -> Vec<f64> {
    match (nominal, c) {
        // The position channel (scale − motor side) is not the current:
        // the motor's thrust from the logged current drives the frame, as
        // logged (the smoothed current has lost the band a mode rings in).
        (Nominal::Physics(p), POSITION) => s.iq_logged.iter().map(|i| p.kt * i / p.k).collect(),
        (Nominal::Physics(p), _) => s.f_ax.iter().map(|f| f * p.k).collect(),
        _ => nominal_pred(s, c),
    }
}

/// The regressor of a lightly damped mode between the motor and the rod
/// (a two-mass system: the motor's thrust drives the rod side through a
/// spring) on channel `c`, with the scale logged beside an encoder: the
/// rod side's ringing `y − u` under the motor's thrust `u` (logged
/// current), per metre-per-newton of compliance, reaches
/// - the position channel (scale − motor side) as itself, plus the nominal
///   drive-train deflection the rod's inertial force from the scale adds
///   (`c_loc m a`);
/// - the torque channel through the rod's inertial force `m a` taken from
///   the scale: `−k m a`, with `a` the same Savitzky–Golay second
///   derivative the channel applies to the scale.
///
/// Without the two bodies measured it is the ringing under the channel's
/// thrust (`thrust`).
fn mode_shape(s: &Segment, c: usize, nominal: &Nominal, f_hz: f64, zeta: f64) -> Vec<f64> {
    let Nominal::Physics(p) = nominal else {
        return ringing(&thrust(s, c, nominal), s.dt, f_hz, zeta);
    };
    if !s.rod_from_scale {
        return ringing(&thrust(s, c, nominal), s.dt, f_hz, zeta);
    }
    let u: Vec<f64> = s.iq_logged.iter().map(|i| p.kt * i / p.k).collect();
    let ring = ringing(&u, s.dt, f_hz, zeta);
    let acc = sg_second(&ring, s.sg_m, s.dt);
    match c {
        POSITION => ring.iter().zip(&acc).zip(&s.c_loc).map(|((y, a), cl)| y + cl * p.m_moving * a).collect(),
        _ => acc.iter().map(|a| -p.k * p.m_moving * a).collect(),
    }
}

/// The ringing part `y − u` of `y'' + 2ζω y' + ω² y = ω² u`, `u` held over
/// each sample step (10 sub-steps, semi-implicit Euler).
fn ringing(u: &[f64], dt: f64, f_hz: f64, zeta: f64) -> Vec<f64> {
    let w = std::f64::consts::TAU * f_hz;
    let h = dt / 10.0;
    let (mut y, mut v) = (u.first().copied().unwrap_or(0.0), 0.0);
    u.iter()
        .map(|uk| {
            for _ in 0..10 {
                v += h * (w * w * (uk - y) - 2.0 * zeta * w * v);
                y += h * v;
            }
            y - uk
        })
        .collect()
}

/// `ringing` with a natural frequency that moves with the sample (rad/s
/// per sample): the rod's axial mode, whose stiffness changes along the
/// stroke.
fn ringing_var(u: &[f64], dt: f64, w: &[f64], zeta: f64) -> Vec<f64> {
    let h = dt / 10.0;
    let (mut y, mut v) = (u.first().copied().unwrap_or(0.0), 0.0);
    u.iter()
        .zip(w)
        .map(|(uk, wk)| {
            for _ in 0..10 {
                v += h * (wk * wk * (uk - y) - 2.0 * zeta * wk * v);
                y += h * v;
            }
            y - uk
        })
        .collect()
}

/// The rig's own axial mode on the position channel: the moving mass on
/// the drive train's local compliance, `ω = 1/√(m c(x))`, ringing under
/// the motor's thrust. It is part of the nominal's floor (the rigid-body
/// nominal leaves it), not an unmodelled resonance: it is fitted first
/// (damping and a ±25 % frequency scale chosen on training, amplitude
/// linear) and the generic classes explain what it leaves.
pub(super) fn rod_mode(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, nominal: &Nominal) -> Option<(Remainder, Remainder)> {
    let Nominal::Physics(p) = nominal else { return None };
    let shape = |s: &Segment, scale: f64, zeta: f64| -> Vec<Vec<f64>> {
        let w: Vec<f64> = s
            .c_loc
            .iter()
            .map(|c| if *c > 0.0 { scale / (p.m_moving * c).sqrt() } else { 0.0 })
            .collect();
        if w.iter().any(|x| !x.is_finite() || *x <= 0.0 || *x * s.dt > 0.5) {
            return vec![vec![0.0]; s.len()];
        }
        ringing_var(&thrust(s, POSITION, nominal), s.dt, &w, zeta)
            .into_iter()
            .map(|v| vec![v])
            .collect()
    };
    let best = [0.8, 0.9, 1.0, 1.1, 1.25]
        .into_iter()
        .flat_map(|sc| [0.05, 0.1, 0.2, 0.3].into_iter().map(move |z| (sc, z)))
        .map(|(sc, z)| {
            let xt: Vec<Vec<Vec<f64>>> = train.iter().map(|s| shape(s, sc, z)).collect();
            let b = lsq(train, rem_t, POSITION, &xt);
            let after = rms(train, rem_t, POSITION, Some((&xt, &b)));
            (sc, z, b, after)
        })
        .min_by(|a, b| a.3.total_cmp(&b.3))?;
    let (sc, z, b, _) = best;
    let sub = |segs: &[&Segment], rem: &Remainder| -> Remainder {
        segs.iter()
            .zip(rem)
            .map(|(s, r)| {
                let x = shape(s, sc, z);
                std::array::from_fn(|c| {
                    let y = r[c].as_ref()?;
                    Some(if c == POSITION {
                        y.iter().zip(&x).map(|(a, xi)| a - xi[0] * b.first().copied().unwrap_or(0.0)).collect()
                    } else {
                        y.clone()
                    })
                })
            })
            .collect()
    };
    Some((sub(train, rem_t), sub(held, rem_h)))
}

