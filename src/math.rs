//! Single-precision maths for the control path.
//!
//! Why not `libm` here: its `sincosf`, `tanf` and `cbrtf` compute in `f64`,
//! which the Cortex-M4F's single-precision FPU runs as software (≈2 400
//! instructions per `sincosf`), and `sqrtf`/`fmaxf` are library calls where
//! the FPU has an instruction or a compare will do. Everything here is plain
//! f32 arithmetic (or the FPU's `vsqrt`), so the host and the target compute
//! bit-identical results, which the golden vectors check. Nothing panics:
//! `f32::clamp` panics on inverted bounds, `clamp` here does not.

/// `x` bounded to `[lo, hi]`; NaN gives `lo`. Never panics (inverted bounds
/// give `hi` for large `x`, `lo` otherwise).
#[inline(always)]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x > hi {
        hi
    } else if x >= lo {
        x
    } else {
        lo
    }
}

#[inline(always)]
pub fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[inline(always)]
pub fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// 0 for a finite `x`, NaN for an infinity or NaN. A sum of these is 0
/// exactly when every term is finite: one compare instead of a test and a
/// branch per value.
#[inline(always)]
#[allow(clippy::eq_op)] // x − x is the point: it is 0 only for a finite x
pub fn finite_probe(x: f32) -> f32 {
    x - x
}

/// Largest integer not above `x`, for |x| < 2³¹ (NaN gives 0).
#[inline(always)]
pub fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t > x { t - 1.0 } else { t }
}

/// Nearest integer, halves away from zero, for |x| < 2³¹.
#[inline(always)]
pub fn round(x: f32) -> f32 {
    if x >= 0.0 { floor(x + 0.5) } else { -floor(0.5 - x) }
}

/// Square root: the FPU's `vsqrt.f32` on the target, libm's (also correctly
/// rounded, hence identical) elsewhere. Negative or NaN input gives NaN.
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let r: u32;
        // SAFETY: register-only FPU instructions, no memory access. The value
        // goes through a core register because the `sreg` operand class is
        // not offered for this target.
        unsafe {
            core::arch::asm!(
                "vmov s15, {x}",
                "vsqrt.f32 s15, s15",
                "vmov {r}, s15",
                x = in(reg) x.to_bits(),
                r = lateout(reg) r,
                out("s15") _,
                options(pure, nomem, nostack),
            )
        };
        f32::from_bits(r)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `sqrt(max(x, 0))` (NaN gives 0), the clamp done on the bit pattern: the
/// value passes through a core register on its way to `vsqrt` anyway, and
/// one unsigned compare there replaces a float compare with its flag
/// transfer and a loaded zero. Every bit pattern above `+∞`'s is a negative
/// number, −0 or a NaN — exactly the inputs `max(x, 0.0)` maps to 0.
#[inline(always)]
pub fn sqrt_non_negative(x: f32) -> f32 {
    let bits = x.to_bits();
    sqrt(f32::from_bits(if bits > f32::INFINITY.to_bits() { 0 } else { bits }))
}

/// Sine and cosine for |x| ≲ 10⁴ rad: quadrant reduction with a three-part
/// π/2 (Cody–Waite; the first part has few bits so `n·part` is exact), then
/// the Cephes minimax polynomials on [−π/4, π/4]. Error ≈ 1e-7 absolute.
pub fn sincos(x: f32) -> (f32, f32) {
    sincos_inline(x)
}

/// [`sincos`] for the current loop's one call per period, inlined there.
#[inline(always)]
pub(crate) fn sincos_inline(x: f32) -> (f32, f32) {
    const DP1: f32 = 1.570_312_5;
    const DP2: f32 = 4.837_513e-4;
    const DP3: f32 = 7.549_79e-8;
    let (n, quadrant) = round_to_int(x * core::f32::consts::FRAC_2_PI);
    let r = ((x - n * DP1) - n * DP2) - n * DP3;
    let z = r * r;
    let s = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * r + r;
    let c = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    match quadrant & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `1.5 · 2²³`: adding it to an `f32` of magnitude below 2²² leaves no
/// fraction bits, so the FPU's own rounding (to nearest, ties to even)
/// rounds to an integer, which sits in the low mantissa bits.
pub(crate) const ROUND_MAGIC: f32 = 12_582_912.0;

/// `x` rounded to the nearest integer (ties to even), as an `f32` and as
/// the low bits of an integer (two's complement, exact for |x| < 2²²): two
/// additions instead of a conversion, a compare and a correction. Outside
/// that range the results are some integer, never a panic.
#[inline(always)]
pub(crate) fn round_to_int(x: f32) -> (f32, u32) {
    let shifted = x + ROUND_MAGIC;
    (shifted - ROUND_MAGIC, shifted.to_bits().wrapping_sub(ROUND_MAGIC.to_bits()))
}

/// Tangent through `sincos` (filter design at start-up, not the hot path).
pub fn tan(x: f32) -> f32 {
    let (s, c) = sincos(x);
    s / c
}

/// Cube root by Newton's method from a bit-level first guess (trajectory
/// planning, once per move). Relative error ≈ 1 ulp after four steps.
pub fn cbrt(x: f32) -> f32 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let a = if x < 0.0 { -x } else { x };
    // Dividing the exponent by three in the bit pattern: within 4 %.
    let mut y = f32::from_bits(a.to_bits().wrapping_div(3).wrapping_add(0x2A51_2CE3));
    for _ in 0..4 {
        y = y - (y * y * y - a) / (3.0 * y * y);
    }
    if x < 0.0 { -y } else { y }
}

