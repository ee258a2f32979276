//! End-to-end training on data whose truth is known.

use host_sim::trainer::dataset::{Dataset, Direction, ModelKind, Run, SplitSpec, N_INPUTS, STATIC_INPUTS};
use host_sim::trainer::ibas::IbasOptions;
use host_sim::trainer::network::{Normaliser, Rbf, TrainedModel};
use host_sim::trainer::optim::{minimise, Method, OptimOptions};
use host_sim::trainer::{synthetic, train_dataset, DataSource, TrainOptions};
use indicatif::ProgressBar;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Physical input ranges the teacher's inputs are drawn from (the paper's
/// four; the fifth slot unused).
const LO: [f64; N_INPUTS] = [-350.0, -0.28, 0.0, 200.0, 0.0];
const HI: [f64; N_INPUTS] = [350.0, 0.28, 0.45, 1500.0, 0.0];

/// A point of the box (the fifth, unused slot at 0).
fn draw(rng: &mut ChaCha8Rng) -> [f64; N_INPUTS] {
    std::array::from_fn(|j| if j < STATIC_INPUTS { rng.random_range(LO[j]..HI[j]) } else { 0.0 })
}

/// A known RBF network (5 units) in metres, over the box above.
fn teacher() -> TrainedModel {
    let rbf = Rbf::new(5);
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut p = rbf.init_random(&mut rng);
    let n = p.len();
    p[n - 1] = 0.3; // bias
    for k in 0..5 {
        p[5 * STATIC_INPUTS + k] = 0.9_f64.ln(); // widths 0.9
    }
    let norm = Normaliser { input_min: LO, input_max: HI, output_offset: 2e-4, output_scale: 1e-4 };
    TrainedModel { kind: ModelKind::Error, rbf, params: p, norm, force_source: None }
}

fn teacher_dataset(runs: usize, per_run: usize) -> Dataset {
    let t = teacher();
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let runs = (0..runs)
        .map(|i| {
            let mut r = Run {
                id: format!("r{i:02}"),
                direction: if i % 2 == 0 { Direction::Elongation } else { Direction::Contraction },
                tilt_swing_deg: 30.0,
                payload_scale: 1.0,
                source: "teacher".into(),
                first_line: 2,
                time_s: vec![],
                inputs: vec![],
                terminal_length_m: vec![],
                motor_side_position_m: vec![],
                terminal_error_m: vec![],
            };
            for s in 0..per_run {
                let x = draw(&mut rng);
                let e = t.predict(&x).0;
                r.time_s.push(s as f64 * 1e-3);
                r.inputs.push(x);
                r.motor_side_position_m.push(x[2]);
                r.terminal_error_m.push(e);
                r.terminal_length_m.push(x[2] + e);
            }
            r
        })
        .collect();
    Dataset::from_runs("teacher", runs)
}

fn quick(hidden: usize) -> TrainOptions {
    let mut o = TrainOptions::new(DataSource::Synthetic { runs: 0 });
    o.hidden = vec![hidden];
    o.ibas = Some(IbasOptions { iterations: 600, ..IbasOptions::default() });
    o.optimiser = Some(OptimOptions { epochs: 800, ..OptimOptions::default() });
    o.max_train_samples = 2000;
    o
}

#[test]
fn training_recovers_a_known_rbf_function() {
    let ds = teacher_dataset(12, 300);
    let r = train_dataset(&ds, &quick(8)).unwrap();
    let sd = 1e-4; // the teacher's output scale: its targets vary by about this much
    let spread = r.test_uncompensated.rmse_m; // RMS of the target itself
    assert!(spread > 1e-4, "the target is not trivially small ({spread})");
    assert!(r.test.rmse_m < 0.01 * sd, "held-out RMSE {:.3e} m vs target scale {sd:e} m", r.test.rmse_m);
    assert!(r.train.rmse_m < 0.01 * sd);
    assert!(r.test.out_of_range_fraction < 0.05, "uniform inputs: the test runs lie (nearly) inside the trained box");
}

