//! The closed loop: the control core's `step` against the plant, one PWM
//! period at a time, with the one-period PWM update delay of the real timer
//! (duties computed from the sample at period k take effect at period k+1).

use crate::plant::{Plant, PlantState};
use crate::scenario::Direction;
use servo_core::{Controller, PwmCommand, SensorSample, Telemetry};

/// The plant's truth at one instant, next to what the drive believed.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct TruthRecord {
    pub time_s: f64,
    pub direction: Direction,
    pub tilt_deg: f64,
    pub external_force_n: f64,
    /// `L θ_m / 2π` from the true motor angle.
    pub motor_side_position_m: f64,
    /// Piston-rod position (what an ideal grating scale reads).
    pub terminal_position_m: f64,
    /// Terminal minus motor-side: the rigid–flexible deformation and lost motion.
    pub deformation_m: f64,
    pub axial_force_n: f64,
    pub motor_speed_rad_s: f64,
    pub current_d_a: f64,
    pub current_q_a: f64,
    pub phase_current_peak_a: f64,
}

/// The control parameters with a different top speed. The stream's
/// velocity check may be at most half the top speed, so a lower top speed
/// brings the check down with it rather than making the set invalid.
pub fn with_top_speed(mut control: servo_core::ControlParams, max_velocity_m_s: f32) -> servo_core::ControlParams {
    control.trajectory.max_velocity_m_s = max_velocity_m_s;
    control.stream.velocity_mismatch_max_m_s = control.stream.velocity_mismatch_max_m_s.min(0.5 * max_velocity_m_s);
    control
}

/// The drive of the simulator's experiments: commissioned (offset and
/// reference known, as with an absolute encoder), its expected load the one
/// the plant starts with, as the user's configuration would state it.
///
/// The electrical offset is what a commutation would find: the drive's count
/// starts at zero on its first sample, where the rotor sits now.
pub fn commissioned_control(control: servo_core::ControlParams, plant: &Plant) -> servo_core::ControlParams {
    use std::f64::consts::TAU;
    let mut c = control.commissioned();
    c.startup.expected_load_force_n = plant.load_force_n() as f32;
    let cpr = f64::from(plant.params().sensors.encoder_counts_per_rev);
    let zero = plant.bench_sensors().encoder_zero_rad;
    let first_count = ((plant.state().theta_m_rad + zero) * cpr / TAU).round();
    let angle_at_count_zero = first_count * TAU / cpr - zero;
    let electrical = (f64::from(plant.params().motor.pole_pairs) * angle_at_count_zero).rem_euclid(TAU);
    c.encoder.electrical_offset_rad = (if electrical > std::f64::consts::PI { electrical - TAU } else { electrical }) as f32;
    c
}

/// A controller and a plant wired together.
pub struct ClosedLoop {
    pub controller: Controller,
    pub plant: Plant,
    pending: PwmCommand,
    periods: u64,
    pwm_period_s: f64,
    bus_voltage_v: f64,
    /// The plant's truth at the last sampling instant (the period start),
    /// which is the instant the telemetry describes.
    sampled_state: PlantState,
    /// The board's comparator overcurrent break, if modelled (see
    /// `set_hardware_break_a`).
    hardware_break_a: Option<f64>,
    hardware_break_period: Option<u64>,
    /// Largest |true phase current| over the last period's integration
    /// steps (with a break modelled), else at its end.
    period_peak_current_a: f64,
    /// Phases b and c swapped between the drive and the motor (a wiring
    /// mistake): the drive's b duty drives the motor's c phase and reads
    /// its current, and the other way round.
    swap_phases_bc: bool,
}

impl ClosedLoop {
    pub fn new(controller: Controller, plant: Plant, bus_voltage_v: f64) -> Self {
        let pwm_period_s = 1.0 / f64::from(controller.params().rates.pwm_frequency_hz);
        Self {
            controller,
            plant,
            pending: PwmCommand::OFF,
            periods: 0,
            pwm_period_s,
            bus_voltage_v,
            sampled_state: PlantState::default(),
            hardware_break_a: None,
            hardware_break_period: None,
            period_peak_current_a: 0.0,
            swap_phases_bc: false,
        }
    }