/// e^x for x ≤ 0 down to about −87 (the chirp's `k^{n/N}`): 2^(x·log₂e)
/// split into the nearest integer power n, set in the exponent bits, and a
/// degree-7 Taylor polynomial of e^r for r = x − n ln 2, |r| ≤ ½ ln 2.
/// Relative error ≈ 1e-7; below −87 (or NaN) gives 0. A positive x (a
/// rounding above 0 at the sweep's end) takes the same path up to 88
/// (n ≤ 127), +∞ above: no libm `expf` in the image (≈ 0.5 KB).
pub fn exp_neg(x: f32) -> f32 {
    if !(x > -87.0) {
        return 0.0;
    }
    if x > 88.0 {
        return f32::INFINITY;
    }
    // Cody–Waite: ln 2 in two parts, the first exact in few bits, so the
    // reduced argument keeps full precision.
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let n = round(x * core::f32::consts::LOG2_E);
    let l = (x - n * LN2_HI) - n * LN2_LO;
    let p = 1.0
        + l * (1.0 + l * (0.5 + l * (1.0 / 6.0 + l * (1.0 / 24.0 + l * (1.0 / 120.0 + l * (1.0 / 720.0 + l * (1.0 / 5040.0)))))));
    // n ∈ [−126, 127]: a normal power of two.
    let bits = ((n as i32).wrapping_add(127) as u32) << 23;
    p * f32::from_bits(bits)
}

/// Natural logarithm of a positive normal `x` (test-signal set-up, not the
/// hot path): exponent from the bits, mantissa reduced to [√½, √2), then
/// `2 atanh s` with `s = (m − 1)/(m + 1)`, |s| ≤ 0.172, to s⁹ (error
/// ≈ 1e-7 relative). Zero, negative, NaN or subnormal give NaN.
pub fn ln(x: f32) -> f32 {
    if !(x >= f32::MIN_POSITIVE) || x == f32::INFINITY {
        return if x == f32::INFINITY { x } else { f32::NAN };
    }
    let bits = x.to_bits();
    let mut e = ((bits >> 23) as i32).wrapping_sub(127);
    let mut m = f32::from_bits((bits & 0x007F_FFFF) | 0x3F80_0000);
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e = e.wrapping_add(1);
    }
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let series = s * (2.0 + z * (2.0 / 3.0 + z * (2.0 / 5.0 + z * (2.0 / 7.0 + z * (2.0 / 9.0)))));
    e as f32 * core::f32::consts::LN_2 + series
}

/// Wraps an angle into [−π, π).
pub fn wrap_pi(angle_rad: f32) -> f32 {
    use core::f32::consts::PI;
    let turns = floor((angle_rad + PI) * (0.5 / PI));
    angle_rad - turns * (2.0 * PI)
}

/// Four-quadrant arctangent, in (−π, π]: the smaller of |y|, |x| over the
/// larger, a minimax polynomial of atan on [0, 1] (odd, degree 15, fitted
/// here for the absolute error), then the octant folded back. Error
/// ≤ 1.5e-7 rad in the first octant, ≤ 3e-7 folded towards ±π, where an
/// f32 ulp is 2.4e-7 (libm's `atan2f`: 2.4e-7 there; host-sim `core_math`
/// checks it against f64 all round the circle). Used off the 20 kHz path only (the
/// commutation fit, the back-EMF watch at the speed rate). libm's `atan2f`
/// (and the `atanf` it calls) took ≈ 600 bytes of flash; this ≈ 150.
///
/// Signed zeros as libm: `atan2(±0, +0) = ±0`, `atan2(±0, −0) = ±π`. A NaN
/// gives NaN; two infinities give NaN (libm: ±π/4, ±3π/4), which nothing in
/// the core feeds it (its inputs are checked finite).
#[inline(never)]
pub fn atan2(y: f32, x: f32) -> f32 {
    use core::f32::consts::{FRAC_PI_2, PI};
    let ax = x.abs();
    let ay = y.abs();
    let steep = ay > ax;
    let (num, den) = if steep { (ax, ay) } else { (ay, ax) };
    // 0/0 (both zero) reads as angle 0 of the octant; a NaN stays a NaN.
    let z = if den == 0.0 { 0.0 } else { num / den };
    let t = z * z;
    let p = -4.054_567_3e-3;
    let p = p * t + 2.186_295_8e-2;
    let p = p * t - 5.591_232_7e-2;
    let p = p * t + 9.642_197e-2;
    let p = p * t - 1.390_862_9e-1;
    let p = p * t + 1.994_656_6e-1;
    let p = p * t - 3.332_986e-1;
    let p = p * t + 9.999_993_4e-1;
    let mut a = z * p;
    if steep {
        a = FRAC_PI_2 - a;
    }
    if x.is_sign_negative() {
        a = PI - a;
    }
    if y.is_sign_negative() { -a } else { a }
}
