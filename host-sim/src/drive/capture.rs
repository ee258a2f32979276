//! Interim capture buffer of the simulated drive, sampled every PWM period
//! from the controller and the plant. Stands in for the core's
//! `Controller::capture_*` (branch core-scope) until that is merged; the
//! protocol side (configure, trigger, status, read in chunks) is the same.

use crate::sim::ClosedLoop;
use servo_core::protocol::{CaptureConfig, CaptureState, CaptureStatus, CaptureTrigger, Signal};

/// Samples per signal the interim buffer holds at most.
pub const SAMPLES_MAX: usize = 8192;

#[derive(Debug, Default)]
pub struct Capture {
    config: Option<CaptureConfig>,
    state: Option<CaptureState>,
    /// Ring of rows (one value per signal).
    rows: Vec<[f32; 4]>,
    head: usize,
    filled: usize,
    after_trigger: usize,
    tick: u32,
    pwm_hz: f32,
}

impl Capture {
    pub fn configure(&mut self, c: CaptureConfig, pwm_hz: f32) -> Result<(), String> {
        if c.signals.is_empty() {
            return Err("no signals".into());
        }
        if c.samples == 0 || usize::from(c.samples) > SAMPLES_MAX {
            return Err(format!("samples must be 1..={SAMPLES_MAX}"));
        }
        if c.pre_trigger >= c.samples || c.decimation == 0 {
            return Err("pre_trigger < samples and decimation >= 1 needed".into());
        }
        self.rows = vec![[0.0; 4]; usize::from(c.samples)];
        self.head = 0;
        self.filled = 0;
        self.after_trigger = 0;
        self.tick = 0;
        self.pwm_hz = pwm_hz;
        self.config = Some(c);
        self.state = Some(CaptureState::Armed);
        Ok(())
    }

    pub fn trigger(&mut self) -> Result<(), String> {
        match self.state {
            Some(CaptureState::Armed) => {
                self.state = Some(CaptureState::Triggered);
                Ok(())
            }
            _ => Err("not armed".into()),
        }
    }

    /// A test signal started (the `TestStart` trigger).
    pub fn test_started(&mut self) {
        if self.config.as_ref().is_some_and(|c| c.trigger == CaptureTrigger::TestStart) {
            let _ = self.trigger();
        }
    }

    pub fn status(&self) -> CaptureStatus {
        let (signals, samples, dec, pre) = self
            .config
            .as_ref()
            .map_or((0, 0, 1, 0), |c| (c.signals.len() as u8, c.samples, c.decimation, c.pre_trigger));
        CaptureStatus {
            state: self.state.unwrap_or(CaptureState::Idle),
            signals,
            samples,
            sample_period_s: f32::from(dec) / self.pwm_hz.max(1.0),
            trigger_index: pre,
        }
    }

    /// One PWM period.
    pub fn sample(&mut self, cl: &ClosedLoop) {
        let Some(c) = &self.config else { return };
        let state = self.state.unwrap_or(CaptureState::Idle);
        if !matches!(state, CaptureState::Armed | CaptureState::Triggered) {
            return;
        }
        if state == CaptureState::Armed && c.trigger == CaptureTrigger::Fault && !cl.controller.faults().is_empty() {
            self.state = Some(CaptureState::Triggered);
        }
        self.tick += 1;
        if self.tick < u32::from(c.decimation) {
            return;
        }
        self.tick = 0;
        let mut row = [0.0f32; 4];
        for (slot, s) in row.iter_mut().zip(&c.signals) {
            *slot = read(cl, *s);
        }
        let n = self.rows.len();
        self.rows[self.head] = row;
        self.head = (self.head + 1) % n;
        self.filled = (self.filled + 1).min(n);
        if self.state == Some(CaptureState::Triggered) {
            self.after_trigger += 1;
            if self.after_trigger >= usize::from(c.samples - c.pre_trigger) && self.filled == n {
                self.state = Some(CaptureState::Done);
            }
        } else if self.filled > usize::from(c.pre_trigger) {
            // Keep only the pre-trigger history until the trigger.
            self.filled = usize::from(c.pre_trigger);
        }
    }

    pub fn read(&self, signal: u8, start: u16, count: u8) -> Result<Vec<f32>, String> {
        if self.state != Some(CaptureState::Done) {
            return Err("capture not done".into());
        }
        let c = self.config.as_ref().ok_or("not configured")?;
        if usize::from(signal) >= c.signals.len() {
            return Err(format!("signal {signal} not captured"));
        }
        let n = self.rows.len();
        let (start, count) = (usize::from(start), usize::from(count));
        if start + count > n {
            return Err(format!("samples {start}..{} beyond {n}", start + count));
        }
        // Oldest row sits at head once the ring is full.
        Ok((start..start + count).map(|i| self.rows[(self.head + i) % n][usize::from(signal)]).collect())
    }
}

fn read(cl: &ClosedLoop, s: Signal) -> f32 {
    let t = cl.controller.telemetry();
    let p = cl.sampled_state();
    match s {
        Signal::CurrentD => p.i_d_a as f32,
        Signal::CurrentQ => p.i_q_a as f32,
        Signal::CurrentQReference => t.current_q_reference_a,
        Signal::CurrentDReference => 0.0,
        Signal::VoltageD => t.voltage_d_v,
        Signal::VoltageQ => t.voltage_q_v,
        Signal::Speed => cl.controller.speed_rad_s(),
        Signal::SpeedReference => t.speed_reference_rad_s,
        Signal::MotorPosition => cl.controller.motor_position_m(),
        Signal::PositionCommand => t.position_command_m,
        Signal::PositionReference => t.position_reference_m,
        Signal::BusVoltage => t.bus_voltage_v,
        Signal::PhaseCurrentA => p.phase_current_a[0] as f32,
        Signal::PhaseCurrentB => p.phase_current_a[1] as f32,
        Signal::PhaseCurrentC => p.phase_current_a[2] as f32,
        Signal::ElectricalAngle => cl.controller.electrical_angle_rad(),
    }
}
