//! The edges of a piecewise-constant disturbance fitted together, as the
//! onsets and offsets of events, at the sample rate.
//!
//! The detector's change points are candidates. Around a move's start
//! the residual carries a transient (the seal's stick, the loop's
//! response), and the detector, whose windows are ± 50 ms, picks it
//! beside a force's edge; held at the detector's separation from such a
//! pick, a real edge cannot reach its place. So the edges are fitted
//! jointly: each is re-placed by least squares between its neighbours
//! (`edges::two_levels`), with only the smoothing window kept between
//! two edges (closer, the smoothed channel cannot tell them apart); then
//! a candidate whose step, measured between the fitted levels either
//! side of it, falls below the detector's threshold is dropped (its two
//! intervals merge), the weakest first, and its neighbours are placed
//! again. An edge kept is a step the levels either side confirm, not a
//! peak of a windowed statistic.
//!
//! An edge is placed on the channel that sees the force first: the torque
//! channel, whose residual is the force itself at once, unfaded by the
//! standstill weights (those weigh the level's uncertainty under the
//! friction the nut and seal hold, which over the ± 100 ms around an edge
//! is one constant offset and moves no edge); the position channel,
//! which follows only as the drive train winds up over a quarter of the
//! axial mode's period, only where the torque channel shows no step.
//!
//! Each edge carries its uncertainty from the profile of the fit's
//! residual over the edge's position: the positions within one noise
//! variance (the residual's, the larger of the whole context's and the
//! edge's own neighbourhood's, scaled by its correlation length, measured
//! as the variance of block means) of the least.

use super::edges::{cost, seen, step_response, two_levels, CONTEXT_S, SEARCH_S};
use crate::diagnose::events::{robust_sigma, step_stat, weights, STEP_WINDOW_S};
use crate::diagnose::residual::{Segment, NCH, TORQUE};

/// Sweeps of joint re-placement: each moves an edge only within its
/// search window, so a few settle a neighbourhood.
const SWEEPS: usize = 3;

/// One fitted edge: its sample, its 1-sigma uncertainty (s), and the
/// channel it was placed on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    pub i: usize,
    pub sd_s: f64,
    pub channel: usize,
}

/// A channel as the fit sees it: residual, weights, the step statistic's
/// robust sigma with those weights, and the step's shape.
struct Chan<'a> {
    c: usize,
    x: &'a [f64],
    wt: Vec<f64>,
    sd: f64,
    stat: Vec<f64>,
    h: Vec<f64>,
}

