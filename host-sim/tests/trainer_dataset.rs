//! Dataset loading, validation and splits by run.

use host_sim::trainer::dataset::{split, Dataset, DatasetLimits, Direction, SplitSpec, REQUIRED_COLUMNS};
use host_sim::trainer::synthetic;
use std::collections::HashSet;
use std::path::Path;

const HEADER: &str = "run_id,direction,tilt_swing_deg,payload_scale,time_s,motor_speed_rad_s,nut_speed_m_s,nut_displacement_m,load_force_n,terminal_length_m,motor_side_position_m,terminal_error_m";

fn row(run: &str, dir: &str, i: usize) -> String {
    let t = i as f64 * 1e-3;
    format!("{run},{dir},30,1,{t},{},{},{},{},{},{},{}", 10.0 + t, 0.01, 0.1 + t, 1000.0, 0.1002 + t, 0.1 + t, 0.0002)
}

fn write(dir: &Path, name: &str, lines: &[String]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, format!("{HEADER}\n{}\n", lines.join("\n"))).unwrap();
    p
}

fn run_rows(run: &str, dir: &str, n: usize) -> Vec<String> {
    (0..n).map(|i| row(run, dir, i)).collect()
}

fn limits() -> DatasetLimits {
    DatasetLimits { min_samples_per_run: 5 }
}

#[test]
fn a_valid_file_loads_runs_in_order_with_their_samples() {
    let d = tempfile::tempdir().unwrap();
    let mut lines = run_rows("b", "Contraction", 7);
    lines.extend(run_rows("a", "Elongation", 6));
    let p = write(d.path(), "one.csv", &lines);
    let ds = Dataset::load(&p, &limits()).unwrap();
    assert_eq!(ds.runs.len(), 2);
    assert_eq!((ds.runs[0].id.as_str(), ds.runs[0].len(), ds.runs[0].direction), ("a", 6, Direction::Elongation));
    assert_eq!((ds.runs[1].id.as_str(), ds.runs[1].len(), ds.runs[1].direction), ("b", 7, Direction::Contraction));
    assert_eq!(ds.runs[1].first_line, 2);
    assert_eq!(ds.runs[0].first_line, 9);
    assert_eq!(ds.runs[0].inputs[1], [10.001, 0.01, 0.101, 1000.0, 0.0]);
    assert_eq!(ds.inputs, 4, "no travel_direction column: the paper's four inputs");
    assert_eq!(ds.name, "one.csv");
}

#[test]
fn a_folder_of_csv_files_is_one_dataset_and_round_trips_through_write_csv() {
    let d = tempfile::tempdir().unwrap();
    let ds = synthetic::paper_like("syn", 4);
    for r in &ds.runs {
        Dataset::from_runs("x", vec![r.clone()]).write_csv(&d.path().join(format!("{}.csv", r.id))).unwrap();
    }
    std::fs::write(d.path().join("notes.txt"), "not a csv").unwrap();
    let back = Dataset::load(d.path(), &DatasetLimits::default()).unwrap();
    assert_eq!(back.runs.len(), 4);
    for (a, b) in ds.runs.iter().zip(&back.runs) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.direction, b.direction);
        assert_eq!(a.inputs, b.inputs, "inputs survive the CSV exactly ({{:e}} round-trips f64)");
        assert_eq!(a.terminal_error_m, b.terminal_error_m);
        assert!(b.source.ends_with(format!("{}.csv", a.id)));
    }
}

fn load_err(lines: &[String]) -> String {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "bad.csv", lines);
    format!("{:#}", Dataset::load(&p, &limits()).unwrap_err())
}

#[test]
fn a_nan_value_is_refused_naming_file_line_and_field() {
    let mut lines = run_rows("a", "Elongation", 10);
    lines[3] = lines[3].replacen(",1000,", ",NaN,", 1);
    let e = load_err(&lines);
    assert!(e.contains("bad.csv") && e.contains("line 5") && e.contains("load_force_n") && e.contains("NaN"), "{e}");
}

#[test]
fn an_infinite_empty_or_unparsable_value_is_refused() {
    let mut lines = run_rows("a", "Elongation", 10);
    lines[0] = lines[0].replacen(",0.01,", ",inf,", 1);
    let e = load_err(&lines);
    assert!(e.contains("line 2") && e.contains("nut_speed_m_s") && e.contains("not finite"), "{e}");

    let mut lines = run_rows("a", "Elongation", 10);
    lines[9] = lines[9].replacen(",0.01,", ",,", 1);
    let e = load_err(&lines);
    assert!(e.contains("line 11") && e.contains("nut_speed_m_s") && e.contains("empty"), "{e}");

    let mut lines = run_rows("a", "Elongation", 10);
    lines[4] = lines[4].replacen(",0.01,", ",fast,", 1);
    let e = load_err(&lines);
    assert!(e.contains("line 6") && e.contains("'fast' is not a number"), "{e}");
}

#[test]
fn a_missing_column_is_refused_naming_it() {
    for missing in REQUIRED_COLUMNS {
        let d = tempfile::tempdir().unwrap();
        let cols: Vec<&str> = HEADER.split(',').collect();
        let k = cols.iter().position(|c| *c == missing).unwrap();
        let keep = |s: &str| s.split(',').enumerate().filter(|(i, _)| *i != k).map(|(_, v)| v).collect::<Vec<_>>().join(",");
        let body: Vec<String> = run_rows("a", "Elongation", 6).iter().map(|l| keep(l)).collect();
        let p = d.path().join("cols.csv");
        std::fs::write(&p, format!("{}\n{}\n", keep(HEADER), body.join("\n"))).unwrap();
        let e = format!("{:#}", Dataset::load(&p, &limits()).unwrap_err());
        assert!(e.contains("cols.csv") && e.contains(&format!("missing column '{missing}'")), "{e}");
    }
}

