//! Whether the disturbance's levels follow the motion. Change points that
//! sit at logged events (move starts, acceleration changes) are either a
//! model error of the nominal — whose size is then a function of the
//! motion: an inertia error scales with the acceleration, a friction
//! error with the direction and speed, a load error with the load — or an
//! unmeasured force that merely comes with the motion (a tool engaging at
//! each move's start), whose level does not care which way or how hard
//! the axis moves. The levels of the intervals between change points are
//! regressed on the motion over each interval, leave-one-out
//! cross-validated: a share under `FOLLOWS_MIN_PCT` says the steps keep
//! their timing but not the motion's size or sign.

use super::Interval;
use crate::diagnose::residual::{Segment, TORQUE};

/// Cross-validated share of the levels' variance the motion must explain
/// for change points at logged events to count as model error, %.
pub const FOLLOWS_MIN_PCT: f64 = 50.0;
/// Intervals needed before the test says anything: over twice the
/// regressors, so a leave-one-out fit still has ten degrees of freedom.
const MIN_INTERVALS: usize = 16;
const P: usize = 7;

/// The motion over one interval: `[1, moving, moving·dir, a, v, F_load,
/// x]` (means; `moving` the standstill weight): what an inertia, friction
/// (either direction), viscous, load or stroke-position (a worn or
/// spalled stretch of the screw) error of the nominal scales with.
fn row(s: &Segment, a: usize, e: usize) -> [f64; P] {
    let n = (e - a).max(1) as f64;
    // A segment may lack a signal (a synthetic one, or no scale): zeros.
    let at = |v: &Vec<f64>, i: usize| v.get(i).copied().unwrap_or(0.0);
    let mean = |f: &dyn Fn(usize) -> f64| (a..e).map(f).sum::<f64>() / n;
    let mv = |i: usize| s.weight(TORQUE, i);
    [
        1.0,
        mean(&mv),
        mean(&|i| mv(i) * at(&s.dir, i)),
        mean(&|i| at(&s.a, i)),
        mean(&|i| at(&s.v, i)),
        mean(&|i| at(&s.f_load, i)),
        mean(&|i| at(&s.x, i)),
    ]
}

/// Leave-one-out cross-validated share (%) of the duration-weighted
/// variance of the interval levels that the motion explains; `None` with
/// too few intervals to tell.
pub fn levels_follow_motion(held: &[&Segment], intervals: &[Interval]) -> Option<f64> {
    let mut xs = Vec::new();
    for iv in intervals {
        let Some(s) = held.iter().find(|s| {
            s.run == iv.run && s.t.first().is_some_and(|t0| *t0 <= iv.start_s + 1e-9) && s.t.last().is_some_and(|t1| *t1 + s.dt >= iv.end_s - 1e-9)
        }) else {
            continue;
        };
        let a = s.t.partition_point(|t| *t < iv.start_s - 0.5 * s.dt);
        let e = s.t.partition_point(|t| *t < iv.end_s - 0.5 * s.dt).max(a + 1).min(s.len());
        if e <= a {
            continue;
        }
        xs.push((row(s, a, e), iv.level, (e - a) as f64 * s.dt));
    }
    if xs.len() < MIN_INTERVALS {
        return None;
    }
    let mut ata = nalgebra::SMatrix::<f64, P, P>::zeros();
    let mut atb = nalgebra::SVector::<f64, P>::zeros();
    for (x, y, w) in &xs {
        let xv = nalgebra::SVector::<f64, P>::from_row_slice(x);
        ata += *w * xv * xv.transpose();
        atb += *w * *y * xv;
    }
    let inv = ata.try_inverse().or_else(|| (ata + nalgebra::SMatrix::<f64, P, P>::identity() * 1e-12 * ata.trace()).try_inverse())?;
    let b = inv * atb;
    let (sw, swy) = xs.iter().fold((0.0, 0.0), |(a, c), (_, y, w)| (a + w, c + w * y));
    let ybar = swy / sw;
    let (mut ss_loo, mut ss_tot) = (0.0, 0.0);
    for (x, y, w) in &xs {
        let xv = nalgebra::SVector::<f64, P>::from_row_slice(x);
        // Leverage of a weighted point: w xᵀ (XᵀWX)⁻¹ x.
        let h = *w * (xv.transpose() * inv * xv)[(0, 0)];
        if h >= 1.0 - 1e-9 {
            return None;
        }
        let e = (y - (xv.transpose() * b)[(0, 0)]) / (1.0 - h);
        ss_loo += w * e * e;
        ss_tot += w * (y - ybar).powi(2);
    }
    (ss_tot > 0.0).then(|| 100.0 * (1.0 - ss_loo / ss_tot))
}
