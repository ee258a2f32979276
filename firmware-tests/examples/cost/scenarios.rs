//! Closed-loop runs of `Controller::step` over the golden script, and the
//! worst PWM period with a bulk request (parameter set, capture configure,
//! test start) landing in each kind of period.

use super::*;

/// The capture both scenarios measure: four signals every period, the
/// figure the capturing budget is stated for.
fn bench_capture() -> CaptureConfig {
    CaptureConfig {
        signals: servo_core::capture::SignalList::from_slice(&[Signal::CurrentQ, Signal::CurrentQReference, Signal::Speed, Signal::MotorPosition]).unwrap_or(servo_core::capture::SignalList::EMPTY),
        decimation: 1,
        samples: 1024,
        pre_trigger: 512,
        trigger: CaptureTrigger::Command,
    }
}

/// `Controller::step` over the golden closed-loop script, measured per
/// period kind: current, speed, position, bridge off; and whether a fault
/// was seen. With `capture`, a four-signal capture records throughout; with
/// `weights`, the observer runs them instead of the compiled model.
pub(crate) fn closed_loop(
    m: &Meter,
    p: ControlParams,
    capture: bool,
    weights: Option<&'static servo_core::observer::block::Weights>,
) -> (Stats, Stats, Stats, Stats, bool) {
    let (mut cur, mut spd, mut pos, mut off) =
        (Stats::new(), Stats::new(), Stats::new(), Stats::new());
    // As the golden closed loop: the rigid plant carries no load and has
    // no brake (a hold current preloaded into it would spin it).
    let mut bench = p.commissioned();
    bench.startup.expected_load_force_n = 0.0;
    bench.brake.fitted = false;
    let mut c = Controller::new(bench);
    if let Some(weights) = weights {
        let _ = c.command(servo_core::Command::SetObserverWeights { weights });
    }
    static STORE: CaptureStore = CaptureStore::new();
    let cfg = bench_capture();
    if capture {
        c.attach_capture_store(&STORE);
    }
    let mut plant = RigidPlant::new(p, 48.0);
    let mut noise = Noise::new(7);
    let mut out = PwmCommand::OFF;
    let periods = golden::CLOSED_LOOP_PERIODS;
    let speed_div = p.rates.speed_loop_divider as usize;
    let pos_div = p.rates.position_loop_divider as usize;
    let mut faults_seen = false;
    for k in 0..periods {
        for (_, cmd) in CLOSED_LOOP_SCRIPT.iter().filter(|(at, _)| *at == k) {
            let _ = c.command(*cmd);
        }
        plant.advance(&out);
        let mut s = plant.sample();
        for i in s.phase_current_a.iter_mut() {
            *i += 0.03 * noise.next();
        }
        if capture {
            if c.capture_status().state != CaptureState::Armed && c.capture_status().state != CaptureState::Triggered {
                let _ = c.capture_configure(&cfg);
            }
            if k % 2000 == 1999 {
                let _ = c.capture_trigger();
            }
        }
        let running = c.mode() == Mode::Running;
        let (o, t) = m.measure(|| step(&mut c, black_box(&s)));
        out = black_box(o);
        faults_seen |= !c.faults().is_empty();
        // The controller counts periods from 1 at its first step.
        let tick = k + 1;
        if !running {
            off.add(t);
        } else if tick % pos_div == 0 {
            pos.add(t);
        } else if tick % speed_div == 0 {
            spd.add(t);
        } else {
            cur.add(t);
        }
    }
    (cur, spd, pos, off, faults_seen)
}

/// A bulk request the PWM interrupt serves between two steps.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Bulk {
    /// `ApplyParams`: a whole validated set (a live gain change, so the
    /// bumpless retune runs).
    ApplyParams,
    /// `Bulk(Capture(Configure))`: four signals, 1024 samples.
    CaptureConfigure,
    /// `Bulk(Test)`: a 10 µm position step test started.
    TestStart,
}

/// One serving of `op` as the interrupt does it: the payload taken from the
/// link's slot (a copy of the slot's size, which is the parameter set's),
/// the controller's call, and the snapshot the interrupt publishes after
/// every request (telemetry and the move flag).
#[inline(never)]
pub(crate) fn serve_bulk(c: &mut Controller, op: Bulk, set: &ValidatedParams, cfg: &CaptureConfig) {
    let payload = black_box(*set);
    match op {
        Bulk::ApplyParams => {
            let _ = black_box(c.apply_params(&payload));
        }
        Bulk::CaptureConfigure => {
            let _ = black_box(c.capture_configure(cfg));
        }
        Bulk::TestStart => {
            let signal = TestSignal::PositionStep { distance_m: 10e-6, duration_s: 0.005 };
            let _ = black_box(c.start_test(signal));
        }
    }
    black_box((c.telemetry(), c.move_in_progress()));
}

