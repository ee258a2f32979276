//! Rigid–flexible deformation (paper §3, Eqs. 21–26) as the compliance between
//! the motor-side position `L θ/2π` and the terminal (grating-scale) position.
//!
//! Axial terms δ1..δ4 form one nonlinear spring between the screw's ideal nut
//! position `x_s = x0 + L θ_s/2π` and the rod: δ_ax(F, x) = δ1 + δ2 + δ3 + δ4.
//! It is odd and strictly increasing in F, so the spring force for a given
//! deflection is found by a safeguarded Newton iteration. The torsion term δ5
//! is a rotational compliance in series with the coupling: the screw twist
//! shows at the nut as `L/2π` times the angle.
//!
//! `x` is the nut's distance travelled; the threaded length carrying load and
//! torque to the nut is `l0 + max(x, 0)` (the paper's δ2 uses `x_n`, i.e. l0 = 0).

use super::params::PlantParams;

/// `C [(|F| + F_p)^k − F_p^k] sign(F)`: a Hertz-type contact preloaded by
/// `F_p`, so the stiffness at zero force is finite (`1 / (k C F_p^{k−1})`).
#[derive(Clone, Copy, Debug)]
pub struct PreloadedPowerLaw {
    coefficient: f64,
    preload: f64,
    exponent: f64,
    /// `F_p^k`, reused every evaluation.
    preload_term: f64,
    /// `k == 2/3`: use `cbrt`, several times faster than `powf`.
    two_thirds: bool,
}

impl PreloadedPowerLaw {
    pub fn new(coefficient: f64, preload: f64, exponent: f64) -> Self {
        let two_thirds = (exponent - 2.0 / 3.0).abs() < 1e-12;
        Self { coefficient, preload, exponent, preload_term: pow(preload, exponent, two_thirds), two_thirds }
    }

    /// Deflection for a force of either sign.
    pub fn deflection(&self, force: f64) -> f64 {
        self.deflection_and_slope(force).0
    }

    /// Deflection and its derivative dδ/dF (always > 0).
    #[inline]
    pub fn deflection_and_slope(&self, force: f64) -> (f64, f64) {
        self.deflection_and_slope_warm(force, &mut 0.0)
    }

    /// `deflection_and_slope`, with the cube root `(|F| + F_p)^{1/3}` of the
    /// last call in `root` as the start of its iteration (0: none), and
    /// this call's left there.
    #[inline]
    pub fn deflection_and_slope_warm(&self, force: f64, root: &mut f64) -> (f64, f64) {
        let a = force.abs() + self.preload;
        let (p, slope) = if self.two_thirds {
            let t = cube_root(a, *root);
            *root = t;
            (t * t, 2.0 / (3.0 * t))
        } else {
            let p = a.powf(self.exponent);
            (p, self.exponent * p / a)
        };
        (self.coefficient * (p - self.preload_term).copysign(force), self.coefficient * slope)
    }

    /// `∫_0^|F| δ(f) df`: the complementary energy, for energy audits.
    pub fn complementary_energy(&self, force: f64) -> f64 {
        let f = force.abs();
        let k1 = self.exponent + 1.0;
        self.coefficient
            * (((f + self.preload).powf(k1) - self.preload.powf(k1)) / k1 - self.preload_term * f)
    }

    /// d²δ/dF² at |F| given the slope `s` = dδ/dF there: `s (k − 1)/(|F| + F_p)`
    /// (negative: the law is concave in |F|).
    #[inline]
    fn curvature_from_slope(&self, force_abs: f64, slope: f64) -> f64 {
        slope * (self.exponent - 1.0) / (force_abs + self.preload)
    }

    /// dδ/dF at zero force: the largest slope (the law is concave in |F|).
    pub fn slope_at_zero(&self) -> f64 {
        self.coefficient * self.exponent * self.preload_term / self.preload
    }
}

/// `a^{1/3}` for a > 0 by Halley's iteration `t ← t (t³ + 2a)/(2t³ + a)`,
/// from `guess` if positive (the last root: one or two steps), else from
/// an exponent-halving bit estimate (within 4 %: three or four steps).
/// Cubic convergence: once a step changes t by under 1e-6 relative, the
/// error left is below 1e-18, so that step is the last. Agrees with
/// `f64::cbrt` to an ulp or two at a third of its cost (the correctly
/// rounded `cbrt` the toolchain links was a quarter of the plant's time).
#[inline]
pub fn cube_root(a: f64, guess: f64) -> f64 {
    if !(a.is_normal() && a > 0.0 && a < 1e100) {
        return a.cbrt();
    }
    let mut t = if guess > 0.0 && guess.is_finite() { guess } else { f64::from_bits(a.to_bits() / 3 + 0x2A9F_7893_782D_A1CE) };
    for _ in 0..8 {
        let t3 = t * t * t;
        let next = t * (t3 + 2.0 * a) / (2.0 * t3 + a);
        let done = (next - t).abs() <= 1e-6 * next;
        t = next;
        if done {
            break;
        }
    }
    t
}

