//! The mode machine's table, walked: every allowed transition is reached by
//! the commands and faults a user or a rig produces, and the drive never
//! asks for one the table does not list (`transitions_refused` stays 0).

use host_sim::config::RigConfig;
use host_sim::plant::Plant;
use host_sim::sim::{commissioned_control, ClosedLoop};
use servo_core::controller::mode::{allowed, transition_bit, MODES, TRANSITIONS};
use servo_core::{Command, Controller, Mode, Readiness};

/// A drive on the simulated rig (the nominal plant, its rated load hanging
/// vertically).
struct Bench {
    cl: ClosedLoop,
}

impl Bench {
    fn new(setup: Setup) -> Self {
        let rig = RigConfig::nominal().unwrap();
        let mut plant = Plant::try_new(rig.plant.clone(), 3).unwrap();
        // The rod at 0.1 m, the payload hanging vertically.
        plant.set_initial_state((0.1 - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), std::f64::consts::FRAC_PI_2);
        let mut control = match setup {
            Setup::New => rig.control,
            _ => commissioned_control(rig.control, &plant),
        };
        if setup == Setup::LongPreload {
            control.brake.preload_time_s = 0.5;
        }
        if setup == Setup::ShortHomingTravel {
            control.homing.travel_max_m = 0.002;
        }
        control.startup.expected_load_force_n = plant.load_force_n() as f32;
        control.brake.fitted = setup != Setup::NoBrake;
        let mut cl = ClosedLoop::new(Controller::try_new(control).unwrap(), plant, rig.plant.inverter.nominal_bus_voltage_v);
        cl.step();
        Self { cl }
    }
    fn step(&mut self) {
        self.cl.step();
    }
    fn run(&mut self, periods: u32) {
        for _ in 0..periods {
            self.step();
        }
    }
    /// One streamed setpoint where the rod is, then none: the stream
    /// times out into a controlled stop.
    fn stream_then_lose(&mut self) {
        let x = self.cl.controller.motor_position_m();
        self.cmd(Command::Stream { position_m: x, velocity_m_s: 0.0, force_n: None });
        let mut k = 0;
        while self.mode() != Mode::Stopping && k < 20_000 {
            self.run(1);
            k += 1;
        }
        self.run(4_000);
    }
    fn nan(&mut self) {
        self.cl.step_with(|s| s.bus_voltage_v = f32::NAN);
        self.run(2);
    }
    fn cmd(&mut self, cmd: Command) {
        let _ = self.cl.controller.command(cmd);
        self.run(1);
    }
    fn mode(&self) -> Mode {
        self.cl.controller.mode()
    }
    fn faults(&self) -> servo_core::FaultSet {
        self.cl.controller.faults()
    }
    fn clear(&mut self) {
        self.run(2);
        self.cmd(Command::ClearFaults);
    }
}

/// How the drive starts: as shipped (nothing known), commissioned (offset
/// and home known), or commissioned without a holding brake.
#[derive(Clone, Copy, PartialEq)]
enum Setup {
    New,
    Commissioned,
    NoBrake,
    /// Commissioned, the hold current building for 0.5 s.
    LongPreload,
    /// Commissioned, homing allowed 2 mm of travel (it finds nothing).
    ShortHomingTravel,
}

/// Runs a scenario and returns the transitions it took; fails if the
/// drive asked for a transition the table refuses.
fn scenario(name: &str, f: impl FnOnce(&mut Bench), setup: Setup) -> u128 {
    let mut b = Bench::new(setup);
    f(&mut b);
    let c = &b.cl.controller;
    assert_eq!(c.transitions_refused(), 0, "{name}: asked for refused transitions {}", names(c.transitions_refused()));
    c.transitions_taken()
}

fn names(mask: u128) -> String {
    let mut out = Vec::new();
    for from in MODES {
        for to in MODES {
            if from != to && mask & transition_bit(from, to) != 0 {
                out.push(format!("{from:?}->{to:?}"));
            }
        }
    }
    out.join(", ")
}

