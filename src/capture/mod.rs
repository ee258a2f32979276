//! The scope: up to [`CAPTURE_SIGNALS_MAX`] signals recorded in the PWM
//! interrupt at up to the PWM rate, with decimation, a pre-trigger ring and a
//! trigger (test start, fault latch, command). docs/capture.md has the
//! signals, their scales and resolutions, and the RAM.
//!
//! Samples are stored as `i16` codes against a fixed full scale per signal
//! taken from the parameters ([`full_scale`]), interleaved one frame (all
//! signals of one sample instant) after the other in a [`CaptureStore`]
//! the controller writes through a `&'static`.
//!
//! The PWM interrupt's part is small on purpose: a sample reads each
//! slot's value and stages it as it is, in a few frames of `f32`
//! ([`PENDING_FRAMES`]); the staged frames are encoded into the ring (one
//! multiply-add and a saturating conversion a value) in a batch, at the
//! next speed-loop tick, or when the staging is full, or before anything
//! that needs the ring up to date (a trigger, the record's end). A
//! current-only period thus pays only the reads and stores; it is there
//! that the firmware serves bulk requests, so that is the period whose
//! length bounds the longest one. The rest (the pre-trigger count, the end)
//! runs only when a count-down of frames runs out; a trigger is taken where
//! it happens, outside the frame (see [`Capture::take_trigger`]). The store is separate from
//! the controller so that the controller stays small enough to build and
//! hand over on the stack, and so thread mode can read a done capture
//! straight from the store (the interrupt writes nothing once a capture is
//! done, until the next configure).
//!
//! Timing: samples sit on one grid of `decimation` PWM periods from the
//! configure on; the trigger sample is the first sample at or after the
//! trigger event (so with decimation 1, the trigger's own period). A test
//! start happens in a sampled period when the capture waits for it (see
//! `controller::scope`).

mod config;
mod store;

pub use config::{CaptureConfig, CaptureRequest, CaptureState, CaptureStatus, CaptureTrigger, Signal, SignalList, CAPTURE_SIGNALS_MAX};
pub use store::{CaptureStore, CAPTURE_STORE_CELLS};

/// The lowest code: a value at or below −full scale, or NaN (the cheap
/// conversion of the 20 kHz path does not tell them apart); it reads back
/// as −full scale · 32768/32767.
pub const NAN_CODE: i16 = i16::MIN;

use core::sync::atomic::{AtomicU16, Ordering};

use crate::params::ControlParams;
use crate::reason::Reason;

/// Largest code a finite value is stored as (the full scale).
pub const FULL_SCALE_CODE: f32 = 32_767.0;

/// Frames staged as raw values before they are encoded into the ring: the
/// frames of one speed-loop period at the default rates (a 20 kHz PWM, a
/// 5 kHz speed loop), so that with decimation 1 the batch lands in the
/// speed-loop period. A power of two: the staging index is masked, not
/// bounds-checked.
pub const PENDING_FRAMES: usize = 4;

/// Share of the stroke span added at each end of the position full scale
/// (homing and overtravel go beyond the stroke).
const POSITION_MARGIN: f32 = 0.1;

/// `(centre, half range)` in the signal's unit: a value is stored as
/// `round((v − centre) / half · 32767)`, saturating at ±32767.
pub fn full_scale(signal: Signal, p: &ControlParams) -> (f32, f32) {
    let r = &p.ratings;
    match signal {
        Signal::CurrentD
        | Signal::CurrentQ
        | Signal::CurrentQReference
        | Signal::CurrentDReference
        | Signal::PhaseCurrentA
        | Signal::PhaseCurrentB
        | Signal::PhaseCurrentC => (0.0, r.inverter_peak_current_a),
        Signal::VoltageD | Signal::VoltageQ => (0.0, r.bus_max_voltage_v),
        Signal::Speed | Signal::SpeedReference => (0.0, 2.0 * r.speed_max_rad_s),
        Signal::MotorPosition | Signal::PositionCommand | Signal::PositionReference => {
            let (lo, hi) = (p.limits.stroke_min_m, p.limits.stroke_max_m);
            ((lo + hi) * 0.5, (hi - lo) * (0.5 + POSITION_MARGIN))
        }
        // 0 … rating, with a quarter of it either side.
        Signal::BusVoltage => (0.5 * r.bus_max_voltage_v, 0.75 * r.bus_max_voltage_v),
        Signal::ElectricalAngle => (0.0, core::f32::consts::PI),
    }
}

