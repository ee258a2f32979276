//! The drive's five-slot observer network: a five-input model (the fifth
//! input the direction of travel) compiled in, the same words uploaded as a
//! block and read back from the flash record, and the compiled four-input
//! model run in the five slots. Host and target must give the same bits,
//! and within each build the uploaded model must predict exactly as the
//! compiled one.

use servo_core::observer::block::{self, ForceSource, Staging, Weights, CHUNK_WORDS};
use servo_core::observer::{self, model, NETWORK_INPUTS};
use servo_core::params::record::{self, RECORD_MAX};
use servo_core::ControlParams;

use crate::{f, flag, w, Column, Family, Tol};

/// A five-input model: the compiled one with the direction of travel added
/// (range −1 … 1, a linear term and centres spread over it). Its fifth
/// input moves the prediction by about 20 µm, inside the drive's shift
/// bound, so the block passes every check an upload makes.
pub static FIVE_INPUT_MODEL: Weights = five_input_model();

const fn five_input_model() -> Weights {
    let mut m = observer::lift(&model::MODEL);
    let last = NETWORK_INPUTS - 1;
    m.input_min[last] = -1.0;
    m.input_max[last] = 1.0;
    m.input_scale[last] = 1.0;
    m.linear[last] = 0.05;
    let mut k = 0;
    while k < model::HIDDEN {
        m.centres[k][last] = k as f32 / 4.0 - 1.0;
        k += 1;
    }
    m
}

/// `m`'s words uploaded in chunks as a host sends them, committed, stored
/// in a flash record with the default parameters and read back: the model
/// the drive runs after a power cycle. `None` if any step refuses it.
pub fn uploaded(m: &Weights) -> Option<Weights> {
    let p = ControlParams::DEFAULT;
    let source = ForceSource::selected(p.compensation.force_from_estimate);
    let inputs = block::inputs_of(m);
    let (words, n) = block::to_block_words(m, inputs);
    let words = words.get(..n)?;
    let mut staging = Staging::new();
    staging
        .begin(
            inputs as u16,
            model::HIDDEN as u16,
            n as u16,
            block::structure_hash_for(inputs, source),
            source,
        )
        .ok()?;
    let mut start = 0usize;
    for chunk in words.chunks(CHUNK_WORDS) {
        staging.write(start as u16, chunk).ok()?;
        start += chunk.len();
    }
    let committed = staging.commit(p.faults.observer_shift_max_m, source).ok()?;
    let mut buf = [0u8; RECORD_MAX];
    let rec = record::encode(&p, Some(&committed), &mut buf).ok()?;
    record::decode_record(rec).ok()?.observer?.weights.ok()
}

/// Five-slot network: rows of the four paper inputs over a 4^4 grid from
/// 10 % below to 10 % above the trained range, each with the direction of
/// travel at −1, 0, +1 and 1.5 (beyond its range); then NaN in the first
/// and in the fifth input.
pub struct Observer5 {
    uploaded: Option<Weights>,
}

impl Family for Observer5 {
    const ID: u32 = 5;
    const NAME: &'static str = "observer5";
    const IN_WORDS: usize = NETWORK_INPUTS;
    const COLUMNS: &'static [Column] = &[
        Column::f32("compiled_m", Tol::Ulps(0)),
        Column::exact("compiled_clamped"),
        Column::exact("compiled_valid"),
        Column::f32("uploaded_m", Tol::Ulps(0)),
        Column::exact("uploaded_equals_compiled"),
        Column::f32("four_input_in_five_slots_m", Tol::Ulps(0)),
        Column::exact("five_slots_equal_four_input"),
    ];
    const WHY: &'static str = "one forward pass for compiled and uploaded weights, in f32 with the core's own exp2: bit-identical";

    fn new() -> Self {
        Self { uploaded: uploaded(&FIVE_INPUT_MODEL) }
    }

    fn eval(&mut self, _row: usize, i: &[u32], out: &mut [u32]) {
        let mut x = [0.0f32; NETWORK_INPUTS];
        for (xi, &wi) in x.iter_mut().zip(i.iter()) {
            *xi = f(wi);
        }
        let compiled = observer::evaluate(&FIVE_INPUT_MODEL, x);
        // A refused upload predicts NaN, which no host row holds.
        let up = match &self.uploaded {
            Some(m) => observer::evaluate(m, x),
            None => observer::Prediction { value_m: f32::NAN, clamped: false, valid: false },
        };
        let lifted = observer::evaluate(&block::COMPILED, x);
        let own = observer::evaluate(&model::MODEL, [x[0], x[1], x[2], x[3]]);
        let bits = |p: &observer::Prediction| (p.value_m.to_bits(), p.clamped, p.valid);
        out.copy_from_slice(&[
            w(compiled.value_m),
            flag(compiled.clamped),
            flag(compiled.valid),
            w(up.value_m),
            flag(bits(&up) == bits(&compiled)),
            w(lifted.value_m),
            flag(bits(&lifted) == bits(&own)),
        ]);
    }

    fn generate(emit: &mut dyn FnMut(&[u32], &[u32])) {
        let m = &model::MODEL;
        let levels = 4u32;
        let travel = [-1.0f32, 0.0, 1.0, 1.5];
        let mut fam = Self::new();
        let mut out = [0u32; 7];
        let mut row = 0usize;
        let mut put = |x: [f32; NETWORK_INPUTS]| {
            let input = x.map(w);
            fam.eval(row, &input, &mut out);
            // The two equalities are what the family is for: a host that
            // breaks them must not write a table the target then agrees with.
            assert!(out[4] == 1 && out[6] == 1, "observer5 row {row}: uploaded or five-slot prediction differs from the compiled one");
            emit(&input, &out);
            row += 1;
        };
        for code in 0..levels.pow(4) {
            let mut x = [0.0f32; NETWORK_INPUTS];
            let mut c = code;
            for (j, xj) in x.iter_mut().take(4).enumerate() {
                let level = (c % levels) as f32;
                c /= levels;
                let (lo, hi) = (m.input_min[j], m.input_max[j]);
                let span = hi - lo;
                *xj = lo - 0.1 * span + level * (1.2 * span / (levels - 1) as f32);
            }
            for &t in &travel {
                x[4] = t;
                put(x);
            }
        }
        let mid = |j: usize| 0.5 * (m.input_min[j] + m.input_max[j]);
        put([f32::NAN, mid(1), mid(2), mid(3), 1.0]);
        put([mid(0), mid(1), mid(2), mid(3), f32::NAN]);
    }
}
