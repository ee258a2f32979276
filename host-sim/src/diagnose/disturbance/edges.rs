//! Event edges at the sample rate: the shape a step takes on a channel
//! and the least-squares fit of one edge between two levels. The step
//! detector finds a change point as the peak of a two-window statistic
//! over ± 50 ms windows: robust against the floor, but its peak is flat
//! over a few samples and moves when the standstill fade or a
//! neighbouring edge weighs one window less than the other. An event's
//! onset and offset are what a user lines up with their rig's own
//! records, so each edge is placed by least squares on the residual
//! around it (`event_fit`): one level either side, the step shaped as the
//! channel shows one — the Savitzky–Golay step response where the
//! residual is smoothed (the torque channel), a sharp step where it is
//! raw — and the edge put at the sample that leaves the least weighted
//! residual.

use crate::diagnose::events::STEP_WINDOW_S;
use crate::diagnose::residual::sg_smooth;

/// Each edge is searched within ± this of the detected change point, s:
/// the detector's half window, inside which its peak can sit.
pub const SEARCH_S: f64 = STEP_WINDOW_S;
/// Each side's level is read from up to this much of the residual, s (or
/// up to the neighbouring change point, whichever is nearer).
pub const CONTEXT_S: f64 = 2.0 * STEP_WINDOW_S;

/// Response of the ±m Savitzky–Golay smoothing to a unit step whose first
/// sample is the edge, by distance `d` from it: `h[d + m]` for
/// `d ∈ [−m, m]` (0 before, 1 after).
pub(super) fn step_response(m: usize) -> Vec<f64> {
    let n = 4 * m + 2;
    let unit: Vec<f64> = (0..n).map(|i| if i >= 2 * m + 1 { 1.0 } else { 0.0 }).collect();
    let sm = sg_smooth(&unit, m);
    (m + 1..=3 * m + 1).map(|i| sm[i]).collect()
}

/// The share of a step at `edge` seen at sample `i` (`h`: `step_response`).
pub(super) fn seen(h: &[f64], edge: usize, i: usize) -> f64 {
    let m = h.len() / 2;
    if h.is_empty() {
        return if i >= edge { 1.0 } else { 0.0 };
    }
    let d = i as isize - edge as isize;
    if d < -(m as isize) {
        0.0
    } else if d > m as isize {
        1.0
    } else {
        h[(d + m as isize) as usize]
    }
}

/// Weighted residual of two levels either side of `edge` on `x[lo..hi]`.
pub(super) fn cost(x: &[f64], wt: &[f64], h: &[f64], lo: usize, hi: usize, edge: usize) -> f64 {
    two_levels(x, wt, h, lo, hi, edge).map_or(f64::INFINITY, |f| f.0)
}

/// The least-squares fit of two levels either side of `edge` on
/// `x[lo..hi]`: (weighted residual, level before, level after), `None`
/// where one side holds no weight.
pub(super) fn two_levels(x: &[f64], wt: &[f64], h: &[f64], lo: usize, hi: usize, edge: usize) -> Option<(f64, f64, f64)> {
    // Normal equations of x ≈ a (1 − s) + b s, s the step's share.
    let (mut uu, mut uv, mut vv, mut ux, mut vx, mut xx) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in lo..hi {
        let w2 = wt[i] * wt[i];
        let s = seen(h, edge, i);
        let (u, v) = (1.0 - s, s);
        uu += w2 * u * u;
        uv += w2 * u * v;
        vv += w2 * v * v;
        ux += w2 * u * x[i];
        vx += w2 * v * x[i];
        xx += w2 * x[i] * x[i];
    }
    let det = uu * vv - uv * uv;
    if det <= 1e-12 * (uu * vv).max(1e-300) {
        return None;
    }
    let a = (ux * vv - vx * uv) / det;
    let b = (vx * uu - ux * uv) / det;
    Some(((xx - a * ux - b * vx).max(0.0), a, b))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Uniform noise of peak-to-peak `amp` from a fixed xorshift seed, so
    /// the tests are deterministic.
    pub(in crate::diagnose::disturbance) fn noise(seed: u64, amp: f64) -> impl FnMut() -> f64 {
        let mut st = seed;
        move || {
            st ^= st << 13;
            st ^= st >> 7;
            st ^= st << 17;
            (st as f64 / u64::MAX as f64 - 0.5) * amp
        }
    }

    /// The step response rises from 0 to 1 symmetrically about the half
    /// sample before the edge, as a symmetric filter's must, and is 1 from
    /// `m` samples on.
    #[test]
    fn step_response_is_symmetric_about_the_edge() {
        let m = 10;
        let h = step_response(m);
        assert_eq!(h.len(), 2 * m + 1);
        for d in 0..m {
            assert!((h[m + d] + h[m - 1 - d] - 1.0).abs() < 1e-12, "d {d}: {} {}", h[m + d], h[m - 1 - d]);
        }
        assert!((h[2 * m] - 1.0).abs() < 1e-12);
    }

    /// A smoothed step in noise, its edge detected a few samples off (as
    /// a flat statistic peak leaves it), is put back within a sample.
    #[test]
    fn a_smoothed_step_is_placed_at_its_edge() {
        let m = 10;
        let n = 600;
        let edge = 317;
        let mut noise = noise(0x2545_f491_4f6c_dd1d, 0.2);
        let raw: Vec<f64> = (0..n).map(|i| if i >= edge { 1.0 } else { 0.0 } + noise()).collect();
        let x = sg_smooth(&raw, m);
        let wt = vec![1.0; n];
        let h = step_response(m);
        let best = (280..=350).min_by(|i, j| cost(&x, &wt, &h, 220, 420, *i).total_cmp(&cost(&x, &wt, &h, 220, 420, *j))).unwrap();
        assert!(best.abs_diff(edge) <= 1, "{best} vs {edge}");
    }
}
