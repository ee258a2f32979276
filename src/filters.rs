//! Discrete filters for the loops.

use core::f32::consts::PI;

/// Second-order Butterworth low-pass (bilinear transform with prewarping),
/// direct form II transposed.
///
/// Used on the q-current reference (the "torque command filter" of industrial
/// servo drives): above the speed crossover the drive sees only the rotor
/// inertia, so the coupling/screw torsional mode (a few hundred hertz) meets
/// a loop gain several times the design value; the filter takes it back below
/// one while costing little phase at the crossover.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Biquad {
    b0: f32,
    b1: f32,
    b2: f32,
    a1: f32,
    a2: f32,
    z1: f32,
    z2: f32,
}

impl Biquad {
    /// Unity gain, no filtering (corner at or above Nyquist, or not positive).
    pub const PASS: Self = Self { b0: 1.0, b1: 0.0, b2: 0.0, a1: 0.0, a2: 0.0, z1: 0.0, z2: 0.0 };

    /// Butterworth low-pass with corner `corner_hz` sampled at `rate_hz`.
    pub fn low_pass(corner_hz: f32, rate_hz: f32) -> Self {
        if !(corner_hz > 0.0) || !(corner_hz < 0.45 * rate_hz) {
            return Self::PASS;
        }
        let k = crate::math::tan(PI * corner_hz / rate_hz);
        let q = core::f32::consts::FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Self {
            b0,
            b1: 2.0 * b0,
            b2: b0,
            a1: 2.0 * (k * k - 1.0) * norm,
            a2: (1.0 - k / q + k * k) * norm,
            z1: 0.0,
            z2: 0.0,
        }
    }

    pub fn reset(&mut self) {
        self.z1 = 0.0;
        self.z2 = 0.0;
    }

    /// The state a constant input `x` leaves behind (output `x`): a filter
    /// preloaded this way starts without a transient.
    pub fn preset(&mut self, x: f32) {
        self.z1 = x * (1.0 - self.b0);
        self.z2 = x * (self.b2 - self.a2);
    }

    pub fn update(&mut self, x: f32) -> f32 {
        let y = self.b0 * x + self.z1;
        self.z1 = self.b1 * x - self.a1 * y + self.z2;
        self.z2 = self.b2 * x - self.a2 * y;
        y
    }
}
