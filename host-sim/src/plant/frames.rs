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
