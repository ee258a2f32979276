//! What the scope can be asked: which signals, how often, how many samples,
//! the trigger; and what it reports back.

use core::fmt;
use core::ops::Deref;

use postcard_schema::schema::{DataModelType, NamedType};
use postcard_schema::Schema;
use serde::de::{Error as _, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Signals one capture records at most.
pub const CAPTURE_SIGNALS_MAX: usize = 4;

/// The signals of one capture: up to [`CAPTURE_SIGNALS_MAX`], in order.
/// `Copy` (a fixed array and a count), so a capture request crosses the
/// lock-free link to the PWM interrupt as it is; on the wire a sequence,
/// as a `Vec` would be.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct SignalList {
    len: u8,
    items: [Signal; CAPTURE_SIGNALS_MAX],
}

impl SignalList {
    pub const EMPTY: Self = Self { len: 0, items: [Signal::CurrentQ; CAPTURE_SIGNALS_MAX] };

    /// `Err(())` for more than [`CAPTURE_SIGNALS_MAX`] signals.
    #[allow(clippy::result_unit_err)]
    pub fn from_slice(signals: &[Signal]) -> Result<Self, ()> {
        let mut list = Self::EMPTY;
        for &s in signals {
            list.push(s).map_err(|_| ())?;
        }
        Ok(list)
    }

    /// Appends `signal`; gives it back if the list is full.
    pub fn push(&mut self, signal: Signal) -> Result<(), Signal> {
        match self.items.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = signal;
                self.len = self.len.wrapping_add(1);
                Ok(())
            }
            None => Err(signal),
        }
    }
}

impl Deref for SignalList {
    type Target = [Signal];
    fn deref(&self) -> &[Signal] {
        self.items.get(..usize::from(self.len)).unwrap_or(&[])
    }
}

impl fmt::Debug for SignalList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl Serialize for SignalList {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.iter())
    }
}

impl<'de> Deserialize<'de> for SignalList {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Signals;
        impl<'de> Visitor<'de> for Signals {
            type Value = SignalList;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("at most 4 capture signals")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<SignalList, A::Error> {
                let mut list = SignalList::EMPTY;
                while let Some(s) = seq.next_element::<Signal>()? {
                    list.push(s).map_err(|_| A::Error::invalid_length(CAPTURE_SIGNALS_MAX + 1, &self))?;
                }
                Ok(list)
            }
        }
        deserializer.deserialize_seq(Signals)
    }
}

impl Schema for SignalList {
    const SCHEMA: &'static NamedType = &NamedType { name: "SignalList", ty: &DataModelType::Seq(Signal::SCHEMA) };
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
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

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct CaptureConfig {
    pub signals: SignalList,
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

