//! Training / held-out parts of the segments: a slice of a segment as a
//! segment of its own, and the default split (alternate runs, or 60 % /
//! 40 % of a single run in time).

use super::residual::Segment;

/// Samples `[a, b)` of a segment as a segment of its own.
pub fn slice_segment(s: &Segment, a: usize, b: usize, held: bool) -> Segment {
    let sl = |v: &Vec<f64>| v[a..b].to_vec();
    Segment {
        run: s.run,
        heldout: held,
        first_row: s.first_row + a,
        t: sl(&s.t),
        t_rel: sl(&s.t_rel),
        theta: sl(&s.theta),
        omega: sl(&s.omega),
        alpha: sl(&s.alpha),
        x: sl(&s.x),
        v: sl(&s.v),
        a: sl(&s.a),
        v_ref: sl(&s.v_ref),
        a_ref: sl(&s.a_ref),
        f_load: sl(&s.f_load),
        f_ax: sl(&s.f_ax),
        iq: sl(&s.iq),
        iq_logged: sl(&s.iq_logged),
        theta_logged: if s.theta_logged.is_empty() { Vec::new() } else { sl(&s.theta_logged) },
        scale_logged: if s.scale_logged.is_empty() { Vec::new() } else { sl(&s.scale_logged) },
        temperature_c: if s.temperature_c.is_empty() {
            Vec::new()
        } else {
            sl(&s.temperature_c)
        },
        dir: sl(&s.dir),
        since_reversal_s: sl(&s.since_reversal_s),
        c_loc: sl(&s.c_loc),
        input: sl(&s.input),
        y: std::array::from_fn(|c| s.y[c].as_ref().map(sl)),
        r: std::array::from_fn(|c| s.r[c].as_ref().map(sl)),
        encoder: s.encoder,
        rod_from_scale: s.rod_from_scale,
        play: s.play.iter().map(sl).collect(),
        flank: if s.flank.is_empty() {
            Vec::new()
        } else {
            sl(&s.flank)
        },
        motion_weight: if s.motion_weight.is_empty() {
            Vec::new()
        } else {
            sl(&s.motion_weight)
        },
        sg_m: s.sg_m,
        dt: s.dt,
    }
}

/// Splits a single long segment into 60 % / 40 %.
pub fn split_segments(mut segs: Vec<Segment>) -> Vec<Segment> {
    if segs.len() >= 2 {
        for (k, s) in segs.iter_mut().enumerate() {
            s.heldout = k % 2 == 1;
        }
        return segs;
    }
    let Some(s) = segs.pop() else { return segs };
    let cut = s.len() * 3 / 5;
    let take = |a: usize, b: usize, held: bool| slice_segment(&s, a, b, held);
    vec![take(0, cut, false), take(cut, s.len(), true)]
}

