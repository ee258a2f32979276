//! The six legs' PWM periods between two couplings, on the calling thread
//! and one helper that lives through the run.
//!
//! Each position-loop period (1 kHz) the legs are put into shared slots and
//! both threads take them one at a time from a common counter until none
//! is left, so the split follows whoever is running: on a quiet machine
//! the two threads take about three legs each; when other work keeps the
//! helper off a core, the calling thread steps every leg itself instead of
//! waiting for it. (A fixed three-and-three split waited for the helper
//! every period, a scheduler time slice at a time under load.) Which thread
//! steps a leg does not change its numbers: a leg's period depends on that
//! leg alone.

use super::six_legs::LegLoop;
use anyhow::{anyhow, bail, Result};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

/// The most legs one step takes.
const SLOTS: usize = 6;

/// One leg's place while it is handed round, and how its periods went.
type Slot = (Option<Box<LegLoop>>, Result<()>);

struct Shared {
    slots: Vec<Mutex<Slot>>,
    /// The next slot to take; at or past `legs` when none is left.
    next: AtomicUsize,
    legs: AtomicUsize,
    periods: AtomicU64,
    control: Mutex<Control>,
    /// Signals a new round to the helper and finished legs to the caller.
    wake: Condvar,
}

#[derive(Default)]
struct Control {
    round: u64,
    finished: usize,
    quit: bool,
}

impl Shared {
    fn control(&self) -> MutexGuard<'_, Control> {
        self.control.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Takes legs from the counter and steps them until none is left.
    fn drain(&self) {
        loop {
            let i = self.next.fetch_add(1, SeqCst);
            if i >= self.legs.load(SeqCst) {
                return;
            }
            let periods = self.periods.load(SeqCst);
            {
                let mut slot = self.slots[i].lock().unwrap_or_else(|e| e.into_inner());
                let (leg, result) = &mut *slot;
                // A panic in a leg becomes its error: the caller would
                // otherwise wait for that leg for ever.
                *result = match leg.as_mut() {
                    Some(leg) => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| step_leg(leg, periods)))
                        .unwrap_or_else(|_| Err(anyhow!("leg {} panicked", i + 1))),
                    None => Err(anyhow!("leg {} missing from its slot", i + 1)),
                };
            }
            self.control().finished += 1;
            self.wake.notify_all();
        }
    }
}

fn step_leg(leg: &mut LegLoop, periods: u64) -> Result<()> {
    for _ in 0..periods {
        let tel = leg.cl.step();
        if !tel.faults.is_empty() {
            bail!("fault {:?} latched at t = {:.4} s", tel.faults, leg.cl.time_s());
        }
    }
    Ok(())
}

/// The helper thread and the slots it shares with the caller.
pub(super) struct Worker {
    shared: Arc<Shared>,
}

impl Worker {
    pub(super) fn spawn() -> Self {
        let shared = Arc::new(Shared {
            slots: (0..SLOTS).map(|_| Mutex::new((None, Ok(())))).collect(),
            next: AtomicUsize::new(SLOTS),
            legs: AtomicUsize::new(0),
            periods: AtomicU64::new(0),
            control: Mutex::new(Control::default()),
            wake: Condvar::new(),
        });
        let helper = Arc::clone(&shared);
        std::thread::spawn(move || {
            let mut seen = 0;
            loop {
                {
                    let mut c = helper.control();
                    while c.round == seen && !c.quit {
                        c = helper.wake.wait(c).unwrap_or_else(|e| e.into_inner());
                    }
                    if c.quit {
                        return;
                    }
                    seen = c.round;
                }
                helper.drain();
            }
        });
        Self { shared }
    }

    /// Advances every leg by `periods` PWM periods, the legs shared out
    /// between the two threads as they come free.
    ///
    /// # Panics
    /// With more than six legs (a caller bug).
    pub(super) fn step(&self, legs: &mut Vec<Box<LegLoop>>, periods: u64) -> Result<()> {
        let n = legs.len();
        assert!(n <= SLOTS, "{n} legs: the worker has {SLOTS} slots");
        let s = &*self.shared;
        for (slot, leg) in s.slots.iter().zip(legs.drain(..)) {
            *slot.lock().unwrap_or_else(|e| e.into_inner()) = (Some(leg), Ok(()));
        }
        // The count is reset before the counter: a helper still taking from
        // the last round finds the counter past the end until then.
        s.legs.store(n, SeqCst);
        s.periods.store(periods, SeqCst);
        {
            let mut c = s.control();
            c.finished = 0;
            c.round += 1;
        }
        s.next.store(0, SeqCst);
        s.wake.notify_all();
        s.drain();
        {
            let mut c = s.control();
            while c.finished < n {
                c = s.wake.wait(c).unwrap_or_else(|e| e.into_inner());
            }
        }
        let mut first_error = None;
        for (i, slot) in s.slots.iter().take(n).enumerate() {
            let (leg, result) = std::mem::replace(&mut *slot.lock().unwrap_or_else(|e| e.into_inner()), (None, Ok(())));
            legs.push(leg.ok_or_else(|| anyhow!("leg {} lost by the worker", i + 1))?);
            if let (Err(e), None) = (result, &first_error) {
                first_error = Some(e);
            }
        }
        first_error.map_or(Ok(()), Err)
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.shared.control().quit = true;
        self.shared.wake.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::super::dynamics::PoseState;
    use super::super::kinematics::Platform;
    use super::super::six_legs::{new_leg, LegLoop, LegSetup, RigSpread};
    use super::{step_leg, Worker};
    use nalgebra::Vector6;

    fn six_legs() -> Vec<Box<LegLoop>> {
        let p = Platform::paper();
        let rig = crate::config::RigConfig::nominal().unwrap();
        let start = p.home();
        let f = p
            .leg_forces(&PoseState { pose: start, velocity: Vector6::zeros(), acceleration: Vector6::zeros() })
            .unwrap();
        let setup = LegSetup { rig: &rig, spread: &RigSpread::TEN_PERCENT, seed: 3, compensation: false };
        (0..6)
            .map(|i| new_leg(&setup, &p, i, &start, f.forces_n[i] + 50.0 * i as f64))
            .collect::<anyhow::Result<_>>()
            .unwrap()
    }

    #[test]
    fn the_shared_out_legs_end_where_one_thread_takes_them() {
        // 40 couplings of 20 periods, the legs handed round between two
        // threads, against the same legs stepped one after another: every
        // plant state bit for bit, every leg back in its place.
        let (mut shared, mut alone) = (six_legs(), six_legs());
        let worker = Worker::spawn();
        for _ in 0..40 {
            worker.step(&mut shared, 20).unwrap();
            for leg in alone.iter_mut() {
                step_leg(leg, 20).unwrap();
            }
        }
        for (i, (a, b)) in shared.iter().zip(&alone).enumerate() {
            assert_eq!(a.cl.plant.state_vector(), b.cl.plant.state_vector(), "leg {}", i + 1);
            assert_eq!(a.cl.periods(), 800);
        }
    }
}