    /// Models the board's comparator break: once any true phase current
    /// exceeds `trip_a` (checked after every plant integration step, as
    /// the comparator acts within microseconds, independently of the core)
    /// the outputs go off and stay off. `None` (the default): no break;
    /// each period is then one `Plant::advance`, as before.
    pub fn set_hardware_break_a(&mut self, trip_a: Option<f64>) {
        self.hardware_break_a = trip_a;
    }

    /// Wires the motor with phases b and c swapped (see `swap_phases_bc`).
    pub fn set_swap_phases_bc(&mut self, swapped: bool) {
        self.swap_phases_bc = swapped;
    }

    /// Largest |true phase current| during the last period: over its
    /// integration steps when a break is modelled (pass `f64::INFINITY` to
    /// get that resolution without a break), else at its end.
    pub fn period_peak_current_a(&self) -> f64 {
        self.period_peak_current_a
    }

    /// The period in which the comparator break tripped, if it did.
    pub fn hardware_break_period(&self) -> Option<u64> {
        self.hardware_break_period
    }

    /// Applies `pending` over one PWM period, through the comparator break
    /// if one is modelled.
    fn advance_period(&mut self) {
        let peak_now = |p: &Plant| p.state().phase_current_a.iter().fold(0.0_f64, |m, i| m.max(i.abs()));
        let Some(trip) = self.hardware_break_a else {
            self.plant.advance(&self.pending, self.bus_voltage_v, self.pwm_period_s);
            self.period_peak_current_a = peak_now(&self.plant);
            return;
        };
        // The comparator acts within microseconds: check it at least twice
        // a period, however long the plant's own RK4 steps may be.
        let n = self.plant.params().substeps().max(2);
        let h = self.pwm_period_s / f64::from(n);
        self.period_peak_current_a = 0.0;
        for _ in 0..n {
            let cmd = if self.hardware_break_period.is_some() { broken(&self.pending) } else { self.pending };
            self.plant.advance(&cmd, self.bus_voltage_v, h);
            let peak = peak_now(&self.plant);
            self.period_peak_current_a = self.period_peak_current_a.max(peak);
            if self.hardware_break_period.is_none() && peak > trip {
                self.hardware_break_period = Some(self.periods);
            }
        }
        if self.hardware_break_period.is_some() {
            self.pending = broken(&self.pending);
        }
    }

    pub fn time_s(&self) -> f64 {
        self.periods as f64 * self.pwm_period_s
    }

    pub fn periods(&self) -> u64 {
        self.periods
    }

    pub fn set_bus_voltage_v(&mut self, v: f64) {
        self.bus_voltage_v = v;
    }

    /// The command the core returned last period, applied over the next one.
    pub fn pending_command(&self) -> &PwmCommand {
        &self.pending
    }

    /// The plant's truth at the last sampling instant.
    pub fn sampled_state(&self) -> &PlantState {
        &self.sampled_state
    }

    /// One PWM period: sample at the period start (the PWM centre), run the
    /// core, apply last period's duties over this period.
    pub fn step(&mut self) -> Telemetry {
        self.step_with(|_| {})
    }

    /// `step`, with `corrupt` given the sensor sample before the core sees
    /// it (fault injection: noise bursts, stuck sensors, encoder glitches,
    /// NaN).
    pub fn step_with(&mut self, corrupt: impl FnOnce(&mut SensorSample)) -> Telemetry {
        let mut sample = self.plant.sample();
        self.sampled_state.clone_from(self.plant.state());
        // The board subtracts the offsets the core's calibration measured.
        let offsets = self.controller.current_offsets_a();
        for (i, o) in sample.phase_current_a.iter_mut().zip(offsets) {
            *i -= o;
        }
        if self.swap_phases_bc {
            sample.phase_current_a.swap(1, 2);
        }
        corrupt(&mut sample);
        // The board's ISR reads the timer's break flag before the step.
        if self.hardware_break_period.is_some() {
            self.controller.report_bridge_break();
        }
        let mut cmd = self.controller.step(&sample);
        if self.swap_phases_bc {
            cmd.duty.swap(1, 2);
        }
        self.advance_period();
        self.pending = if self.hardware_break_period.is_some() { broken(&cmd) } else { cmd };
        self.periods += 1;
        self.controller.telemetry()
    }

