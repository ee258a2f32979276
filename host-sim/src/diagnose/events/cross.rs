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

/// A cut keeps at least this far from every change point, s: an event's
/// step, its filter response (±10 ms smoothing) and the drive train's
/// ringing after it (the rod's ≈ 30 Hz mode, a few periods) stay whole in
/// one piece.
pub const CUT_GUARD_S: f64 = 0.1;
/// Pieces are at least this long, s: each holds an event with enough
/// quiet either side of it for its level (the disturbance's blocks are
/// 2 × 21 ms).
pub const MIN_PIECE_S: f64 = 0.8;
/// The split needs this many pieces holding change points on each side;
/// with fewer events the default split in time is used.
pub const MIN_EVENT_PIECES: usize = 2;

/// The segments cut between the change points found at `k` robust sigmas
/// (`change_points::detect_floor` with `floor`, on the nominal residual),
/// alternate pieces held out. `None` when the log carries too few events
/// to give each side `MIN_EVENT_PIECES` pieces with change points.
pub fn split_across_events(segs: &[Segment], k: f64, floor: [f64; 2]) -> Option<Vec<Segment>> {
    let refs: Vec<&Segment> = segs.iter().collect();
    let rem: Remainder = segs.iter().map(|s| std::array::from_fn(|c| s.r[c].clone())).collect();
    let cps = change_points::detect_floor(&refs, &rem, k, floor);
    let mut out = Vec::new();
    let mut with_events = [0usize; 2];
    let mut side = 0usize;
    for (s, cp) in segs.iter().zip(&cps) {
        let n = s.len();
        if n == 0 {
            continue;
        }
        let guard = (CUT_GUARD_S / s.dt).round() as usize;
        let min_len = (MIN_PIECE_S / s.dt).round() as usize;
        // Candidate cuts: midway between neighbouring change points (and
        // the segment's ends) that lie at least two guards apart.
        let mut bounds = vec![0usize];
        bounds.extend(cp.iter().copied());
        bounds.push(n);
        let cand: Vec<usize> = bounds
            .windows(2)
            .filter(|w| w[1] - w[0] >= 2 * guard)
            .map(|w| (w[0] + w[1]) / 2)
            .filter(|m| *m > 0 && *m < n)
            .collect();
        // Greedy from the start: a cut only where the piece before it and
        // what is left after it are both long enough.
        let mut cuts = vec![0usize];
        for m in cand {
            let last = *cuts.last().unwrap_or(&0);
            if m - last >= min_len && n - m >= min_len {
                cuts.push(m);
            }
        }
        cuts.push(n);
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            if cp.iter().any(|i| (a..b).contains(i)) {
                with_events[side] += 1;
            }
            out.push(slice_segment(s, a, b, side == 1));
            side = 1 - side;
        }
    }
    (with_events.iter().all(|e| *e >= MIN_EVENT_PIECES)).then_some(out)
}
