//! Generated firmware source: compiles into the control core, and the core's
//! `f32` forward pass agrees with the trainer's `f64` evaluation.

use host_sim::trainer::codegen::{generate, to_core_model};
use host_sim::trainer::dataset::{ModelKind, Samples, N_INPUTS};
use host_sim::trainer::ibas::IbasOptions;
use host_sim::trainer::optim::OptimOptions;
use host_sim::trainer::{synthetic, train_dataset, DataSource, TrainOptions, TrainReport};
use servo_core::observer::{evaluate, predict};
use std::path::{Path, PathBuf};
use std::process::Command;

const H: usize = 8;

fn trained(kind: ModelKind) -> (TrainReport, Samples) {
    let ds = synthetic::paper_like("codegen-test", 8);
    let mut o = TrainOptions::new(DataSource::Synthetic { runs: 0 });
    o.kind = kind;
    o.hidden = vec![H];
    o.ibas = Some(IbasOptions { iterations: 300, ..IbasOptions::default() });
    o.optimiser = Some(OptimOptions { epochs: 300, ..OptimOptions::default() });
    o.max_train_samples = 1500;
    let r = train_dataset(&ds, &o).unwrap();
    let test_ix: Vec<usize> = (0..ds.runs.len()).filter(|&i| r.runs.test.contains(&ds.runs[i].id)).collect();
    let s = Samples::gather(&ds, &test_ix, kind, 1);
    (r, s)
}

/// Held-out inputs plus inputs pushed beyond the trained range on every side.
fn probe_inputs(r: &TrainReport, s: &Samples) -> Vec<[f64; N_INPUTS]> {
    let mut v: Vec<[f64; N_INPUTS]> = s.inputs.iter().step_by(7).copied().collect();
    let n = &r.model.norm;
    for j in 0..N_INPUTS {
        let span = n.input_max[j] - n.input_min[j];
        for f in [-0.5, 1.5] {
            let mut x = s.inputs[s.len() / 3];
            x[j] = n.input_min[j] + f * span;
            v.push(x);
        }
    }
    v
}

#[test]
fn the_cores_f32_forward_pass_matches_the_trainers_f64_evaluation() {
    for kind in [ModelKind::Error, ModelKind::Length] {
        let (r, s) = trained(kind);
        let core = to_core_model::<H>(&r.model).unwrap();
        // Agreement bound: 0.1 µm for the error model; the length model's
        // output carries the stroke (≈0.45 m), where one f32 ulp is 0.03 µm,
        // so it gets a few ulps of the output more.
        let tol = match kind {
            ModelKind::Error => 1e-7,
            ModelKind::Length => 1e-7 + 4.0 * f64::from(f32::EPSILON) * 0.45,
        };
        let mut worst = 0.0_f64;
        for x in probe_inputs(&r, &s) {
            let (y64, clamped64) = r.model.predict(&x);
            let p = evaluate(&core, x.map(|v| v as f32));
            assert!(p.valid);
            assert_eq!(p.clamped, clamped64, "clamp flags agree at {x:?}");
            assert_eq!(predict(&core, x.map(|v| v as f32)), p.value_m);
            worst = worst.max((f64::from(p.value_m) - y64).abs());
        }
        assert!(worst <= tol, "{kind:?}: f32 vs f64 differ by {worst:.3e} m");
        assert!(to_core_model::<{ H + 1 }>(&r.model).is_err(), "the hidden size is checked");
    }
}

#[test]
fn a_nan_input_gives_no_compensation_and_says_so() {
    let (r, s) = trained(ModelKind::Error);
    let core = to_core_model::<H>(&r.model).unwrap();
    let mut x = s.inputs[0].map(|v| v as f32);
    x[2] = f32::NAN;
    let p = evaluate(&core, x);
    assert_eq!((p.value_m, p.valid), (0.0, false));
    assert_eq!(predict(&core, x), 0.0);
}

