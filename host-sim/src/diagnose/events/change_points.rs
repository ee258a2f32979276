//! Change points: where the residual steps (a two-window
//! statistic in robust sigmas, over the torque and position channels) and
//! where the logged signals change (move starts and stops, the reference
//! acceleration's phases, the logged load). Kept apart from what is measured
//! around them (`locked`), so the detector can be tuned and tested alone.

use super::Remainder;
use crate::diagnose::residual::Segment;

/// Half window of the two-window step detector, s: long enough to average
/// the ±10 ms Savitzky–Golay smoothing and the floor's jitter, short
/// against the 0.1–1 s between a real rig's load events.
pub const STEP_WINDOW_S: f64 = 0.05;
/// A change point: the step statistic exceeds this many robust sigmas
/// (1.4826 · MAD of the statistic over the whole record, which the rare
/// steps do not move). Calibrated per log for the disturbance effect.
pub const STEP_SIGMA: f64 = 8.0;

/// Two-window step statistic `mean(x[i..i+w]) − mean(x[i−w..i])` of the
/// weighted signal (0 where a window would leave the record).
pub fn step_stat(x: &[f64], wt: &[f64], w: usize) -> Vec<f64> {
    let n = x.len();
    let mut out = vec![0.0; n];
    if n < 2 * w + 1 || w == 0 {
        return out;
    }
    let mut px = vec![0.0; n + 1];
    let mut pw = vec![0.0; n + 1];
    for i in 0..n {
        px[i + 1] = px[i] + wt[i] * x[i];
        pw[i + 1] = pw[i] + wt[i];
    }
    for (i, o) in out.iter_mut().enumerate().take(n - w + 1).skip(w) {
        let (wa, wb) = (pw[i + w] - pw[i], pw[i] - pw[i - w]);
        if wa > 0.2 * w as f64 && wb > 0.2 * w as f64 {
            *o = (px[i + w] - px[i]) / wa - (px[i] - px[i - w]) / wb;
        }
    }
    out
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1
}

/// 1.4826 · MAD (a Gaussian's sigma), over the non-zero values.
pub fn robust_sigma(v: &[f64]) -> f64 {
    let mut a: Vec<f64> = v.iter().copied().filter(|x| *x != 0.0).collect();
    let m = median(&mut a);
    let mut d: Vec<f64> = a.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&mut d)
}

/// Change points of a segment from several channels' step statistics
/// (each in robust sigmas; the largest counts), at least `w` apart.
pub fn change_points(stats: &[Vec<f64>], sigmas: &[f64], w: usize, k: f64) -> Vec<usize> {
    let n = stats.first().map_or(0, Vec::len);
    let z: Vec<f64> = (0..n)
        .map(|i| {
            stats
                .iter()
                .zip(sigmas)
                .filter(|(_, s)| **s > 0.0)
                .map(|(d, s)| d[i].abs() / s)
                .fold(0.0, f64::max)
        })
        .collect();
    let mut cand: Vec<usize> = (0..n).filter(|&i| z[i] >= k).collect();
    cand.sort_by(|a, b| z[*b].total_cmp(&z[*a]));
    let mut taken: Vec<usize> = Vec::new();
    for i in cand {
        if taken.iter().all(|t| t.abs_diff(i) > w) {
            taken.push(i);
        }
    }
    taken.sort_unstable();
    taken
}

/// Weights of channel `c` of a segment.
pub fn weights(s: &Segment, c: usize) -> Vec<f64> {
    (0..s.len()).map(|i| s.weight(c, i)).collect()
}

/// Residual change points per segment, from the torque and position
/// channels (the ones an unmeasured force acts on), sigma per channel over
/// all segments.
pub fn detect(segs: &[&Segment], rem: &Remainder, k: f64) -> Vec<Vec<usize>> {
    detect_floor(segs, rem, k, [0.0; 2])
}

