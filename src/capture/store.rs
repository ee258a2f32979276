//! Where the samples live: a static array of 16-bit cells, written by the
//! PWM interrupt through a shared reference and read by anyone once a
//! capture is done. A cell holds the `i16` code + 32768 (offset binary):
//! that is what the interrupt's saturating conversion yields, so it stores
//! it as it is, and a reader takes the 32768 off.
//!
//! The cells are `AtomicU16`: on the Cortex-M4 a relaxed store or load is a
//! plain `strh`/`ldrh`, so they cost nothing over a plain array, and the
//! store can be a `static` that both the interrupt (through the controller)
//! and thread mode hold a `&'static` to, without `unsafe`. The interrupt
//! stops writing once a capture is done (until the next configure), so a
//! reader with a [`CaptureLayout`] of a done capture sees finished values.

use core::sync::atomic::{AtomicU16, Ordering};

use super::CaptureLayout;
use crate::reason::Reason;

/// Cells in the store: 4 signals × 1024 samples, 2 × 2048 or 1 × 4096.
pub const CAPTURE_STORE_CELLS: usize = 4096;

/// 8 KiB of samples. `const`-constructible: `static CAPTURE: CaptureStore =
/// CaptureStore::new();` puts it in `.bss`.
#[derive(Debug)]
pub struct CaptureStore {
    cells: [AtomicU16; CAPTURE_STORE_CELLS],
}

impl Default for CaptureStore {
    fn default() -> Self {
        Self::new()
    }
}

impl CaptureStore {
    pub const fn new() -> Self {
        Self { cells: [const { AtomicU16::new(0) }; CAPTURE_STORE_CELLS] }
    }

    /// Every cell, for the capture to write frames into.
    pub(crate) fn all(&self) -> &[AtomicU16] {
        &self.cells
    }

    /// The code in cell `index` (0 outside the store).
    #[inline(always)]
    fn get(&self, index: usize) -> i16 {
        self.cells.get(index).map_or(0, |c| (c.load(Ordering::Relaxed) ^ 0x8000) as i16)
    }

    /// Values of `signal` (its slot in the configuration) from record sample
    /// `start` (0 = oldest) into `out`, in engineering units; returns how
    /// many (fewer than `out.len()` at the record's end).
    pub fn read(&self, layout: &CaptureLayout, signal: u8, start: u16, out: &mut [f32]) -> Result<usize, Reason> {
        let k = usize::from(signal);
        if k >= usize::from(layout.signals) {
            return Err(Reason::NoSuchSignal);
        }
        if start >= layout.length {
            return Err(Reason::StartBeyondRecord);
        }
        let (Some(&inv), Some(&offset)) = (layout.unit_per_code.get(k), layout.offset.get(k)) else {
            return Err(Reason::NoSuchSignal);
        };
        let n = out.len().min(usize::from(layout.length.saturating_sub(start)));
        let frames = usize::from(layout.samples);
        let stride = usize::from(layout.signals);
        // first_frame < samples and start < length ≤ samples: one wrap at most.
        let mut frame = usize::from(layout.first_frame).saturating_add(usize::from(start));
        if frame >= frames {
            frame = frame.saturating_sub(frames);
        }
        for v in out.iter_mut().take(n) {
            let code = self.get(frame.wrapping_mul(stride).wrapping_add(k));
            *v = f32::from(code) * inv + offset;
            frame = frame.wrapping_add(1);
            if frame >= frames {
                frame = 0;
            }
        }
        Ok(n)
    }
}
