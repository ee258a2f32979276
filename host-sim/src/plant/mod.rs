//! The plant: averaged inverter, PMSM, coupling, ball screw, deformation,
//! nut/rod/payload, friction, load and sensors, integrated with fixed-step
//! RK4 in f64. The controller sees it only through `SensorSample` in and
//! `PwmCommand` out, exactly as on the real board.
//!
//! Conventions: positive motor rotation extends the rod; a positive axial
//! load opposes extension; phase current is positive into the motor;
//! θ_e = p θ_m with zero offset and encoder count 0 at θ_m = 0, so a
//! controller with `electrical_offset_rad = 0` is aligned. The motor-side
//! position is `x0 + L θ_m/2π` (x0 = `stroke.initial_position_m`); the
//! terminal position is the rod's; terminal error = terminal − motor side,
//! negative under a compressive load. See `docs/plant.md`.

pub mod brake;
pub mod deformation;
pub mod effects;
pub mod frames;
pub mod friction;
pub mod integrator;
pub mod inverter;
pub mod mechanics;
pub mod motor;
pub mod params;
pub mod params_check;
pub mod sensors;

use servo_core::{PwmCommand, SensorSample};

pub use deformation::{Compliance, Deflection};
pub use effects::UnmodelledEffects;
pub use inverter::{Drive, Leg};
pub use mechanics::{EnergyAudit, StateVec};
pub use params::PlantParams;
pub use params_check::{LoadError, ParamError};

use mechanics::{Inputs, Model, StateTerms, I_D, I_Q, OMEGA_M, OMEGA_S, THETA_M, THETA_S, V_ROD, X_ROD};

/// True plant quantities (f64) after the latest `advance`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlantState {
    pub time_s: f64,
    // --- states ---
    pub i_d_a: f64,
    pub i_q_a: f64,
    /// Rotor angle from construction (unwrapped), rad.
    pub theta_m_rad: f64,
    pub omega_m_rad_s: f64,
    /// Screw angle at the nut, same origin as θ_m.
    pub theta_s_rad: f64,
    pub omega_s_rad_s: f64,
    /// Rod (nut + rod + payload) position, the terminal position.
    pub x_rod_m: f64,
    pub v_rod_m_s: f64,
    // --- derived ---
    /// `x0 + L θ_m/2π`: what a semi-closed loop on the encoder controls.
    pub motor_side_position_m: f64,
    /// `x0 + L θ_s/2π`: the screw's ideal nut position.
    pub screw_side_position_m: f64,
    /// Rod position as the grating scale sees it (before quantisation).
    pub terminal_position_m: f64,
    /// Terminal − motor side: minus the total deformation.
    pub terminal_error_m: f64,
    /// Force transmitted by the nut (compliance spring + damper), positive
    /// when the screw pushes the rod out.
    pub axial_force_n: f64,
    pub motor_torque_n_m: f64,
    /// Rotor-to-screw torque (coupling + screw twist, spring + damper).
    pub coupling_torque_n_m: f64,
    /// `p θ_m` wrapped into [0, 2π).
    pub electrical_angle_rad: f64,
    pub phase_current_a: [f64; 3],
    /// Phase-to-neutral voltages applied by the inverter.
    pub phase_voltage_v: [f64; 3],
    pub u_d_v: f64,
    pub u_q_v: f64,
    /// Gravity along the cylinder plus the external force.
    pub load_force_n: f64,
    /// Rod-end load cell force (payload inertia + weight + external force).
    pub load_cell_force_n: f64,
    pub rod_acceleration_m_s2: f64,
    pub tilt_rad: f64,
    pub external_force_n: f64,
    pub bus_voltage_v: f64,
    pub inverter_enabled: bool,
    /// The holding brake's disc is holding the motor shaft.
    pub brake_engaged: bool,
    /// Duties outside [0, 1] (or NaN) the inverter saturated so far.
    pub duty_saturation_count: u64,
}

/// The simulated rig.
#[derive(Clone, Debug)]
pub struct Plant {
    params: PlantParams,
    model: Model,
    x: StateVec,
    time_s: f64,
    tilt_rad: f64,
    /// sin(tilt), kept with it: the load and the load cell need it every
    /// period and the tilt changes at most once a position-loop period.
    sin_tilt: f64,
    external_force_n: f64,
    bus_v: f64,
    drive: Drive,
    warm: mechanics::WarmStart,
    /// The state record's right-hand-side terms at the period's end, kept
    /// to serve as the next step's first RK4 stage (see `first_stage`).
    record_terms: Option<RecordTerms>,
    max_step_s: f64,
    duty_saturation_count: u64,
    /// A phase disconnected from the inverter (fault injection).
    open_phase: Option<usize>,
    brake: brake::Brake,
    sensors: sensors::Sensors,
    state: PlantState,
    /// Unmodelled effects of a truth rig (none by default).
    effects: UnmodelledEffects,
}

