//! A change point at a move, told from an event by the reference.
//!
//! A nominal fitted on a healthy reference leaves its own error at the
//! moves (the loops' settling, friction at a reversal); a change point at
//! a move on the diagnosed log is then model error. But an unmeasured
//! force may start or stop at a move too, and with the moves logged the
//! lock test cannot tell the two apart. The reference can: model error
//! recurs in the reference's own residual at the same phase of the same
//! kind of move (start or stop, same direction), an event is absent from
//! it. Each change point near a move is scored by the step the reference
//! shows there; only the steps the reference repeats count as locked.

use super::disturbance::{self, DisturbanceFit};
use super::events::{self, motion_events, Remainder};
use super::gates::Gate;
use super::log::Log;
use super::residual::{build_segments, Nominal, Segment, TORQUE};
use anyhow::Result;

/// A change point is anchored to the nearest move start or stop within
/// this, s; the phase is its offset from it.
pub const ANCHOR_S: f64 = 0.3;
/// The step at a change point: mean residual over this after it minus
/// the same before it, s.
pub const STEP_WINDOW_S: f64 = 0.03;
/// The reference repeats a step when its median step at the same phase
/// removes at least this share of the step's size.
pub const REPEATED_SHARE: f64 = 0.5;

/// Move starts and stops of a log's segments: (segment, sample, kind)
/// with kind `±1` for a start in direction ±, `±2` for a stop.
fn moves(segs: &[&Segment]) -> Vec<(usize, usize, i8)> {
    let ev = motion_events(segs);
    let mut out = Vec::new();
    for (k, (s, e)) in segs.iter().zip(ev).enumerate() {
        let look = ((0.02 / s.dt).round() as usize).max(1);
        for i in e {
            let after = s.v_ref[(i + look).min(s.len() - 1)];
            let before = s.v_ref[i.saturating_sub(look)];
            let start = after.abs() > before.abs();
            let dir = if start {
                after.signum()
            } else {
                before.signum()
            };
            out.push((k, i, (dir as i8) * if start { 1 } else { 2 }));
        }
    }
    out
}

/// Step of channel `x` at sample i: mean over `[i, i+w)` minus `[i−w, i)`.
fn step(x: &[f64], i: usize, w: usize) -> Option<f64> {
    if i < w || i + w > x.len() {
        return None;
    }
    let before = x[i - w..i].iter().sum::<f64>() / w as f64;
    let after = x[i..i + w].iter().sum::<f64>() / w as f64;
    Some(after - before)
}

/// The change points `cps` of the held-out segments that the reference's
/// torque residual does not repeat at the same phase of the same kind of
/// move (all those farther than `ANCHOR_S` from a move, or without a
/// like move in the reference), and how many of those near a move it
/// repeats.
pub fn not_repeated(
    held: &[&Segment],
    rem_held: &Remainder,
    cps: &[Vec<usize>],
    reference: &[&Segment],
) -> (Vec<Vec<usize>>, usize) {
    let mv_h = moves(held);
    let mv_r = moves(reference);
    let mut repeated = 0;
    let mut kept: Vec<Vec<usize>> = cps.iter().map(|_| Vec::new()).collect();
    for (k, (s, cp)) in held.iter().zip(cps).enumerate() {
        let Some(x) = rem_held.get(k).and_then(|r| r[TORQUE].as_ref()) else {
            kept[k] = cp.clone();
            continue;
        };
        let anchor = (ANCHOR_S / s.dt).round() as i64;
        let w = ((STEP_WINDOW_S / s.dt).round() as usize).max(2);
        for &i in cp {
            let is_repeated = || -> Option<bool> {
                let &(_, e, kind) = mv_h
                    .iter()
                    .filter(|(kk, e, _)| *kk == k && (*e as i64 - i as i64).abs() <= anchor)
                    .min_by_key(|(_, e, _)| (*e as i64 - i as i64).abs())?;
                let h_step = step(x, i, w)?;
                let d = i as i64 - e as i64;
                let mut r_steps: Vec<f64> = mv_r
                    .iter()
                    .filter(|(_, _, kd)| *kd == kind)
                    .filter_map(|&(kr, er, _)| {
                        let s = reference[kr];
                        let r = s.r[TORQUE].as_ref()?;
                        let j = er as i64 + d;
                        (j >= 0).then_some(())?;
                        step(r, j as usize, w)
                    })
                    .collect();
                if r_steps.is_empty() {
                    return None;
                }
                r_steps.sort_by(f64::total_cmp);
                let r_med = r_steps[r_steps.len() / 2];
                Some((h_step - r_med).abs() <= (1.0 - REPEATED_SHARE) * h_step.abs())
            };
            if is_repeated() == Some(true) {
                repeated += 1;
            } else {
                kept[k].push(i);
            }
        }
    }
    (kept, repeated)
}

/// With a regression nominal and its reference log: the disturbance's lock
/// to the logged signals judged again on the change points the reference
/// does not repeat (`not_repeated`). A lock that no longer holds there is
/// lifted, with a gate saying why; the change points the reference repeats
/// stay model error.
pub fn recheck_lock(
    dist: &mut DisturbanceFit,
    held: &[&Segment],
    rem_held: &Remainder,
    cps: &[Vec<usize>],
    reference: &Log,
    nominal: &Nominal,
    tilt_default_deg: f64,
) -> Result<Option<Gate>> {
    if !matches!(nominal, Nominal::Regression(_)) {
        return Ok(None);
    }
    let rs = build_segments(reference, nominal, tilt_default_deg)?;
    let refs: Vec<&Segment> = rs.iter().collect();
    let (kept, repeated) = not_repeated(held, rem_held, cps, &refs);
    let steps: Vec<Vec<(usize, f64)>> = kept
        .iter()
        .map(|v| v.iter().map(|i| (*i, 1.0)).collect())
        .collect();
    let (lk, ch) = events::locked_share(
        held,
        &steps,
        &events::signal_events(held),
        disturbance::LOCK_TOL_S,
    );
    let locked = lk >= disturbance::LOCKED_RATIO * ch
        && lk - ch >= disturbance::LOCKED_EXCESS_POINTS
        && events::lock_significant(&steps, lk, ch, disturbance::LOCK_ALPHA);
    let n_kept: usize = kept.iter().map(Vec::len).sum();
    if locked || n_kept == 0 {
        return Ok(None);
    }
    dist.locked_to_signals = false;
    Ok(Some(Gate {
        kind: "moves_checked_against_reference".into(),
        channel: Some("torque".into()),
        message: format!(
            "{repeated} of the disturbance's change points recur in the reference's own residual at the same phase of the same kind of move (model error); the other {n_kept} do not, and {lk:.0} % of those sit at a logged-signal event (chance {ch:.0} %): not locked to the motion"
        ),
        figure: repeated as f64,
    }))
}
