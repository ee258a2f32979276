//! Drift or level shift: whether the remainder's slow part
//! is one step (an event) or a trend (a drift). Both carry most of their
//! energy slower than `SLOW_S`; only the shape tells them apart.

use super::{Remainder, SLOW_S, STEP_OVER_TREND};
use crate::diagnose::residual::Segment;

/// Does one level shift explain the slow part of the remainder better than
/// a trend? On the `SLOW_S` moving average of the weighted remainder, per
/// segment: the residual sum of squares of the best single step (two levels)
/// against that of a straight line; a step when it leaves at most
/// `STEP_OVER_TREND` of the line's. Returns (is a step, its time s, ratio).
pub fn step_or_trend(segs: &[&Segment], rem: &Remainder, c: usize) -> (bool, f64, f64) {
    let (mut sse_step, mut sse_line, mut t_step, mut best_gain) = (0.0, 0.0, f64::NAN, 0.0);
    for (s, r) in segs.iter().zip(rem) {
        let Some(x) = &r[c] else { continue };
        let n = s.len();
        if n < 10 {
            continue;
        }
        let half = ((0.5 * SLOW_S / s.dt) as usize).max(1);
        let mut pre = vec![0.0; n + 1];
        for (i, xi) in x.iter().enumerate() {
            pre[i + 1] = pre[i] + s.weight(c, i) * xi;
        }
        let y: Vec<f64> = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
                (pre[b] - pre[a]) / (b - a) as f64
            })
            .collect();
        // Straight line.
        let t: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let (mt, my) = (
            t.iter().sum::<f64>() / n as f64,
            y.iter().sum::<f64>() / n as f64,
        );
        let stt: f64 = t.iter().map(|v| (v - mt).powi(2)).sum();
        let sty: f64 = t.iter().zip(&y).map(|(a, b)| (a - mt) * (b - my)).sum();
        let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
        sse_line += syy - if stt > 0.0 { sty * sty / stt } else { 0.0 };
        // Best single step: maximise the between-level sum of squares.
        let mut cy = 0.0;
        let (mut gain, mut at) = (0.0, 0);
        for k in 1..n {
            cy += y[k - 1] - my;
            let g = cy * cy * n as f64 / (k as f64 * (n - k) as f64);
            if g > gain {
                gain = g;
                at = k;
            }
        }
        sse_step += syy - gain;
        if gain > best_gain {
            best_gain = gain;
            t_step = s.t[at];
        }
    }
    let ratio = if sse_line > 0.0 {
        sse_step / sse_line
    } else {
        1.0
    };
    (ratio <= STEP_OVER_TREND, t_step, ratio)
}