#[test]
fn the_paper_like_synthetic_error_is_observed_within_5_um_on_held_out_runs() {
    // 32 runs (realistic size), mixed split, default training at one hidden size.
    let ds = synthetic::paper_like("syn", 32);
    let mut o = TrainOptions::new(DataSource::Synthetic { runs: 0 });
    o.hidden = vec![24];
    let r = train_dataset(&ds, &o).unwrap();
    assert!(r.test_uncompensated.rmse_um > 100.0, "the error to observe is ≈0.1–0.4 mm ({})", r.test_uncompensated.rmse_um);
    assert!(r.test.rmse_um <= 5.0, "held-out RMSE {:.3} µm", r.test.rmse_um);
    assert!(r.test.mape_pct.unwrap() < r.test_uncompensated.mape_pct.unwrap() / 10.0);
    assert_eq!(r.runs.train.len() + r.runs.validation.len() + r.runs.test.len(), 32);
}

#[test]
fn training_is_deterministic_for_a_seed() {
    let ds = synthetic::paper_like("syn", 8);
    let mut o = quick(6);
    o.optimiser = Some(OptimOptions { epochs: 100, ..OptimOptions::default() });
    let a = train_dataset(&ds, &o).unwrap();
    let b = train_dataset(&ds, &o).unwrap();
    assert_eq!(a.model, b.model);
    o.seed = 2;
    let c = train_dataset(&ds, &o).unwrap();
    assert_ne!(a.model.params, c.model.params);
}

#[test]
fn the_hidden_size_is_chosen_on_validation_runs() {
    let ds = teacher_dataset(12, 300);
    let mut o = quick(4);
    o.hidden = vec![2, 12];
    let r = train_dataset(&ds, &o).unwrap();
    assert_eq!(r.candidates.len(), 2);
    let v: Vec<f64> = r.candidates.iter().map(|c| c.validation_rmse_m.unwrap()).collect();
    // Two Gaussians cannot follow the five-unit teacher; twelve can, and are chosen.
    assert!(v[1] < 0.5 * v[0], "{v:?}");
    assert_eq!(r.hidden, 12);
    // With a tolerance wide enough, the smaller size wins.
    o.select_tolerance = v[0] / v[1];
    assert_eq!(train_dataset(&ds, &o).unwrap().hidden, 2);
}

#[test]
fn baselines_run_and_back_propagation_improves_on_ibas_alone() {
    let ds = teacher_dataset(12, 300);
    let mut ibas_only = quick(10);
    ibas_only.optimiser = None;
    let mut bp_only = quick(10);
    bp_only.ibas = None;
    let both = quick(10);
    let (ri, rb, rf) =
        (train_dataset(&ds, &ibas_only).unwrap(), train_dataset(&ds, &bp_only).unwrap(), train_dataset(&ds, &both).unwrap());
    assert!(ri.candidates[0].bp_train_loss.is_none() && rb.candidates[0].ibas_loss.is_none());
    assert!(ri.train.rmse_m < ri.test_uncompensated.rmse_m / 3.0, "IBAS alone already fits roughly");
    assert!(rf.train.rmse_m < 0.5 * ri.train.rmse_m, "BP refines IBAS: {} vs {}", rf.train.rmse_m, ri.train.rmse_m);
    assert!(rb.train.rmse_m.is_finite());
    let mut none = quick(4);
    none.ibas = None;
    none.optimiser = None;
    assert!(train_dataset(&ds, &none).is_err());
}

#[test]
fn a_diverging_run_stops_keeps_the_last_good_weights_and_says_so() {
    let ds = synthetic::paper_like("syn", 8);
    let mut o = quick(8);
    o.optimiser = Some(OptimOptions { learning_rate: 50.0, epochs: 500, ..OptimOptions::for_method(Method::Gd) });
    let r = train_dataset(&ds, &o).unwrap();
    let d = r.diverged.as_ref().expect("η = 50 blows up");
    assert!(d.epoch < 500 && (d.loss.is_nan() || d.loss > 100.0 * d.last_good_loss), "{d:?}");
    assert!(r.warnings.iter().any(|w| w.contains("diverged") && w.contains("last good weights")), "{:?}", r.warnings);
    assert!(r.model.params.iter().all(|p| p.is_finite()));
    let c = &r.candidates[0];
    assert!(c.bp_train_loss.unwrap() <= c.ibas_loss.unwrap() * 1.5, "kept weights are no worse than where BP began (fitness set differs slightly)");
    assert!(r.test.rmse_m.is_finite());
}

