//! What a power stage survives: its rating, a value the board gives (the
//! ESC1's from its data sheet and shunt network) or the simulated drive
//! reads from its rig file. A parameter set asks no more of the power stage
//! than this: at power-up a saved set is lowered to it (and the log says
//! so), while a set sent or loaded live is refused, naming the leaf.

use super::ControlParams;

/// A power stage's rating.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerStageRating {
    /// Highest bus voltage the stage takes (`faults.bus_overvoltage_v` at most).
    pub bus_max_v: f32,
    /// Highest continuous phase current (`limits.current_max_a` at most).
    pub current_max_a: f32,
    /// Highest overcurrent trip the stage's protection can stand behind
    /// (`faults.overcurrent_trip_a` at most).
    pub overcurrent_trip_max_a: f32,
}

/// What [`PowerStageRating::lower`] lowered, each to the rating's value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RatingLowered {
    pub bus_overvoltage_v: Option<f32>,
    pub current_max_a: Option<f32>,
    pub overcurrent_trip_a: Option<f32>,
}

impl RatingLowered {
    /// The first leaf that was lowered, if any (for a refusal naming it).
    pub const fn first_leaf(&self) -> Option<u16> {
        if self.bus_overvoltage_v.is_some() {
            Some(crate::leaf!(faults.bus_overvoltage_v))
        } else if self.current_max_a.is_some() {
            Some(crate::leaf!(limits.current_max_a))
        } else if self.overcurrent_trip_a.is_some() {
            Some(crate::leaf!(faults.overcurrent_trip_a))
        } else {
            None
        }
    }
}

impl PowerStageRating {
    /// Lowers (never raises) the limits of `params` to this rating, and says
    /// what it lowered. `const`, so a board's built-in set is lowered and
    /// then validated at compile time.
    pub const fn lower(&self, params: ControlParams) -> (ControlParams, RatingLowered) {
        // NaN counts as "above": it is replaced by the rating.
        const fn lower(value: f32, max: f32) -> (f32, Option<f32>) {
            if value > max || value.is_nan() { (max, Some(max)) } else { (value, None) }
        }
        let mut p = params;
        let (bus_ov, bus_overvoltage_v) = lower(p.faults.bus_overvoltage_v, self.bus_max_v);
        let (i_max, current_max_a) = lower(p.limits.current_max_a, self.current_max_a);
        let (ocp, overcurrent_trip_a) = lower(p.faults.overcurrent_trip_a, self.overcurrent_trip_max_a);
        p.faults.bus_overvoltage_v = bus_ov;
        p.limits.current_max_a = i_max;
        p.faults.overcurrent_trip_a = ocp;
        (p, RatingLowered { bus_overvoltage_v, current_max_a, overcurrent_trip_a })
    }

    /// The first leaf of `params` beyond this rating, if any.
    pub const fn exceeded_by(&self, params: &ControlParams) -> Option<u16> {
        self.lower(*params).1.first_leaf()
    }
}
