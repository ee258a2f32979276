//! The firmware's committed observer model (`src/observer/model.rs`, generated
//! by `host-sim train`) is well formed and behaves at the edges.

use servo_core::observer::model::{HIDDEN, INPUTS, INPUT_NAMES, META, MODEL};
use servo_core::observer::{evaluate, log2_decay, predict, ModelKind};

#[test]
fn the_committed_model_is_well_formed() {
    assert_eq!(INPUT_NAMES[..], host_sim::trainer::dataset::INPUT_COLUMNS[..INPUTS]);
    assert_eq!(MODEL.widths.len(), HIDDEN);
    for j in 0..INPUTS {
        let (lo, hi, s) = (MODEL.input_min[j], MODEL.input_max[j], MODEL.input_scale[j]);
        assert!(lo.is_finite() && hi.is_finite() && lo <= hi, "input {j}: [{lo}, {hi}]");
        if hi > lo {
            assert!((s * (hi - lo) - 2.0).abs() < 1e-5, "input {j}: scale {s} is 2/(max−min)");
        } else {
            assert_eq!(s, 0.0);
        }
    }
    assert!(MODEL.widths.iter().all(|&w| w.is_finite() && w > 0.0));
    for (k, (&w, &d)) in MODEL.widths.iter().zip(MODEL.log2_decay.iter()).enumerate() {
        assert_eq!(d, log2_decay(w), "unit {k}: log2_decay is log2(e)/(2 width^2) of the committed width");
    }
    assert!(MODEL.weights.iter().chain([&MODEL.bias, &MODEL.output_scale, &MODEL.output_offset]).all(|v| v.is_finite()));
    assert!(MODEL.centres.iter().flatten().all(|v| v.is_finite()));
    assert!(META.test_rmse_m.is_finite() && META.test_rmse_m >= 0.0 && !META.dataset.is_empty());
}

#[test]
fn the_committed_model_clamps_to_its_trained_range_and_stays_finite() {
    let mid: [f32; 4] = core::array::from_fn(|j| 0.5 * (MODEL.input_min[j] + MODEL.input_max[j]));
    let p = evaluate(&MODEL, mid);
    assert!(p.valid && !p.clamped && p.value_m.is_finite());
    if META.kind == ModelKind::Error {
        assert!(p.value_m.abs() < 0.01, "an error model predicts millimetres, not {} m", p.value_m);
    }
    for j in 0..INPUTS {
        let span = MODEL.input_max[j] - MODEL.input_min[j];
        let (mut lo, mut below, mut hi, mut above) = (mid, mid, mid, mid);
        lo[j] = MODEL.input_min[j];
        below[j] = MODEL.input_min[j] - 10.0 * span - 1.0;
        hi[j] = MODEL.input_max[j];
        above[j] = MODEL.input_max[j] + 10.0 * span + 1.0;
        let (pb, pa) = (evaluate(&MODEL, below), evaluate(&MODEL, above));
        assert!(pb.clamped && pa.clamped && pb.valid && pa.valid);
        assert_eq!(pb.value_m, predict(&MODEL, lo), "input {j}: below the range = at its lower edge");
        assert_eq!(pa.value_m, predict(&MODEL, hi), "input {j}: above the range = at its upper edge");
        for x in [f32::INFINITY, f32::NEG_INFINITY] {
            let mut v = mid;
            v[j] = x;
            assert!(evaluate(&MODEL, v).value_m.is_finite());
        }
    }
}