impl Plant {
    /// A plant at rest in static equilibrium under the initial load, holding
    /// current flowing (see `set_initial_state`). For parameters already
    /// validated (a loaded rig file, `PlantParams::default()`); the
    /// commands build their plants with `try_new`.
    ///
    /// # Panics
    /// If `params` fail `validate()`; use `try_new` for a `Result`.
    pub fn new(params: PlantParams, seed: u64) -> Plant {
        match Self::try_new(params, seed) {
            Ok(p) => p,
            Err(e) => panic!("invalid plant parameters: {e}"),
        }
    }

    /// `new`, refusing invalid parameters with the field's name.
    pub fn try_new(params: PlantParams, seed: u64) -> Result<Plant, ParamError> {
        params.validate()?;
        let model = Model::new(&params);
        let tilt = params_check::deg_to_rad(params.load.initial_tilt_deg);
        let mut plant = Plant {
            sensors: sensors::Sensors::new(&params.sensors, seed),
            max_step_s: params.max_step_s(),
            bus_v: params.inverter.nominal_bus_voltage_v,
            external_force_n: params.load.initial_external_force_n,
            tilt_rad: tilt,
            sin_tilt: tilt.sin(),
            model,
            x: [0.0; mechanics::N],
            time_s: 0.0,
            drive: Drive::Pwm([0.5; 3]),
            warm: mechanics::WarmStart::default(),
            record_terms: None,
            duty_saturation_count: 0,
            open_phase: None,
            brake: brake::Brake::new(&params.brake),
            state: PlantState::default(),
            effects: UnmodelledEffects::default(),
            params,
        };
        plant.sensors.bench.encoder_zero_rad = plant.params.sensors.encoder_zero_rad;
        if plant.params.screw.lead_error_m_per_m != 0.0 {
            // The rig's own lead error acts through the effects' thread law.
            plant.effects = UnmodelledEffects { lead_error_m_per_m: plant.params.screw.lead_error_m_per_m, ..Default::default() };
            plant.model.fx = plant.effects.dynamics(&plant.params);
        }
        plant.set_initial_state(0.0, tilt);
        Ok(plant)
    }

    /// Puts the plant at rest in static equilibrium at rotor angle `θ_m`
    /// (motor-side position `x0 + L θ_m/2π`) and tilt, under the present
    /// external force: every spring pre-loaded, the motor carrying the
    /// holding current `i_q = L F /(2π · 1.5 p ψ_f)`, `i_d = 0`. The
    /// inverter is assumed to be enabled with the voltage that keeps that
    /// current (`u_q = R i_q`); a controller starting from zero integrators
    /// will let the load sag until its loops pick it up.
    pub fn set_initial_state(&mut self, motor_angle_rad: f64, tilt_rad: f64) {
        self.set_tilt_rad(tilt_rad);
        let load = self.model.load_force_n(tilt_rad, self.external_force_n);
        self.x = self.model.equilibrium(motor_angle_rad, load);
        self.warm = mechanics::WarmStart { axial: deformation::AxialWarmStart::from_force(load), ..Default::default() };
        let (sin_e, cos_e) = (self.model.motor.pole_pairs * motor_angle_rad).sin_cos();
        let (u_a, u_b) = frames::inverse_park(0.0, self.model.motor.resistance_ohm * self.x[I_Q], sin_e, cos_e);
        let u = frames::inverse_clarke(u_a, u_b);
        let bus = self.bus_v.max(f64::MIN_POSITIVE);
        self.drive = Drive::Pwm(std::array::from_fn(|k| 0.5 + u[k] / bus));
        self.refresh_state();
    }

    /// A truth rig: the nominal `params` with `effects` (see `effects.rs`).
    /// The parameter-type effects change `params()`; the others act in
    /// the right-hand side and the sensors. Starts at rest as `new`.
    pub fn with_effects(params: PlantParams, effects: UnmodelledEffects, seed: u64) -> Result<Plant, ParamError> {
        let mut p = params;
        effects.apply_to_params(&mut p);
        let mut effects = effects;
        // The rig file's lead error and the effect's add up.
        effects.lead_error_m_per_m += p.screw.lead_error_m_per_m;
        let mut plant = Self::try_new(p, seed)?;
        plant.model.fx = effects.dynamics(&plant.params);
        plant.effects = effects;
        plant.update_effects();
        let tilt = plant.tilt_rad;
        plant.set_initial_state(0.0, tilt);
        Ok(plant)
    }

