//! Synthetic observer datasets: strokes shaped like the paper's §5.2 runs
//! with a smooth, known terminal error. Stands in for simulator or rig data
//! in tests and for the placeholder firmware model.
//!
//! Run `i`: elongation (even `i`) 0 → 0.45 m or contraction (odd `i`)
//! 0.45 → 0 m along `x(t) = S (1 − cos(π t/T))/2` (T = 2 s, 1 kHz); tilt
//! 90° → 90° ∓ swing → 90°; load `F = payload · 1380 N · sin(tilt) + m ẍ`; and
//! [`error_m`] gives the terminal error from the four inputs.

use super::dataset::{Dataset, Direction, Run};
use std::f64::consts::PI;

/// Stroke (m), duration (s), sample rate (Hz), screw lead (m).
pub const STROKE_M: f64 = 0.45;
pub const DURATION_S: f64 = 2.0;
pub const RATE_HZ: f64 = 1000.0;
pub const LEAD_M: f64 = 0.005;
/// Rated thrust (N), moving mass (kg).
pub const RATED_N: f64 = 1380.0;
pub const MASS_KG: f64 = 100.0;

/// The known terminal error (m) for nut speed `v` (m/s), displacement `x`
/// (m) and load `f` (N): deformation growing with load and with the stroke
/// (screw tension), a Hertz-like `F^(2/3)` contact term and a friction lost
/// motion that flips with the direction of motion (±0.05 mm).
pub fn error_m(v: f64, x: f64, f: f64) -> f64 {
    let load = f / RATED_N;
    load * (0.08e-3 + 0.25e-3 * x / STROKE_M) + 0.02e-3 * load.abs().powf(2.0 / 3.0) * load.signum()
        + 0.05e-3 * (v / 0.05).tanh()
}

/// `runs` runs (alternating directions), payload scale and tilt swing spread
/// over 0.5–1.0 and 20–30°.
pub fn paper_like(name: &str, runs: usize) -> Dataset {
    let n = (DURATION_S * RATE_HZ) as usize;
    let mut out = Vec::with_capacity(runs);
    for i in 0..runs {
        let direction = if i % 2 == 0 { Direction::Elongation } else { Direction::Contraction };
        let k = (i / 2) as f64;
        let m = (runs.div_ceil(2).max(2) - 1) as f64;
        let payload = 0.5 + 0.5 * k / m;
        let swing = 30.0 - 10.0 * ((k * 0.618_034).fract());
        let mut r = Run {
            id: format!("syn{i:03}"),
            direction,
            tilt_swing_deg: swing,
            payload_scale: payload,
            source: name.into(),
            first_line: 2,
            time_s: Vec::with_capacity(n),
            inputs: Vec::with_capacity(n),
            terminal_length_m: Vec::with_capacity(n),
            motor_side_position_m: Vec::with_capacity(n),
            terminal_error_m: Vec::with_capacity(n),
        };
        for s in 0..n {
            let t = s as f64 / RATE_HZ;
            let ph = PI * t / DURATION_S;
            let (mut x, mut v, mut a) = (
                STROKE_M * (1.0 - ph.cos()) / 2.0,
                STROKE_M * PI / (2.0 * DURATION_S) * ph.sin(),
                STROKE_M * PI * PI / (2.0 * DURATION_S * DURATION_S) * ph.cos(),
            );
            if direction == Direction::Contraction {
                x = STROKE_M - x;
                v = -v;
                a = -a;
            }
            let tilt_deg = match direction {
                Direction::Elongation => 90.0 - swing * ph.sin(),
                Direction::Contraction => 90.0 + swing * ph.sin(),
            };
            let f = payload * RATED_N * tilt_deg.to_radians().sin() + MASS_KG * a;
            let e = error_m(v, x, f);
            r.time_s.push(t);
            r.inputs.push([2.0 * PI * v / LEAD_M, v, x, f, 0.0]);
            r.motor_side_position_m.push(x);
            r.terminal_error_m.push(e);
            r.terminal_length_m.push(x + e);
        }
        out.push(r);
    }
    Dataset::from_runs(name, out)
}