fn pow(x: f64, k: f64, two_thirds: bool) -> f64 {
    if two_thirds {
        // The same root as `deflection_and_slope` takes cold, so δ(0) = 0.
        let t = cube_root(x, 0.0);
        t * t
    } else {
        x.powf(k)
    }
}

/// The five deformation terms at one load and stroke position, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deflection {
    /// δ1: ball–raceway Hertz contact.
    pub contact_m: f64,
    /// δ2: screw tension/compression over the loaded length.
    pub screw_axial_m: f64,
    /// δ3: piston rod, two segments.
    pub rod_m: f64,
    /// δ4: fixed-end bearing pair.
    pub bearing_m: f64,
    /// δ5: screw torsion seen at the nut, `L/2π · δθ5`.
    pub torsion_m: f64,
    /// Coupling twist seen at the nut; not one of the paper's terms (it is
    /// Eq. 11's spring), tiny, but part of the static terminal error.
    pub coupling_m: f64,
}

impl Deflection {
    /// The paper's Eq. 26 total, δ1 + … + δ5 (what Fig. 5 plots).
    pub fn paper_total_m(&self) -> f64 {
        self.contact_m + self.screw_axial_m + self.rod_m + self.bearing_m + self.torsion_m
    }

    /// Everything between motor-side and terminal position at standstill.
    pub fn terminal_total_m(&self) -> f64 {
        self.paper_total_m() + self.coupling_m
    }
}

/// The last axial-force inversion, to warm-start the next one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxialWarmStart {
    pub deflection_m: f64,
    pub force_n: f64,
    /// dF/dδ there (0: unknown, start from `force_n` alone).
    pub stiffness_n_per_m: f64,
    /// d²F/dδ² there (0: unknown).
    pub curvature_n_per_m2: f64,
    /// The linear (screw + rod) compliance there, m/N: it changes with the
    /// stroke.
    pub linear_m_per_n: f64,
    /// The contact's and bearing's cube roots there (0: unknown).
    pub roots: [f64; 2],
}

impl AxialWarmStart {
    /// From a force alone (no tangent known yet).
    pub fn from_force(force_n: f64) -> Self {
        Self { force_n, ..Self::default() }
    }
}

/// Axial and torsional compliance of the drive train.
#[derive(Clone, Copy, Debug)]
pub struct Compliance {
    contact: PreloadedPowerLaw,
    bearing: PreloadedPowerLaw,
    /// dδ/dF of contact + bearing at F = 0 (their largest), for the bracket.
    nonlinear_slope_at_zero: f64,
    /// `1/(E_s A_s)`, per metre of loaded screw.
    screw_per_m: f64,
    /// Rod segments, constant.
    rod: f64,
    /// Threaded length at x = 0.
    length_at_zero_m: f64,
    /// Coupling `1/K_co`.
    coupling_rad_per_n_m: f64,
    /// `1/(G I_s1)` per metre of loaded screw.
    torsion_per_m: f64,
    /// Fixed-end journal `L_s2/(G I_s2)`.
    torsion_fixed: f64,
    metres_per_rad: f64,
}

impl Compliance {
    pub fn new(p: &PlantParams) -> Self {
        let d = &p.deformation;
        let contact = PreloadedPowerLaw::new(d.contact.coefficient_m_per_n2_3, d.contact.preload_n, 2.0 / 3.0);
        let bearing = PreloadedPowerLaw::new(d.bearing.coefficient_m_per_n_k, d.bearing.preload_n, d.bearing.exponent);
        Self {
            nonlinear_slope_at_zero: contact.slope_at_zero() + bearing.slope_at_zero(),
            contact,
            bearing,
            screw_per_m: 1.0 / (d.screw_axial.youngs_modulus_pa * d.screw_axial.area_m2),
            rod: d.rod.segment1_length_m / (d.rod.youngs_modulus_pa * d.rod.segment1_area_m2)
                + d.rod.segment2_length_m / (d.rod.youngs_modulus_pa * d.rod.segment2_area_m2),
            length_at_zero_m: p.screw.nut_distance_at_zero_m,
            coupling_rad_per_n_m: 1.0 / p.coupling.torsional_stiffness_n_m_rad,
            torsion_per_m: 1.0 / (d.torsion.shear_modulus_pa * d.torsion.screw_polar_moment_m4),
            torsion_fixed: d.torsion.fixed_end_length_m / (d.torsion.shear_modulus_pa * d.torsion.fixed_end_polar_moment_m4),
            metres_per_rad: p.metres_per_rad(),
        }
    }