#[test]
fn the_table_is_what_allowed_answers() {
    for from in MODES {
        for to in MODES {
            let listed = from == to || TRANSITIONS.contains(&(from, to));
            assert_eq!(allowed(from, to), listed, "{from:?} -> {to:?}");
        }
    }
    // Every mode can reach `Fault` (a bridge-off fault is never refused)
    // and `Fault` leaves only through `ClearFaults` to `Disabled`.
    for m in MODES {
        assert!(allowed(m, Mode::Fault), "{m:?} cannot fault");
        if m != Mode::Fault && m != Mode::Disabled {
            assert!(!allowed(Mode::Fault, m), "Fault -> {m:?}");
        }
    }
}

#[test]
fn every_allowed_transition_is_reached_and_no_other_is_asked_for() {
    let mut taken = 0u128;
    // Start-up steps with synthetic samples, and a fault in each.
    taken |= scenario("calibrate", |b| {
        b.cmd(Command::Calibrate);
        assert_eq!(b.mode(), Mode::Calibrating);
        b.run(20_000);
        assert!(b.cl.controller.readiness().contains(Readiness::CURRENTS_CALIBRATED), "{:?}", b.mode());
        b.cmd(Command::Calibrate);
        b.nan();
        b.clear();
        b.cmd(Command::Calibrate);
        b.cmd(Command::Disable);
        b.cmd(Command::Align);
        assert_eq!(b.mode(), Mode::Aligning);
        b.nan();
        assert_eq!(b.mode(), Mode::Fault);
        b.clear();
        assert_eq!(b.mode(), Mode::Disabled);
        b.nan();
    }, Setup::New);
    // Enable with the brake: preload, run, stop, brake, and back.
    taken |= scenario("brake", |b| {
        b.cmd(Command::Enable);
        assert_eq!(b.mode(), Mode::Preloading);
        b.cmd(Command::Disable);
        assert_eq!(b.mode(), Mode::Braking);
        b.cmd(Command::Enable);
        assert_eq!(b.mode(), Mode::Running);
        b.cmd(Command::Disable);
        b.run(4_000);
        assert_eq!(b.mode(), Mode::Disabled, "{:?}", b.faults());
        b.cmd(Command::Enable);
        b.run(4_000);
        assert_eq!(b.mode(), Mode::Running, "{:?}", b.faults());
        b.cmd(Command::Home);
        assert_eq!(b.mode(), Mode::Homing);
        b.cmd(Command::Stop);
        assert_eq!(b.mode(), Mode::Running);
        b.run(4_000);
        b.cmd(Command::Home);
        assert_eq!(b.mode(), Mode::Homing);
        b.cmd(Command::Disable);
        assert_eq!(b.mode(), Mode::Braking);
        b.nan();
        assert_eq!(b.mode(), Mode::Fault);
        b.clear();
        b.cmd(Command::Enable);
        b.cmd(Command::Home);
        assert_eq!(b.mode(), Mode::Homing, "Home during the preload");
        b.nan();
        b.clear();
        b.cmd(Command::Enable);
        b.nan();
        b.clear();
        b.cmd(Command::Enable);
        b.run(4_000);
        assert_eq!(b.mode(), Mode::Running, "{:?}", b.faults());
        b.nan();
        assert_eq!(b.mode(), Mode::Fault);
    }, Setup::Commissioned);
    // Controlled stops: a stream that stops arriving (running, and during
    // a longer preload), a homing that finds nothing within its travel;
    // then clear, brake or fault out of `Stopping`.
    taken |= scenario("stream lost while running, cleared", |b| {
        b.cmd(Command::Enable);
        b.run(4_000);
        b.stream_then_lose();
        assert_eq!(b.mode(), Mode::Stopping, "{:?}", b.faults());
        b.clear();
        assert_eq!(b.mode(), Mode::Running, "{:?}", b.faults());
        b.stream_then_lose();
        assert_eq!(b.mode(), Mode::Stopping, "{:?}", b.faults());
        b.nan();
        assert_eq!(b.mode(), Mode::Fault);
    }, Setup::Commissioned);
    taken |= scenario("the encoder jumps 6 mm during the preload", |b| {
        b.cmd(Command::Enable);
        assert_eq!(b.mode(), Mode::Preloading);
        // The reading creeps away at 20 counts a period (200 rad/s, a speed
        // the motor can have, so no encoder jump) while the brake holds the
        // rod: a following fault, a controlled stop.
        let mut offset = 0u16;
        let mut k = 0;
        while b.mode() == Mode::Preloading && k < 4_000 {
            offset = offset.wrapping_add(20);
            let o = offset;
            b.cl.step_with(|s| s.encoder_count = s.encoder_count.wrapping_add(o));
            k += 1;
        }
        assert_eq!(b.mode(), Mode::Stopping, "after {k} periods: {:?}", b.faults());
        b.nan();
        assert_eq!(b.mode(), Mode::Fault);
    }, Setup::LongPreload);
    taken |= scenario("homing finds nothing", |b| {
        b.cmd(Command::Enable);
        b.run(4_000);
        b.cmd(Command::Home);
        assert_eq!(b.mode(), Mode::Homing);
        let mut k = 0;
        while b.mode() == Mode::Homing && k < 100_000 {
            b.run(1);
            k += 1;
        }
        assert_eq!(b.mode(), Mode::Stopping, "{:?}", b.faults());
        b.cmd(Command::Disable);
        assert_eq!(b.mode(), Mode::Braking);
        b.run(4_000);
        assert_eq!(b.mode(), Mode::Fault, "braking ends in Fault while the fault stands");
    }, Setup::ShortHomingTravel);
    // No brake: enable straight to running, disable straight to off.
    taken |= scenario("no brake", |b| {
        b.cmd(Command::Enable);
        assert_eq!(b.mode(), Mode::Running);
        b.cmd(Command::Disable);
        assert_eq!(b.mode(), Mode::Disabled);
        b.cmd(Command::Enable);
        b.cmd(Command::Home);
        b.cmd(Command::Disable);
        assert_eq!(b.mode(), Mode::Disabled);
    }, Setup::NoBrake);
    // The full power-up on the simulated rig: commutation and homing.
    taken |= power_up();

    let all: u128 = TRANSITIONS.iter().fold(0, |m, &(f, t)| m | transition_bit(f, t));
    assert_eq!(taken & !all, 0, "taken outside the table: {}", names(taken & !all));
    assert_eq!(all & !taken, 0, "allowed but never reached: {}", names(all & !taken));
}

/// `StartUp` on the nominal rig under its load: offsets, commutation,
/// homing, ready.
fn power_up() -> u128 {
    let rig = RigConfig::nominal().unwrap();
    let plant = Plant::try_new(rig.plant.clone(), 7).unwrap();
    let mut control = rig.control;
    control.startup.expected_load_force_n = plant.load_force_n() as f32;
    let mut cl = ClosedLoop::new(Controller::try_new(control).unwrap(), plant, rig.plant.inverter.nominal_bus_voltage_v);
    cl.step();
    cl.controller.command(Command::StartUp).unwrap();
    let mut k = 0;
    while !(cl.controller.readiness() == Readiness::ALL && cl.controller.mode() == Mode::Running && !cl.controller.move_in_progress()) {
        cl.step();
        k += 1;
        assert!(k < 20 * 20_000, "power-up did not finish: {:?} {:?}", cl.controller.mode(), cl.controller.faults());
    }
    assert_eq!(cl.controller.transitions_refused(), 0, "power-up: {}", names(cl.controller.transitions_refused()));
    cl.controller.transitions_taken()
}
