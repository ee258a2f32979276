//! The analytic gradient of the observer loss against central finite differences.

use host_sim::trainer::dataset::N_INPUTS;
use host_sim::trainer::network::{Batch, Rbf};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_batch(rng: &mut ChaCha8Rng, n: usize) -> Batch {
    let mut b = Batch::default();
    for _ in 0..n {
        let z: [f64; N_INPUTS] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        b.t.push((2.0 * z[0]).sin() + z[1] * z[3] - 0.5 * z[2] * z[2]);
        b.z.push(z);
    }
    b
}

/// Each component of the analytic gradient matches the central difference
/// `(L(p + h e_i) − L(p − h e_i)) / 2h` to 1e-6 relative (with an absolute
/// floor of 1e-6 × the gradient's largest component for components near zero).
#[test]
fn analytic_gradient_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    // Four inputs (the paper's) and five (with the direction of travel).
    for (h, lambda, linear, inputs) in [(1usize, 0.0, false, 4), (5, 1e-3, true, 4), (12, 0.05, false, 4), (7, 0.0, true, 4), (6, 1e-3, true, 5), (3, 0.0, false, 5)] {
        let rbf = Rbf::with_linear(h, linear).with_inputs(inputs);
        let batch = random_batch(&mut rng, 60);
        for _trial in 0..3 {
            let mut p = rbf.init_random(&mut rng);
            assert_eq!(p.len(), h * (inputs + 2) + 1 + if linear { inputs } else { 0 });
            assert!(inputs <= N_INPUTS);
            // Move off the symmetric start: non-zero bias, varied widths.
            for v in p.iter_mut() {
                *v += rng.random_range(-0.3..0.3);
            }
            let mut g = vec![0.0; rbf.n_params()];
            let loss = rbf.loss_grad(&p, &batch, lambda, &mut g);
            assert!((loss - rbf.loss(&p, &batch, lambda)).abs() <= 1e-12 * loss.abs().max(1.0), "loss_grad and loss disagree");
            let gmax = g.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            assert!(gmax > 1e-3, "degenerate test point");
            for i in 0..p.len() {
                let step = 1e-5 * p[i].abs().max(1.0);
                let (mut pp, mut pm) = (p.clone(), p.clone());
                pp[i] += step;
                pm[i] -= step;
                let fd = (rbf.loss(&pp, &batch, lambda) - rbf.loss(&pm, &batch, lambda)) / (2.0 * step);
                let err = (fd - g[i]).abs();
                let tol = 1e-6 * g[i].abs().max(fd.abs()).max(gmax * 1e-3);
                assert!(err <= tol.max(1e-10), "H {h} λ {lambda} param {i}: analytic {:.12e} vs finite difference {:.12e}", g[i], fd);
            }
        }
    }
}

/// A wrong gradient would be caught: perturbing one analytic component by
/// 1e-4 relative exceeds the check's tolerance (guards the test itself).
#[test]
fn the_gradient_check_is_sharp_enough_to_fail() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let rbf = Rbf::new(4);
    let batch = random_batch(&mut rng, 40);
    let p = rbf.init_random(&mut rng);
    let mut g = vec![0.0; rbf.n_params()];
    rbf.loss_grad(&p, &batch, 0.0, &mut g);
    let i = g.iter().enumerate().max_by(|a, b| a.1.abs().total_cmp(&b.1.abs())).map(|(i, _)| i).unwrap_or(0);
    let step = 1e-5;
    let (mut pp, mut pm) = (p.clone(), p.clone());
    pp[i] += step;
    pm[i] -= step;
    let fd = (rbf.loss(&pp, &batch, 0.0) - rbf.loss(&pm, &batch, 0.0)) / (2.0 * step);
    let wrong = g[i] * (1.0 + 1e-4);
    assert!((fd - g[i]).abs() <= 1e-6 * g[i].abs());
    assert!((fd - wrong).abs() > 1e-6 * g[i].abs());
}