fn cargo() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".into())
}

/// A throw-away binary crate that depends on the control core and includes
/// the generated model; prints the f32 bits of each probe's prediction.
fn probe_crate(dir: &Path, model_src: &str, probes: &[[f32; N_INPUTS]]) {
    let core = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::write(
        dir.join("Cargo.toml"),
        format!(
            "[package]\nname = \"codegen-probe\"\nversion = \"0.0.0\"\nedition = \"2021\"\n\n[dependencies]\n\
             servo-core = {{ path = {:?}, default-features = false }}\n\n[workspace]\n",
            core.canonicalize().unwrap().display().to_string()
        ),
    )
    .unwrap();
    let lock = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.lock");
    if lock.exists() {
        std::fs::copy(lock, dir.join("Cargo.lock")).unwrap();
    }
    std::fs::write(dir.join("src/model.rs"), model_src).unwrap();
    let probes_src: Vec<String> = probes.iter().map(|p| format!("[{:?}, {:?}, {:?}, {:?}]", p[0], p[1], p[2], p[3])).collect();
    std::fs::write(
        dir.join("src/main.rs"),
        format!(
            "use servo_core::observer::{{ModelKind, ModelMeta, RbfModel}};\nmod model;\n\
             const PROBES: [[f32; model::INPUTS]; {}] = [{}];\n\
             fn main() {{\n    println!(\"{{}} {{}} {{}}\", model::HIDDEN, model::META.dataset, model::META.kind == ModelKind::Error);\n\
             \x20   for x in PROBES {{ let p = servo_core::observer::evaluate(&model::MODEL, x); println!(\"{{}} {{}}\", p.value_m.to_bits(), p.clamped); }}\n\
             \x20   let _: &ModelMeta = &model::META; let _: &RbfModel<{{ model::INPUTS }}, {{ model::HIDDEN }}> = &model::MODEL;\n}}\n",
            probes.len(),
            probes_src.join(", ")
        ),
    )
    .unwrap();
}

fn build(dir: &Path, target: &Path, run: bool) -> std::process::Output {
    let mut c = Command::new(cargo());
    c.arg(if run { "run" } else { "build" }).args(["--quiet", "--offline"]).current_dir(dir).env("CARGO_TARGET_DIR", target);
    c.output().unwrap()
}

#[test]
fn generated_source_compiles_into_the_core_and_a_wrong_shape_does_not() {
    let (r, s) = trained(ModelKind::Error);
    let src = generate(&r.model, &r.codegen_meta("host-sim train --test")).unwrap();
    assert!(src.contains("GENERATED") && src.contains(&format!("pub const HIDDEN: usize = {H};")));
    let core = to_core_model::<H>(&r.model).unwrap();
    let probes: Vec<[f32; N_INPUTS]> = probe_inputs(&r, &s).iter().map(|x| x.map(|v| v as f32)).collect();

    let tmp = tempfile::tempdir().unwrap();
    let target: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join("codegen-probe");
    probe_crate(tmp.path(), &src, &probes);
    let out = build(tmp.path(), &target, true);
    assert!(out.status.success(), "generated model failed to build:\n{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let mut lines = stdout.lines();
    assert_eq!(lines.next(), Some(format!("{H} codegen-test true").as_str()));
    for x in &probes {
        let want = evaluate(&core, *x);
        let got = lines.next().unwrap();
        assert_eq!(got, format!("{} {}", want.value_m.to_bits(), want.clamped), "compiled constants are bit-identical to to_core_model's");
    }

    // The same file with a hidden size that does not match its arrays.
    let bad = src.replace(&format!("pub const HIDDEN: usize = {H};"), &format!("pub const HIDDEN: usize = {};", H + 1));
    probe_crate(tmp.path(), &bad, &probes);
    let out = build(tmp.path(), &target, false);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("E0308"), "a shape mismatch must not compile:\n{err}");
}