    /// The unmodelled effects (none for a nominal plant).
    pub fn effects(&self) -> &UnmodelledEffects {
        &self.effects
    }

    /// Time-varying effects (thermal strain, load disturbance) at the
    /// present time, held through the next period.
    fn update_effects(&mut self) {
        let e = &self.effects;
        if e.thermal_strain_per_s != 0.0 || e.load_offset_n != 0.0 || e.load_disturbance_n != 0.0 {
            self.model.fx.thermal_strain = e.thermal_strain(self.time_s);
            self.model.fx.load_offset = e.load_offset_n + e.load_disturbance(self.time_s);
            // The thread's strain is a state term: the record's are stale.
            self.record_terms = None;
        }
    }

    pub fn set_tilt_rad(&mut self, tilt_rad: f64) {
        self.tilt_rad = tilt_rad;
        self.sin_tilt = tilt_rad.sin();
    }

    /// Extra axial load on the rod; positive opposes extension.
    pub fn set_external_force_n(&mut self, f: f64) {
        self.external_force_n = f;
    }

    /// Disconnects phase `Some(k)` (0 = a, 1 = b, 2 = c) from the inverter, a
    /// broken lead or a dead leg, or reconnects all with `None`. The open
    /// phase's current is forced to zero at once (a lead that breaks under
    /// current arcs for microseconds; the model skips that).
    ///
    /// # Panics
    /// If `k > 2` (a caller bug).
    pub fn set_open_phase(&mut self, phase: Option<usize>) {
        assert!(phase.is_none_or(|k| k < 3), "open phase {phase:?}: phases are 0, 1, 2");
        self.open_phase = phase;
        if let Some(k) = phase {
            self.force_open_phase(k);
        }
        self.refresh_state();
    }

    /// The disconnected phase, if any.
    pub fn open_phase(&self) -> Option<usize> {
        self.open_phase
    }

    /// Integrates `duration_s` with `cmd` applied, in equal RK4 steps no
    /// longer than `PlantParams::max_step_s()`.
    ///
    /// # Panics
    /// On a negative or non-finite duration or bus voltage (a caller bug).
    pub fn advance(&mut self, cmd: &PwmCommand, bus_voltage_v: f64, duration_s: f64) {
        self.brake.command(cmd.brake_release);
        let duty = cmd.enable.then(|| cmd.duty.map(f64::from));
        self.advance_duties(duty, bus_voltage_v, duration_s);
    }

    /// `advance` with f64 duties (`None`: switches off). For tests and
    /// studies that must not see the f32 rounding of a `PwmCommand`. The
    /// holding brake keeps its last command.
    ///
    /// # Panics
    /// As `advance`.
    pub fn advance_duties(&mut self, duty: Option<[f64; 3]>, bus_voltage_v: f64, duration_s: f64) {
        assert!(duration_s.is_finite() && duration_s >= 0.0, "advance: duration {duration_s} s");
        assert!(bus_voltage_v.is_finite() && bus_voltage_v >= 0.0, "advance: bus voltage {bus_voltage_v} V");
        self.bus_v = bus_voltage_v;
        let duty = duty.map(|d| self.saturate_duties(d));
        self.update_effects();
        let load = self.load_force_n();
        self.drive = self.drive_for(duty, bus_voltage_v);
        if duration_s > 0.0 {
            let steps = ((duration_s / self.max_step_s) * (1.0 - 1e-12)).ceil().max(1.0);
            let h = duration_s / steps;
            for _ in 0..steps as u64 {
                self.drive = self.drive_for(duty, bus_voltage_v);
                let inputs = Inputs {
                    drive: self.drive,
                    bus_v: bus_voltage_v,
                    load_force_n: load,
                    open_phase: self.open_phase,
                    brake: self.brake.torque_law(),
                };
                let k1 = self.first_stage(&inputs);
                let model = &self.model;
                let guess = &mut self.warm;
                self.x = integrator::rk4_step_from(&self.x, h, &k1, |s| model.deriv_warm(s, &inputs, guess));
                match (self.drive, self.open_phase) {
                    // The open phase is `Leg::Open` in the diode pattern.
                    (Drive::Diodes(legs), _) => self.enforce_diode_blocking(legs),
                    (Drive::Pwm(_), Some(k)) => self.force_open_phase(k),
                    (Drive::Pwm(_), None) => {}
                }
                self.brake.after_step(h, self.x[THETA_M]);
                self.time_s += h;
            }
        }
        // The state record shows the conduction pattern at the end.
        self.drive = self.drive_for(duty, bus_voltage_v);
        self.refresh_state();
    }

