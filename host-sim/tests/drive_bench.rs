//! `drive bench-stream`: the paper run's reference streamed at 1 kHz
//! through the simulated drive over TCP meets the tracking bar (the planned
//! move's: motor-side tracking RMS ≤ 5 µm, max ≤ 50 µm), with no refusal.

use host_sim::config::RigConfig;

#[test]
fn the_paper_reference_streamed_at_1_khz_meets_the_bar() {
    let dir = tempfile::tempdir().unwrap();
    let s = host_sim::tool::bench::run(&RigConfig::nominal().unwrap(), dir.path()).unwrap();
    println!("{}", serde_json::to_string_pretty(&s).unwrap());
    assert_eq!(s["refusals"], 0);
    assert_eq!(s["telemetry_records"], s["stream_points"]);
    assert!(s["faults"].as_array().unwrap().is_empty());
    assert!(s["motor_tracking_rms_um"].as_f64().unwrap() <= 5.0);
    assert!(s["motor_tracking_max_um"].as_f64().unwrap() <= 50.0);
    assert_eq!(s["capture"]["samples"], servo_core::capture::CAPTURE_STORE_CELLS / 4);
    assert!(dir.path().join("summary.json").exists() && dir.path().join("capture.csv").exists());
}
