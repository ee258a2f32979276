//! Training and held-out parts cut across the events of one log: when the
//! training log is the reference the nominal was fitted on, the held-out
//! log is all the diagnosis has, and a split in time leaves the held-out
//! part only the events of its last seconds (two or three force pulses,
//! a long step's one edge). Cut instead between events, and give alternate
//! pieces to training and scoring: the disturbance's choices (threshold,
//! channels, level model) and every fit are made on half the events and
//! scored on the other half, spread over the whole log.
//!
//! Only the change points' positions choose the cuts (as the disturbance
//! locates its change points on the scored part itself); no level is
//! read, so nothing of what is scored is fitted.

use super::{change_points, Remainder};
use crate::diagnose::residual::Segment;
use crate::diagnose::split::slice_segment;

/// A cut sits where the step statistic stays lowest over ± this, s: an
/// event's step, its filter response (±10 ms smoothing) and the drive
/// train's ringing after it (the rod's ≈ 30 Hz mode, a few periods) stay
/// whole in one piece.
pub const CUT_GUARD_S: f64 = 0.1;
/// Pieces are about this long, s (each cut searched within
/// ± `CUT_SEARCH_S` of it): long against an event and its quiet either
/// side (the disturbance's level blocks are 2 × 21 ms), short enough that
/// a log of a few seconds gives each side several pieces.
pub const PIECE_S: f64 = 1.0;
pub const CUT_SEARCH_S: f64 = 0.4;
/// The split needs this many pieces holding a change point on each side;
/// with fewer events the default split in time is used.
pub const MIN_EVENT_PIECES: usize = 1;

/// The segments cut at the quietest points of the residual's step
/// statistic about every `PIECE_S` (`change_points::step_z` with `floor`,
/// on the nominal residual), alternate pieces held out. `None` when the
/// log carries too few events (step statistic ≥ `k` robust sigmas) to give
/// each side `MIN_EVENT_PIECES` pieces with one.
pub fn split_across_events(segs: &[Segment], k: f64, floor: [f64; 2]) -> Option<Vec<Segment>> {
    let refs: Vec<&Segment> = segs.iter().collect();
    let rem: Remainder = segs.iter().map(|s| std::array::from_fn(|c| s.r[c].clone())).collect();
    let z = change_points::step_z(&refs, &rem, floor);
    let mut out = Vec::new();
    let mut with_events = [0usize; 2];
    let mut side = 0usize;
    for (s, z) in segs.iter().zip(&z) {
        let n = s.len();
        if n == 0 {
            continue;
        }
        let steps = |x: f64| (x / s.dt).round() as usize;
        let (guard, piece, search) = (steps(CUT_GUARD_S), steps(PIECE_S), steps(CUT_SEARCH_S));
        // The largest statistic within the guard of each sample.
        let near = |j: usize| z[j.saturating_sub(guard)..(j + guard + 1).min(n)].iter().fold(0.0f64, |m, x| m.max(*x));
        let mut cuts = vec![0usize];
        loop {
            let a = *cuts.last().unwrap_or(&0);
            let (lo, hi) = (a + piece - search, (a + piece + search).min(n.saturating_sub(piece - search)));
            if lo >= hi {
                break;
            }
            let j = (lo..hi).min_by(|x, y| near(*x).total_cmp(&near(*y))).unwrap_or(lo);
            cuts.push(j);
        }
        cuts.push(n);
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            if z[a..b].iter().any(|x| *x >= k) {
                with_events[side] += 1;
            }
            out.push(slice_segment(s, a, b, side == 1));
            side = 1 - side;
        }
    }
    (with_events.iter().all(|e| *e >= MIN_EVENT_PIECES)).then_some(out)
}
