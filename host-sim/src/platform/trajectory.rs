//! Pose trajectories with analytic derivatives: each degree of freedom is a
//! constant plus a sum of sines about the neutral pose.
//!
//! The neutral pose is the plate level at the height where every leg is at
//! mid-stroke, (l_min + l_max)/2: the home pose of Table 3 sits 38 mm of leg
//! above l_min, too low for a ±heave about it.

use super::dynamics::PoseState;
use super::kinematics::{Platform, Pose};
use nalgebra::{Vector3, Vector6};
use std::f64::consts::TAU;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Sine {
    pub amplitude: f64,
    pub frequency_hz: f64,
    pub phase_rad: f64,
}

const fn sine(amplitude: f64, frequency_hz: f64) -> Sine {
    Sine { amplitude, frequency_hz, phase_rad: 0.0 }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Trajectory {
    pub name: &'static str,
    pub duration_s: f64,
    /// q at t = 0 before the sines (m, rad).
    pub neutral: [f64; 6],
    /// Per degree of freedom (x, y, z m; roll, pitch, yaw rad).
    pub sines: [Vec<Sine>; 6],
}

impl Platform {
    /// Level, centred, every leg at mid-stroke.
    pub fn neutral(&self) -> Pose {
        let g = &self.geometry;
        let mid = 0.5 * (g.leg_min_length_m + g.leg_max_length_m);
        let horizontal = (self.joints.top[0] - self.joints.base[0]).xy().norm();
        Pose::new(Vector3::new(0.0, 0.0, (mid * mid - horizontal * horizontal).sqrt()), Vector3::zeros())
    }
}

impl Trajectory {
    pub fn state(&self, t: f64) -> PoseState {
        let mut q = Vector6::from(self.neutral);
        let mut v = Vector6::zeros();
        let mut a = Vector6::zeros();
        for (k, sines) in self.sines.iter().enumerate() {
            for s in sines {
                let w = TAU * s.frequency_hz;
                let (sn, cs) = (w * t + s.phase_rad).sin_cos();
                q[k] += s.amplitude * sn;
                v[k] += s.amplitude * w * cs;
                a[k] -= s.amplitude * w * w * sn;
            }
        }
        PoseState { pose: Pose::from_vector(&q), velocity: v, acceleration: a }
    }

    fn about(platform: &Platform, name: &'static str, duration_s: f64, sines: [Vec<Sine>; 6]) -> Self {
        Self { name, duration_s, neutral: platform.neutral().to_vector().into(), sines }
    }

    /// Heave ±0.15 m at 0.5 Hz.
    pub fn heave(p: &Platform) -> Self {
        Self::about(p, "heave", 4.0, [vec![], vec![], vec![sine(0.15, 0.5)], vec![], vec![], vec![]])
    }

    /// Roll ±10° at 0.5 Hz.
    pub fn roll(p: &Platform) -> Self {
        Self::about(p, "roll", 4.0, [vec![], vec![], vec![], vec![sine(10f64.to_radians(), 0.5)], vec![], vec![]])
    }

    /// Pitch ±10° at 0.5 Hz.
    pub fn pitch(p: &Platform) -> Self {
        Self::about(p, "pitch", 4.0, [vec![], vec![], vec![], vec![], vec![sine(10f64.to_radians(), 0.5)], vec![]])
    }

    /// A motion-cueing mix: slow tilt coordination with surge and sway,
    /// heave with a road-texture component, a small yaw.
    pub fn combined(p: &Platform) -> Self {
        let deg = |d: f64| d.to_radians();
        Self::about(
            p,
            "combined",
            10.0,
            [
                vec![sine(0.05, 0.3)],
                vec![Sine { amplitude: 0.04, frequency_hz: 0.2, phase_rad: 1.0 }],
                vec![sine(0.06, 1.0), sine(0.01, 3.1)],
                vec![Sine { amplitude: deg(5.0), frequency_hz: 0.4, phase_rad: 0.5 }],
                vec![sine(deg(6.0), 0.25), sine(deg(1.0), 2.3)],
                vec![sine(deg(4.0), 0.2)],
            ],
        )
    }

    /// The paper's stroke at leg level (§5.2: 0 → 450 mm → 0): the plate
    /// level and centred heaves so that every leg goes from
    /// l_min + `margin_m` to l_max − `margin_m` and back, one slow sine
    /// period starting at rest at the bottom. On the platform the legs'
    /// tilt follows from the geometry (it steepens as they extend); it is
    /// not the single rig's 90° → 60° → 90° schedule.
    pub fn leg_stroke(p: &Platform, margin_m: f64, period_s: f64) -> Self {
        let g = &p.geometry;
        let h = (p.joints.top[0] - p.joints.base[0]).xy().norm();
        let z = |l: f64| (l * l - h * h).sqrt();
        let (zb, zt) = (z(g.leg_min_length_m + margin_m), z(g.leg_max_length_m - margin_m));
        let heave = Sine { amplitude: 0.5 * (zt - zb), frequency_hz: 1.0 / period_s, phase_rad: -std::f64::consts::FRAC_PI_2 };
        Self {
            name: "leg_stroke",
            duration_s: period_s,
            neutral: [0.0, 0.0, 0.5 * (zb + zt), 0.0, 0.0, 0.0],
            sines: [vec![], vec![], vec![heave], vec![], vec![], vec![]],
        }
    }

    pub fn all(p: &Platform) -> Vec<Self> {
        vec![Self::heave(p), Self::roll(p), Self::pitch(p), Self::combined(p)]
    }
}