/// Fits the edges of one segment from the detector's candidates `cps`
/// (`k`: the detector's threshold, robust sigmas; `floor`: its weight
/// floor per channel; `smoothed(c)`: whether channel `c` is smoothed).
pub fn fit_edges(
    s: &Segment,
    r: &[Option<Vec<f64>>; NCH],
    cps: &[usize],
    k: f64,
    floor: [f64; 2],
    smoothed: impl Fn(usize) -> bool,
) -> Vec<Edge> {
    let n = s.len();
    let steps = |x: f64| ((x / s.dt).round() as usize).max(1);
    let (search, context) = (steps(SEARCH_S), steps(CONTEXT_S));
    let w = steps(STEP_WINDOW_S).max(3);
    let min_gap = 2 * s.sg_m + 1;
    let chan = |c: usize, wt: Vec<f64>| -> Option<Chan> {
        let x = r[c].as_ref()?;
        let stat = step_stat(x, &wt, w);
        let sd = robust_sigma(&stat);
        let h = if smoothed(c) { step_response(s.sg_m) } else { Vec::new() };
        (sd > 0.0).then_some(Chan { c, x, wt, sd, stat, h })
    };
    // Judged as the detector judges (its weights); placed on the torque
    // channel unfaded where it shows the step.
    let judged: Vec<Chan> = (0..2)
        .filter_map(|c| chan(c, weights(s, c).into_iter().map(|v| v.max(floor[c])).collect()))
        .collect();
    let torque_place = chan(TORQUE, vec![1.0; n]);
    let place_on = |cp: usize| -> Option<&Chan> {
        let z = |ch: &Chan| ch.stat[cp].abs() / ch.sd;
        match &torque_place {
            Some(t) if z(t) >= k || judged.iter().any(|j| j.c == TORQUE && z(j) >= k) => Some(t),
            _ => judged.iter().max_by(|a, b| z(a).total_cmp(&z(b))),
        }
    };
    let mut e: Vec<usize> = cps.iter().copied().filter(|i| *i > 0 && *i < n).collect();
    // The level context either side of edge j: up to the neighbours,
    // past their own step's smoothing.
    let span = |e: &[usize], j: usize, ch: &Chan| -> (usize, usize) {
        let m = if ch.h.is_empty() { 0 } else { s.sg_m };
        let prev = if j == 0 { 0 } else { e[j - 1] + m };
        let next = e.get(j + 1).map_or(n, |v| v.saturating_sub(m));
        (prev.max(e[j].saturating_sub(context)), next.min(e[j] + context).min(n))
    };
    let place = |e: &mut Vec<usize>, from: usize, to: usize| {
        for _ in 0..SWEEPS {
            let mut moved = false;
            for j in from..to.min(e.len()) {
                let cp = e[j];
                let Some(ch) = place_on(cp) else { continue };
                let (lo, hi) = span(e, j, ch);
                let prev = if j == 0 { 0 } else { e[j - 1] + min_gap };
                let next = e.get(j + 1).map_or(n, |v| v.saturating_sub(min_gap));
                let a = cp.saturating_sub(search).max(prev).max(lo + s.sg_m + 2);
                let b = (cp + search).min(next).min(hi.saturating_sub(s.sg_m + 2));
                if a >= b {
                    continue;
                }
                let c = |i: usize| cost(ch.x, &ch.wt, &ch.h, lo, hi, i);
                if let Some(best) = (a..=b).min_by(|i, j| c(*i).total_cmp(&c(*j))) {
                    moved |= best != cp;
                    e[j] = best;
                }
            }
            if !moved {
                break;
            }
        }
    };
    // The step at edge j in robust sigmas of the detector's statistic (a
    // step of height d reads d there), the largest over the channels.
    let step_z = |e: &[usize], j: usize| -> f64 {
        judged
            .iter()
            .filter_map(|ch| {
                let (lo, hi) = span(e, j, ch);
                two_levels(ch.x, &ch.wt, &ch.h, lo, hi, e[j]).map(|f| (f.2 - f.1).abs() / ch.sd)
            })
            .fold(0.0, f64::max)
    };
    let all = e.len();
    place(&mut e, 0, all);
    while let Some((j, z)) = (0..e.len()).map(|j| (j, step_z(&e, j))).min_by(|a, b| a.1.total_cmp(&b.1)) {
        if z >= k {
            break;
        }
        // Its neighbours, now bounded by the next ones out, settle again.
        e.remove(j);
        place(&mut e, j.saturating_sub(1), j + 1);
    }
    (0..e.len())
        .map(|j| {
            let ch = place_on(e[j]);
            Edge {
                i: e[j],
                sd_s: ch.map_or(f64::NAN, |ch| edge_sd(ch, &e, j, span(&e, j, ch), s.sg_m) * s.dt),
                channel: ch.map_or(TORQUE, |ch| ch.c),
            }
        })
        .collect()
}