    /// Threaded length between the fixed-end bearing and the nut.
    #[inline]
    pub fn loaded_length_m(&self, x_m: f64) -> f64 {
        self.length_at_zero_m + x_m.max(0.0)
    }

    /// Linear axial compliance (screw + rod), m/N.
    #[inline]
    fn linear_m_per_n(&self, x_m: f64) -> f64 {
        self.screw_per_m * self.loaded_length_m(x_m) + self.rod
    }

    /// δ_ax = δ1 + δ2 + δ3 + δ4 for an axial force `F` (positive = the screw
    /// pushes the rod out, compressing the drive train).
    pub fn axial_deflection_m(&self, force_n: f64, x_m: f64) -> f64 {
        self.contact.deflection(force_n) + self.bearing.deflection(force_n) + self.linear_m_per_n(x_m) * force_n
    }

    /// The spring force that produces axial deflection `δ` at stroke `x`:
    /// the inverse of `axial_deflection_m`. `guess` is a warm start (the
    /// previous answer); the result is exact to ~1e-14 relative.
    ///
    /// For δ ≥ 0, g(F) = δ_ax(F) − δ is increasing and concave on F ≥ 0 and
    /// bracketed by `δ/(c_lin + c_0) ≤ F ≤ δ/c_lin` (c_0: the nonlinear terms'
    /// slope at zero, their largest). Newton from the left of the root of a
    /// concave increasing function never overshoots; a step from the right
    /// lands left of it. Clamping into the bracket keeps every iterate safe.
    pub fn axial_force_n(&self, deflection_m: f64, x_m: f64, guess: f64) -> f64 {
        self.axial_force_and_compliance(deflection_m, x_m, guess, &mut [0.0; 2]).0
    }

    /// `axial_force_n` warm-started from the Taylor parabola at the last
    /// answer: the guess is `F + Δδ·dF/dδ + ½Δδ²·d²F/dδ²`, within ~(Δδ)³
    /// of the root, so one Newton step meets the tolerance where a guess of
    /// the last force alone needs two or three (each costs two cube roots)
    /// and the tangent alone, with the 50 µs RK4 step's larger Δδ, two.
    /// Same tolerance, same answer to ~1e-14 relative.
    #[inline]
    pub fn axial_force_warm(&self, deflection_m: f64, x_m: f64, warm: &mut AxialWarmStart) -> f64 {
        let lin = self.linear_m_per_n(x_m);
        // The stroke moved too: at fixed δ, F changes by −F·Δc_lin·dF/dδ.
        let d = deflection_m - warm.deflection_m;
        let d_lin = if warm.linear_m_per_n > 0.0 { lin - warm.linear_m_per_n } else { 0.0 };
        let guess = warm.force_n
            + warm.stiffness_n_per_m * (d - warm.force_n * d_lin)
            + 0.5 * d * d * warm.curvature_n_per_m2;
        let mut roots = warm.roots;
        let (f, k, c) = self.axial_force_and_compliance(deflection_m, x_m, guess, &mut roots);
        *warm = AxialWarmStart {
            deflection_m,
            force_n: f,
            stiffness_n_per_m: k,
            curvature_n_per_m2: c,
            linear_m_per_n: lin,
            roots,
        };
        f
    }

