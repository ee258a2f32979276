//! Six closed-loop legs follow a pose trajectory by streamed setpoints.

use host_sim::config::RigConfig;
use host_sim::platform::six_legs::RigSpread;
use host_sim::platform::stream::{run_stream, StreamOptions};
use host_sim::platform::{Platform, Trajectory};

#[test]
#[ignore]
fn explore() {
    let p = Platform::paper();
    let rig = RigConfig::nominal().unwrap();
    let name = std::env::var("TRAJ").unwrap_or("combined".into());
    let traj = Trajectory::all(&p).into_iter().find(|t| t.name == name).unwrap();
    for (comp, ff) in [(false, false), (false, true), (true, false), (true, true)] {
        let r = run_stream(&p, &rig, &traj, &StreamOptions::new(comp, ff, RigSpread::NONE)).unwrap();
        println!(
            "comp {comp} ff {ff} scale {:.3} peak {:.3}/{:.3}: pos rms {:.4} max {:.4} mm, att rms {:.5} max {:.5} deg, lag {:?}, term rms {:?}, motor rms {:?}, limits {}, rtf {:.1}",
            r.amplitude_scale, r.peak_leg_rate_full_m_s, r.peak_leg_rate_streamed_m_s, r.pose_error_position_rms_mm, r.pose_error_position_max_mm, r.pose_error_attitude_rms_deg, r.pose_error_attitude_max_deg,
            r.reference_lag_check_um, r.terminal_error_rms_um.map(|v| v.round()), r.motor_tracking_rms_um.map(|v| (v*100.0).round()/100.0), r.limits_seen, r.sim_realtime_factor
        );
    }
}

#[test]
#[ignore]
fn rates() {
    let p = Platform::paper();
    for traj in Trajectory::all(&p) {
        for ramp in [0.5, 1.0, 2.0] {
            let mut vmax: f64 = 0.0;
            let mut amax: f64 = 0.0;
            let mut prev: Option<nalgebra::Vector6<f64>> = None;
            for k in 0..(traj.duration_s * 1000.0) as usize {
                let s = host_sim::platform::stream::commanded(&traj, ramp, k as f64 * 1e-3);
                let r = p.pose_jacobian(&s.pose) * s.velocity;
                if let Some(pr) = prev { amax = amax.max(((r - pr) / 1e-3f64).amax()); }
                prev = Some(r);
                vmax = vmax.max(r.amax());
            }
            println!("{} ramp {ramp}: leg rate max {vmax:.3} m/s, accel max {amax:.2} m/s²", traj.name);
        }
    }
}
