//! The shipped parameter set, [`ControlParams::DEFAULT`], with the reasoning
//! for each value, and the 24 V bench variant.

use core::f32::consts::PI;

use super::*;

const CURRENT_BANDWIDTH_RAD_S: f32 = 2.0 * PI * 1000.0;
const MOTOR_R_OHM: f32 = 0.12;
const MOTOR_L_H: f32 = 0.35e-3;
const MOTOR_PSI_WB: f32 = 0.0175;
const POLE_PAIRS: u32 = 4;
/// Rotor 0.30e-4 + coupling 0.02e-4 + Ø20×600 mm steel screw 0.74e-4 kg·m².
const ROTATING_INERTIA: f32 = 1.06e-4;
/// Rated thrust 1.38 kN borne vertically: 1380 / 9.81 ≈ 140.7 kg nut+rod+payload.
const MOVING_MASS_KG: f32 = 140.7;
const LEAD_M: f32 = 0.005;
const SPEED_BANDWIDTH_RAD_S: f32 = 2.0 * PI * 40.0;
const ENCODER_PLL_RAD_S: f32 = 2.0 * PI * 400.0;

impl ControlParams {
    pub const DEFAULT: Self = Self {
        motor: MotorParams {
            pole_pairs: POLE_PAIRS,
            phase_resistance_ohm: MOTOR_R_OHM,
            inductance_d_h: MOTOR_L_H,
            inductance_q_h: MOTOR_L_H,
            // 1.5·4·0.0175 = 0.105 N·m/A: rated 1.27 N·m at ≈12 A; back-EMF at
            // 3000 rpm is 22 V peak, inside 48 V/√3 = 27.7 V.
            flux_linkage_wb: MOTOR_PSI_WB,
        },
        drive_train: DriveTrainParams {
            screw_lead_m: LEAD_M,
            // DESIGN.md check: 1.38 kN × 5 mm / (2π·0.9) ≈ 1.22 N·m.
            screw_efficiency: 0.9,
            rotating_inertia_kg_m2: ROTATING_INERTIA,
            moving_mass_kg: MOVING_MASS_KG,
            viscous_friction_n_m_s_rad: 2.0e-4,
            // Nut preload drag 0.03 N·m + rod seal 30 N × L/2π (0.024 N·m).
            coulomb_friction_n_m: 0.054,
            // 1 rad/s is 0.8 mm/s of rod: the S-curve passes it in ≈8 ms, so
            // the friction step is taken as a ramp, not a kick to the rod mode.
            friction_feedforward_speed_rad_s: 1.0,
            friction_feedforward_gain: 1.0,
        },
        rates: RateParams { pwm_frequency_hz: 20_000.0, speed_loop_divider: 4, position_loop_divider: 20 },
        // Pole-zero cancellation: kp = L·ω_c, ki = R·ω_c with ω_c = 2π·1 kHz,
        // a twentieth of the PWM rate so the one-period delay costs < 20° phase.
        current_pi: PiGains {
            kp: MOTOR_L_H * CURRENT_BANDWIDTH_RAD_S,
            ki: MOTOR_R_OHM * CURRENT_BANDWIDTH_RAD_S,
        },
        // kp = J_total ω_s / K_t with ω_s = 2π·40 Hz (J_total = 1.95e-4 kg·m²,
        // K_t = 0.105 N·m/A); ki = kp·ω_s/4 puts the PI zero a quarter-decade
        // below crossover. 40 Hz stays clear of the ≈28 Hz rod resonance's
        // anti-resonance region while rejecting the gravity load quickly.
        speed_pi: PiGains {
            kp: 1.95e-4 * SPEED_BANDWIDTH_RAD_S / 0.105,
            ki: 1.95e-4 * SPEED_BANDWIDTH_RAD_S / 0.105 * SPEED_BANDWIDTH_RAD_S / 4.0,
        },
        speed_setpoint_weight: 1.0,
        // The coupling + screw-twist torsional mode sits near 370 Hz at full
        // extension (lower stiffness) with ≈2 % damping; 150 Hz takes its
        // loop gain under one and costs ≈22° at the 40 Hz crossover.
        torque_filter_hz: 150.0,
        // A quarter of the speed bandwidth (ω_s/4 ≈ 63/s): no overshoot; the
        // velocity feedforward carries the tracking.
        position_kp_per_s: SPEED_BANDWIDTH_RAD_S / 4.0,
        encoder: EncoderParams {
            counts_per_rev: 10_000,
            direction: 1,
            electrical_offset_rad: 0.0,
            pll_kp_per_s: 2.0 * ENCODER_PLL_RAD_S,
            pll_ki_per_s2: ENCODER_PLL_RAD_S * ENCODER_PLL_RAD_S,
        },
        // 80 % of Table 1's rated 250 mm/s: at exactly rated speed the
        // position loop has no speed left to correct with (the 3000 rpm limit
        // binds) and the back-EMF leaves no voltage for the current loop.
        // 2.5 m/s² with a 0.1 s jerk time.
        trajectory: TrajectoryParams {
            max_velocity_m_s: 0.2,
            max_acceleration_m_s2: 2.5,
            max_jerk_m_s3: 25.0,
        },
        limits: LimitParams {
            // Three times rated current, the usual servo peak rating.
            current_max_a: 36.0,
            // 1.5·0.12·33.3² = 200 W: twice the rated-torque copper loss plus
            // margin; above it the winding heats faster than the I²t model allows.
            copper_power_max_w: 200.0,
            // 3000 rpm.
            speed_max_rad_s: 2.0 * PI * 3000.0 / 60.0,
            stroke_min_m: 0.0,
            stroke_max_m: 0.5,
            max_modulation: 0.95,
        },
        faults: FaultParams {
            overcurrent_trip_a: 45.0,
            bus_overvoltage_v: 60.0,
            bus_undervoltage_v: 36.0,
            // 3000 rpm = 500 counts per 50 µs at 10 000 counts/rev; 4× margin.
            encoder_max_step_counts: 2_000,
            // 100 counts (3.6° mechanical, 14° electrical): the observer lags
            // the rotor's peak acceleration (36 A on the rotor alone) by ≈30.
            encoder_max_innovation_counts: 100.0,
            position_following_error_m: 0.005,
            stroke_overtravel_m: 0.005,
            // A quarter of rated speed for 50 ms: far outside what the loop
            // leaves in normal running (a few rad/s), quick enough that the
            // rod moves < 5 mm before the stop.
            speed_following_error_rad_s: 80.0,
            speed_following_time_s: 0.05,
            // 30 rad/s gives 48 counts per ms at 10 000 counts/rev; none in
            // 20 ms is no quantisation effect.
            encoder_lost_speed_rad_s: 30.0,
            encoder_lost_time_s: 0.02,
            // Stops land within 2 mm of the stroke ends, inside the 5 mm
            // overtravel trip and the end stops 10 mm out.
            stroke_soft_margin_m: 0.002,
            // Twice the trajectory's: a stop is shorter than any planned move.
            stop_deceleration_m_s2: 5.0,
            // The paper's largest compensation, 1.5 mm, with a third more room.
            observer_shift_max_m: 0.002,
            // ≈100 ADC codes of the ESC1's 29 mA/code: far above noise and
            // quantisation, far below a stuck sensor at rated current (12 A).
            current_sum_max_a: 3.0,
            // 0.5 ms: noise on three channels (σ_Σ = 1.7 A for 1 A each) stays
            // above 3 A ten periods running with odds of 1e-11.
            current_sum_periods: 10,
            // 3 mm: the stop starts from the measured position, so anything
            // near the 5 mm following trip means the load is winning.
            stop_following_error_m: 0.003,
            // 2 ms is a tenth of an electrical turn at rated speed and two
            // windows fit in the 5 ms the open-phase scenario allows. 1 A
            // mean is met within two windows of an open lead by the lightest
            // payload (the speed loop asks more as the torque falls); an
            // open lead carries noise only (mean |i| ≈ 0.8 σ = 0.024 A at the
            // ESC1's 0.03 A), far under the 0.2 A (20 % of 1 A, 7 ADC codes)
            // an empty phase may carry. A loop that cannot make its current
            // (a frame that slips under a frozen encoder) still leaves more
            // than that in a phase asked for less than 1 A.
            open_phase_window_s: 0.002,
            open_phase_current_a: 1.0,
            open_phase_ratio: 0.2,
        },
        load_estimate: LoadEstimateParams { filter_hz: 5.0 },
        // Nothing is known at power-up on an incremental encoder, and nothing
        // moves until asked. The expected load is the rated thrust borne
        // vertically (the payload behind `MOVING_MASS_KG`).
        startup: StartupParams {
            commutation_known: false,
            homed: false,
            expected_load_force_n: 1380.0,
            run_at_power_up: false,
        },
        // 2 A is ≈ 70 ESC1 codes, a tenth of the amplifier's range; 1 A RMS
        // is 35 codes of noise, ten times what a healthy channel shows.
        calibration: CalibrationParams { duration_s: 0.1, offset_max_a: 2.0, noise_max_a: 1.0, bus_ripple_max_v: 2.0 },
        // Reasons in `CommutationParams`. 0.03 rad of twist is 2.4× what
        // the 2.5 N·m disc gives elastically (≈ 200 N·m/rad catalogue class):
        // beyond it the disc slipped.
        commutation: CommutationParams {
            test_current_a: 8.0,
            ramp_s: 0.05,
            sweep_s: 0.5,
            settle_s: 0.05,
            settle_speed_rad_s: 0.5,
            settle_timeout_s: 1.0,
            min_amplitude_counts: 1.5,
            max_twist_rad: 0.03,
            hold_current_d_a: 25.0,
            check_angle_rad: 0.2,
            check_time_s: 0.3,
            ratio_tolerance: 0.15,
            blocked_ratio: 0.3,
            timeout_s: 5.0,
        },
        // Into the lower end stop (10 mm below stroke 0, `plant.stroke`),
        // contact at home_position −0.010 m, then back to stroke 0 + 2 mm.
        homing: HomingParams {
            method: HomingMethod::HardStop,
            direction: -1,
            speed_m_s: 0.02,
            current_max_a: 15.0,
            contact_following_m: 0.0005,
            contact_speed_rad_s: 0.5,
            contact_time_s: 0.3,
            home_position_m: -0.010,
            backoff_m: 0.012,
            travel_max_m: 0.53,
            jog_speed_max_m_s: 0.01,
        },
        // A 48 V stage: fold back from 80 °C, trip at 100 °C (MOSFET
        // junctions ≈ 25 K above the sink at rated current). Regeneration:
        // the bus capacitors take what 54 → 58 V allows, below the 60 V trip;
        // 50 W is what a bench supply with its own small sink may absorb.
        // Back-EMF check: 20 rad/s is 80 rad/s electrical, 1.4 V of EMF, far
        // above the dead-time voltage error at standstill current; netted
        // over 20 ms, the dead time's wobble and a platform leg's reversals
        // cancel (10 ms tripped a streamed platform leg falsely).
        stream: StreamParams {
            period_max_s: 0.01,
            timeout_s: 0.05,
            leg_index: 0,
            can_termination: false,
            velocity_mismatch_max_m_s: super::stream::VELOCITY_MISMATCH_MAX_DEFAULT_M_S,
        },
        power_stage: PowerStageParams {
            temperature_foldback_c: 80.0,
            temperature_trip_c: 100.0,
            regen_bus_start_v: 54.0,
            regen_bus_max_v: 58.0,
            regen_power_max_w: 50.0,
            emf_speed_mismatch_rad_s: 20.0,
            emf_mismatch_time_s: 0.02,
        },
        // Rated torque 1.27 N·m at K_t = 0.105 → 12 A continuous. A 400 W
        // servo winding's thermal time constant is minutes; 30 s is on the
        // safe side and still allows 3× current for ≈3.5 s from cold.
        thermal: ThermalParams { continuous_current_a: 12.0, time_constant_s: 30.0, foldback_start: 0.8, trip_level: 1.05 },
        // Motor: 3× rated peak (catalogue class); inverter: a 48 V stage
        // rated 50 A peak (the overcurrent trip at 45 A must sit below it); bus: 63 V capacitors; speed: motor 3000 rpm rating (the
        // Ø20×5 screw's critical speed at 600 mm is higher).
        ratings: RatingParams {
            motor_peak_current_a: 36.0,
            inverter_peak_current_a: 50.0,
            bus_max_voltage_v: 63.0,
            speed_max_rad_s: 2.0 * PI * 3000.0 / 60.0,
        },
        // Off at power-up: the operator switches it on once the model in the
        // log is the one trained for this rig. 20 mm/s: the full 0.3 mm sag is
        // taken up in 15 ms, faster than the load changes, and a jump in the
        // load estimate moves the rod at most 20 µm per millisecond.
        compensation: CompensationParams {
            enabled_at_start: false,
            shift_max_m: 0.0015,
            shift_rate_max_m_s: 0.02,
            force_from_estimate: false,
        },
        // Catalogue class for a 2.5 N·m spring-applied servo brake (≈2× the
        // 1.1 N·m that holds rated thrust): 50 ms to open, 30 ms to close.
        // Preload: 20 ms is eight speed-loop time constants at 40 Hz.
        brake: BrakeParams { fitted: true, release_time_s: 0.05, engage_time_s: 0.03, holding_torque_n_m: 2.5, preload_time_s: 0.02,
            // 10 µm: the most a release may sag with the right commutation
            // (the power-up bar; 4.6 µm measured over the rig family), and
            // early: the short-circuit sink through the brake's 25 ms
            // engage time (≈ 12 mm/s at rated load) is most of the drop.
            torque_watch_travel_m: 1.0e-5,
            // 0.5 mm: fifty times a 200 N·m/rad disc's twist at its holding
            // torque (10 µm of rod), a sixth of the stop's 3 mm error bound.
            handover_slip_m: 5.0e-4 },
    };
}

impl ControlParams {
    /// The same drive on a 24 V bench supply (B-G431B-ESC1: 28 V max). The
    /// motor's back-EMF reaches the 24 V linear range at about 1700 rpm, so
    /// the speed limit drops to 1500 rpm and the trajectory to 100 mm/s
    /// (1200 rpm); the bus trips move to the supply's window. Everything else
    /// — gains, current limits, stroke — is the default.
    pub const BENCH_24V: Self = {
        let mut p = Self::DEFAULT;
        p.faults.bus_overvoltage_v = 28.0;
        p.faults.bus_undervoltage_v = 18.0;
        p.limits.speed_max_rad_s = 2.0 * PI * 1500.0 / 60.0;
        p.trajectory.max_velocity_m_s = 0.1;
        // Regeneration bounded between 25 and 27 V, under the 28 V trip.
        p.power_stage.regen_bus_start_v = 25.0;
        p.power_stage.regen_bus_max_v = 27.0;
        p
    };
}

impl Default for ControlParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}