    /// The first RK4 stage f(x) of a step. At a period's start the state
    /// record has just evaluated the state terms at this very x (same
    /// warm start), so only the input-dependent part is redone with this
    /// step's drive, brake and load: the same numbers, bit for bit, as a
    /// full evaluation, without a second force inversion.
    fn first_stage(&mut self, inputs: &Inputs) -> StateVec {
        match self.record_terms.take() {
            Some(r) if r.x == self.x => {
                self.warm = r.warm;
                self.model.deriv_from(&self.x, &r.terms, inputs)
            }
            _ => self.model.deriv_warm(&self.x, inputs, &mut self.warm),
        }
    }

    /// The drive mode for the next step: PWM, or whichever diodes conduct
    /// at the present currents and back-EMF.
    fn drive_for(&self, duty: Option<[f64; 3]>, bus_voltage_v: f64) -> Drive {
        match duty {
            Some(d) => Drive::Pwm(d),
            None => {
                let (i_abc, e_abc) = self.model.currents_and_emf(&self.x);
                Drive::Diodes(match self.open_phase {
                    None => inverter::diode_legs(i_abc, e_abc, bus_voltage_v),
                    Some(k) => inverter::diode_legs_open(i_abc, e_abc, bus_voltage_v, k),
                })
            }
        }
    }

    /// Sensors at this instant (noise and quantisation drawn from the seed).
    pub fn sample(&mut self) -> SensorSample {
        let truth = sensors::Truth {
            phase_current_a: self.effects.sensed_currents(self.state.phase_current_a),
            theta_m_rad: self.effects.encoder_angle(self.x[THETA_M]),
            bus_voltage_v: self.bus_v,
            rod_position_m: self.x[X_ROD],
            load_cell_force_n: self.state.load_cell_force_n,
        };
        self.sensors.sample(&truth)
    }

    pub fn state(&self) -> &PlantState {
        &self.state
    }

    pub fn bench_sensors(&self) -> &sensors::BenchSensors {
        &self.sensors.bench
    }

    /// The bench's sensor facts (encoder zero, current bias, home switch,
    /// heat-sink temperature): none by default.
    pub fn bench_sensors_mut(&mut self) -> &mut sensors::BenchSensors {
        &mut self.sensors.bench
    }

    /// Puts the holding brake's disc on (coil off) at the present angle, as
    /// a drive that was switched off leaves it.
    pub fn engage_brake(&mut self) {
        self.brake.engage_now(self.x[THETA_M]);
    }

    /// True while the brake's disc holds.
    pub fn brake_engaged(&self) -> bool {
        self.brake.engaged()
    }

    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// The raw state vector `[i_d, i_q, θ_m, ω_m, θ_s, ω_s, x_r, v_r]`.
    pub fn state_vector(&self) -> &StateVec {
        &self.x
    }

    /// The deformation model (static deflection, stiffness, inversions).
    pub fn compliance(&self) -> &Compliance {
        &self.model.compliance
    }

    /// δ1..δ5 (+ coupling) at axial force `F` and stroke `x`, at standstill.
    pub fn static_deflection(&self, force_n: f64, x_m: f64) -> Deflection {
        self.model.compliance.static_deflection(force_n, x_m)
    }

    /// Axial load `m g sin(tilt) + F_ext` at the present tilt and force.
    pub fn load_force_n(&self) -> f64 {
        self.model.load_force_from_sin(self.sin_tilt, self.external_force_n)
    }

    /// q-axis current that holds axial force `F` at rest: `L F/(2π · 1.5 p ψ_f)`.
    pub fn holding_current_a(&self, force_n: f64) -> f64 {
        self.model.metres_per_rad * force_n / (1.5 * self.model.motor.pole_pairs * self.model.motor.flux_wb)
    }

    /// The inverter's present drive mode (duties, or conducting diodes).
    pub fn drive(&self) -> Drive {
        self.drive
    }

    /// Stored energy and power flows at this instant, under the last drive.
    pub fn energy_audit(&self) -> EnergyAudit {
        let inputs = self.inputs();
        let mut guess = self.warm;
        let e = self.model.evaluate_warm(&self.x, &inputs, &mut guess);
        self.model.energy_audit(&self.x, &e, inputs.load_force_n)
    }

