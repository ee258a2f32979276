//! Current-sensor offsets, averaged with the bridge off.
//!
//! The core measures and judges them; the host (board ISR, simulator)
//! subtracts them from the phase currents it reports, so the 20 kHz path
//! of the core does not pay for the subtraction.

use crate::params::CalibrationParams;

/// The running average.
#[derive(Clone, Copy, Debug, Default)]
pub struct CurrentCalibration {
    samples: u32,
    needed: u32,
    sum_a: [f32; 3],
    sum_sq_a2: [f32; 3],
    bus_min_v: f32,
    bus_max_v: f32,
}

/// How a finished average came out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CalibrationResult {
    Pending,
    /// Offsets per phase, amperes, to subtract from later readings.
    Done { offset_a: [f32; 3] },
    /// An offset, the noise or the bus beyond its bound.
    Failed,
}

impl CurrentCalibration {
    pub fn new(needed_samples: u32) -> Self {
        Self { needed: needed_samples, bus_min_v: f32::INFINITY, bus_max_v: f32::NEG_INFINITY, ..Self::default() }
    }

    /// One sample with the bridge off.
    pub fn add(&mut self, p: &CalibrationParams, current_a: [f32; 3], bus_v: f32) -> CalibrationResult {
        for ((sum, sum_sq), i) in self.sum_a.iter_mut().zip(self.sum_sq_a2.iter_mut()).zip(current_a) {
            *sum += i;
            *sum_sq += i * i;
        }
        self.bus_min_v = crate::math::min(self.bus_min_v, bus_v);
        self.bus_max_v = crate::math::max(self.bus_max_v, bus_v);
        self.samples = self.samples.saturating_add(1);
        if self.samples < self.needed {
            return CalibrationResult::Pending;
        }
        let n = self.samples as f32;
        let mut offset_a = [0.0; 3];
        for ((offset, sum), sum_sq) in offset_a.iter_mut().zip(self.sum_a).zip(self.sum_sq_a2) {
            let mean = sum / n;
            let var = crate::math::max(sum_sq / n - mean * mean, 0.0);
            // NaN fails both tests, so a broken channel never passes.
            let ok = mean.abs() <= p.offset_max_a && crate::math::sqrt(var) <= p.noise_max_a;
            if !ok {
                return CalibrationResult::Failed;
            }
            *offset = mean;
        }
        if !(self.bus_max_v - self.bus_min_v <= p.bus_ripple_max_v) {
            return CalibrationResult::Failed;
        }
        CalibrationResult::Done { offset_a }
    }
}
