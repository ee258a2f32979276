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
//! Each edge carries its uncertainty from the residual as it is, not
//! from a noise model: the fit is repeated with the fit's own residual
//! shifted through the context (`edge_sd`). The residual beside an edge
//! is coloured — the smoothing, the loop's response, a move's transient
//! — and a white-noise profile of the cost, which the edge's step makes
//! steep, states a fraction of a sample where the edge may sit tens of
//! milliseconds off beside such a transient.

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
    // The range an edge is placed within between its neighbours, a search window about it.
    let range = |e: &[usize], j: usize, (lo, hi): (usize, usize)| -> (usize, usize) {
        let prev = if j == 0 { 0 } else { e[j - 1] + min_gap };
        let next = e.get(j + 1).map_or(n, |v| v.saturating_sub(min_gap));
        (e[j].saturating_sub(search).max(prev).max(lo + s.sg_m + 2), (e[j] + search).min(next).min(hi.saturating_sub(s.sg_m + 2)))
    };
    let place = |e: &mut Vec<usize>, from: usize, to: usize| {
        for _ in 0..SWEEPS {
            let mut moved = false;
            for j in from..to.min(e.len()) {
                let cp = e[j];
                let Some(ch) = place_on(cp) else { continue };
                let (lo, hi) = span(e, j, ch);
                let (a, b) = range(e, j, (lo, hi));
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
                sd_s: ch.map_or(f64::NAN, |ch| {
                    let sp = span(&e, j, ch);
                    edge_sd(ch, &e, j, sp, range(&e, j, sp)) * s.dt
                }),
                channel: ch.map_or(TORQUE, |ch| ch.c),
            }
        })
        .collect()
}

/// Residual shifts the edge is re-fitted under: enough for a spread to
/// within about 15 % (1/√(2K)) at a few hundred multiply-adds per
/// position and shift.
const SHIFTS: usize = 24;

/// 1-sigma uncertainty (samples) of edge `j`, from the residual itself:
/// the fitted two levels plus the fit's own residual, circularly shifted
/// through the context (which keeps its colour — the smoothing's, the
/// loop's, a move's transient — and its size, where a white-noise
/// profile would see neither), re-fitted over the edge's own search
/// range; the root-mean-square distance of those re-fits from the edge,
/// with the sample's own resolution in quadrature.
fn edge_sd(ch: &Chan, e: &[usize], j: usize, (lo, hi): (usize, usize), (a, b): (usize, usize)) -> f64 {
    let at = e[j];
    let Some((_, la, lb)) = two_levels(ch.x, &ch.wt, &ch.h, lo, hi, at) else {
        return f64::NAN;
    };
    let l = hi - lo;
    let model: Vec<f64> = (lo..hi).map(|i| {
        let s = seen(&ch.h, at, i);
        la * (1.0 - s) + lb * s
    }).collect();
    let res: Vec<f64> = (lo..hi).map(|i| ch.x[i] - model[i - lo]).collect();
    let wt = &ch.wt[lo..hi];
    let (a, b) = (a.max(lo + 1) - lo, b.min(hi - 1).max(a.max(lo + 1)) - lo);
    let mut y = vec![0.0; l];
    let mut ss = 0.0;
    for q in 1..=SHIFTS {
        let k = q * l / (SHIFTS + 1);
        for i in 0..l {
            y[i] = model[i] + res[(i + k) % l];
        }
        let c = |i: usize| cost(&y, wt, &ch.h, 0, l, i);
        let best = (a..=b).min_by(|i, j| c(*i).total_cmp(&c(*j))).unwrap_or(at - lo);
        ss += (best as f64 - (at - lo) as f64).powi(2);
    }
    // Which sample first shows a step depends on where within the
    // sampling period the force changed and on when each logged signal
    // feeding the channel was sampled in it: ± one sample, uniform.
    let resolution = 1.0 / 3f64.sqrt();
    (ss / SHIFTS as f64 + resolution * resolution).sqrt()
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

    /// A step in coloured noise (uniform noise averaged over 25 samples,
    /// then smoothed as the torque channel is), its edge detected 7
    /// samples late, over 60 noise draws: the fitted edge lies within
    /// twice its stated sigma in at least 85 % of draws, as an honest
    /// sigma's 95 % allows over 60 draws (57 of 60 here). The sample's
    /// resolution alone, the noise unseen, covers 45.
    #[test]
    fn the_stated_sigma_covers_the_edge_in_coloured_noise() {
        let (n, m, dt, edge) = (800, 10, 1e-3, 400);
        let mut hits = 0;
        let draws = 60;
        for d in 0..draws {
            let mut white = noise(0x9e37_79b9_7f4a_7c15 ^ (d as u64 + 1).wrapping_mul(0x2545_f491_4f6c_dd1d), 3.0);
            let w: Vec<f64> = (0..n + 25).map(|_| white()).collect();
            let raw: Vec<f64> = (0..n).map(|i| if i >= edge { 1.0 } else { 0.0 } + w[i..i + 25].iter().sum::<f64>() / 25.0).collect();
            let x = sg_smooth(&raw, m);
            let s = Segment { t: (0..n).map(|i| i as f64 * dt).collect(), dt, sg_m: m, motion_weight: vec![1.0; n], ..Default::default() };
            let r: [Option<Vec<f64>>; NCH] = std::array::from_fn(|c| (c == TORQUE).then(|| x.clone()));
            let e = fit_edges(&s, &r, &[edge + 7], 0.0, [0.0, 0.5], |c| c == TORQUE);
            let f = e[0];
            hits += usize::from(f.i.abs_diff(edge) as f64 * dt <= 2.0 * f.sd_s);
        }
        assert!(hits * 100 >= 85 * draws, "{hits}/{draws} within 2 sigma");
    }
}