/// One code of `signal`, in its unit.
pub fn resolution(signal: Signal, p: &ControlParams) -> f32 {
    full_scale(signal, p).1 / FULL_SCALE_CODE
}

/// What a reader needs to turn a done capture's codes back into values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureLayout {
    /// Signals per frame.
    pub signals: u8,
    pub signal: [Signal; CAPTURE_SIGNALS_MAX],
    /// Frames in the ring (the configured samples per signal).
    pub samples: u16,
    /// Ring frame of record sample 0 (the oldest).
    pub first_frame: u16,
    /// Samples per signal in the record (pre-trigger kept + post-trigger).
    pub length: u16,
    pub trigger_index: u16,
    pub sample_period_s: f32,
    pub unit_per_code: [f32; CAPTURE_SIGNALS_MAX],
    pub offset: [f32; CAPTURE_SIGNALS_MAX],
}

/// The capture's state, kept in the controller.
#[derive(Debug)]
pub struct Capture {
    /// The ring: the store's first samples × signals cells (empty until
    /// configured). Its length is the ring's end, so the frame's wrap
    /// check and bounds check compare the same two numbers.
    ring: &'static [AtomicU16],
    store: Option<&'static CaptureStore>,
    // The counters the PWM interrupt touches are words: halfwords cost a
    // zero-extension or a shift at each test.
    /// PWM periods to skip before the next sample, and its reload
    /// (decimation − 1): with decimation 1 a sampled period tests one
    /// zero and stores one.
    skip: u32,
    skip_reload: u16,
    /// Armed or triggered: the controller's `HOOK_CAPTURE` mirrors it, so
    /// the period tests the hook byte, not this.
    recording: bool,
    /// Cell of the next encoded frame's first signal (a halfword: then the
    /// frame's end cannot overflow, and that test drops out).
    write_cell: u16,
    /// Sampled frames not yet encoded, oldest first: they go to the ring
    /// from `write_cell` on. Fewer than [`PENDING_FRAMES`] between periods.
    pending: [[f32; CAPTURE_SIGNALS_MAX]; PENDING_FRAMES],
    pending_len: u32,
    /// Frames to the next change of the bookkeeping: the pre-trigger
    /// samples all in the ring (armed), the end (triggered).
    frames_to_event: u32,
    count: u8,
    state: CaptureState,
    trigger: CaptureTrigger,
    /// Armed with all its pre-trigger samples in the ring.
    pre_filled: bool,
    signal: [Signal; CAPTURE_SIGNALS_MAX],
    /// Codes per unit, and the code of 0 plus `ENCODE_OFFSET`.
    scale: [f32; CAPTURE_SIGNALS_MAX],
    bias: [f32; CAPTURE_SIGNALS_MAX],
    samples: u16,
    pre_trigger: u16,
    trigger_index: u16,
    first_frame: u16,
    length: u16,
    sample_period_s: f32,
}

impl Capture {
    pub const fn new() -> Self {
        Self {
            ring: &[],
            store: None,
            skip: 0,
            skip_reload: 0,
            recording: false,
            write_cell: 0,
            pending: [[0.0; CAPTURE_SIGNALS_MAX]; PENDING_FRAMES],
            pending_len: 0,
            frames_to_event: 0,
            count: 0,
            state: CaptureState::Idle,
            trigger: CaptureTrigger::Command,
            pre_filled: false,
            signal: [Signal::CurrentQ; CAPTURE_SIGNALS_MAX],
            scale: [0.0; CAPTURE_SIGNALS_MAX],
            bias: [0.0; CAPTURE_SIGNALS_MAX],
            samples: 0,
            pre_trigger: 0,
            trigger_index: 0,
            first_frame: 0,
            length: 0,
            sample_period_s: 0.0,
        }
    }

    pub fn attach(&mut self, store: &'static CaptureStore) {
        *self = Self::new();
        self.store = Some(store);
    }

