//! One definition of each shrink figure, used by the verdict, the ranking
//! table and `summary.json` alike.
//!
//! Both are on the held-out part, on the standstill weights of the torque
//! and position channels (`Segment::weight`), `100 (1 − after / before)`
//! with `before` the nominal's RMS residual and `after` the residual left
//! once the effect (or stack, or disturbance) is subtracted.

use std::collections::BTreeMap;

/// Label of the primary-channel figure.
pub const PRIMARY: &str = "primary-channel shrink";
/// Label of the weighted figure.
pub const WEIGHTED: &str = "weighted shrink";
/// Label of the weighted figure over the channels an effect acts on.
pub const WEIGHTED_ACTING: &str = "weighted shrink over the channels it acts on";
/// Label of the share of the held-out gap that remains.
pub const REMAINING: &str = "remaining gap";

pub fn definitions(primary_channel: &str) -> BTreeMap<String, String> {
    BTreeMap::from([
        (
            PRIMARY.to_string(),
            format!("held-out RMS residual shrink of the primary channel ({primary_channel}), standstill-weighted, %: 100·(1 − RMS after / RMS before)"),
        ),
        (
            WEIGHTED.to_string(),
            "held-out shrink of the gap over all channels, each weighted by 1/RMS of its training nominal residual (the ranking score), %".to_string(),
        ),
        (
            WEIGHTED_ACTING.to_string(),
            "the weighted figure over only the channels the effect's model acts on, fixed by the physics (the disturbance, an axial force: torque and position; the voltage channel, which holds no force, left out), %".to_string(),
        ),
        (
            REMAINING.to_string(),
            "100 − the primary-channel shrink of the best explanation (library stack or disturbance), %".to_string(),
        ),
    ])
}

/// `100 (1 − after / before)`, 0 when there is no gap.
pub fn shrink(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        100.0 * (1.0 - after / before)
    } else {
        0.0
    }
}
