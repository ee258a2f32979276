//! Clarke, Park and their inverses (amplitude-invariant: a phase current of
//! amplitude I gives |i_dq| = I).

const SQRT3: f32 = 1.732_050_8;
const INV_SQRT3: f32 = 0.577_350_26;

/// A vector in the stationary α-β frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlphaBeta {
    pub alpha: f32,
    pub beta: f32,
}

/// A vector in the rotor d-q frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dq {
    pub d: f32,
    pub q: f32,
}

/// Sine and cosine of one angle, computed once per period and shared by Park
/// and inverse Park.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinCos {
    pub sin: f32,
    pub cos: f32,
}

impl SinCos {
    #[inline(always)]
    pub fn of(angle_rad: f32) -> Self {
        let (sin, cos) = crate::math::sincos_inline(angle_rad);
        Self { sin, cos }
    }

    /// Sine and cosine of `angle + delta_rad`, found by rotating these by δ
    /// rather than by a second `sincos`: for |δ| ≤ 1/4 rad, `sin δ` and
    /// `cos δ` from their Taylor series to δ⁵ and δ⁴ (truncation below 2e-8,
    /// under the polynomial sin/cos's own 1e-7; the current loop's phase
    /// advance is ≈ 0.1 rad at the rated speed), a larger δ (or NaN) through
    /// `sincos(δ)`.
    #[inline(always)]
    pub fn advanced_by(self, delta_rad: f32) -> Self {
        let d2 = delta_rad * delta_rad;
        let r = if d2 <= ADVANCE_SERIES_MAX_RAD * ADVANCE_SERIES_MAX_RAD {
            let sin = delta_rad * (1.0 + d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0)));
            let cos = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0));
            Self { sin, cos }
        } else {
            let (sin, cos) = crate::math::sincos(delta_rad);
            Self { sin, cos }
        };
        Self { sin: self.sin * r.cos + self.cos * r.sin, cos: self.cos * r.cos - self.sin * r.sin }
    }
}

/// Largest advance `SinCos::advanced_by` takes by series.
const ADVANCE_SERIES_MAX_RAD: f32 = 0.25;

/// Three phase quantities to α-β. All three samples are used so a common
/// offset on the sensors (which cancels in a balanced machine) drops out.
#[inline(always)]
pub fn clarke(abc: [f32; 3]) -> AlphaBeta {
    let [a, b, c] = abc;
    AlphaBeta { alpha: (2.0 * a - b - c) * (1.0 / 3.0), beta: (b - c) * INV_SQRT3 }
}

/// α-β back to three phase quantities (zero common mode).
#[inline(always)]
pub fn inverse_clarke(v: AlphaBeta) -> [f32; 3] {
    let half_sqrt3_beta = 0.5 * SQRT3 * v.beta;
    [v.alpha, -0.5 * v.alpha + half_sqrt3_beta, -0.5 * v.alpha - half_sqrt3_beta]
}

/// Stationary to rotor frame at the electrical angle given by `sc`.
#[inline(always)]
pub fn park(v: AlphaBeta, sc: SinCos) -> Dq {
    Dq { d: v.alpha * sc.cos + v.beta * sc.sin, q: -v.alpha * sc.sin + v.beta * sc.cos }
}

/// Rotor to stationary frame.
#[inline(always)]
pub fn inverse_park(v: Dq, sc: SinCos) -> AlphaBeta {
    AlphaBeta { alpha: v.d * sc.cos - v.q * sc.sin, beta: v.d * sc.sin + v.q * sc.cos }
}

pub use crate::math::wrap_pi;
