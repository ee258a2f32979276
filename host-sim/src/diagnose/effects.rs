//! The library of candidate unmodelled effects. Each is a parameterised
//! extension of the nominal model, linear in its parameters once its
//! (optional) shape parameter is fixed from a grid: `regressors` gives, for
//! every parameter, its contribution to each residual channel at a sample.

use super::residual::{
    backlash_grid_m, sg_smooth_gain, Nominal, Segment, NCH, POSITION, TORQUE, VOLTAGE,
};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    CoulombAsym,
    ViscousAsym,
    Stribeck,
    Backlash,
    ScrewStiffness,
    HertzContact,
    CouplingCompliance,
    LeadErrorCumulative,
    LeadErrorPerRev,
    ThermalDrift,
    Cogging,
    DeadTime,
    CurrentSensor,
    EncoderEccentricity,
    LoadOffset,
}

pub const ALL: [Effect; 15] = [
    Effect::CoulombAsym,
    Effect::ViscousAsym,
    Effect::Stribeck,
    Effect::Backlash,
    Effect::ScrewStiffness,
    Effect::HertzContact,
    Effect::CouplingCompliance,
    Effect::LeadErrorCumulative,
    Effect::LeadErrorPerRev,
    Effect::ThermalDrift,
    Effect::Cogging,
    Effect::DeadTime,
    Effect::CurrentSensor,
    Effect::EncoderEccentricity,
    Effect::LoadOffset,
];

/// Most parameters of any effect.
pub const MAXP: usize = 3;

