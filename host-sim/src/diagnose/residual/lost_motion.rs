//! Lost-motion shapes the segment builder stores for the backlash effect:
//! the play operator's deviation over a grid of plays, and the flank the
//! rod rests on when the nut force is known.

/// Plays (lost motions) tried by the backlash effect, m: 2 µm … 4.6 mm.
pub fn backlash_grid_m() -> Vec<f64> {
    (0..24).map(|k| 2e-6 * 1.4f64.powi(k)).collect()
}

/// `(play_b(x) − x)/b` of the play operator `y = clamp(y, x − b/2, x + b/2)`
/// started centred.
pub fn play_deviation(x: &[f64], b: f64) -> Vec<f64> {
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&xi| {
            y = y.clamp(xi - 0.5 * b, xi + 0.5 * b);
            (y - xi) / b
        })
        .collect()
}

/// Lost motion with a known nut force: the rod rests on the flank the force
/// pushes it against, `−½ flank` of the gap behind the screw. The flank
/// turns when the force (load + inertia + the seal's sliding friction,
/// given with the weight `moving` of the sliding law) leaves a hold band:
/// at rest the seal's breakaway `f_hold` must be overcome to push the rod
/// across the gap; sliding, only the sign counts. Without a load the
/// force follows the motion and this is the play operator.
pub fn flank_deviation(force: &[(f64, f64)], f_hold: f64) -> Vec<f64> {
    let mut flank = force
        .first()
        .map_or(1.0, |f| if f.0 < 0.0 { -1.0 } else { 1.0 });
    force
        .iter()
        .map(|&(f, moving)| {
            let band = (1.0 - moving) * f_hold;
            if f > band {
                flank = 1.0;
            } else if f < -band {
                flank = -1.0;
            }
            -0.5 * flank
        })
        .collect()
}
