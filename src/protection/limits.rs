//! Which of the Eq. 19 limits (and the inverter's) acted: a limit that bites
//! is reported in telemetry, never applied silently.

/// A set of limit bits, refreshed every position period (sticky within it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
#[serde(transparent)]
pub struct LimitFlags(u8);

bitflags::bitflags! {
    impl LimitFlags: u8 {
        /// The q-current reference hit the current circle / copper-power bound.
        const CURRENT = 1 << 0;
        /// The voltage circle limited u_d or u_q.
        const VOLTAGE = 1 << 1;
        /// The speed reference hit `limits.speed_max_rad_s`.
        const SPEED = 1 << 2;
        /// A position command was clamped into the stroke.
        const STROKE = 1 << 3;
        /// The I²t model folded the current limit back.
        const THERMAL = 1 << 4;
        /// The compensation shift hit its bound or rate limit.
        const COMPENSATION = 1 << 5;
        /// An observer input lay outside the trained range and was clamped.
        const OBSERVER_INPUT = 1 << 6;
        /// The bus rose: the speed was bounded so the load gives back less
        /// power than `power_stage.regen_power_max_w` allows.
        const REGEN = 1 << 7;
    }
}

impl LimitFlags {
    pub const NONE: Self = Self::empty();
}

#[cfg(feature = "defmt")]
impl defmt::Format for LimitFlags {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=u8:#06b}", self.bits());
    }
}

/// Clamps a position into the stroke, saying whether it had to.
pub fn clamp_to_stroke(position_m: f32, min_m: f32, max_m: f32) -> (f32, bool) {
    let clamped = crate::math::clamp(position_m, min_m, max_m);
    (clamped, clamped != position_m)
}