#[test]
fn an_unknown_direction_a_short_row_or_a_run_changing_direction_is_refused() {
    let mut lines = run_rows("a", "Elongation", 10);
    lines[2] = lines[2].replace("Elongation", "Sideways");
    let e = load_err(&lines);
    assert!(e.contains("line 4") && e.contains("Sideways"), "{e}");

    let mut lines = run_rows("a", "Elongation", 10);
    lines[6] = lines[6].rsplit_once(',').unwrap().0.to_string();
    let e = load_err(&lines);
    assert!(e.contains("bad.csv"), "{e}");

    let mut lines = run_rows("a", "Elongation", 10);
    lines[8] = lines[8].replace("Elongation", "Contraction");
    let e = load_err(&lines);
    assert!(e.contains("line 10") && e.contains("changes direction"), "{e}");
}

#[test]
fn too_few_samples_in_a_run_or_no_rows_is_refused() {
    let mut lines = run_rows("a", "Elongation", 10);
    lines.extend(run_rows("short", "Contraction", 3));
    let e = load_err(&lines);
    assert!(e.contains("bad.csv") && e.contains("line 12") && e.contains("'short' has 3 samples") && e.contains("at least 5"), "{e}");

    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("empty.csv");
    std::fs::write(&p, format!("{HEADER}\n")).unwrap();
    let e = format!("{:#}", Dataset::load(&p, &limits()).unwrap_err());
    assert!(e.contains("empty.csv") && e.contains("no data row"), "{e}");
}

#[test]
fn a_run_split_over_two_files_is_refused() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "1.csv", &run_rows("a", "Elongation", 6));
    write(d.path(), "2.csv", &run_rows("a", "Elongation", 6));
    let e = format!("{:#}", Dataset::load(d.path(), &limits()).unwrap_err());
    assert!(e.contains("2.csv") && e.contains("run 'a' already appeared in") && e.contains("1.csv"), "{e}");
}

fn sides(s: &host_sim::trainer::dataset::Split) -> [HashSet<usize>; 3] {
    [s.train.iter().copied().collect(), s.validation.iter().copied().collect(), s.test.iter().copied().collect()]
}

#[test]
fn splits_put_whole_runs_on_one_side_and_follow_the_direction_rules() {
    let ds = synthetic::paper_like("syn", 20);
    let n = ds.runs.len();
    // Opposite: every contraction run is test, every elongation run trains or validates.
    let s = split(&ds, &SplitSpec::Opposite { train: Direction::Elongation }, 0.2, 3).unwrap();
    let [tr, va, te] = sides(&s);
    assert_eq!(tr.len() + va.len() + te.len(), n);
    assert!(tr.is_disjoint(&va) && tr.is_disjoint(&te) && va.is_disjoint(&te));
    assert!(te.iter().all(|&i| ds.runs[i].direction == Direction::Contraction) && te.len() == 10);
    assert!(tr.iter().chain(&va).all(|&i| ds.runs[i].direction == Direction::Elongation));
    assert_eq!(va.len(), 2);
    // Reverse.
    let s = split(&ds, &SplitSpec::Opposite { train: Direction::Contraction }, 0.2, 3).unwrap();
    assert!(s.test.iter().all(|&i| ds.runs[i].direction == Direction::Elongation));
    // Mixed: both directions in every side, a quarter of each held out.
    let s = split(&ds, &SplitSpec::Mixed { test_fraction: 0.25 }, 0.2, 3).unwrap();
    let [tr, va, te] = sides(&s);
    assert_eq!(tr.len() + va.len() + te.len(), n);
    assert!(tr.is_disjoint(&va) && tr.is_disjoint(&te) && va.is_disjoint(&te));
    for d in [Direction::Elongation, Direction::Contraction] {
        let count = |set: &HashSet<usize>| set.iter().filter(|&&i| ds.runs[i].direction == d).count();
        assert_eq!(count(&te), 3, "{d:?}: round(0.25 × 10)");
        assert!(count(&tr) > 0 && count(&va) > 0);
    }
    // Deterministic for the seed, different for another.
    assert_eq!(split(&ds, &SplitSpec::Mixed { test_fraction: 0.25 }, 0.2, 3).unwrap(), s);
    let others: Vec<_> = (4..10).map(|seed| split(&ds, &SplitSpec::Mixed { test_fraction: 0.25 }, 0.2, seed).unwrap()).collect();
    assert!(others.iter().any(|o| o.test != s.test));
}

#[test]
fn an_impossible_split_is_refused_with_a_reason() {
    let only_elongation: Vec<_> = synthetic::paper_like("syn", 6).runs.into_iter().filter(|r| r.direction == Direction::Elongation).collect();
    let ds = Dataset::from_runs("elong-only", only_elongation);
    let e = format!("{:#}", split(&ds, &SplitSpec::Opposite { train: Direction::Elongation }, 0.2, 1).unwrap_err());
    assert!(e.contains("needs runs of both directions") && e.contains("0 Contraction"), "{e}");
    let one_each = Dataset::from_runs("two", synthetic::paper_like("syn", 2).runs);
    let e = format!("{:#}", split(&one_each, &SplitSpec::Mixed { test_fraction: 0.25 }, 0.2, 1).unwrap_err());
    assert!(e.contains("only one run"), "{e}");
}
