//! Motion faults: the load, the mechanics and what is commanded.

use super::*;

/// +1.5 kN for 100 ms on top of the rated 1.38 kN (2.1× rating): within the
/// drive's 36 A peak (≈4.3 kN), ridden through.
pub fn load_spike(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "load_spike",
        what: "+1.5 kN load step for 100 ms (2.1× rated thrust in all) while moving",
        setup: base(rig),
        injections: vec![during(FAULT_AT_S, FAULT_AT_S + 0.1, Injection::ExternalForce { newtons: 1500.0 })],
        commands: moving(),
        duration_s: 0.9,
        fault_at_s: None,
        expect: ride_through(),
    }
}

/// The cylinder's rated thrust (the paper's Table 1), newtons.
pub const RATED_THRUST_N: f64 = 1380.0;

/// The load `load_beyond_rating` puts on the rod in all, in rated thrusts.
pub const BEYOND_RATING_TOTAL: f64 = 3.9;

/// The push `load_beyond_rating` adds to the rig's own weight: +4 kN, and on
/// a rig lighter than rated the weight it lacks on top, so that the rod
/// carries 3.9× the rated thrust in all on every rig. The scenario states a
/// load relative to the rating: +4 kN alone on a near-empty rod (7.2 kg
/// moving, 2.9× rated in all) is less than the drive holds against
/// back-driving (≈ 4.8 kN), not a load beyond the rating. A heavier rig
/// keeps the 4 kN (3.9× or more in all).
pub fn beyond_rating_push_n(rig: &RigConfig) -> f64 {
    let p = &rig.plant;
    let weight_n = p.moving_mass_kg() * p.load.gravity_m_s2 * Setup::nominal(rig).tilt_deg.to_radians().sin();
    (BEYOND_RATING_TOTAL * RATED_THRUST_N - weight_n).max(4000.0)
}

/// 3.9× the rated thrust in all for 200 ms (+4 kN on the rated payload,
/// the weight a lighter rod lacks made up): beyond the drive's peak thrust.
pub fn load_beyond_rating(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "load_beyond_rating",
        what: "3.9× rated thrust in all for 200 ms (+4 kN on the rated payload) while moving",
        setup: base(rig),
        injections: vec![during(FAULT_AT_S, FAULT_AT_S + 0.2, Injection::ExternalForce { newtons: beyond_rating_push_n(rig) })],
        commands: moving(),
        duration_s: 1.0,
        fault_at_s: None,
        // Beyond the rating neither the motor nor (on a light rod) the brake
        // holds the load alone; together they do. The rod moves while the
        // stop strays its 3 mm and the brake closes under the loops (≈ 0.2
        // m/s over its 30 ms), then stays: bounded at 15 mm from where it
        // was at the latch, and the run ends at rest, held or on the brake.
        expect: Expect {
            travel_after_latch_max_m: Some(BEYOND_RATING_TRAVEL_MAX_M),
            ends_at_rest: true,
            ..expect(FaultSet::POSITION_FOLLOWING, Mode::Stopping, 1000)
        },
    }
}

/// How far the rod may go after `load_beyond_rating` latched, metres.
pub const BEYOND_RATING_TRAVEL_MAX_M: f64 = 0.015;

/// The rod runs into a rigid obstacle 20 mm ahead during a move (a
/// collision, a jammed guide): 20 N/µm, steel structure class.
pub fn stall(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "stall",
        what: "rod runs into a rigid obstacle (2e7 N/m) at 300 mm while moving to 350 mm",
        setup: base(rig),
        injections: vec![at(0.0, Injection::Obstacle { position_m: 0.30, stiffness_n_m: 2.0e7 })],
        commands: moving(),
        duration_s: 1.2,
        fault_at_s: None,
        // After the latch the rod only rings on the contact (the payload on
        // the structure's and the obstacle's stiffness, fed by the impact
        // and decaying), never faster than it struck; where the latch falls
        // in that ringing is chance. A bridge switched off under the load
        // lets it fall (g over the brake's engage time) faster than that.
        expect: Expect { rod_no_faster_than_impact: true, ..expect(FaultSet::POSITION_FOLLOWING, Mode::Stopping, 1000) },
    }
}

