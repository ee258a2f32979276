//! Truth rigs on the full simulator: the shipped nominal rig with one or two
//! `UnmodelledEffects` switched on (random, physically plausible values), in
//! closed loop with the firmware's control core, driven through the core's
//! planner on a random identification experiment
//! (`host_sim::scenario::identification`) and logged from its telemetry.
//! The diagnosis only ever sees the nominal `RigConfig` and the log.

use super::TrueEffect;
use host_sim::config::RigConfig;
use host_sim::diagnose::effects::Effect;
use host_sim::diagnose::log::Log;
use host_sim::plant::UnmodelledEffects;
use host_sim::scenario::identification::{run, Experiment};

pub fn nominal_rig() -> RigConfig {
    RigConfig::nominal().expect("shipped rig")
}

/// The plant's effect set for library effects with their true parameters
/// (the library's parameter meaning; dead time is drawn as a per-phase
/// voltage and given to the plant as a time).
pub fn plant_effects(rig: &RigConfig, truth: &[TrueEffect]) -> UnmodelledEffects {
    let mut u = UnmodelledEffects::default();
    for t in truth {
        let q = &t.params;
        match t.effect {
            Effect::CoulombAsym => (u.coulomb_pos_n_m, u.coulomb_neg_n_m) = (q[0], q[1]),
            Effect::ViscousAsym => {
                (u.viscous_pos_n_m_s_rad, u.viscous_neg_n_m_s_rad) = (q[0], q[1])
            }
            Effect::Stribeck => (u.stribeck_torque_n_m, u.stribeck_speed_rad_s) = (q[0], t.hyper),
            Effect::Backlash => u.backlash_m = q[0],
            Effect::ScrewStiffness => u.screw_compliance_m_per_n_m = q[0],
            Effect::HertzContact => u.contact_coefficient_m_per_n2_3 = q[0],
            Effect::CouplingCompliance => u.coupling_compliance_rad_per_n_m = q[0],
            Effect::LeadErrorCumulative => u.lead_error_m_per_m = q[0],
            Effect::LeadErrorPerRev => (u.lead_sin_m, u.lead_cos_m) = (q[0], q[1]),
            Effect::ThermalDrift => u.thermal_strain_per_s = q[0],
            Effect::Cogging => {
                (
                    u.cogging_sin_n_m,
                    u.cogging_cos_n_m,
                    u.cogging_periods_per_rev,
                ) = (q[0], q[1], t.hyper)
            }
            Effect::DeadTime => {
                u.dead_time_s = q[0]
                    / (rig.plant.integration.pwm_frequency_hz
                        * rig.plant.inverter.nominal_bus_voltage_v)
            }
            Effect::CurrentSensor => {
                (
                    u.current_gain_error,
                    u.current_offset_alpha_a,
                    u.current_offset_beta_a,
                ) = (q[0], q[1], q[2])
            }
            Effect::EncoderEccentricity => {
                (u.encoder_ecc_sin_rad, u.encoder_ecc_cos_rad) = (q[0], q[1])
            }
            Effect::LoadOffset => u.load_offset_n = q[0],
        }
    }
    u
}

/// A log of the truth rig on random experiment `seed` (`duration_s` logged).
pub fn truth_log(rig: &RigConfig, truth: &[TrueEffect], seed: u64, duration_s: f64) -> Log {
    let exp = Experiment::random(rig, seed, duration_s);
    run(rig, &plant_effects(rig, truth), &exp, seed)
        .unwrap_or_else(|e| panic!("truth rig {truth:?}, seed {seed}: {e}"))
}