    /// One PWM period in which the core does not run (a hung ISR, a dead ADC
    /// trigger): the timer keeps applying the duties it holds.
    pub fn step_without_core(&mut self) {
        self.sampled_state.clone_from(self.plant.state());
        self.advance_period();
        self.periods += 1;
    }

    /// Replaces what the timer will apply next period, from outside the
    /// core: a hardware break clearing the outputs, a reset disabling them.
    pub fn override_pending(&mut self, cmd: PwmCommand) {
        self.pending = cmd;
    }

    /// The plant's truth at the instant the last telemetry record describes.
    pub fn truth(&self, direction: Direction, tilt_deg: f64, external_force_n: f64) -> TruthRecord {
        let s = &self.sampled_state;
        TruthRecord {
            time_s: s.time_s,
            direction,
            tilt_deg,
            external_force_n,
            motor_side_position_m: s.motor_side_position_m,
            terminal_position_m: s.terminal_position_m,
            deformation_m: s.terminal_position_m - s.motor_side_position_m,
            axial_force_n: s.axial_force_n,
            motor_speed_rad_s: s.omega_m_rad_s,
            current_d_a: s.i_d_a,
            current_q_a: s.i_q_a,
            phase_current_peak_a: s.phase_current_a.iter().fold(0.0_f64, |m, i| m.max(i.abs())),
        }
    }
}

/// What the timer applies after its break fired: outputs off in hardware;
/// the brake pin is a GPIO the break does not touch, so it follows the core.
fn broken(cmd: &PwmCommand) -> PwmCommand {
    PwmCommand { brake_release: cmd.brake_release, ..PwmCommand::OFF }
}

/// The nominal rig's rated payload hanging vertically with the rod at
/// `x0_m`: commissioned, homed there, enabled and settled (0.2 s), with
/// `capture` attached if given. Where the core's closed-loop tests and
/// benchmarks start.
pub fn holding_vertical(
    x0_m: f64,
    seed: u64,
    capture: Option<&'static servo_core::capture::CaptureStore>,
) -> anyhow::Result<ClosedLoop> {
    let rig = crate::config::RigConfig::nominal()?;
    let mut plant = Plant::try_new(rig.plant.clone(), seed).map_err(|e| anyhow::anyhow!("params/rig.toml: {e}"))?;
    plant.set_initial_state((x0_m - rig.plant.stroke.initial_position_m) / rig.plant.metres_per_rad(), std::f64::consts::FRAC_PI_2);
    let mut controller = Controller::try_new(commissioned_control(rig.control, &plant)).map_err(|e| anyhow::anyhow!("{e}"))?;
    if let Some(store) = capture {
        controller.attach_capture_store(store);
    }
    let mut cl = ClosedLoop::new(controller, plant, rig.plant.inverter.nominal_bus_voltage_v);
    let ok = |r: Result<servo_core::CommandOutcome, servo_core::CommandError>, what: &str| {
        r.map(|_| ()).map_err(|e| anyhow::anyhow!("{what}: {e:?}"))
    };
    ok(cl.controller.command(servo_core::Command::SetHome { position_m: x0_m as f32 }), "SetHome")?;
    ok(cl.controller.command(servo_core::Command::Enable), "Enable")?;
    for _ in 0..4000 {
        cl.step();
    }
    if cl.controller.mode() != servo_core::Mode::Running {
        anyhow::bail!("not Running after enabling: {:?}, faults {:?}", cl.controller.mode(), cl.controller.faults().names().collect::<Vec<_>>());
    }
    Ok(cl)
}
