//! What the scope can be asked: which signals, how often, how many samples,
//! the trigger; and what it reports back.

use heapless::Vec;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// Signals one capture records at most.
pub const CAPTURE_SIGNALS_MAX: usize = 4;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum CaptureRequest {
    /// Signals, decimation (1 = every PWM period), samples per signal,
    /// pre-trigger samples, trigger. Arms the capture.
    Configure(CaptureConfig),
    /// Trigger now (the `Command` trigger).
    Trigger,
    Status,
    /// `count` samples of signal `signal` from sample `start` (0 = oldest).
    Read { signal: u8, start: u16, count: u8 },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct CaptureConfig {
    pub signals: Vec<Signal, CAPTURE_SIGNALS_MAX>,
    pub decimation: u16,
    pub samples: u16,
    pub pre_trigger: u16,
    pub trigger: CaptureTrigger,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum CaptureTrigger {
    /// When a test signal starts.
    TestStart,
    /// When a fault latches.
    Fault,
    /// On `CaptureRequest::Trigger` (or at once if armed with it).
    Command,
}

/// What a capture can record; each is sampled in the PWM interrupt.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum Signal {
    CurrentD,
    CurrentQ,
    CurrentQReference,
    CurrentDReference,
    VoltageD,
    VoltageQ,
    Speed,
    SpeedReference,
    MotorPosition,
    PositionCommand,
    PositionReference,
    BusVoltage,
    PhaseCurrentA,
    PhaseCurrentB,
    PhaseCurrentC,
    ElectricalAngle,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct CaptureStatus {
    pub state: CaptureState,
    pub signals: u8,
    pub samples: u16,
    /// Seconds between samples (decimation / PWM rate).
    pub sample_period_s: f32,
    /// Index of the trigger sample within the record.
    pub trigger_index: u16,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum CaptureState {
    Idle,
    Armed,
    Triggered,
    Done,
}

