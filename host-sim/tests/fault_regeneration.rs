//! Regeneration on a bus that cannot sink: lowering the rated payload with
//! the bus at 57 V (the bound acts between 54 and 58 V) returns no more
//! than the power the bus may take, steadily (no limit cycle), and trips
//! nothing.

use host_sim::config::RigConfig;
use host_sim::plant::Plant;
use host_sim::sim::{commissioned_control, ClosedLoop};
use servo_core::{Command, Controller, LimitFlags};
use std::f64::consts::FRAC_PI_2;

#[test]
fn lowering_on_a_high_bus_returns_at_most_the_allowed_power() {
    let rig = RigConfig::nominal().unwrap();
    let bus = 57.0;
    let mut plant = Plant::new(rig.plant.clone(), 5);
    plant.set_initial_state(0.25 / rig.plant.metres_per_rad(), FRAC_PI_2);
    let c = Controller::try_new(commissioned_control(rig.control, &plant)).unwrap();
    let ps = c.params().power_stage;
    let allowed_w = f64::from(ps.regen_power_max_w) * (f64::from(ps.regen_bus_max_v) - bus)
        / f64::from(ps.regen_bus_max_v - ps.regen_bus_start_v);
    let mut cl = ClosedLoop::new(c, plant, bus);
    cl.controller.command(Command::SetHome { position_m: 0.25 }).unwrap();
    cl.controller.command(Command::Enable).unwrap();
    for _ in 0..4000 {
        cl.step();
    }
    cl.controller.command(Command::MoveTo { position_m: 0.15 }).unwrap();
    let (mut worst_w, mut speeds, mut regen_flagged) = (0.0f64, vec![], false);
    for k in 0..40_000u32 {
        let t = cl.step();
        assert!(t.faults.is_empty(), "period {k}: {:?}", t.faults);
        regen_flagged |= t.limits.contains(LimitFlags::REGEN);
        if k > 4000 && k % 20 == 0 {
            let s = cl.sampled_state();
            // Mechanical power the load pushes into the motor (> 0: generating).
            worst_w = worst_w.max(-s.motor_torque_n_m * s.omega_m_rad_s);
            speeds.push(s.v_rod_m_s);
        }
    }
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    let sd = (speeds.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / speeds.len() as f64).sqrt();
    println!("allowed {allowed_w:.1} W, worst returned {worst_w:.1} W; descent {:.2} mm/s ± {:.2}", mean * 1e3, sd * 1e3);
    assert!(regen_flagged);
    // Shaft power includes what the winding and friction dissipate: the bus
    // sees less than this. 20 % for the speed loop's ripple.
    assert!(worst_w <= 1.2 * allowed_w, "returned {worst_w} W, allowed {allowed_w} W");
    assert!(mean < -0.002, "the payload is still lowered ({mean} m/s)");
    assert!(sd < 0.2 * mean.abs(), "unsteady descent: {mean} ± {sd} m/s");
}
