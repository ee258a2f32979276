//! Open-phase detection: a broken motor lead or a dead inverter leg.
//!
//! An open phase carries no current whatever its voltage, while the other
//! two carry ± the same current, so the three still sum to zero and the
//! current-sum check cannot see it. What gives it away is a phase that the
//! current reference needs and that stays empty: over a window, a phase
//! asked for a mean |i| of at least `open_phase_current_a` that carries less
//! than `open_phase_ratio` of that threshold, i.e. sensor noise only.
//!
//! The bound on what the phase carries is absolute, not a fraction of the
//! demand: an open lead carries nothing whatever the load, so the check
//! holds from a light payload (a demand just above the threshold) to the
//! rated one, and a phase that carries a real but lagging share of a large
//! demand (a slipping frame, a saturated loop) is not called open.
//!
//! Why not a current-following check on |i_dq,ref − i_dq|: an encoder that
//! stops counting also makes the dq currents miss their references (the
//! back-EMF rotates in the frozen frame), so that check fires on encoder
//! faults first and names the wrong cause. Per phase, a wrong angle still
//! puts current in all three phases; only an open circuit empties one.
//!
//! At standstill the reference may ask next to nothing of one phase (its
//! axis perpendicular to the current vector); a window without enough
//! demand on any empty phase gives no verdict, and the last one stands.

use crate::params::FaultParams;

#[derive(Clone, Copy, Debug, Default)]
pub struct OpenPhaseMonitor {
    reference_abs_sum_a: [f32; 3],
    measured_abs_sum_a: [f32; 3],
    samples: u32,
}

impl OpenPhaseMonitor {
    pub const fn new() -> Self {
        Self { reference_abs_sum_a: [0.0; 3], measured_abs_sum_a: [0.0; 3], samples: 0 }
    }

    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Adds one sample of the reference and measured phase currents. At the
    /// end of a window of `window_samples` returns `Some(open)`: whether a
    /// phase that was asked for at least `open_phase_current_a` on average
    /// carried less than `open_phase_ratio` of that threshold; `Some(false)`
    /// if every phase with that demand carried more; `None` mid-window or
    /// when no phase was asked for enough to judge.
    pub fn update(
        &mut self,
        f: &FaultParams,
        window_samples: u32,
        reference_a: [f32; 3],
        measured_a: [f32; 3],
    ) -> Option<bool> {
        for ((r, m), (rs, ms)) in reference_a
            .iter()
            .zip(measured_a.iter())
            .zip(self.reference_abs_sum_a.iter_mut().zip(self.measured_abs_sum_a.iter_mut()))
        {
            *rs += r.abs();
            *ms += m.abs();
        }
        self.samples = self.samples.saturating_add(1);
        if self.samples < window_samples {
            return None;
        }
        let demand_min = f.open_phase_current_a * self.samples as f32;
        let empty_max = f.open_phase_ratio * demand_min;
        let mut verdict = None;
        for (rs, ms) in self.reference_abs_sum_a.iter().zip(self.measured_abs_sum_a.iter()) {
            if *rs >= demand_min {
                // NaN sums (non-finite samples are refused before this, but
                // never trust it) compare false and give no verdict.
                if *ms < empty_max {
                    verdict = Some(true);
                } else if *ms >= empty_max && verdict.is_none() {
                    verdict = Some(false);
                }
            }
        }
        self.reset();
        verdict
    }
}
