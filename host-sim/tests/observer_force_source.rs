//! Observer weights are tied to the force they were trained on: the load
//! cell or the drive's current-based estimate read the same load apart by
//! the friction and the filtering in between, so weights trained on one and
//! run on the other compensate the wrong deformation. The structure hash
//! carries the force source; the drive refuses a block trained on the
//! other input than `control.compensation.force_from_estimate` selects,
//! naming both, and refuses to switch the input under uploaded weights.

mod drive_support;

use drive_support::Drive;
use host_sim::tool::{self, observer as obs};
use clap::Parser;
use host_sim::trainer::dataset::{Dataset, DatasetLimits, ForceSource as DataForce};
use host_sim::trainer::TrainArgs;
use servo_core::observer::block::{self, ForceSource, Part, STRUCTURE_HASH, STRUCTURE_HASH_ESTIMATE};
use servo_core::observer::model::{HIDDEN, INPUTS};

const MODEL: servo_core::observer::block::Weights = servo_core::observer::lift(&servo_core::observer::model::MODEL);
use servo_core::params::record;
use servo_core::protocol::ObserverSource;
use servo_core::Reason;

const SHIFT_MAX_M: f32 = 0.002;
const FORCE_PARAM: &str = "compensation.force_from_estimate";

#[test]
fn the_two_force_sources_hash_apart_and_each_refusal_names_the_other() {
    assert_ne!(STRUCTURE_HASH, STRUCTURE_HASH_ESTIMATE);
    let (words, n) = block::to_block_words(&MODEL, INPUTS);
    let words = &words[..n];
    let check = |hash: &[u8; 8], drive: ForceSource| block::validate(INPUTS as u16, HIDDEN as u16, hash, words, SHIFT_MAX_M, drive);
    assert!(check(&STRUCTURE_HASH, ForceSource::LoadCell).is_ok());
    assert!(check(&STRUCTURE_HASH_ESTIMATE, ForceSource::Estimate).is_ok());
    let e = check(&STRUCTURE_HASH_ESTIMATE, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::StructureHash, Reason::ObserverTrainedOnEstimate));
    let e = check(&STRUCTURE_HASH, ForceSource::Estimate).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::StructureHash, Reason::ObserverTrainedOnLoadCell));
    // Another network stays "another network", whatever the force input.
    let mut other = STRUCTURE_HASH_ESTIMATE;
    other[0] ^= 1;
    assert_eq!(check(&other, ForceSource::Estimate).unwrap_err().reason, Reason::ObserverStructureHash);
    // Staging checks the same at Begin, before any word is sent.
    let mut st = block::Staging::new();
    let e = st.begin(INPUTS as u16, HIDDEN as u16, block::WORDS_STATIC as u16, STRUCTURE_HASH, ForceSource::Estimate).unwrap_err();
    assert_eq!(e.reason, Reason::ObserverTrainedOnLoadCell);
}

#[test]
fn a_drive_takes_weights_only_for_the_force_input_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("flash.bin");
    let d = Drive::start(Some(store.clone()));
    let mut c = d.connect();
    // The shipped estimate weights on a drive reading its load cell: refused,
    // the reason naming both, the compiled weights still running.
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/observer/no_load_cell_model.json");
    let (w, source) = obs::read_model_file(&shipped).unwrap();
    assert_eq!(source, ForceSource::Estimate);
    let e = obs::upload(&mut c, &w, source).unwrap_err().to_string();
    assert!(e.contains("structure_hash") && e.contains("trained on the drive's force estimate") && e.contains("force_from_estimate"), "{e}");
    assert_eq!(obs::status(&mut c).unwrap().source, ObserverSource::Compiled);
    // Select the estimate first (allowed under the compiled weights), then
    // the upload is taken; the status gives the hash an upload must carry.
    tool::param_set(&mut c, FORCE_PARAM, "true").unwrap();
    assert_eq!(obs::status(&mut c).unwrap().structure_hash, STRUCTURE_HASH_ESTIMATE);
    assert_eq!(obs::upload(&mut c, &w, source).unwrap().source, ObserverSource::Uploaded);
    // Switching the input under those weights is refused, nothing changed.
    let e = tool::param_set(&mut c, FORCE_PARAM, "false").unwrap_err().to_string();
    assert!(e.contains("uploaded observer weights run"), "{e}");
    assert_eq!(obs::status(&mut c).unwrap().source, ObserverSource::Uploaded);
    // Load-cell weights are now the mismatch.
    let e = obs::upload(&mut c, &MODEL, ForceSource::LoadCell).unwrap_err().to_string();
    assert!(e.contains("trained on the load cell"), "{e}");
    // The record keeps the estimate's hash, and reads back with its weights.
    let rec = record::decode_record(&std::fs::read(&store).unwrap()).unwrap();
    assert!(rec.params.get().compensation.force_from_estimate);
    assert!(rec.observer.unwrap().weights.is_ok());
    // Back to the compiled weights, the input may change again.
    obs::use_compiled(&mut c).unwrap();
    tool::param_set(&mut c, FORCE_PARAM, "false").unwrap();
}

#[test]
fn a_dataset_names_its_force_source_by_its_force_column_and_refuses_both() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, force_col: &str| {
        let p = dir.path().join(name);
        let mut s = format!("run_id,direction,time_s,motor_speed_rad_s,nut_speed_m_s,nut_displacement_m,{force_col},terminal_error_m\n");
        for (run, dir) in [("a", "Elongation"), ("b", "Contraction")] {
            for k in 0..25 {
                s += &format!("{run},{dir},{},1,0.001,{},500,-1e-4\n", k as f64 * 1e-3, k as f64 * 1e-3);
            }
        }
        std::fs::write(&p, s).unwrap();
        p
    };
    let lim = DatasetLimits::default();
    assert_eq!(Dataset::load(&write("cell.csv", "load_force_n"), &lim).unwrap().force_source, DataForce::LoadCell);
    let est = Dataset::load(&write("est.csv", "load_force_estimate_n"), &lim).unwrap();
    assert_eq!(est.force_source, DataForce::Estimate);
    // Written back, the column keeps its name.
    let again = dir.path().join("again.csv");
    est.write_csv(&again).unwrap();
    assert_eq!(Dataset::load(&again, &lim).unwrap().force_source, DataForce::Estimate);
    let e = format!("{:#}", Dataset::load(&write("both.csv", "load_force_n,load_force_estimate_n"), &lim).unwrap_err());
    assert!(e.contains("both") && e.contains("line 1"), "{e}");
    // Estimate-trained weights are uploaded, never compiled in as the
    // image's (load-cell) model: refused before any training.
    let out = dir.path().join("out");
    let core = dir.path().join("model.rs");
    let est = dir.path().join("est.csv");
    let argv = ["train", "--data", est.to_str().unwrap(), "--out", out.to_str().unwrap(), "--hidden", "8", "--emit-core", core.to_str().unwrap()];
    let cli = TrainCli::try_parse_from(argv).unwrap();
    let e = format!("{:#}", host_sim::trainer::run_cli(&cli.a).unwrap_err());
    assert!(e.contains("--emit-core") && e.contains("load-cell model"), "{e}");
    assert!(!core.exists() && !out.exists());
}

#[derive(Parser)]
struct TrainCli {
    #[command(flatten)]
    a: TrainArgs,
}