impl Effect {
    pub fn name(self) -> &'static str {
        match self {
            Effect::CoulombAsym => "coulomb_asym",
            Effect::ViscousAsym => "viscous_asym",
            Effect::Stribeck => "stribeck",
            Effect::Backlash => "backlash",
            Effect::ScrewStiffness => "screw_stiffness",
            Effect::HertzContact => "hertz_contact",
            Effect::CouplingCompliance => "coupling_compliance",
            Effect::LeadErrorCumulative => "lead_error_cumulative",
            Effect::LeadErrorPerRev => "lead_error_per_rev",
            Effect::ThermalDrift => "thermal_drift",
            Effect::Cogging => "cogging",
            Effect::DeadTime => "dead_time",
            Effect::CurrentSensor => "current_sensor",
            Effect::EncoderEccentricity => "encoder_eccentricity",
            Effect::LoadOffset => "load_offset",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            Effect::CoulombAsym => "extra Coulomb friction torque, different per direction: c₊·s₊ + c₋·s₋",
            Effect::ViscousAsym => "extra viscous friction, different per direction: b₊·ω₊ + b₋·ω₋",
            Effect::Stribeck => "Stribeck (breakaway) friction T_s·exp(−(ω/ω_s)²)·sgn ω, ω_s on a grid",
            Effect::Backlash => {
                "lost motion b: the rod rests on the flank the nut force pushes it to (physical nominal), or follows the motor side through a play of width b (play operator, b on a grid; regression nominal)"
            }
            Effect::ScrewStiffness => "position-dependent screw compliance: extra deflection c·F·x",
            Effect::HertzContact => "nonlinear (Hertz) contact: extra deflection C·sgn F·((|F|+F_p)^⅔ − F_p^⅔)",
            Effect::CouplingCompliance => "coupling torsional compliance: rod lags by (L/2π)·T_shaft/k_c",
            Effect::LeadErrorCumulative => "cumulative lead error: terminal gains ε·(motor-side travel)",
            Effect::LeadErrorPerRev => "once-per-revolution lead error a·sin θ + b·cos θ",
            Effect::ThermalDrift => "thermal expansion drift: terminal gains κ·x·t (screw warming over the run)",
            Effect::Cogging => "cogging torque a·sin nθ + b·cos nθ, n (periods per revolution) on a grid",
            Effect::DeadTime => "inverter dead time: q-voltage error V_dt·sgn(i_q)",
            Effect::CurrentSensor => "current-sensor gain g and offsets (o_α, o_β): i_meas = g·i + o rotated to q",
            Effect::EncoderEccentricity => "encoder eccentricity: θ_meas = θ + e_c sin θ + e_s cos θ",
            Effect::LoadOffset => "external load offset ΔF (constant unmeasured force)",
        }
    }

    pub fn params(self) -> &'static [&'static str] {
        match self {
            Effect::CoulombAsym => &["coulomb_pos_n_m", "coulomb_neg_n_m"],
            Effect::ViscousAsym => &["viscous_pos_n_m_s_rad", "viscous_neg_n_m_s_rad"],
            Effect::Stribeck => &["stribeck_torque_n_m"],
            Effect::Backlash => &["lost_motion_m"],
            Effect::ScrewStiffness => &["compliance_m_per_n_m"],
            Effect::HertzContact => &["contact_coefficient_m_per_n2_3"],
            Effect::CouplingCompliance => &["compliance_rad_per_n_m"],
            Effect::LeadErrorCumulative => &["lead_error_m_per_m"],
            Effect::LeadErrorPerRev => &["sin_amplitude_m", "cos_amplitude_m"],
            Effect::ThermalDrift => &["drift_m_per_m_s"],
            Effect::Cogging => &["sin_torque_n_m", "cos_torque_n_m"],
            Effect::DeadTime => &["dead_time_voltage_v"],
            Effect::CurrentSensor => &["gain_error", "offset_alpha_a", "offset_beta_a"],
            Effect::EncoderEccentricity => &["eccentricity_sin_rad", "eccentricity_cos_rad"],
            Effect::LoadOffset => &["load_offset_n"],
        }
    }

    /// Parameter names with the units of the log's own channels. With the
    /// rig's physics the torque channel is N·m; with a regression nominal
    /// (`--reference`) it is the logged current (A), the position channel
    /// the tracking error (m) and speed the rod's (m/s): nothing borrows a
    /// lead or torque constant the rig does not have.
    pub fn params_for(self, nominal: &Nominal) -> Vec<String> {
        if matches!(nominal, Nominal::Physics(_)) {
            return self.params().iter().map(|p| p.to_string()).collect();
        }
        let names: &[&str] = match self {
            Effect::CoulombAsym => &["coulomb_pos_a", "coulomb_neg_a"],
            Effect::ViscousAsym => &["viscous_pos_a_s_per_m", "viscous_neg_a_s_per_m"],
            Effect::Stribeck => &["stribeck_current_a"],
            Effect::LoadOffset => &["current_offset_a"],
            Effect::Cogging => &["sin_current_a", "cos_current_a"],
            Effect::HertzContact => &["contact_coefficient_m_per_n2_3_at_500n_preload"],
            _ => self.params(),
        };
        names.iter().map(|p| p.to_string()).collect()
    }

    /// The shape parameter's name for this nominal (regression: the
    /// Stribeck speed is the rod's, m/s).
    pub fn grid_name_for(self, nominal: &Nominal) -> Option<&'static str> {
        match (self, nominal) {
            (Effect::Stribeck, Nominal::Regression(_)) => Some("stribeck_speed_m_s"),
            _ => self.grid_for(nominal).map(|g| g.0),
        }
    }

    /// Shape parameter on a grid for this nominal, if any: with the
    /// physical model the lost motion follows the nut force (`flank`) and
    /// is linear in the play, with no shape to search.
    pub fn grid_for(self, nominal: &Nominal) -> Option<(&'static str, Vec<f64>)> {
        match (self, nominal) {
            (Effect::Backlash, Nominal::Physics(_)) => None,
            // The rod's speed, m/s (0.4 mm/s … 40 mm/s).
            (Effect::Stribeck, Nominal::Regression(_)) => Some((
                "stribeck_speed_m_s",
                (0..=24).map(|k| 4e-4 * 1.2f64.powi(k)).collect(),
            )),
            _ => self.grid(),
        }
    }

    /// Shape parameter on a grid, if any.
    pub fn grid(self) -> Option<(&'static str, Vec<f64>)> {
        match self {
            Effect::Stribeck => Some((
                "stribeck_speed_rad_s",
                (0..=24).map(|k| 0.5 * 1.2f64.powi(k)).collect(),
            )),
            Effect::Backlash => Some(("play_shape_m", backlash_grid_m())),
            Effect::Cogging => Some(("periods_per_rev", (2..=72).map(f64::from).collect())),
            _ => None,
        }
    }

    /// Channels the effect shows in.
    pub fn channels(self) -> &'static [usize] {
        match self {
            Effect::CoulombAsym
            | Effect::ViscousAsym
            | Effect::Stribeck
            | Effect::Cogging
            | Effect::CurrentSensor => &[TORQUE],
            Effect::LoadOffset | Effect::EncoderEccentricity => &[TORQUE, POSITION],
            Effect::DeadTime => &[VOLTAGE],
            _ => &[POSITION],
        }
    }

    /// Why the effect cannot be tested on these segments, if so.
    pub fn not_applicable(self, seg: &Segment, nominal: &Nominal) -> Option<String> {
        let phys = matches!(nominal, Nominal::Physics(_));
        // Once per revolution needs a revolution: without an encoder a
        // regression nominal has no lead to turn the rod travel into turns.
        let needs_encoder = matches!(
            self,
            Effect::Cogging | Effect::EncoderEccentricity | Effect::CurrentSensor
        ) || (self == Effect::LeadErrorPerRev && !phys);
        if needs_encoder && !seg.encoder {
            return Some("needs the motor angle (encoder) in the log".into());
        }
        let needs_phys = matches!(
            self,
            Effect::EncoderEccentricity
                | Effect::CouplingCompliance
                | Effect::CurrentSensor
                | Effect::DeadTime
        );
        if needs_phys && !phys {
            return Some(
                "needs the rig's physical model (a regression nominal has no torque constant or inertia)".into(),
            );
        }
        let chans = self.channels();
        if chans.iter().all(|c| seg.r[*c].is_none()) {
            let names: Vec<&str> = chans
                .iter()
                .map(|c| super::residual::CHANNELS[*c])
                .collect();
            return Some(format!(
                "the {} residual is not available from the logged columns",
                names.join("/")
            ));
        }
        None
    }

    /// Regressor values of every parameter on every channel at sample i.
    pub fn regressors(
        self,
        hyper: f64,
        seg: &Segment,
        i: usize,
        nominal: &Nominal,
        out: &mut [[f64; NCH]; MAXP],
    ) {
        *out = [[0.0; NCH]; MAXP];
        let (om, th) = (seg.omega[i], seg.theta[i]);
        let sgn = match nominal {
            Nominal::Physics(p) => p.sgn(om),
            Nominal::Regression(r) => (seg.v[i] / r.v_eps).tanh(),
        };
        let (k, j_eq, kt, pp) = match nominal {
            Nominal::Physics(p) => (p.k, p.j_eq(), p.kt, p.pole_pairs),
            Nominal::Regression(_) => (0.005 / std::f64::consts::TAU, 0.0, 1.0, 1.0),
        };
        let f = seg.f_ax[i];
        match self {
            Effect::CoulombAsym => {
                out[0][TORQUE] = sgn.max(0.0);
                out[1][TORQUE] = sgn.min(0.0);
            }
            Effect::ViscousAsym => {
                let w = if matches!(nominal, Nominal::Physics(_)) {
                    om
                } else {
                    seg.v[i]
                };
                out[0][TORQUE] = w.max(0.0);
                out[1][TORQUE] = w.min(0.0);
            }
            Effect::Stribeck => {
                let w = if matches!(nominal, Nominal::Physics(_)) {
                    om
                } else {
                    seg.v[i]
                };
                out[0][TORQUE] = (-(w / hyper).powi(2)).exp() * sgn;
            }
            Effect::Backlash => {
                out[0][POSITION] = match nominal {
                    Nominal::Physics(_) => seg.flank.get(i).copied().unwrap_or(-0.5 * seg.dir[i]),
                    Nominal::Regression(_) => {
                        let k = backlash_grid_m()
                            .iter()
                            .position(|b| *b == hyper)
                            .unwrap_or(0);
                        seg.play.get(k).map_or(-0.5 * seg.dir[i], |p| p[i])
                    }
                };
            }
            Effect::ScrewStiffness => out[0][POSITION] = -f * seg.x[i],
            Effect::HertzContact => {
                let fp = match nominal {
                    Nominal::Physics(p) => p.contact_preload_n,
                    Nominal::Regression(_) => 500.0,
                };
                out[0][POSITION] =
                    -f.signum() * ((f.abs() + fp).powf(2.0 / 3.0) - fp.powf(2.0 / 3.0));
            }
            Effect::CouplingCompliance => {
                let t_shaft =
                    seg.y[TORQUE].as_ref().map_or(0.0, |y| y[i]) - j_eq_rot(nominal) * seg.alpha[i];
                out[0][POSITION] = -k * t_shaft;
            }
            Effect::LeadErrorCumulative => {
                out[0][POSITION] = match nominal {
                    Nominal::Physics(_) => k * th,
                    // The rod's own travel, not a default lead × angle.
                    Nominal::Regression(_) => seg.x[i],
                }
            }
            Effect::LeadErrorPerRev => {
                out[0][POSITION] = th.sin();
                out[1][POSITION] = th.cos();
            }
            Effect::ThermalDrift => out[0][POSITION] = seg.x[i] * seg.t_rel[i],
            Effect::Cogging => {
                // The torque residual is Savitzky–Golay smoothed: so is the
                // regressor (gain at its frequency).
                let g = sg_smooth_gain(seg.sg_m, hyper * om * seg.dt);
                out[0][TORQUE] = g * (hyper * th).sin();
                out[1][TORQUE] = g * (hyper * th).cos();
            }
            Effect::DeadTime => out[0][VOLTAGE] = (seg.iq[i] / 0.1).tanh(),
            Effect::CurrentSensor => {
                let the = pp * th;
                let g = sg_smooth_gain(seg.sg_m, pp * om * seg.dt);
                out[0][TORQUE] = kt * seg.iq[i];
                out[1][TORQUE] = -g * kt * the.sin();
                out[2][TORQUE] = g * kt * the.cos();
            }
            Effect::EncoderEccentricity => {
                let (s, c) = th.sin_cos();
                let al = seg.alpha[i];
                let w2 = om * om;
                // d²/dt² sin θ and cos θ.
                let dds = c * al - s * w2;
                let ddc = -s * al - c * w2;
                // The rod follows the nut's once-per-revolution ripple through
                // the drive train's axial spring: a mass on a spring shaken at
                // Ω = |ω| answers with the gain H of its mode (ω_r² = 1/(c m));
                // H → 1 slow (rigid body), and turns negative above the mode.
                let (j_rot, m_k2, cm, h) = match nominal {
                    // The rod's inertial force is measured (scale): only
                    // the rotor's inertia sees the ripple in the torque,
                    // and the deflection it causes is in the nut force.
                    Nominal::Physics(p) if seg.rod_from_scale => (p.j_rot, 0.0, 0.0, 0.0),
                    Nominal::Physics(p) => {
                        let r = om * om * seg.c_loc[i] * p.m_moving;
                        let z = p.rod_damping_ratio(seg.c_loc[i]);
                        let h = (1.0 - r) / ((1.0 - r).powi(2) + 4.0 * z * z * r);
                        (
                            p.j_rot,
                            p.m_moving * p.k * p.k,
                            seg.c_loc[i] * p.m_moving * p.k,
                            h,
                        )
                    }
                    Nominal::Regression(_) => (j_eq, 0.0, 0.0, 1.0),
                };
                // The torque residual is Savitzky–Golay smoothed (the current,
                // or the acceleration): so is the once-per-revolution ripple.
                let g = sg_smooth_gain(seg.sg_m, om * seg.dt);
                let j_ripple = g * (j_rot + m_k2 * h);
                let cm = cm * h;
                out[0][TORQUE] = -j_ripple * dds;
                out[1][TORQUE] = -j_ripple * ddc;
                out[0][POSITION] = -k * s + cm * dds;
                out[1][POSITION] = -k * c + cm * ddc;
            }
            Effect::LoadOffset => match nominal {
                Nominal::Physics(p) => {
                    out[0][TORQUE] = k * (1.0 + p.mu * sgn * f.signum());
                    out[0][POSITION] = -seg.c_loc[i];
                }
                // No lead and no compliance known: a constant offset of the
                // logged current (A), nothing in the tracking error.
                Nominal::Regression(_) => out[0][TORQUE] = 1.0,
            },
        }
    }
}

fn j_eq_rot(nominal: &Nominal) -> f64 {
    match nominal {
        Nominal::Physics(p) => p.j_rot,
        Nominal::Regression(_) => 0.0,
    }
}

pub fn by_name(name: &str) -> Option<Effect> {
    ALL.iter().copied().find(|e| e.name() == name)
}
