//! Classical fourth-order Runge–Kutta, fixed step.
//!
//! Fixed rather than adaptive so a run is bit-for-bit repeatable and its
//! cost predictable; the step is bounded by `PlantParams::max_step_s()`
//! (one step per PWM period on the shipped rig) and `params_check`
//! refuses a step that does not resolve the model's fastest rate. Inputs
//! (inverter state, load) are held constant across a step: the caller
//! splits steps at every change.

/// One RK4 step of `ẋ = f(x)` with step `h`.
#[inline]
pub fn rk4_step<const N: usize>(x: &[f64; N], h: f64, mut f: impl FnMut(&[f64; N]) -> [f64; N]) -> [f64; N] {
    let k1 = f(x);
    rk4_step_from(x, h, &k1, f)
}

/// `rk4_step` with its first stage `k1 = f(x)` already known (the caller
/// evaluated f at x for another purpose): the same step, three evaluations.
#[inline]
pub fn rk4_step_from<const N: usize>(
    x: &[f64; N],
    h: f64,
    k1: &[f64; N],
    mut f: impl FnMut(&[f64; N]) -> [f64; N],
) -> [f64; N] {
    let k2 = f(&axpy(x, 0.5 * h, k1));
    let k3 = f(&axpy(x, 0.5 * h, &k2));
    let k4 = f(&axpy(x, h, &k3));
    std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]))
}

#[inline]
fn axpy<const N: usize>(x: &[f64; N], a: f64, k: &[f64; N]) -> [f64; N] {
    std::array::from_fn(|i| x[i] + a * k[i])
}

#[cfg(test)]
mod tests {
    use super::{rk4_step, rk4_step_from};

    #[test]
    fn rk4_matches_exponential_to_fifth_order_per_step() {
        // ẋ = −x: one step gives the Taylor series of e^{−h} to h⁴, so the
        // local error is h⁵/120 to leading order.
        let h: f64 = 0.1;
        let x = rk4_step(&[1.0], h, |x| [-x[0]]);
        let err = x[0] - (-h).exp();
        assert!((err.abs() - h.powi(5) / 120.0).abs() < 0.2 * h.powi(5) / 120.0, "err {err}");
    }

    #[test]
    fn a_given_first_stage_gives_the_same_step() {
        // ẋ = (x1, −x0 − 0.3 x1): the step from a precomputed k1 is the
        // step that computes it, bit for bit.
        let f = |x: &[f64; 2]| [x[1], -x[0] - 0.3 * x[1]];
        let x = [0.7, -0.2];
        assert_eq!(rk4_step(&x, 0.05, f), rk4_step_from(&x, 0.05, &f(&x), f));
    }
}