#[test]
fn each_optimiser_lowers_the_loss_and_lbfgs_goes_furthest() {
    let ds = teacher_dataset(6, 200);
    let s = host_sim::trainer::dataset::Samples::gather(&ds, &[0, 1, 2, 3], ModelKind::Error, 1);
    let norm = Normaliser::fit(&s.inputs, &s.target);
    let batch = host_sim::trainer::network::Batch::new(&norm, &s.inputs, &s.target);
    let rbf = Rbf::new(6);
    let p0 = rbf.init_random(&mut ChaCha8Rng::seed_from_u64(1));
    let l0 = rbf.loss(&p0, &batch, 0.0);
    let pb = ProgressBar::hidden();
    let mut finals = vec![];
    for m in [Method::Gd, Method::Adam, Method::Lbfgs] {
        let o = OptimOptions { epochs: 400, ..OptimOptions::for_method(m) };
        let out = minimise(p0.clone(), |p, g| rbf.loss_grad(p, &batch, 0.0, g), None, &o, &pb);
        assert!(out.diverged.is_none(), "{m:?}: {}", out.stop_reason);
        assert!(out.train_loss < 0.2 * l0, "{m:?}: {l0} → {}", out.train_loss);
        assert!((rbf.loss(&out.params, &batch, 0.0) - out.train_loss).abs() < 1e-12);
        finals.push(out.train_loss);
    }
    assert!(finals[2] < finals[0] && finals[2] < finals[1], "{finals:?}");
}

#[test]
fn inputs_outside_the_trained_range_are_reported_and_clamped() {
    // Opposite split: trained on elongation (positive speeds), tested on
    // contraction (negative speeds): every moving test sample is out of range.
    let ds = synthetic::paper_like("syn", 8);
    let mut o = quick(6);
    o.split = SplitSpec::Opposite { train: Direction::Elongation };
    o.optimiser = Some(OptimOptions { epochs: 50, ..OptimOptions::default() });
    let r = train_dataset(&ds, &o).unwrap();
    assert!(r.test.out_of_range_fraction > 0.9, "{}", r.test.out_of_range_fraction);
    assert!(r.test.below_range_per_input[0] > 0 && r.test.below_range_per_input[1] > 0);
    assert!(r.warnings.iter().any(|w| w.contains("outside the trained range")));
    let m = &r.model;
    let mut x = [m.norm.input_min[0], m.norm.input_min[1], 0.2, 1000.0, 0.0];
    let (at_edge, c0) = m.predict(&x);
    x[0] -= 500.0;
    x[1] -= 1.0;
    let (beyond, c1) = m.predict(&x);
    assert!(!c0 && c1 && at_edge == beyond);
}

#[test]
fn the_physics_baseline_recovers_coefficients_of_data_in_its_span() {
    use host_sim::trainer::dataset::Samples;
    use host_sim::trainer::physics::PhysicsFit;
    let truth = [1e-5, 2e-7, 5e-7, -3e-6, 4e-5, 1e-4, 1e-3];
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let mut s = Samples::default();
    for _ in 0..500 {
        let x = draw(&mut rng);
        let f = [1.0, x[3], x[3] * x[2], x[3].signum() * x[3].abs().powf(2.0 / 3.0), x[1].signum(), x[1], x[2]];
        s.target.push(f.iter().zip(&truth).map(|(a, b)| a * b).sum());
        s.length_m.push(x[2]);
        s.error_m.push(0.0);
        s.inputs.push(x);
    }
    let fit = PhysicsFit::fit(&s).unwrap();
    for (c, t) in fit.coefficients.iter().zip(&truth) {
        assert!((c - t).abs() <= 1e-9 * t.abs().max(1e-12) + 1e-15, "{:?} vs {truth:?}", fit.coefficients);
    }
    assert!(fit.residuals(&s).iter().all(|r| r.abs() < 1e-12));
}
