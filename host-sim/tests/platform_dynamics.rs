//! Plate dynamics and leg forces against independent references: the
//! weight balance, virtual work on the potential energy, the energy balance
//! along a trajectory, and finite differences of the rotation.

use host_sim::platform::{Geometry, Platform, Pose, PoseState, Trajectory, GRAVITY_M_S2};
use nalgebra::{Rotation3, Vector3, Vector6};

/// The axial vector of the skew part of a small rotation (accurate where
/// `scaled_axis`, through acos, loses half the digits).
fn vee(r: &Rotation3<f64>) -> Vector3<f64> {
    let m = r.matrix();
    0.5 * Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)])
}

fn at_rest(pose: Pose) -> PoseState {
    PoseState { pose, velocity: Vector6::zeros(), acceleration: Vector6::zeros() }
}

/// The paper's platform with the payload's centre of mass off-centre, so
/// that no symmetry hides an error.
fn lopsided() -> Platform {
    let mut g = Geometry::paper();
    g.payload_com_m = [0.04, -0.03, 0.12];
    Platform::new(g).unwrap()
}

#[test]
fn static_leg_forces_carry_the_weight() {
    let p = lopsided();
    let q = Pose::new(Vector3::new(0.03, -0.02, p.neutral().position_m.z + 0.05), Vector3::new(0.05, -0.08, 0.1));
    let f = p.leg_forces(&at_rest(q)).unwrap();
    let total: Vector3<f64> = (0..6).map(|i| f.legs.units[i] * f.forces_n[i]).sum();
    let weight = p.geometry.payload_mass_kg * GRAVITY_M_S2;
    assert!((total - Vector3::new(0.0, 0.0, weight)).norm() < 1e-9, "{total}");
    // Moments about the centre of mass vanish.
    let com = q.position_m + q.rotation() * p.geometry.com_body();
    let moment: Vector3<f64> = (0..6).map(|i| (q.position_m + f.legs.arms[i] - com).cross(&(f.legs.units[i] * f.forces_n[i]))).sum();
    assert!(moment.norm() < 1e-9, "{moment}");
}

#[test]
fn static_forces_agree_with_virtual_work() {
    // f · δl = δV with V = m g z_c: f = J_q⁻ᵀ ∇_q V, the gradient by finite
    // differences of the centre of mass height alone.
    let p = lopsided();
    let q = Pose::new(Vector3::new(-0.02, 0.04, p.neutral().position_m.z - 0.03), Vector3::new(-0.07, 0.04, -0.12));
    let z_c = |q: &Vector6<f64>| {
        let pose = Pose::from_vector(q);
        (pose.position_m + pose.rotation() * p.geometry.com_body()).z
    };
    let mut grad = Vector6::zeros();
    for k in 0..6 {
        let (mut a, mut b) = (q.to_vector(), q.to_vector());
        a[k] += 1e-6;
        b[k] -= 1e-6;
        grad[k] = p.geometry.payload_mass_kg * GRAVITY_M_S2 * (z_c(&a) - z_c(&b)) / 2e-6;
    }
    let reference = p.pose_jacobian(&q).transpose().lu().solve(&grad).unwrap();
    let f = p.leg_forces(&at_rest(q)).unwrap();
    for i in 0..6 {
        assert!((f.forces_n[i] - reference[i]).abs() < 1e-5, "leg {}: {} vs {}", i + 1, f.forces_n[i], reference[i]);
    }
}

#[test]
fn symmetric_heave_loads_every_leg_equally() {
    let p = Platform::paper();
    let traj = Trajectory::heave(&p);
    for k in 0..40 {
        let s = traj.state(k as f64 * 0.05);
        let f = p.leg_forces(&s).unwrap();
        let uz = f.legs.units[0].z;
        let expected = p.geometry.payload_mass_kg * (GRAVITY_M_S2 + s.acceleration[2]) / (6.0 * uz);
        for (i, fi) in f.forces_n.iter().enumerate() {
            assert!((fi - expected).abs() < 1e-9 * expected.abs().max(1.0), "leg {}: {fi} vs {expected}", i + 1);
        }
    }
}

#[test]
fn angular_velocity_matches_the_rotation_finite_difference() {
    let p = Platform::paper();
    let traj = Trajectory::combined(&p);
    let h = 1e-5;
    for k in 1..20 {
        let t = k as f64 * 0.37;
        let m = p.plate_motion(&traj.state(t));
        let r = |t: f64| traj.state(t).pose.rotation();
        // Ṙ Rᵀ = [ω]×.
        let w = |t: f64| {
            let d: Rotation3<f64> = r(t + h) * r(t - h).inverse();
            vee(&d) / (2.0 * h)
        };
        assert!((w(t) - m.angular_velocity).norm() < 1e-6, "t = {t}");
        let hh = 1e-3;
        let alpha = (w(t + hh) - w(t - hh)) / (2.0 * hh);
        assert!((alpha - m.angular_acceleration).norm() < 1e-3, "t = {t}: {alpha} vs {}", m.angular_acceleration);
    }
}

#[test]
fn leg_power_equals_the_rate_of_change_of_energy() {
    // Σ f_i l̇_i = d/dt (½ m v_c² + ½ ωᵀ I ω + m g z_c), every term of the
    // right-hand side by finite differences of positions and rotations.
    let p = lopsided();
    let g = &p.geometry;
    for traj in Trajectory::all(&p) {
        let energy = |t: f64| {
            let h = 1e-5;
            let com = |t: f64| {
                let q = traj.state(t).pose;
                q.position_m + q.rotation() * g.com_body()
            };
            let v = (com(t + h) - com(t - h)) / (2.0 * h);
            let d: Rotation3<f64> = traj.state(t + h).pose.rotation() * traj.state(t - h).pose.rotation().inverse();
            let w = vee(&d) / (2.0 * h);
            let r = traj.state(t).pose.rotation();
            let inertia = r.matrix() * g.inertia_body() * r.matrix().transpose();
            0.5 * g.payload_mass_kg * v.norm_squared() + 0.5 * w.dot(&(inertia * w)) + g.payload_mass_kg * GRAVITY_M_S2 * com(t).z
        };
        for k in 1..15 {
            let t = k as f64 * traj.duration_s / 15.0;
            let h = 1e-3;
            let de = (energy(t + h) - energy(t - h)) / (2.0 * h);
            let f = p.leg_forces(&traj.state(t)).unwrap();
            let la = p.inverse(&traj.state(t + h).pose).lengths_m;
            let lb = p.inverse(&traj.state(t - h).pose).lengths_m;
            let power: f64 = (0..6).map(|i| f.forces_n[i] * (la[i] - lb[i]) / (2.0 * h)).sum();
            assert!((power - de).abs() < 1e-3 * de.abs().max(10.0), "{} t = {t}: legs {power} W vs energy {de} W", traj.name);
        }
    }
}

#[test]
fn trajectories_stay_inside_the_workspace() {
    let p = Platform::paper();
    for traj in Trajectory::all(&p) {
        let n = (traj.duration_s * 200.0) as usize;
        for k in 0..=n {
            let t = k as f64 / 200.0;
            if let Err(e) = p.inverse_checked(&traj.state(t).pose) {
                panic!("{} at t = {t}: {e}", traj.name);
            }
        }
    }
}
