//! A count loss: an encoder (or scale) that drops counts once leaves the
//! scale − motor difference offset by the lost distance from that instant
//! on, and nothing else — no force changed, so the torque channel does not
//! step with it.
//!
//! Many things leave steps in the position channel: a lost motion at every
//! reversal, force steps through the drive train's compliance, a drift.
//! The class is gated on its own evidence, run by run (how many counts a
//! run loses, and when, is a state of that run, not a constant of the
//! rig):
//! - **sharp**: lines fitted to the remainder over `WINDOW_S` on each side
//!   of the instant (leaving `GAP_S` for the loss itself) disagree there by
//!   `SHARP_Z` times the scatter about them — a ramp or a drift has none;
//! - **single**: the largest other step of the run, away from it, is under
//!   `SINGLE_RATIO` of it — a lost motion steps at every reversal;
//! - **no force**: the torque channel steps by under `FORCE_RATIO` of the
//!   torque the nut force through the nominal compliance would need for
//!   that offset (`k Δx / c`).
//!
//! Each part is scored with its runs' steps (a constant per run with and
//! without the step), like the drifting gain.

use super::super::events::Remainder;
use super::super::figures::shrink;
use super::super::residual::{Nominal, Segment, CHANNELS, POSITION, TORQUE};
use super::GenericFit;

/// Lines each side of the instant, s, and the span left out between them
/// for the loss itself (a burst of lost counts lasts tens of ms), s.
pub const WINDOW_S: f64 = 0.15;
pub const GAP_S: f64 = 0.03;
/// The jump at the instant against the scatter about the lines.
pub const SHARP_Z: f64 = 8.0;
/// The largest other step of the run against this one, away from it by
/// `AWAY_S`.
pub const SINGLE_RATIO: f64 = 0.3;
pub const AWAY_S: f64 = 0.3;
/// The torque channel's step against the torque a force making the offset
/// would need.
pub const FORCE_RATIO: f64 = 0.25;

/// One run's step: sample, size (m), the sharpness, the other step's ratio,
/// the torque's ratio, and why it is refused (if it is).
#[derive(Clone, Debug)]
struct Step {
    at: usize,
    size_m: f64,
    z: f64,
    other_ratio: f64,
    force_ratio: f64,
    refused: Option<String>,
}

/// The best single step `a + s H(i ≥ i0)` of `y` (weights `w`) with `i0` in
/// `lo..hi` and outside `skip`: (i0, s, energy it removes).
fn best_step(y: &[f64], w: &[f64], lo: usize, hi: usize, skip: Option<(usize, usize)>) -> Option<(usize, f64, f64)> {
    let n = y.len();
    let (mut sw, mut sy) = (vec![0.0; n + 1], vec![0.0; n + 1]);
    for i in 0..n {
        sw[i + 1] = sw[i] + w[i];
        sy[i + 1] = sy[i] + w[i] * y[i];
    }
    (lo.max(1)..hi.min(n))
        .filter(|i| skip.is_none_or(|(a, b)| *i < a || *i >= b))
        .filter_map(|i| {
            let (wl, wr) = (sw[i], sw[n] - sw[i]);
            if wl <= 0.0 || wr <= 0.0 {
                return None;
            }
            let (ml, mr) = (sy[i] / wl, (sy[n] - sy[i]) / wr);
            Some((i, mr - ml, wl * wr / (wl + wr) * (mr - ml).powi(2)))
        })
        .max_by(|a, b| a.2.total_cmp(&b.2))
}

/// Lines over `a..b` of `y`: the value at `at` and the RMS scatter about it.
fn line_at(y: &[f64], t: &[f64], a: usize, b: usize, at: f64) -> Option<(f64, f64)> {
    if b <= a + 3 {
        return None;
    }
    let m = (b - a) as f64;
    let (st, sy) = (t[a..b].iter().sum::<f64>() / m, y[a..b].iter().sum::<f64>() / m);
    let stt: f64 = t[a..b].iter().map(|x| (x - st).powi(2)).sum();
    let sty: f64 = t[a..b].iter().zip(&y[a..b]).map(|(x, v)| (x - st) * (v - sy)).sum();
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    let scatter = (t[a..b].iter().zip(&y[a..b]).map(|(x, v)| (v - sy - slope * (x - st)).powi(2)).sum::<f64>() / m).sqrt();
    Some((sy + slope * (at - st), scatter))
}

/// The jump of `y` at sample `i0` between the lines on each side, and the
/// pooled scatter about them.
fn jump(y: &[f64], t: &[f64], i0: usize, dt: f64) -> Option<(f64, f64)> {
    let (g, w) = ((GAP_S / dt).round() as usize, (WINDOW_S / dt).round() as usize);
    let (la, lb) = (i0.checked_sub(g + w)?, i0.checked_sub(g)?);
    let (ra, rb) = (i0 + g, (i0 + g + w).min(y.len()));
    let (l, sl) = line_at(y, t, la, lb, t[i0])?;
    let (r, sr) = line_at(y, t, ra, rb, t[i0])?;
    Some((r - l, (0.5 * (sl * sl + sr * sr)).sqrt()))
}