    pub fn store(&self) -> Option<&'static CaptureStore> {
        self.store
    }

    /// True while samples are being written (armed or triggered).
    #[inline(always)]
    pub fn recording(&self) -> bool {
        self.recording
    }

    pub fn state(&self) -> CaptureState {
        self.state
    }

    /// Armed and waiting for this trigger.
    pub fn awaits(&self, trigger: CaptureTrigger) -> bool {
        self.state == CaptureState::Armed && self.trigger == trigger
    }

    /// Armed with its pre-trigger samples all in the ring.
    pub fn pre_trigger_filled(&self) -> bool {
        self.pre_filled
    }

    /// Checks `c` and arms the capture; nothing changes on refusal.
    pub fn configure(&mut self, c: &CaptureConfig, p: &ControlParams) -> Result<(), Reason> {
        let Some(store) = self.store else {
            return Err(Reason::NoCaptureStore);
        };
        let n = c.signals.len();
        if n == 0 {
            return Err(Reason::NoSignals);
        }
        if n > CAPTURE_SIGNALS_MAX {
            return Err(Reason::TooManySignals);
        }
        if c.decimation == 0 {
            return Err(Reason::DecimationZero);
        }
        if c.samples < 2 {
            return Err(Reason::TooFewSamples);
        }
        let Some(ring) = store.all().get(..usize::from(c.samples).saturating_mul(n)) else {
            return Err(Reason::CaptureBufferTooSmall);
        };
        if c.pre_trigger >= c.samples {
            return Err(Reason::PreTriggerNotBelowSamples);
        }
        let mut scale = [0.0; CAPTURE_SIGNALS_MAX];
        let mut bias = [0.0; CAPTURE_SIGNALS_MAX];
        let mut signal = [Signal::CurrentQ; CAPTURE_SIGNALS_MAX];
        for (k, &s) in c.signals.iter().enumerate() {
            let (centre, half) = full_scale(s, p);
            if !(half > 0.0 && half.is_finite() && centre.is_finite()) {
                return Err(Reason::FullScaleNotPositive);
            }
            let codes = FULL_SCALE_CODE / half;
            if let (Some(sc), Some(b), Some(sg)) = (scale.get_mut(k), bias.get_mut(k), signal.get_mut(k)) {
                *sc = codes;
                // The code of 0, plus the offset `encode` works with.
                *b = -centre * codes + ENCODE_OFFSET;
                *sg = s;
            }
        }
        // With no pre-trigger samples to wait for, the first event is
        // only a refill of the count-down (see `event`).
        let pre_filled = c.pre_trigger == 0;
        *self = Self {
            ring,
            store: self.store,
            // The first sample in the first period after the configure.
            skip: 0,
            skip_reload: c.decimation.wrapping_sub(1), // ≥ 1, checked above
            recording: true,
            write_cell: 0,
            pending: [[0.0; CAPTURE_SIGNALS_MAX]; PENDING_FRAMES],
            pending_len: 0,
            frames_to_event: if pre_filled { u32::MAX } else { u32::from(c.pre_trigger) },
            count: n as u8,
            state: CaptureState::Armed,
            trigger: c.trigger,
            pre_filled,
            signal,
            scale,
            bias,
            samples: c.samples,
            pre_trigger: c.pre_trigger,
            trigger_index: 0,
            first_frame: 0,
            length: 0,
            sample_period_s: f32::from(c.decimation) / p.rates.pwm_frequency_hz,
        };
        Ok(())
    }

    /// A trigger event of kind `kind`: taken if the capture is armed for it.
    pub fn event(&mut self, kind: CaptureTrigger) {
        if self.awaits(kind) {
            self.take_trigger();
        }
    }

    /// Triggers an armed capture at its next sample, whatever it waits for.
    pub fn trigger_now(&mut self) -> Result<(), Reason> {
        if self.state != CaptureState::Armed {
            return Err(Reason::CaptureNotArmed);
        }
        self.take_trigger();
        Ok(())
    }

    /// Counts one PWM period of a recording capture (the caller knows it
    /// records); true when this period is sampled.
    #[inline(always)]
    pub fn tick(&mut self) -> bool {
        if self.skip != 0 {
            self.skip = self.skip.wrapping_sub(1);
            return false;
        }
        self.skip = u32::from(self.skip_reload);
        true
    }

    /// The signals this capture records, in slot order.
    pub fn signals(&self) -> &[Signal] {
        self.signal.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// Slot `K`'s signal.
    #[inline(always)]
    pub fn signal<const K: usize>(&self) -> Signal {
        self.signal.get(K).copied().unwrap_or(Signal::CurrentQ)
    }

    /// Makes the next frame written the trigger sample: the first sample
    /// at or after the event. Taken where the event happens (a command,
    /// a fault, a test's start), not in the frame: nothing the frame
    /// reads (the write position, the frame count-down) changes between
    /// the event and the next sample, so the record is the same as if it
    /// were taken there, and the sampled period tests nothing for it.
    #[cold]
    #[inline(never)]
    fn take_trigger(&mut self) {
        // The write position below is the ring's: staged frames first.
        self.flush();
        self.state = CaptureState::Triggered;
        // Armed, `frames_to_event` counts down to the pre-trigger
        // samples all in: fewer than `pre_trigger` written until then.
        let filled = if self.pre_filled { self.pre_trigger } else { self.pre_trigger.wrapping_sub(self.frames_to_event as u16) };
        self.trigger_index = filled;
        // The next frame is the trigger sample: write_cell / signals, and
        // trigger_index ≤ pre_trigger < samples.
        let write_frame = self.write_cell.checked_div(u16::from(self.count)).unwrap_or(0);
        self.first_frame = if write_frame >= filled {
            write_frame.wrapping_sub(filled)
        } else {
            write_frame.wrapping_add(self.samples).wrapping_sub(filled)
        };
        let post = self.samples.wrapping_sub(self.pre_trigger);
        self.length = filled.wrapping_add(post);
        // From the trigger sample on, `post` frames to the end.
        self.frames_to_event = u32::from(post);
    }

    /// Stages one sampled frame (slot `k`'s value in `values[k]`; slots
    /// beyond the configured count are ignored); true when the staging is
    /// full and must be [flushed](Self::flush) before the next frame.
    #[inline(always)]
    pub fn stage(&mut self, values: [f32; CAPTURE_SIGNALS_MAX]) -> bool {
        // Below PENDING_FRAMES (a flush follows a full staging); the mask
        // keeps the index in bounds without a check.
        let j = self.pending_len as usize & (PENDING_FRAMES - 1);
        if let Some(frame) = self.pending.get_mut(j) {
            *frame = values;
        }
        self.pending_len = self.pending_len.wrapping_add(1);
        self.pending_len as usize >= PENDING_FRAMES
    }

    /// Encodes the staged frames into the ring, oldest first.
    #[inline(never)]
    pub fn flush(&mut self) {
        // One copy per signal count, its slots written out: the core is
        // built for size, so the compiler would keep a loop over them. The
        // count is 1 to 4: `& 3` makes the four cases a jump table (4 → 0).
        match self.count & 3 {
            0 => self.flush_frames::<4>(),
            1 => self.flush_frames::<1>(),
            2 => self.flush_frames::<2>(),
            _ => self.flush_frames::<3>(),
        }
    }

    /// [`Self::flush`] for `N` (the configured count) signals: each frame
    /// with one wrap check and one bounds check (on the same compare; it
    /// never fails, the ring being whole frames).
    #[inline(always)]
    fn flush_frames<const N: usize>(&mut self) {
        let len = (self.pending_len as usize).min(PENDING_FRAMES);
        self.pending_len = 0;
        // Held in registers over the frames, not reloaded for each.
        let (scale, bias) = (self.scale, self.bias);
        for j in 0..len {
            let at = usize::from(self.write_cell);
            let next = at.wrapping_add(N);
            self.write_cell = if next >= self.ring.len() { 0 } else { next as u16 };
            if let (Some(cells), Some(values)) = (self.ring.get(at..next), self.pending.get(j)) {
                put::<0>(cells, values, &scale, &bias);
                if N > 1 {
                    put::<1>(cells, values, &scale, &bias);
                }
                if N > 2 {
                    put::<2>(cells, values, &scale, &bias);
                }
                if N > 3 {
                    put::<3>(cells, values, &scale, &bias);
                }
            }
        }
    }

    /// Whether the next PWM period of a recording capture encodes a batch
    /// into the ring: it is sampled (no skip left) and either fills the
    /// staging or is the record's last sample (the end flushes and closes
    /// the record there). Such a period is the capture's longest (≈ 225
    /// instructions above a plain current-loop period).
    #[inline(always)]
    pub fn flushes_next_period(&self) -> bool {
        self.recording
            && self.skip == 0
            && (self.pending_len as usize >= PENDING_FRAMES - 1 || (self.state == CaptureState::Triggered && self.frames_to_event == 1))
    }

    /// Ends a frame; true when the frame count-down ran out: the caller
    /// then calls [`Self::frames_event`] (out of line, from the caller so
    /// that the frame's code keeps no pointer to the capture for it).
    #[inline(always)]
    pub fn advance(&mut self) -> bool {
        self.frames_to_event = self.frames_to_event.wrapping_sub(1);
        self.frames_to_event == 0
    }

    /// The frame count-down ran out: the pre-trigger samples are all in
    /// (armed), or the record is complete (triggered). False once done.
    pub fn frames_event(&mut self) -> bool {
        if self.state == CaptureState::Triggered {
            // Done: the record whole in the ring before anyone may read it.
            self.flush();
            self.state = CaptureState::Done;
            self.recording = false;
            return false;
        }
        // Armed: the pre-trigger part of the ring is full; nothing more to
        // count until the trigger (a refill every 2³² − 1 frames).
        self.pre_filled = true;
        self.frames_to_event = u32::MAX;
        true
    }

    pub fn status(&self) -> CaptureStatus {
        CaptureStatus {
            state: self.state,
            signals: self.count,
            samples: if self.state == CaptureState::Done { self.length } else { self.samples },
            sample_period_s: self.sample_period_s,
            trigger_index: self.trigger_index,
        }
    }

    /// The layout of a done capture.
    pub fn layout(&self) -> Result<CaptureLayout, Reason> {
        if self.state != CaptureState::Done {
            return Err(Reason::CaptureNotDone);
        }
        let mut unit_per_code = [0.0; CAPTURE_SIGNALS_MAX];
        let mut offset = [0.0; CAPTURE_SIGNALS_MAX];
        for k in 0..CAPTURE_SIGNALS_MAX {
            if let (Some(u), Some(o), Some(&sc), Some(&b)) = (unit_per_code.get_mut(k), offset.get_mut(k), self.scale.get(k), self.bias.get(k)) {
                if sc > 0.0 {
                    *u = 1.0 / sc;
                    *o = -(b - ENCODE_OFFSET) / sc;
                }
            }
        }
        Ok(CaptureLayout {
            signals: self.count,
            signal: self.signal,
            samples: self.samples,
            first_frame: self.first_frame,
            length: self.length,
            trigger_index: self.trigger_index,
            sample_period_s: self.sample_period_s,
            unit_per_code,
            offset,
        })
    }

    /// Reads `out.len()` values (or to the record's end) of slot `signal`
    /// from record sample `start` (0 = oldest).
    pub fn read(&self, signal: u8, start: u16, out: &mut [f32]) -> Result<usize, Reason> {
        let layout = self.layout()?;
        let store = self.store.ok_or(Reason::NoCaptureStore)?;
        store.read(&layout, signal, start, out)
    }
}

