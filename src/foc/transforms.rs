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
    pub fn of(angle_rad: f32) -> Self {
        let (sin, cos) = crate::math::sincos(angle_rad);
        Self { sin, cos }
    }
}

/// Three phase quantities to α-β. All three samples are used so a common
/// offset on the sensors (which cancels in a balanced machine) drops out.
pub fn clarke(abc: [f32; 3]) -> AlphaBeta {
    let [a, b, c] = abc;
    AlphaBeta { alpha: (2.0 * a - b - c) * (1.0 / 3.0), beta: (b - c) * INV_SQRT3 }
}

/// α-β back to three phase quantities (zero common mode).
pub fn inverse_clarke(v: AlphaBeta) -> [f32; 3] {
    let half_sqrt3_beta = 0.5 * SQRT3 * v.beta;
    [v.alpha, -0.5 * v.alpha + half_sqrt3_beta, -0.5 * v.alpha - half_sqrt3_beta]
}

/// Stationary to rotor frame at the electrical angle given by `sc`.
pub fn park(v: AlphaBeta, sc: SinCos) -> Dq {
    Dq { d: v.alpha * sc.cos + v.beta * sc.sin, q: -v.alpha * sc.sin + v.beta * sc.cos }
}

/// Rotor to stationary frame.
pub fn inverse_park(v: Dq, sc: SinCos) -> AlphaBeta {
    AlphaBeta { alpha: v.d * sc.cos - v.q * sc.sin, beta: v.d * sc.sin + v.q * sc.cos }
}

pub use crate::math::wrap_pi;
