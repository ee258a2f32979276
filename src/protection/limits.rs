//! Which of the Eq. 19 limits (and the inverter's) acted: a limit that bites
//! is reported in telemetry, never applied silently.

/// A set of limit bits, refreshed every position period (sticky within it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
#[serde(transparent)]
pub struct LimitFlags(pub u8);

impl LimitFlags {
    pub const NONE: Self = Self(0);
    /// The q-current reference hit the current circle / copper-power bound.
    pub const CURRENT: Self = Self(1 << 0);
    /// The voltage circle limited u_d or u_q.
    pub const VOLTAGE: Self = Self(1 << 1);
    /// The speed reference hit `limits.speed_max_rad_s`.
    pub const SPEED: Self = Self(1 << 2);
    /// A position command was clamped into the stroke.
    pub const STROKE: Self = Self(1 << 3);
    /// The I²t model folded the current limit back.
    pub const THERMAL: Self = Self(1 << 4);
    /// The compensation shift hit its bound or rate limit.
    pub const COMPENSATION: Self = Self(1 << 5);
    /// An observer input lay outside the trained range and was clamped.
    pub const OBSERVER_INPUT: Self = Self(1 << 6);
    /// The bus rose: the speed was bounded so the load gives back less
    /// power than `power_stage.regen_power_max_w` allows.
    pub const REGEN: Self = Self(1 << 7);

    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }

    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    pub const fn bits(self) -> u8 {
        self.0
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for LimitFlags {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=u8:#06b}", self.0);
    }
}

/// Clamps a position into the stroke, saying whether it had to.
pub fn clamp_to_stroke(position_m: f32, min_m: f32, max_m: f32) -> (f32, bool) {
    let clamped = crate::math::clamp(position_m, min_m, max_m);
    (clamped, clamped != position_m)
}