    fn inputs(&self) -> Inputs {
        Inputs {
            drive: self.drive,
            bus_v: self.bus_v,
            load_force_n: self.load_force_n(),
            open_phase: self.open_phase,
            brake: self.brake.torque_law(),
        }
    }

    fn force_open_phase(&mut self, k: usize) {
        let (sin_e, cos_e) = (self.model.motor.pole_pairs * self.x[THETA_M]).sin_cos();
        let i_abc = frames::dq_to_abc(self.x[I_D], self.x[I_Q], sin_e, cos_e);
        let (d, q) = frames::abc_to_dq(inverter::force_open(i_abc, k), sin_e, cos_e);
        self.x[I_D] = d;
        self.x[I_Q] = q;
    }

    /// Duties the power stage will actually produce. A timer compare
    /// register cannot hold a value outside [0, 1] (or NaN): such a duty
    /// saturates (NaN to 0, as a float-to-integer cast does), and the event
    /// is counted in the state.
    fn saturate_duties(&mut self, duty: [f64; 3]) -> [f64; 3] {
        duty.map(|d| {
            if (0.0..=1.0).contains(&d) {
                d
            } else {
                self.duty_saturation_count += 1;
                if d > 1.0 { 1.0 } else { 0.0 }
            }
        })
    }

    fn enforce_diode_blocking(&mut self, legs: [Leg; 3]) {
        let (sin_e, cos_e) = (self.model.motor.pole_pairs * self.x[THETA_M]).sin_cos();
        let i_abc = frames::dq_to_abc(self.x[I_D], self.x[I_Q], sin_e, cos_e);
        let fixed = inverter::enforce_blocking(legs, i_abc);
        if fixed != i_abc {
            let (d, q) = frames::abc_to_dq(fixed, sin_e, cos_e);
            self.x[I_D] = d;
            self.x[I_Q] = q;
        }
    }

    fn refresh_state(&mut self) {
        let inputs = self.inputs();
        let mut guess = self.warm;
        let terms = self.model.state_terms(&self.x, &mut guess);
        let e = self.model.finish(&self.x, &terms, &inputs);
        self.record_terms = Some(RecordTerms { x: self.x, terms, warm: guess });
        let m = &self.model;
        let x = &self.x;
        let motor_side = m.motor_side_position_m(x[THETA_M]);
        let e_abc = m.motor.back_emf_abc(x[OMEGA_M], e.sin_e, e.cos_e);
        let accel = e.deriv[V_ROD];
        self.state = PlantState {
            time_s: self.time_s,
            i_d_a: x[I_D],
            i_q_a: x[I_Q],
            theta_m_rad: x[THETA_M],
            omega_m_rad_s: x[OMEGA_M],
            theta_s_rad: x[THETA_S],
            omega_s_rad_s: x[OMEGA_S],
            x_rod_m: x[X_ROD],
            v_rod_m_s: x[V_ROD],
            motor_side_position_m: motor_side,
            screw_side_position_m: e.screw_position,
            terminal_position_m: x[X_ROD],
            terminal_error_m: x[X_ROD] - motor_side,
            axial_force_n: e.axial_force,
            motor_torque_n_m: e.motor_torque,
            coupling_torque_n_m: e.coupling_torque,
            electrical_angle_rad: (m.motor.pole_pairs * x[THETA_M]).rem_euclid(std::f64::consts::TAU),
            phase_current_a: frames::dq_to_abc(x[I_D], x[I_Q], e.sin_e, e.cos_e),
            phase_voltage_v: inverter::phase_voltages_open(&self.drive, self.bus_v, e_abc, self.open_phase),
            u_d_v: e.u_d,
            u_q_v: e.u_q,
            load_force_n: inputs.load_force_n,
            load_cell_force_n: m.payload_mass * (m.gravity * self.sin_tilt + accel) + self.external_force_n,
            rod_acceleration_m_s2: accel,
            tilt_rad: self.tilt_rad,
            external_force_n: self.external_force_n,
            bus_voltage_v: self.bus_v,
            inverter_enabled: matches!(self.drive, Drive::Pwm(_)),
            brake_engaged: self.brake.engaged(),
            duty_saturation_count: self.duty_saturation_count,
        };
    }
}

/// `Plant::refresh_state`'s evaluation: the state it was made at, its
/// state terms and the warm start they left.
#[derive(Clone, Copy, Debug)]
struct RecordTerms {
    x: StateVec,
    terms: StateTerms,
    warm: mechanics::WarmStart,
}