    /// The inversion, with dF/dδ and d²F/dδ² at the last iterate (0 when
    /// δ = 0).
    ///
    /// The bracket costs two divisions, so a warm start skips it while
    /// Newton's steps stay small (under 1e-3·F, where an iterate is within
    /// ~1e-6·F of the root and cannot leave the bracket the root lies in);
    /// a cold start or a large step clamps as before.
    fn axial_force_and_compliance(&self, deflection_m: f64, x_m: f64, guess: f64, roots: &mut [f64; 2]) -> (f64, f64, f64) {
        if deflection_m == 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let target = deflection_m.abs();
        let lin = self.linear_m_per_n(x_m);
        let bracket = || (target / (lin + self.nonlinear_slope_at_zero), target / lin);
        let mut clamp = None;
        let mut f = if guess.is_finite() && guess * deflection_m > 0.0 {
            guess.abs()
        } else {
            let b = *clamp.get_or_insert_with(bracket);
            b.0
        };
        let mut stiffness = 0.0;
        let mut slopes = (0.0, 0.0, 0.0);
        for _ in 0..50 {
            let (d1, s1) = self.contact.deflection_and_slope_warm(f, &mut roots[0]);
            let (d4, s4) = self.bearing.deflection_and_slope_warm(f, &mut roots[1]);
            let g = d1 + d4 + lin * f - target;
            stiffness = 1.0 / (s1 + s4 + lin);
            slopes = (f, s1, s4);
            let mut next = f - g * stiffness;
            if clamp.is_some() || !((next - f).abs() <= 1e-3 * f) {
                let (lo, hi) = *clamp.get_or_insert_with(bracket);
                next = next.clamp(lo, hi);
            }
            // Newton's error after a step is ~ (step/F)² · F (the curvature
            // term is O(1/F)), so a step under 1e-7·F leaves < 1e-14·F.
            let done = (next - f).abs() <= 1e-7 * next.max(1e-3);
            f = next;
            if done {
                break;
            }
        }
        // F(δ) is the inverse of δ(F): F'' = −δ''·F'³, odd in δ like F.
        let (at, s1, s4) = slopes;
        let d2 = self.contact.curvature_from_slope(at, s1) + self.bearing.curvature_from_slope(at, s4);
        let curvature = (-d2 * stiffness * stiffness * stiffness).copysign(deflection_m);
        (f.copysign(deflection_m), stiffness, curvature)
    }

    /// Local axial stiffness dF/dδ at force `F`.
    pub fn axial_stiffness_n_m(&self, force_n: f64, x_m: f64) -> f64 {
        let (_, s1) = self.contact.deflection_and_slope(force_n);
        let (_, s4) = self.bearing.deflection_and_slope(force_n);
        1.0 / (s1 + s4 + self.linear_m_per_n(x_m))
    }

    /// Potential energy stored in the axial spring at force `F`: `F δ − ∫δ dF`.
    pub fn axial_energy_j(&self, force_n: f64, x_m: f64) -> f64 {
        let lin = self.linear_m_per_n(x_m);
        let complementary =
            self.contact.complementary_energy(force_n) + self.bearing.complementary_energy(force_n) + 0.5 * lin * force_n * force_n;
        force_n * self.axial_deflection_m(force_n, x_m) - complementary
    }

    /// Rate of change of the stored spring energies caused by the loaded
    /// length `l0 + x` changing at speed `v` (deflections held):
    /// `−½ (F²/(E_s A_s) + T²/(G I_s1)) v` while x > 0.
    pub fn parametric_power_w(&self, axial_force_n: f64, torque_n_m: f64, x_m: f64, v_m_s: f64) -> f64 {
        if x_m <= 0.0 {
            return 0.0;
        }
        -0.5 * (axial_force_n * axial_force_n * self.screw_per_m + torque_n_m * torque_n_m * self.torsion_per_m) * v_m_s
    }

    /// Rotor-to-nut torsional compliance: coupling in series with the screw
    /// journal and the threaded length to the nut, rad/(N·m).
    #[inline]
    pub fn torsional_compliance_rad_per_n_m(&self, x_m: f64) -> f64 {
        self.coupling_rad_per_n_m + self.torsion_per_m * self.loaded_length_m(x_m) + self.torsion_fixed
    }

    /// Screw twist alone (δθ5, Eq. 25) under torque `T`, rad.
    pub fn screw_twist_rad(&self, torque_n_m: f64, x_m: f64) -> f64 {
        torque_n_m * (self.torsion_per_m * self.loaded_length_m(x_m) + self.torsion_fixed)
    }

    /// The static deflection breakdown at axial force `F` and stroke `x`,
    /// at standstill: the screw torque is `F L/2π` (no friction at rest).
    pub fn static_deflection(&self, force_n: f64, x_m: f64) -> Deflection {
        let torque = force_n * self.metres_per_rad;
        Deflection {
            contact_m: self.contact.deflection(force_n),
            screw_axial_m: self.screw_per_m * self.loaded_length_m(x_m) * force_n,
            rod_m: self.rod * force_n,
            bearing_m: self.bearing.deflection(force_n),
            torsion_m: self.metres_per_rad * self.screw_twist_rad(torque, x_m),
            coupling_m: self.metres_per_rad * torque * self.coupling_rad_per_n_m,
        }
    }
}
