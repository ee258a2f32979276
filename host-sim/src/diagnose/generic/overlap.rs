//! Classes that explain the same thing. Two generic classes fitted alone
//! on one channel can both remove much of a remainder when their shapes
//! overlap: the rod's ringing seen through `m a` from the scale looks, a
//! half period later, like the nominal shifted in time (a delay), and a
//! short delay like a heavily damped resonance. Which one the remainder is
//! follows from fitting them together: the right class keeps explaining
//! what the other cannot, while the other adds little to it (a nested
//! comparison, scored held-out like everything here).

use super::super::events::Remainder;
use super::super::residual::Segment;
use super::{lsq, rms, GenericFit};

/// Share of the held-out remainder's energy, %, a class must explain beyond
/// the other to lead it when the two overlap.
pub const BEYOND_MIN_PCT: f64 = 5.0;
/// How many times what the other explains beyond it the leading class must
/// explain beyond the other: the lead a class needs alone
/// (`GENERIC_LEAD` on the RMS), in energy.
pub const BEYOND_LEAD: f64 = super::GENERIC_LEAD * super::GENERIC_LEAD;

/// A fit's regressors (training, held-out), kept while the classes of a
/// channel are compared; not printed (they are the length of the log).
#[derive(Clone, Default)]
pub struct Basis(pub Option<(Vec<Vec<Vec<f64>>>, Vec<Vec<Vec<f64>>>)>);

impl std::fmt::Debug for Basis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() { "Basis(…)" } else { "Basis(none)" })
    }
}

/// Whether `best` leads the other class `other` (on its channel) by what it
/// explains beyond it.
pub fn leads_beyond(best: &GenericFit, other: &str) -> bool {
    best.beyond_pct.get(other).is_some_and(|[own, theirs]| *own >= BEYOND_MIN_PCT && *own >= BEYOND_LEAD * theirs.max(0.0))
}

/// Held-out RMS left by the regressor sets `parts` fitted together on
/// training.
fn joint_rms(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, c: usize, parts: &[&Basis]) -> Option<f64> {
    let join = |pick: &dyn Fn(&(Vec<Vec<Vec<f64>>>, Vec<Vec<Vec<f64>>>)) -> &Vec<Vec<Vec<f64>>>| -> Option<Vec<Vec<Vec<f64>>>> {
        let sets: Vec<&Vec<Vec<Vec<f64>>>> = parts.iter().map(|b| b.0.as_ref().map(pick)).collect::<Option<_>>()?;
        Some(
            (0..sets[0].len())
                .map(|k| (0..sets[0][k].len()).map(|i| sets.iter().flat_map(|x| x[k][i].iter().copied()).collect()).collect())
                .collect(),
        )
    };
    let xt = join(&|b| &b.0)?;
    let xh = join(&|b| &b.1)?;
    let b = lsq(train, rem_t, c, &xt);
    Some(rms(held, rem_h, c, Some((&xh, &b))))
}

/// Fills `beyond_pct` of every pair of fits on channel `c` that carry
/// regressors, then drops the regressors.
pub fn compare(train: &[&Segment], rem_t: &Remainder, held: &[&Segment], rem_h: &Remainder, c: usize, fits: &mut [GenericFit]) {
    let before = rms(held, rem_h, c, None);
    if before > 0.0 {
        let alone: Vec<Option<f64>> = fits.iter().map(|g| joint_rms(train, rem_t, held, rem_h, c, &[&g.basis])).collect();
        for a in 0..fits.len() {
            for b in a + 1..fits.len() {
                let (Some(ra), Some(rb)) = (alone[a], alone[b]) else { continue };
                let Some(rj) = joint_rms(train, rem_t, held, rem_h, c, &[&fits[a].basis, &fits[b].basis]) else { continue };
                let e = |r: f64| 100.0 * (r / before).powi(2);
                let (beyond_a, beyond_b) = (e(rb) - e(rj), e(ra) - e(rj));
                let (ca, cb) = (fits[a].class.clone(), fits[b].class.clone());
                fits[a].beyond_pct.insert(cb, [beyond_a, beyond_b]);
                fits[b].beyond_pct.insert(ca, [beyond_b, beyond_a]);
            }
        }
    }
    for g in fits.iter_mut() {
        g.basis = Basis(None);
    }
}