impl Default for Capture {
    fn default() -> Self {
        Self::new()
    }
}

/// Slot `K`'s staged value, encoded, into its cell of `frame`.
#[inline(always)]
fn put<const K: usize>(frame: &[AtomicU16], values: &[f32; CAPTURE_SIGNALS_MAX], scale: &[f32; CAPTURE_SIGNALS_MAX], bias: &[f32; CAPTURE_SIGNALS_MAX]) {
    if let (Some(cell), Some(&v), Some(&scale), Some(&bias)) = (frame.get(K), values.get(K), scale.get(K), bias.get(K)) {
        cell.store(encode(v, scale, bias), Ordering::Relaxed);
    }
}

/// Added to `v·scale + bias` so the code is a non-negative number whose
/// truncation is the rounded code + 32768.
const ENCODE_OFFSET: f32 = 32_768.5;

/// `round(v·scale + bias)` (halves up), saturated to [−32768, 32767], as
/// the store keeps it: + 32768, in a `u16` ([`CaptureStore`]). NaN gives
/// −32768 ([`NAN_CODE`]). One multiply-add, the FPU's saturating
/// conversion (`vcvt.s32.f32`: NaN to 0) and one `usat` to [0, 65535]:
/// where the biased value is positive, truncation is the floor.
#[inline(always)]
fn encode(v: f32, scale: f32, bias: f32) -> u16 {
    // `bias` includes ENCODE_OFFSET (set at configure).
    ((v * scale + bias) as i32).clamp(0, 65_535) as u16
}
