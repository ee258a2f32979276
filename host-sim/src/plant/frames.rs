//! Reference-frame transforms, in the convention the controller uses:
//! amplitude-invariant Clarke `α = a`, `β = (a + 2b)/√3` (valid for a
//! zero-sum triple) and Park `d = α cosθ + β sinθ`, `q = −α sinθ + β cosθ`.

const INV_SQRT3: f64 = 0.577_350_269_189_625_8;
const SQRT3_2: f64 = 0.866_025_403_784_438_6;

/// abc (zero-sum) → αβ.
#[inline]
pub fn clarke(abc: [f64; 3]) -> (f64, f64) {
    (abc[0], (abc[0] + 2.0 * abc[1]) * INV_SQRT3)
}

/// αβ → abc.
#[inline]
pub fn inverse_clarke(alpha: f64, beta: f64) -> [f64; 3] {
    [alpha, -0.5 * alpha + SQRT3_2 * beta, -0.5 * alpha - SQRT3_2 * beta]
}

/// αβ → dq, given `(sin θ, cos θ)`.
#[inline]
pub fn park(alpha: f64, beta: f64, sin: f64, cos: f64) -> (f64, f64) {
    (alpha * cos + beta * sin, -alpha * sin + beta * cos)
}

/// dq → αβ, given `(sin θ, cos θ)`.
#[inline]
pub fn inverse_park(d: f64, q: f64, sin: f64, cos: f64) -> (f64, f64) {
    (d * cos - q * sin, d * sin + q * cos)
}

/// abc → dq at electrical angle θ.
#[inline]
pub fn abc_to_dq(abc: [f64; 3], sin: f64, cos: f64) -> (f64, f64) {
    let (a, b) = clarke(abc);
    park(a, b, sin, cos)
}

/// dq → abc at electrical angle θ.
#[inline]
pub fn dq_to_abc(d: f64, q: f64, sin: f64, cos: f64) -> [f64; 3] {
    let (a, b) = inverse_park(d, q, sin, cos);
    inverse_clarke(a, b)
}

/// sin and cos of an angle that moves little between calls (the electrical
/// angle through the stages of an RK4 step): one exact `sin_cos` at a base
/// angle, then the rotation by the small difference d = a − base, with
/// sin d and cos d from their series (|d| ≤ 0.1: the terms left out,
/// d¹¹/11! and d¹²/12!, are below 3e-19, a three-hundredth of an ulp of 1). Every result is one rotation from an exact base, so errors do not
/// build up; they stay within a few ulps of `f64::sin_cos`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SinCosCache {
    base: f64,
    sin: f64,
    cos: f64,
    valid: bool,
}

impl SinCosCache {
    /// Largest |a − base| served by rotation.
    pub const REACH_RAD: f64 = 0.1;

    #[inline]
    pub fn sin_cos(&mut self, a: f64) -> (f64, f64) {
        let d = a - self.base;
        if self.valid && d.abs() <= Self::REACH_RAD {
            let d2 = d * d;
            // Horner on d²: multiplications by constants, no divisions.
            let sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0) * (1.0 - d2 * (1.0 / 72.0)))));
            let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0) * (1.0 - d2 * (1.0 / 56.0) * (1.0 - d2 * (1.0 / 90.0)))));
            (self.sin * cd + self.cos * sd, self.cos * cd - self.sin * sd)
        } else {
            let (s, c) = a.sin_cos();
            *self = Self { base: a, sin: s, cos: c, valid: a.is_finite() };
            (s, c)
        }
    }
}
