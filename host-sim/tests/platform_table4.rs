//! The Table 4 reproduction: every pose it reports gives back the table's
//! leg lengths, and its errors are the differences of those poses.

use host_sim::platform::table4::{reproduce_paper, PAPER_SETS};
use host_sim::platform::{Platform, Pose};
use nalgebra::{Vector3, Vector6};

fn from_mm_deg(q: &[f64; 6]) -> Pose {
    Pose::new(Vector3::new(q[0], q[1], q[2]) * 1e-3, Vector3::new(q[3], q[4], q[5]).map(f64::to_radians))
}

#[test]
fn reported_poses_reproduce_the_table_lengths() {
    let p = Platform::paper();
    let results = reproduce_paper(&p).unwrap();
    for (set, r) in PAPER_SETS.iter().zip(&results) {
        for (pose, row) in [(&r.pose_given, &set.given_mm), (&r.pose_before, &set.before_mm), (&r.pose_after, &set.after_mm)] {
            let l = p.inverse(&from_mm_deg(pose)).lengths_m;
            for i in 0..6 {
                assert!((l[i] * 1e3 - row[i]).abs() < 1e-8, "{} leg {}: {} vs {}", set.name, i + 1, l[i] * 1e3, row[i]);
            }
        }
        let d = Vector6::from(r.pose_before) - Vector6::from(r.pose_given);
        assert!((d[0] - r.error_before.position_mm[0]).abs() < 1e-9 && (d[5] - r.error_before.attitude_deg[2]).abs() < 1e-9);
        assert_eq!(r.fk_starts_agreeing_min, 13, "{}: the forward solution must be unique near the guess", set.name);
    }
}

#[test]
fn a_geometry_file_with_an_impossible_layout_is_refused_naming_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    let text = host_sim::platform::geometry::PAPER_GEOMETRY_TOML.replace("leg_max_length_m = 1.05", "leg_max_length_m = 0.62");
    std::fs::write(&path, text).unwrap();
    let err = host_sim::platform::Geometry::load(&path).unwrap_err().to_string();
    assert!(err.contains("bad.toml") && err.contains("home_height_m") && err.contains("leg_max_length_m"), "{err}");
}
