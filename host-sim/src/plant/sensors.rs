//! What the drive measures: quantised, noisy, deterministic given the seed.
//!
//! - Phase currents: Gaussian noise, then an `adc_bits` ADC spanning
//!   ±`current_full_scale_a` (mid-code = 0 A); a current beyond the span
//!   reads as the end code, as a real ADC saturates.
//! - Bus voltage: noise, then an ADC spanning 0..`bus_voltage_full_scale_v`.
//! - Encoder: the nearest count to `θ_m · cpr/2π` (so count 0 ↔ θ_m = 0, the
//!   edges sitting half a count either side), wrapped into a u16 like an
//!   STM32 timer counter.
//! - Linear scale: rod position to the nearest `linear_scale_resolution_m`.
//! - Load cell: the force between rod and payload plus Gaussian noise.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use servo_core::SensorSample;

use super::params::SensorParams;

/// The true quantities the sensors look at.
#[derive(Clone, Copy, Debug)]
pub struct Truth {
    pub phase_current_a: [f64; 3],
    pub theta_m_rad: f64,
    pub bus_voltage_v: f64,
    pub rod_position_m: f64,
    pub load_cell_force_n: f64,
}

#[derive(Clone, Debug)]
pub struct Sensors {
    p: SensorParams,
    rng: ChaCha8Rng,
    max_code: f64,
    current_lsb: f64,
    bus_lsb: f64,
    /// What a real board brings that an ideal one does not (all off by
    /// default, so the nominal runs are unchanged):
    pub bench: BenchSensors,
}

/// Sensor facts of a real bench that the start-up steps must cope with.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BenchSensors {
    /// Mechanical angle the encoder's count zero sits at, radians: the
    /// magnets and the encoder disc are mounted with no known relation.
    pub encoder_zero_rad: f64,
    /// Amplifier bias left over after the board's own zeroing, amperes.
    pub current_offset_a: [f64; 3],
    /// A home switch that closes while the rod is at or below (direction −1)
    /// or at or above (+1) this position.
    pub home_switch: Option<(f64, i32)>,
    /// Heat-sink temperature reading, °C.
    pub power_stage_temperature_c: Option<f64>,
}

impl Sensors {
    pub fn new(p: &SensorParams, seed: u64) -> Self {
        let codes = 2f64.powi(p.adc_bits as i32);
        Self {
            p: p.clone(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            max_code: codes - 1.0,
            current_lsb: 2.0 * p.current_full_scale_a / codes,
            bus_lsb: p.bus_voltage_full_scale_v / codes,
            bench: BenchSensors::default(),
        }
    }

    /// One ADC current LSB, amperes.
    pub fn current_lsb_a(&self) -> f64 {
        self.current_lsb
    }

    fn noise(&mut self, sigma: f64) -> f64 {
        if sigma > 0.0 {
            let z: f64 = self.rng.sample(StandardNormal);
            sigma * z
        } else {
            0.0
        }
    }

    /// A bipolar ADC reading of `value` spanning ±`full_scale`.
    fn bipolar(&self, value: f64, full_scale: f64, lsb: f64) -> f64 {
        let code = ((value + full_scale) / lsb).round().clamp(0.0, self.max_code);
        code * lsb - full_scale
    }

    pub fn sample(&mut self, t: &Truth) -> SensorSample {
        let mut currents = [0f32; 3];
        for (k, out) in currents.iter_mut().enumerate() {
            let noisy = t.phase_current_a[k] + self.bench.current_offset_a[k] + self.noise(self.p.current_noise_a);
            *out = self.bipolar(noisy, self.p.current_full_scale_a, self.current_lsb) as f32;
        }
        let bus = t.bus_voltage_v + self.noise(self.p.bus_voltage_noise_v);
        let bus_code = (bus / self.bus_lsb).round().clamp(0.0, self.max_code);
        let terminal = self.p.linear_scale_enabled.then(|| {
            let res = self.p.linear_scale_resolution_m;
            ((t.rod_position_m / res).round() * res) as f32
        });
        let load = if self.p.load_cell_enabled {
            Some((t.load_cell_force_n + self.noise(self.p.load_cell_noise_n)) as f32)
        } else {
            None
        };
        SensorSample {
            phase_current_a: currents,
            encoder_count: encoder_count(t.theta_m_rad + self.bench.encoder_zero_rad, self.p.encoder_counts_per_rev),
            bus_voltage_v: (bus_code * self.bus_lsb) as f32,
            terminal_position_m: terminal,
            load_cell_force_n: load,
            home_switch: self.bench.home_switch.map(|(at_m, dir)| (t.rod_position_m - at_m) * f64::from(dir) >= 0.0),
            power_stage_temperature_c: self.bench.power_stage_temperature_c.map(|c| c as f32),
        }
    }
}

/// Nearest count to `θ · cpr / 2π`, wrapped into 16 bits.
pub fn encoder_count(theta_m_rad: f64, counts_per_rev: u32) -> u16 {
    let counts = (theta_m_rad * f64::from(counts_per_rev) / std::f64::consts::TAU).round();
    // Far beyond any stroke (±1e15 counts) the f64 → i64 cast saturates;
    // the wrap is still a valid u16.
    (counts as i64).rem_euclid(1 << 16) as u16
}