/// The step of one run, with its gates.
fn run_step(s: &Segment, y: &[f64], torque: Option<&[f64]>, p_k: f64) -> Option<Step> {
    let n = s.len();
    let edge = ((GAP_S + WINDOW_S) / s.dt).ceil() as usize;
    if n < 2 * edge + 2 {
        return None;
    }
    let w: Vec<f64> = (0..n).map(|i| s.weight(POSITION, i).powi(2)).collect();
    let (at, size, _) = best_step(y, &w, edge, n - edge, None)?;
    let (jmp, scatter) = jump(y, &s.t, at, s.dt)?;
    let z = if scatter > 0.0 { jmp.abs() / scatter } else { f64::INFINITY };
    let away = (AWAY_S / s.dt).round() as usize;
    // The other step, on what this one leaves.
    let rest: Vec<f64> = y.iter().enumerate().map(|(i, v)| if i >= at { v - size } else { *v }).collect();
    let other = best_step(&rest, &w, 1, n, Some((at.saturating_sub(away), at + away))).map_or(0.0, |o| o.1.abs());
    let other_ratio = if size != 0.0 { other / size.abs() } else { f64::INFINITY };
    let c = s.c_loc.get(at).copied().unwrap_or(0.0);
    let force_ratio = match torque {
        Some(tq) if c > 0.0 => jump(tq, &s.t, at, s.dt).map_or(f64::INFINITY, |(d, _)| d.abs() / (p_k * jmp.abs() / c)),
        _ => 0.0,
    };
    let refused = if z < SHARP_Z {
        Some(format!("not sharp: the jump is {z:.1}× the scatter about the lines either side (a loss of counts is ≥ {SHARP_Z}×)"))
    } else if other_ratio >= SINGLE_RATIO {
        Some(format!("not single: another step of the run is {:.0} % of it (a lost motion or force steps)", 100.0 * other_ratio))
    } else if force_ratio >= FORCE_RATIO {
        Some(format!("a force explains it: the torque steps by {:.0} % of what a force making that offset needs", 100.0 * force_ratio))
    } else {
        None
    };
    Some(Step { at, size_m: size, z, other_ratio, force_ratio, refused })
}

/// Weighted RMS over the runs of the position remainder less a constant per
/// run, and less each run's accepted step too.
fn scored(segs: &[&Segment], rem: &Remainder, steps: &[Option<Step>]) -> (f64, f64) {
    let (mut s0, mut s1, mut n) = (0.0, 0.0, 0usize);
    for ((s, r), st) in segs.iter().zip(rem).zip(steps) {
        let Some(y) = &r[POSITION] else { continue };
        let w: Vec<f64> = (0..s.len()).map(|i| s.weight(POSITION, i).powi(2)).collect();
        let sw: f64 = w.iter().sum();
        if sw <= 0.0 {
            continue;
        }
        let mean = y.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>() / sw;
        s0 += y.iter().zip(&w).map(|(a, b)| b * (a - mean).powi(2)).sum::<f64>();
        let left: Vec<f64> = match st.as_ref().filter(|x| x.refused.is_none()) {
            Some(x) => y.iter().enumerate().map(|(i, v)| if i >= x.at { v - x.size_m } else { *v }).collect(),
            None => y.clone(),
        };
        let mean = left.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>() / sw;
        s1 += left.iter().zip(&w).map(|(a, b)| b * (a - mean).powi(2)).sum::<f64>();
        n += s.len();
    }
    let k = n.max(1) as f64;
    ((s0 / k).sqrt(), (s1 / k).sqrt())
}

/// The count-loss class on the position channel (encoder and scale both
/// logged, physics nominal); `nominal_rms_h`: the nominal's held-out RMS on
/// the position channel. Its parameters are the held-out log's loss: the
/// offset (`lost_m`, `lost_rad` at the motor) and its time.
pub fn fit(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, nominal: &Nominal, nominal_rms_h: f64) -> Option<GenericFit> {
    let Nominal::Physics(p) = nominal else { return None };
    if !train.iter().chain(held).all(|s| s.rod_from_scale) {
        return None;
    }
    let steps = |segs: &[&Segment], rem: &Remainder| -> Vec<Option<Step>> {
        segs.iter()
            .zip(rem)
            .map(|(s, r)| run_step(s, r[POSITION].as_deref()?, r[TORQUE].as_deref(), p.k))
            .collect()
    };
    let (st, sh) = (steps(train, rem_t), steps(held, rem_h));
    let ((bt, at), (bh, ah)) = (scored(train, rem_t, &st), scored(held, rem_h, &sh));
    // The held-out log's largest step: accepted if any is, else the
    // largest refused one, whose reason is the class's.
    let pick = sh
        .iter()
        .enumerate()
        .filter_map(|(k, x)| x.as_ref().map(|x| (k, x)))
        .max_by(|a, b| (a.1.refused.is_none(), a.1.size_m.abs()).partial_cmp(&(b.1.refused.is_none(), b.1.size_m.abs())).unwrap_or(std::cmp::Ordering::Equal))?;
    let (k, x) = pick;
    let mut g = GenericFit {
        class: "count_loss".into(),
        channel: CHANNELS[POSITION].into(),
        primary_shrink_pct: shrink(nominal_rms_h, ah),
        remainder_shrink_pct: shrink(bh, ah),
        train_shrink_pct: shrink(bt, at),
        refused: x.refused.clone(),
        ..Default::default()
    };
    let seg = held[k];
    for (name, v) in [
        ("lost_m", x.size_m),
        ("lost_rad", x.size_m / p.k),
        ("time_s", seg.t[x.at]),
        ("sharpness", x.z),
        ("other_step_ratio", x.other_ratio),
        ("torque_step_ratio", x.force_ratio),
    ] {
        g.params.insert(name.into(), v);
    }
    Some(g)
}