/// `detect` on the remainder weighted by `max(weight, floor[c])` (torque,
/// position).
pub fn detect_floor(
    segs: &[&Segment],
    rem: &Remainder,
    k: f64,
    floor: [f64; 2],
) -> Vec<Vec<usize>> {
    let (stats, sig) = step_stats(segs, rem, floor);
    segs.iter()
        .zip(&stats)
        .map(|(s, st)| {
            change_points(
                st,
                &sig,
                ((STEP_WINDOW_S / s.dt).round() as usize).max(3),
                k,
            )
        })
        .collect()
}

/// The step statistic in robust sigmas per sample (the largest over the
/// torque and position channels), per segment.
pub fn step_z(segs: &[&Segment], rem: &Remainder, floor: [f64; 2]) -> Vec<Vec<f64>> {
    let (stats, sig) = step_stats(segs, rem, floor);
    stats
        .iter()
        .map(|st| {
            let n = st.first().map_or(0, Vec::len);
            (0..n)
                .map(|i| {
                    st.iter()
                        .zip(&sig)
                        .filter(|(_, s)| **s > 0.0)
                        .map(|(d, s)| d[i].abs() / s)
                        .fold(0.0, f64::max)
                })
                .collect()
        })
        .collect()
}

/// Step statistics per segment and channel, and each channel's robust
/// sigma over all segments.
#[allow(clippy::type_complexity)]
fn step_stats(segs: &[&Segment], rem: &Remainder, floor: [f64; 2]) -> (Vec<Vec<Vec<f64>>>, Vec<f64>) {
    let chans: Vec<usize> = (0..2)
        .filter(|c| rem.iter().any(|r| r[*c].is_some()))
        .collect();
    let stats: Vec<Vec<Vec<f64>>> = segs
        .iter()
        .zip(rem)
        .map(|(s, r)| {
            let w = ((STEP_WINDOW_S / s.dt).round() as usize).max(3);
            chans
                .iter()
                .map(|&c| {
                    let wt: Vec<f64> = weights(s, c).into_iter().map(|v| v.max(floor[c])).collect();
                    r[c].as_ref()
                        .map_or(vec![0.0; s.len()], |x| step_stat(x, &wt, w))
                })
                .collect()
        })
        .collect();
    let sig: Vec<f64> = chans
        .iter()
        .enumerate()
        .map(|(j, _)| {
            robust_sigma(
                &stats
                    .iter()
                    .flat_map(|st| st[j].iter().copied())
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    (stats, sig)
}

/// Events in the logged signals: move starts and stops, and change points
/// of the reference acceleration (the jerk-limited phases) and of the
/// logged load.
pub fn signal_events(segs: &[&Segment]) -> Vec<Vec<usize>> {
    let mot = motion_events(segs);
    segs.iter()
        .zip(mot)
        .map(|(s, mut ev)| {
            let w = ((STEP_WINDOW_S / s.dt).round() as usize).max(3);
            let ones = vec![1.0; s.len()];
            for sig in [&s.a_ref, &s.f_load] {
                let st = step_stat(sig, &ones, w);
                let sd = robust_sigma(&st);
                if sd > 0.0 {
                    ev.extend(change_points(&[st], &[sd], w, STEP_SIGMA));
                }
            }
            ev.sort_unstable();
            ev.dedup();
            ev
        })
        .collect()
}

/// Move starts and stops: the reference speed crossing 5 % of its peak.
pub fn motion_events(segs: &[&Segment]) -> Vec<Vec<usize>> {
    let vmax = segs
        .iter()
        .flat_map(|s| s.v_ref.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    segs.iter()
        .map(|s| {
            let th = 0.05 * vmax;
            (1..s.len())
                .filter(|&i| (s.v_ref[i].abs() > th) != (s.v_ref[i - 1].abs() > th))
                .collect()
        })
        .collect()
}

/// Events (segment, sample) nearest to the given times of one log's
/// segments; times outside every segment are dropped.
pub fn events_at(segs: &[&Segment], times: &[f64]) -> Vec<Vec<usize>> {
    segs.iter()
        .map(|s| {
            times
                .iter()
                .filter(|t| {
                    s.t.first().is_some_and(|t0| **t >= *t0)
                        && s.t.last().is_some_and(|t1| **t <= *t1)
                })
                .map(|t| s.t.partition_point(|x| x < t).min(s.len() - 1))
                .collect()
        })
        .collect()
}
