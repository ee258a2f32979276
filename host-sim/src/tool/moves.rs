//! `move` and `jog` checked against the stroke before anything is sent.
//! The drive clamps a planned move's target to the stroke and says so, but
//! by then the rod is on its way to the end stop: a target typed in
//! millimetres (`move 250` for 0.25 m) must not become a full-stroke move.

use super::access::fetch_one_f32;
use super::client::Client;
use super::{stream, view};
use anyhow::{bail, Result};

/// ` (millimetres? positions are in metres: X m)` when `value_m / 1000`
/// would lie within `lo … hi`; else nothing.
pub fn millimetre_hint(value_m: f64, lo: f64, hi: f64) -> String {
    let m = value_m / 1000.0;
    if value_m.abs() > hi.abs().max(lo.abs()) && (lo..=hi).contains(&m) {
        format!(" (millimetres? positions are in metres: {m} m)")
    } else {
        String::new()
    }
}

/// Refuses `target_m` outside the drive's stroke, naming `what` (the command
/// as typed) and the stroke parameters; nothing is sent.
pub fn within_stroke(c: &mut Client, what: &str, target_m: f64) -> Result<()> {
    within_stroke_from(c, what, 0.0, target_m)
}

/// `within_stroke` for a target `from_m + distance` (`from_m` = 0: an
/// absolute target); the millimetre hint is about the distance then.
fn within_stroke_from(c: &mut Client, what: &str, from_m: f64, target_m: f64) -> Result<()> {
    let (Some(lo), Some(hi)) = (fetch_one_f32(c, "limits.stroke_min_m"), fetch_one_f32(c, "limits.stroke_max_m")) else {
        bail!("{what}: the drive's stroke (control.limits.stroke_min_m, stroke_max_m) could not be read; nothing was sent");
    };
    let (lo, hi) = (f64::from(lo), f64::from(hi));
    if !(lo..=hi).contains(&target_m) {
        let hint = if from_m == 0.0 {
            millimetre_hint(target_m, lo, hi)
        } else {
            let d = (target_m - from_m) / 1000.0;
            if (lo..=hi).contains(&(from_m + d)) { format!(" (millimetres? distances are in metres: {d} m)") } else { String::new() }
        };
        bail!(
            "{what}: the target {} m is outside the stroke {lo} … {hi} m (control.limits.stroke_min_m, stroke_max_m){hint}; nothing was sent",
            if target_m.abs() < 1e6 { format!("{target_m:.6}") } else { format!("{target_m:.3e}") }
        );
    }
    Ok(())
}

/// `jog DISTANCE_M` on a homed, running drive: from where its reference
/// rests. Before homing the stroke is unknown and the drive limits the
/// jog's speed instead.
pub fn check_jog(c: &mut Client, distance_m: f64) -> Result<()> {
    let s = view::status(c)?;
    if s.readiness & 4 == 0 || s.mode != servo_core::Mode::Running {
        return Ok(());
    }
    let from = stream::reference_position(c)?;
    within_stroke_from(c, &format!("jog {distance_m}"), from, from + distance_m)
}