/// The drive is enabled with the rod 2.2 mm beyond the top of the stroke
/// (moved there by hand, or homed wrongly): the soft limit sees a rest
/// position beyond `stroke_max + stroke_soft_margin_m` at the first
/// position period, and the controlled stop brings the rod back to the
/// stroke end (its reference is clamped to the stroke) and holds.
pub fn soft_limit(rig: &RigConfig) -> Scenario {
    let mut setup = base(rig);
    setup.position_m = 0.5022;
    Scenario {
        name: "soft_limit",
        what: "enabled with the rod 2.2 mm beyond the top of the stroke",
        setup,
        injections: vec![],
        commands: vec![],
        duration_s: 0.5,
        fault_at_s: Some(0.0),
        expect: expect(FaultSet::SOFT_LIMIT, Mode::Stopping, 20),
    }
}

/// The observer's output bound shrunk to 10 µm (below the ≈0.25 mm
/// deformation it predicts under rated load), then compensation switched on.
pub fn observer_out_of_bounds(rig: &RigConfig) -> Scenario {
    let mut setup = base(rig);
    setup.control.faults.observer_shift_max_m = 1e-5;
    setup.control.compensation.shift_max_m = 1e-5;
    Scenario {
        name: "observer_out_of_bounds",
        what: "compensation switched on with the observer bound at 10 µm while holding",
        setup,
        injections: vec![],
        commands: vec![CommandAt { at_s: FAULT_AT_S, command: Command::SetCompensation { enabled: true } }],
        duration_s: 0.8,
        fault_at_s: Some(FAULT_AT_S),
        expect: expect(FaultSet::OBSERVER_OUT_OF_BOUNDS, Mode::Stopping, 20),
    }
}

/// A 200 mm reference jump (250 → 450 mm in one command) and the largest
/// allowed setpoint shift in one step: planned, not stepped.
pub fn reference_jump(rig: &RigConfig) -> Scenario {
    let max_shift = rig.control.faults.observer_shift_max_m;
    Scenario {
        name: "reference_jump",
        what: "MoveTo 450 mm from rest at 250 mm, then a full-bound position-shift step",
        setup: base(rig),
        injections: vec![],
        commands: vec![
            CommandAt { at_s: FAULT_AT_S, command: Command::MoveTo { position_m: 0.45 } },
            CommandAt { at_s: 1.8, command: Command::SetPositionShift { shift_m: max_shift } },
            CommandAt { at_s: 1.8, command: Command::SetPositionShift { shift_m: 10.0 * max_shift } },
        ],
        duration_s: 2.1,
        fault_at_s: Some(FAULT_AT_S),
        expect: ride_through(),
    }
}

/// NaN and infinite references are refused; nothing moves.
pub fn nan_reference(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "nan_reference",
        what: "MoveTo NaN / +∞, SetPositionShift NaN, SetHome NaN while moving",
        setup: base(rig),
        injections: vec![],
        commands: vec![
            CommandAt { at_s: 0.4, command: Command::MoveTo { position_m: f32::NAN } },
            CommandAt { at_s: 0.4, command: Command::MoveTo { position_m: f32::INFINITY } },
            CommandAt { at_s: 0.4, command: Command::SetPositionShift { shift_m: f32::NAN } },
            CommandAt { at_s: 0.4, command: Command::SetHome { position_m: f32::NAN } },
            CommandAt { at_s: 0.4, command: Command::MoveTo { position_m: MOVE_TO_M as f32 } },
            CommandAt { at_s: FAULT_AT_S, command: Command::MoveTo { position_m: f32::NAN } },
        ],
        duration_s: 1.3,
        fault_at_s: Some(0.4),
        expect: ride_through(),
    }
}

/// Setpoints beyond both ends are clamped (and reported); the rod stops at
/// the ends without touching the soft limits.
pub fn out_of_stroke_setpoint(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "out_of_stroke_setpoint",
        what: "MoveTo 800 mm, then MoveTo −300 mm",
        setup: base(rig),
        injections: vec![],
        commands: vec![
            CommandAt { at_s: 0.4, command: Command::MoveTo { position_m: 0.8 } },
            CommandAt { at_s: 2.2, command: Command::MoveTo { position_m: -0.3 } },
        ],
        duration_s: 5.5,
        fault_at_s: Some(0.4),
        expect: ride_through(),
    }
}