/// 1-sigma half-width (samples) of the edge positions whose fit leaves
/// within one noise variance of the least residual: the residual's
/// variance per weight times its correlation length (block means' variance
/// over the samples', blocks of the smoothing window).
fn edge_sd(ch: &Chan, e: &[usize], j: usize, (lo, hi): (usize, usize), m: usize) -> f64 {
    let at = e[j];
    let Some((best, la, lb)) = two_levels(ch.x, &ch.wt, &ch.h, lo, hi, at) else {
        return f64::NAN;
    };
    let res: Vec<(f64, f64)> = (lo..hi)
        .map(|i| {
            let s = seen(&ch.h, at, i);
            (ch.wt[i] * (ch.x[i] - la * (1.0 - s) - lb * s), ch.wt[i] * ch.wt[i])
        })
        .collect();
    let sw: f64 = res.iter().map(|r| r.1).sum();
    if sw <= 0.0 {
        return f64::NAN;
    }
    let block = 2 * m + 1;
    // Where the edge is decided, the residual is the step's shape
    // mismatch (the loop's and the sensor's own response), not the floor:
    // the variance is the larger of the context's and that of the
    // smoothing window either side of the edge.
    let near = at.saturating_sub(block).max(lo) - lo..(at + block).min(hi) - lo;
    let (ne, nw) = res[near].iter().fold((0.0, 0.0), |(e, w), r| (e + r.0 * r.0, w + r.1));
    let var = if nw > 0.0 { (best / sw).max(ne / nw) } else { best / sw };
    let means: Vec<f64> = res.chunks(block).filter(|b| b.len() == block).map(|b| b.iter().map(|r| r.0).sum::<f64>() / block as f64).collect();
    let corr = if means.len() >= 2 && var > 0.0 {
        let mu = means.iter().sum::<f64>() / means.len() as f64;
        let vb = means.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / (means.len() - 1) as f64;
        (block as f64 * vb / var).clamp(1.0, block as f64)
    } else {
        block as f64
    };
    let tol = var * corr;
    let c = |i: usize| cost(ch.x, &ch.wt, &ch.h, lo, hi, i);
    let inside = |i: usize| c(i) - best <= tol;
    let first = (lo + 1..=at).rev().take_while(|i| inside(*i)).last().unwrap_or(at);
    let last = (at..hi).take_while(|i| inside(*i)).last().unwrap_or(at);
    // A single sample's width: uniform within it.
    (0.5 * (last - first) as f64).max(1.0 / 12f64.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use super::super::edges::tests::noise;
    use crate::diagnose::residual::sg_smooth;

    /// A 120 ms pulse on the smoothed torque channel, its onset 25 ms
    /// after a move-start transient (a 15 ms blip) that the detector also
    /// picked, and its edges detected 12 samples off: the joint fit puts
    /// both edges within a sample and its stated 1-sigma, which a clamp at
    /// the detector's separation from the transient's pick cannot (the
    /// onset would be held 51 samples from it, 26 late).
    #[test]
    fn an_edge_beside_a_transient_pick_is_placed_at_its_step() {
        let (n, m, dt) = (1200, 10, 1e-3);
        let (on, off, blip) = (500, 620, 475);
        let mut noise = noise(0x9e37_79b9_7f4a_7c15, 0.4);
        let raw: Vec<f64> = (0..n)
            .map(|i| {
                let pulse = if (on..off).contains(&i) { 5.0 } else { 0.0 };
                let tr = if (blip..blip + 15).contains(&i) { 3.0 } else { 0.0 };
                pulse + tr + noise()
            })
            .collect();
        let x = sg_smooth(&raw, m);
        let s = Segment { t: (0..n).map(|i| i as f64 * dt).collect(), dt, sg_m: m, motion_weight: vec![1.0; n], ..Default::default() };
        let r: [Option<Vec<f64>>; NCH] = std::array::from_fn(|c| (c == TORQUE).then(|| x.clone()));
        let cands = [blip, on + 12, off - 12];
        let e = fit_edges(&s, &r, &cands, 8.0, [0.0, 0.5], |c| c == TORQUE);
        for truth in [on, off] {
            let f = e.iter().min_by_key(|f| f.i.abs_diff(truth)).unwrap();
            assert!(f.i.abs_diff(truth) <= 1, "edge {} vs {truth}: {e:?}", f.i);
            assert!(f.i.abs_diff(truth) as f64 * dt <= 2.0 * f.sd_s + dt, "{f:?} vs {truth}");
            assert_eq!(f.channel, TORQUE);
        }
    }

    /// A candidate on a flat stretch (no step either side) is dropped and
    /// the real step kept.
    #[test]
    fn a_candidate_without_a_step_is_merged_away() {
        let (n, m, dt) = (1000, 10, 1e-3);
        let mut noise = noise(0x2545_f491_4f6c_dd1d, 0.4);
        let raw: Vec<f64> = (0..n).map(|i| if i >= 600 { 4.0 } else { 0.0 } + noise()).collect();
        let x = sg_smooth(&raw, m);
        let s = Segment { t: (0..n).map(|i| i as f64 * dt).collect(), dt, sg_m: m, motion_weight: vec![1.0; n], ..Default::default() };
        let r: [Option<Vec<f64>>; NCH] = std::array::from_fn(|c| (c == TORQUE).then(|| x.clone()));
        let e = fit_edges(&s, &r, &[300, 603], 8.0, [0.0, 0.5], |c| c == TORQUE);
        assert_eq!(e.iter().map(|f| f.i).collect::<Vec<_>>(), vec![600], "{e:?}");
    }
}
