//! Checks on the library's answer before it is named: the effects the log
//! cannot separate from the top one (named as a group), and a current-sensor
//! gain that is really a torque-constant (flux) change.

use super::super::summary::RankEntry;

/// A current-sensor gain `g` read as a torque-constant (flux) change: the
/// back-EMF falls short of the rig file's by at least this share of the
/// `g` a flux drop of that size predicts. A sensor gain leaves the
/// back-EMF alone (it changes only `R i_q`, a few mV); a flux drop lowers
/// `K_t` and `p ω ψ_f` together (a logged current `1/(1 − δ)` high, a
/// back-EMF `1 − δ` low).
pub const FLUX_SHARE_OF_GAIN: f64 = 0.5;

/// The top effect and the ranked effects the tool flags indistinguishable
/// from it (`rank`: held-out predictions correlating > 0.95, or scores
/// within 1 point, both > 10 %), with their primary-channel shrink.
pub(super) fn group_of(ranking: &[RankEntry], top: &str) -> Vec<(String, f64)> {
    let Some(t) = ranking.iter().find(|r| r.effect == top) else {
        return Vec::new();
    };
    std::iter::once(t)
        .chain(
            ranking
                .iter()
                .filter(|r| t.indistinguishable_from.contains(&r.effect)),
        )
        .map(|r| (r.effect.clone(), r.primary_shrink_pct.max(0.0)))
        .collect()
}

/// When the top effect is the current sensor, whether its gain is a
/// torque-constant (flux) change instead: the held-out back-EMF falls
/// short as a flux drop of that size predicts (`FLUX_SHARE_OF_GAIN`).
pub(super) fn flux_stand_in(ranking: &[RankEntry], top: Option<&str>, k: Option<f64>) -> Option<String> {
    let t = ranking.first().filter(|r| Some(r.effect.as_str()) == top)?;
    let g = *t
        .params
        .get("gain_error")
        .filter(|_| t.effect == "current_sensor")?;
    let k = k?;
    // The fitted coefficient on `K_t i_q` is the share of the logged
    // current that makes no torque: a flux drop δ (current 1/(1 − δ) of
    // the nominal's) fits g = δ and leaves a back-EMF 1 − δ.
    let delta = g;
    let deficit = 1.0 - k;
    (g.abs() > 0.0 && deficit * delta > 0.0 && deficit.abs() >= FLUX_SHARE_OF_GAIN * delta.abs())
        .then(|| format!(
            "; current_sensor's gain error {:+.1} % stands in for a torque-constant change: the held-out back-EMF is {k:.3} × the rig file's, as a flux drop of {:.1} % predicts (a sensor gain leaves the back-EMF alone); the magnets' flux, and with it K_t, is lower than the rig file says (warm magnets: −0.12 %/K), which no library effect models",
            100.0 * g,
            100.0 * delta
        ))
}