/// Where a bulk request may be served.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Serve {
    /// Wherever it lands.
    AnyPeriod,
    /// Before any period that runs the current loop only
    /// (`Controller::next_period_is_current_only`), a capture's end or not.
    CurrentOnly,
    /// As the firmware's interrupt does: before a current-only period in
    /// which no capture encodes a batch (`Controller::next_period_serves_bulk`).
    Firmware,
}

/// The longest PWM period with bulk requests in it: the golden closed loop,
/// with `op` served before the step of every 7th period while the drive
/// runs (7 is prime to the dividers 4 and 20, so the requests land in
/// every kind of period), where `serve` allows. `capturing`: a 64-sample,
/// four-signal capture records throughout, re-armed (not counted) as each
/// ends, so its ends (the capture's longest periods) meet the requests.
/// Returns the longest (step + request) period by kind (current-only,
/// speed, position) and how many requests the controller accepted.
pub(crate) fn worst_with_bulk(m: &Meter, p: ControlParams, op: Bulk, serve: Serve, capturing: bool) -> ([u32; 3], u32) {
    let mut bench = p.commissioned();
    bench.startup.expected_load_force_n = 0.0;
    bench.brake.fitted = false;
    let mut c = Controller::new(bench);
    static STORE: CaptureStore = CaptureStore::new();
    c.attach_capture_store(&STORE);
    let cfg = bench_capture();
    // Two sets a live proportional gain apart: each apply retunes.
    let mut alt = bench;
    alt.current_pi.kp *= 1.01;
    let sets = [ValidatedParams::new(bench), ValidatedParams::new(alt)];
    let mut plant = RigidPlant::new(p, 48.0);
    let mut noise = Noise::new(7);
    let mut out = PwmCommand::OFF;
    let speed_div = p.rates.speed_loop_divider as usize;
    let pos_div = p.rates.position_loop_divider as usize;
    let mut worst = [0u32; 3];
    let mut accepted = 0u32;
    let mut pending = false;
    for k in 0..golden::CLOSED_LOOP_PERIODS {
        // A test is refused during a move and until the axis has held
        // still once after Enable; the script's move lasts until after
        // period 4600, past which the axis cannot settle before Disable.
        // The test starts are measured at home instead: the axis settles
        // after about 1200 periods and the rest of the run serves them.
        let script = CLOSED_LOOP_SCRIPT.iter().filter(|(at, cmd)| *at == k && !(op == Bulk::TestStart && matches!(cmd, servo_core::Command::MoveTo { .. })));
        for (_, cmd) in script {
            let _ = c.command(*cmd);
        }
        plant.advance(&out);
        let mut s = plant.sample();
        for i in s.phase_current_a.iter_mut() {
            *i += 0.03 * noise.next();
        }
        let running = c.mode() == Mode::Running;
        if capturing && running && c.capture_status().state != servo_core::capture::CaptureState::Armed && c.capture_status().state != servo_core::capture::CaptureState::Triggered {
            let short = CaptureConfig { samples: 64, pre_trigger: 0, ..cfg };
            let _ = c.capture_configure(&short);
            let _ = c.capture_trigger();
        }
        if running && k % 7 == 0 && !(op == Bulk::TestStart && c.test_running()) {
            pending = true;
        }
        let serve = pending
            && match serve {
                Serve::AnyPeriod => true,
                Serve::CurrentOnly => c.next_period_is_current_only(),
                Serve::Firmware => c.next_period_serves_bulk(),
            };
        let set = sets.get(k % 2).and_then(|v| v.as_ref().ok());
        let (o, t) = match (serve, set) {
            (true, Some(set)) => {
                pending = false;
                let before = (c.params().current_pi.kp, c.capture_status().state, c.test_running());
                let r = m.measure(|| {
                    serve_bulk(&mut c, op, set, &cfg);
                    step(&mut c, black_box(&s))
                });
                let after = (c.params().current_pi.kp, c.capture_status().state, c.test_running());
                accepted += u32::from(before != after || op == Bulk::CaptureConfigure);
                r
            }
            _ => m.measure(|| step(&mut c, black_box(&s))),
        };
        out = black_box(o);
        let tick = k + 1;
        let kind = if tick % pos_div == 0 {
            2
        } else if tick % speed_div == 0 {
            1
        } else {
            0
        };
        if running {
            if let Some(w) = worst.get_mut(kind) {
                *w = (*w).max(t);
            }
        }
    }
    (worst.map(|ticks| libm::round(m.insns(u64::from(ticks))) as u32), accepted)
}

