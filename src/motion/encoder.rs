//! Quadrature encoder: unwrapping the 16-bit counter and a type-2 tracking
//! observer (PLL) that gives angle between counts and a low-noise speed.

use crate::params::EncoderParams;
use core::f32::consts::PI;

/// Multi-turn position and speed estimate from raw counter readings.
///
/// The estimate is kept as an integer count plus a fraction in [−½, ½] so that
/// integrating tiny speed·dt increments never loses resolution far from zero,
/// which a single f32 in radians would after a few hundred revolutions.
#[derive(Clone, Copy, Debug, Default)]
pub struct EncoderTracker {
    last_raw: u16,
    /// Unwrapped measured count, direction applied.
    count: i32,
    est_base: i32,
    est_frac: f32,
    speed_counts_s: f32,
    started: bool,
}

/// One tracker update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderUpdate {
    /// The counter moved further in one period than the motor can turn.
    pub implausible_step: bool,
}

impl EncoderTracker {
    pub const fn new() -> Self {
        Self { last_raw: 0, count: 0, est_base: 0, est_frac: 0.0, speed_counts_s: 0.0, started: false }
    }

    /// Feeds one raw counter value taken `dt_s` after the previous one.
    /// `max_innovation_counts` bounds how far the count may land from where
    /// the observer predicted it: a tighter test than the step bound, since
    /// the prediction already carries the speed (a type-2 loop lags a
    /// constant acceleration α by α/ki counts: ≈30 at the rotor's peak).
    #[inline]
    pub fn update(&mut self, p: &EncoderParams, raw: u16, dt_s: f32, max_step_counts: u32, max_innovation_counts: f32) -> EncoderUpdate {
        if !self.started {
            self.started = true;
            self.last_raw = raw;
            return EncoderUpdate { implausible_step: false };
        }
        // The counter wraps at 2^16; as long as it moves less than half that
        // per period, the wrapping difference read as i16 is the true step.
        let step = i32::from(raw.wrapping_sub(self.last_raw) as i16).wrapping_mul(p.direction);
        self.last_raw = raw;
        self.count = self.count.wrapping_add(step);
        self.est_frac += self.speed_counts_s * dt_s;
        let err = (self.count.wrapping_sub(self.est_base)) as f32 - self.est_frac;
        let implausible_step = step.unsigned_abs() > max_step_counts || !(err.abs() <= max_innovation_counts);
        self.est_frac += p.pll_kp_per_s * err * dt_s;
        self.speed_counts_s += p.pll_ki_per_s2 * err * dt_s;
        // Nearest rather than floor: two additions instead of a conversion,
        // a compare and a correction, every period.
        let (whole, whole_counts) = crate::math::round_to_int(self.est_frac);
        self.est_base = self.est_base.wrapping_add(whole_counts as i32);
        self.est_frac -= whole;
        EncoderUpdate { implausible_step }
    }

    /// Redefines the present position as `count` (homing), keeping the speed.
    pub fn set_count(&mut self, count: i32) {
        let shift = count.wrapping_sub(self.count);
        self.count = count;
        self.est_base = self.est_base.wrapping_add(shift);
    }

    /// Unwrapped measured count.
    pub fn count(&self) -> i32 {
        self.count
    }

    /// Estimated multi-turn position in counts (with interpolation).
    pub fn position_counts(&self) -> f32 {
        self.est_base as f32 + self.est_frac
    }

    /// Estimated position within one revolution, counts in
    /// [−½, counts_per_rev − ½].
    #[inline]
    pub fn counts_in_rev(&self, p: &EncoderParams) -> f32 {
        let cpr = p.counts_per_rev as i32;
        // counts_per_rev ≥ 1 by validation; 0 would give 0, not a panic.
        self.est_base.checked_rem_euclid(cpr).unwrap_or(0) as f32 + self.est_frac
    }

    /// Estimated position within one revolution or the one before it:
    /// counts in [½ − counts_per_rev, counts_per_rev − ½], the same angle
    /// modulo a turn as [`counts_in_rev`](Self::counts_in_rev) — all sin/cos
    /// need — without the Euclidean correction.
    #[inline]
    pub fn counts_in_turn(&self, p: &EncoderParams) -> f32 {
        // ≤ 32 768 by validation; the mask lets the compiler see it is not −1
        // (no overflow case to test) without changing any valid value.
        let cpr = (p.counts_per_rev & 0xFFFF) as i32;
        self.est_base.checked_rem(cpr).unwrap_or(0) as f32 + self.est_frac
    }

    /// Estimated mechanical angle within one revolution, radians, within half
    /// a count of [0, 2π).
    pub fn angle_in_rev_rad(&self, p: &EncoderParams) -> f32 {
        self.counts_in_rev(p) * (2.0 * PI / p.counts_per_rev as f32)
    }

    /// Estimated speed, counts per second.
    #[inline]
    pub fn speed_counts_s(&self) -> f32 {
        self.speed_counts_s
    }

    /// Estimated mechanical speed, rad/s.
    pub fn speed_rad_s(&self, p: &EncoderParams) -> f32 {
        self.speed_counts_s * (2.0 * PI / p.counts_per_rev as f32)
    }
}
