//! Each generic-structure fitter alone against a closed-form synthetic
//! remainder: a frame resonance driven by the logged thrust (integrated
//! here by RK4, not by the fitter's scheme), a torque gain warming with a
//! first-order time constant, a count loss, a scale rounded coarser than
//! the rig file, and the cases that must not be named — a constant gain (a
//! gain error, not a drift), white noise, a lost motion, a force step, a
//! ramp, a column at the rig's own resolution or unrounded, and a rounding
//! buried under another cause's floor.

mod diagnose_support;

use diagnose_support::truth::nominal_rig;
use host_sim::diagnose::generic::{fit_all, named, GenericFit};
use host_sim::diagnose::residual::{Nominal, Physics, Segment, NCH, POSITION, TORQUE};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

const DT: f64 = 1e-3;
const LEN_S: f64 = 8.0;

/// A motion-like drive: current pulses of random sign and size (moves'
/// accelerations and decelerations) on a slow load current, A.
fn current(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let n = (LEN_S / DT) as usize;
    let mut i = vec![0.0; n];
    let mut k = rng.random_range(100..300);
    loop {
        let (a, len) = (rng.random_range(1.0..4.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 }, rng.random_range(40..150));
        let cruise = rng.random_range(50..250);
        if k + 2 * len + cruise >= n {
            break;
        }
        for j in 0..len {
            i[k + j] += a;
            i[k + len + cruise + j] -= a;
        }
        k += 2 * len + cruise + rng.random_range(100..350);
    }
    for (j, v) in i.iter_mut().enumerate() {
        *v += 2.0 * (std::f64::consts::TAU * 0.3 * j as f64 * DT).sin();
    }
    i
}

/// Ringing `y − c u` of `y'' + 2ζω y' + ω² y = ω² c u` (u held per sample),
/// by RK4 with 20 sub-steps, starting at rest on the first input.
fn ringing_rk4(u: &[f64], f_hz: f64, zeta: f64, c: f64) -> Vec<f64> {
    let w = std::f64::consts::TAU * f_hz;
    let h = DT / 20.0;
    let (mut y, mut v) = (c * u[0], 0.0);
    u.iter()
        .map(|uk| {
            let acc = |y: f64, v: f64| w * w * (c * uk - y) - 2.0 * zeta * w * v;
            for _ in 0..20 {
                let (k1y, k1v) = (v, acc(y, v));
                let (k2y, k2v) = (v + 0.5 * h * k1v, acc(y + 0.5 * h * k1y, v + 0.5 * h * k1v));
                let (k3y, k3v) = (v + 0.5 * h * k2v, acc(y + 0.5 * h * k2y, v + 0.5 * h * k2v));
                let (k4y, k4v) = (v + h * k3v, acc(y + h * k3y, v + h * k3v));
                y += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
            y - c * uk
        })
        .collect()
}

/// A segment with the given nominal torque and residuals (the position
/// channel's nominal prediction is zero).
fn segment(t0: f64, iq: Vec<f64>, torque_nominal: &[f64], r_torque: Vec<f64>, r_position: Vec<f64>) -> Segment {
    let n = iq.len();
    let t: Vec<f64> = (0..n).map(|k| t0 + k as f64 * DT).collect();
    let mut y: [Option<Vec<f64>>; NCH] = Default::default();
    let mut r: [Option<Vec<f64>>; NCH] = Default::default();
    y[TORQUE] = Some(torque_nominal.iter().zip(&r_torque).map(|(a, b)| a + b).collect());
    r[TORQUE] = Some(r_torque);
    y[POSITION] = Some(r_position.clone());
    r[POSITION] = Some(r_position);
    Segment {
        t_rel: (0..n).map(|k| k as f64 * DT).collect(),
        t,
        iq: iq.clone(),
        iq_logged: iq,
        // Moving at a steady speed, so every channel keeps its weight.
        theta: (0..n).map(|k| 50.0 * k as f64 * DT).collect(),
        omega: vec![50.0; n],
        alpha: vec![0.0; n],
        x: vec![0.0; n],
        v: vec![0.0; n],
        a: vec![0.0; n],
        v_ref: vec![0.0; n],
        a_ref: vec![0.0; n],
        f_load: vec![0.0; n],
        f_ax: vec![0.0; n],
        dir: vec![1.0; n],
        since_reversal_s: vec![1.0; n],
        input: vec![0.0; n],
        c_loc: vec![0.0; n],
        y,
        r,
        dt: DT,
        ..Default::default()
    }
}

fn noise(rng: &mut ChaCha8Rng, n: usize, sd: f64) -> Vec<f64> {
    (0..n).map(|_| sd * (rng.random::<f64>() + rng.random::<f64>() + rng.random::<f64>() - 1.5) * 2.0).collect()
}

fn diagnose_pair(train: Segment, held: Segment, p: &Physics) -> Vec<GenericFit> {
    let rem = |s: &Segment| vec![s.r.clone()];
    let (rt, rh) = (rem(&train), rem(&held));
    fit_all(&[&train], &rt, &[&held], &rh, &Nominal::Physics(p.clone()))
}

fn torque_nominal(iq: &[f64], p: &Physics) -> Vec<f64> {
    iq.iter().map(|i| p.kt * i).collect()
}

#[test]
fn a_frame_resonance_driven_by_the_thrust_is_named_with_its_frequency() {
    let p = Physics::from_rig(&nominal_rig());
    for (seed, f_hz, c_f) in [(1u64, 38.0, 3e-9), (2, 47.0, 2e-9), (3, 58.0, 4e-9)] {
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
        let seg = |t0: f64, rng: &mut ChaCha8Rng| {
            let iq = current(rng);
            let thrust: Vec<f64> = iq.iter().map(|i| p.kt * i / p.k).collect();
            let ring = ringing_rk4(&thrust, f_hz, 0.03, c_f);
            let rms = (ring.iter().map(|v| v * v).sum::<f64>() / ring.len() as f64).sqrt();
            // A floor of half the ringing's RMS, white.
            let pos: Vec<f64> = ring.iter().zip(noise(rng, iq.len(), 0.5 * rms)).map(|(a, b)| a + b).collect();
            let tn = torque_nominal(&iq, &p);
            segment(t0, iq.clone(), &tn, noise(rng, iq.len(), 0.01), pos)
        };
        let train = seg(0.0, &mut rng);
        let held = seg(0.0, &mut rng);
        let fits = diagnose_pair(train, held, &p);
        let g = named(&fits).unwrap_or_else(|| panic!("{f_hz} Hz: nothing named: {fits:#?}"));
        assert_eq!((g.class.as_str(), g.channel.as_str()), ("resonance", "position"), "{fits:#?}");
        let f = g.params["frequency_hz"];
        assert!((f / f_hz - 1.0).abs() <= 0.05, "{f_hz} Hz found at {f:.1} Hz");
        let z = g.params["damping_ratio"];
        assert!((z / 0.03 - 1.0).abs() <= 0.2, "ζ 0.03 found as {z:.4}");
        // White noise of half the ringing's RMS leaves 1 − 0.5/√1.25 = 55 %
        // at best.
        assert!(g.remainder_shrink_pct >= 45.0, "{g:?}");
    }
}

/// Second derivative of `y` by a least-squares quadratic over ±m samples
/// (solved here as a small normal-equation system, independently of the
/// diagnosis's Savitzky–Golay coefficients); zero where the window does
/// not fit.
fn quadratic_second(y: &[f64], m: usize) -> Vec<f64> {
    let n = y.len();
    let x = nalgebra::DMatrix::from_fn(2 * m + 1, 3, |r, c| ((r as f64 - m as f64) * DT).powi(c as i32));
    let pinv = (x.transpose() * &x).try_inverse().expect("quadratic normal matrix") * x.transpose();
    (0..n)
        .map(|i| {
            if i < m || i + m >= n {
                return 0.0;
            }
            let w = nalgebra::DVector::from_column_slice(&y[i - m..=i + m]);
            2.0 * (pinv.row(2) * w)[0]
        })
        .collect()
}

/// A mode between motor and rod seen as a two-mass system, with the scale
/// logged beside the encoder: the rod side rings under the motor's thrust,
/// and the torque channel meets it through the rod's inertial force
/// `m a` taken from the scale (the ±10 ms quadratic second derivative),
/// `−k m a`. Here the position channel's floor is three times the
/// ringing, so only the torque channel can name it: the fitter alone on
/// that channel recovers f within 5 % and ζ within 20 %.
#[test]
fn a_motor_rod_mode_seen_through_the_rods_inertial_force_is_named_on_the_torque_channel() {
    let p = Physics::from_rig(&nominal_rig());
    let m = 10usize;
    for (seed, f_hz, zeta, c_f) in [(41u64, 37.0, 0.025, 3e-9), (42, 46.0, 0.04, 2e-9), (43, 57.0, 0.03, 3e-9)] {
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
        let seg = |rng: &mut ChaCha8Rng| {
            let iq = current(rng);
            let thrust: Vec<f64> = iq.iter().map(|i| p.kt * i / p.k).collect();
            let ring = ringing_rk4(&thrust, f_hz, zeta, c_f);
            let acc = quadratic_second(&ring, m);
            let c_loc = p.local_compliance(0.0, p.x0);
            let rms = (ring.iter().map(|v| v * v).sum::<f64>() / ring.len() as f64).sqrt();
            let pos: Vec<f64> = ring.iter().zip(&acc).zip(noise(rng, iq.len(), 3.0 * rms)).map(|((y, a), e)| y + c_loc * p.m_moving * a + e).collect();
            let tq: Vec<f64> = acc.iter().zip(noise(rng, iq.len(), 3e-4)).map(|(a, e)| -p.k * p.m_moving * a + e).collect();
            let tn = torque_nominal(&iq, &p);
            let n = iq.len();
            let mut s = segment(0.0, iq, &tn, tq, pos);
            (s.rod_from_scale, s.sg_m, s.c_loc) = (true, m, vec![c_loc; n]);
            s
        };
        let train = seg(&mut rng);
        let held = seg(&mut rng);
        let fits = diagnose_pair(train, held, &p);
        let g = named(&fits).unwrap_or_else(|| panic!("{f_hz} Hz: nothing named: {fits:#?}"));
        assert_eq!((g.class.as_str(), g.channel.as_str()), ("resonance", "torque"), "{fits:#?}");
        let (f, z) = (g.params["frequency_hz"], g.params["damping_ratio"]);
        assert!((f / f_hz - 1.0).abs() <= 0.05, "{f_hz} Hz found at {f:.1} Hz");
        assert!((z / zeta - 1.0).abs() <= 0.2, "ζ {zeta} found as {z:.4}");
        let k = g.params["stiffness_n_per_um"];
        assert!((k / (1e-6 / c_f) - 1.0).abs() <= 0.2, "stiffness {k:.1} N/µm against {:.1}", 1e-6 / c_f);
        assert!(g.remainder_shrink_pct >= 70.0, "{g:?}");
    }
}

/// Torque channel remainder `d(t) N(t)`: a gain error `d` on the nominal
/// torque `N`, with white noise of 2 mN·m; with `temperature`, the
/// temperature at each time is logged.
fn gain_case_logged(seed: u64, d: &dyn Fn(f64) -> f64, held_t0: f64, temperature: Option<&dyn Fn(f64) -> f64>) -> Vec<GenericFit> {
    let p = Physics::from_rig(&nominal_rig());
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let seg = |t0: f64, rng: &mut ChaCha8Rng| {
        let iq = current(rng);
        let tn = torque_nominal(&iq, &p);
        let tr: Vec<f64> = tn.iter().enumerate().map(|(k, n)| d(t0 + k as f64 * DT) * n).zip(noise(rng, iq.len(), 0.002)).map(|(a, b)| a + b).collect();
        let n = iq.len();
        let mut s = segment(t0, iq, &tn, tr, noise(rng, n, 1e-7));
        if let Some(temp) = temperature {
            s.temperature_c = (0..n).map(|k| temp(t0 + k as f64 * DT)).collect();
        }
        s
    };
    let train = seg(0.0, &mut rng);
    let held = seg(held_t0, &mut rng);
    diagnose_pair(train, held, &p)
}

fn gain_case(seed: u64, d: &dyn Fn(f64) -> f64, held_t0: f64) -> Vec<GenericFit> {
    gain_case_logged(seed, d, held_t0, None)
}

#[test]
fn a_gain_following_the_logged_temperature_is_named_with_its_coefficient() {
    // NdFeB: the torque constant falls 0.12 %/K, so the current needed
    // rises by ≈ β ΔT; the magnets warm 60 K with τ = 3 s.
    let (beta, dtm, tau) = (1.2e-3, 60.0, 3.0);
    let temp = move |t: f64| 30.0 + dtm * (1.0 - (-t / tau).exp());
    let d = move |t: f64| beta * (temp(t) - 30.0);
    let fits = gain_case_logged(31, &d, LEN_S, Some(&temp));
    let g = named(&fits).unwrap_or_else(|| panic!("nothing named: {fits:#?}"));
    assert_eq!((g.class.as_str(), g.channel.as_str()), ("gain_drift", "torque"), "{fits:#?}");
    let k = g.params["gain_per_k"];
    assert!((k / beta - 1.0).abs() <= 0.1, "gain per K {k:.3e} against {beta:.3e}");
    // Held-out, the law learnt on training predicts the warm run.
    assert!(g.remainder_shrink_pct >= 70.0, "{g:?}");
}

#[test]
fn a_torque_gain_warming_over_the_run_is_named_a_drift() {
    for (seed, drop, tau) in [(11u64, 0.06, 3.0), (12, 0.09, 2.0), (13, 0.05, 5.0)] {
        // The held-out run continues warm: its gain hardly moves, and no
        // course on the training run's clock predicts it.
        let d = move |t: f64| drop * (1.0 - (-t / tau).exp());
        let fits = gain_case(seed, &d, LEN_S);
        let g = named(&fits).unwrap_or_else(|| panic!("drop {drop}: nothing named: {fits:#?}"));
        assert_eq!((g.class.as_str(), g.channel.as_str()), ("gain_drift", "torque"), "{fits:#?}");
        // The fitted course rises by about the warming over the training
        // run (the gain's range) at a positive mean rate.
        let change = g.params["gain_change_pct"] / 100.0;
        let truth = d(LEN_S) - d(0.0);
        assert!((change / truth - 1.0).abs() <= 0.2, "gain change {change:.4} against {truth:.4}");
        assert!(g.params["drift_per_s"] > 0.0, "{g:?}");
    }
}

#[test]
fn a_constant_gain_or_white_noise_is_not_named_a_drift() {
    let fits = gain_case(21, &|_| 0.05, LEN_S);
    let g = fits.iter().find(|g| g.class == "gain_drift" && g.channel == "torque").expect("fitted");
    assert!(g.refused.is_some(), "a constant gain taken for a drift: {g:?}");
    assert!(named(&fits).is_none_or(|n| n.class != "gain_drift"), "{fits:#?}");
    let fits = gain_case(22, &|_| 0.0, LEN_S);
    assert!(named(&fits).is_none(), "white noise named: {fits:#?}");
}

/// Moving-average high pass (±7 samples): what is above ≈ 30 Hz at 1 kHz.
fn high_pass(v: &[f64]) -> Vec<f64> {
    let m = 7usize;
    (0..v.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(m), (i + m + 1).min(v.len()));
            v[i] - v[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

/// How large the open-world suite's structural resonance is against the
/// position channel's floor: the truth's ringing (the same run with and
/// without it) and the nominal residual, weighted like every fit, all and
/// above ≈ 30 Hz. Prints them and checks the drawn 3–10× ratio:
/// `cargo test --release --test diagnose_generic resonance_truth_against_floor -- --ignored --nocapture`
#[test]
#[ignore = "measurement: cargo test --release --test diagnose_generic resonance_truth_against_floor -- --ignored --nocapture"]
fn resonance_truth_against_floor() {
    use diagnose_support::open::{nominal_logs, novel_logs, Novel};
    use host_sim::diagnose::residual::build_segments;
    let rig = nominal_rig();
    let p = Physics::from_rig(&rig);
    for s in 0..4u64 {
        // The suite's draws for seed s (its offset 60 000); the base run is
        // the same with and without the resonance.
        let with = novel_logs(&rig, Novel::StructuralResonance, 60_000 + s).train;
        let without = nominal_logs(&rig, 60_000 + s).train;
        let ring: Vec<f64> = with.get("terminal_position_m").unwrap().iter().zip(without.get("terminal_position_m").unwrap()).map(|(a, b)| a - b).collect();
        let segs = build_segments(&without, &Nominal::Physics(p.clone()), p.tilt_deg).expect("segments");
        let mut ss = [0.0; 4];
        let mut n = 0.0;
        for sg in &segs {
            let r = sg.r[POSITION].as_ref().expect("position residual");
            let d: Vec<f64> = (0..sg.len()).map(|i| ring[sg.first_row + i]).collect();
            let (rh, dh) = (high_pass(r), high_pass(&d));
            for i in 0..sg.len() {
                let w2 = sg.weight(POSITION, i).powi(2);
                for (k, v) in [r[i], d[i], rh[i], dh[i]].into_iter().enumerate() {
                    ss[k] += w2 * v * v;
                }
                n += 1.0;
            }
        }
        let [fl, rg, flh, rgh] = ss.map(|v| 1e6 * (v / n).sqrt());
        println!("seed {s}: position floor {fl:.3} µm, resonance {rg:.3} µm; above 30 Hz: floor {flh:.3} µm, resonance {rgh:.3} µm");
        // The suite draws the ringing at 3–10× the floor on this very run.
        assert!((2.99..=10.01).contains(&(rg / fl)), "seed {s}: the resonance is {:.2}× the floor, drawn at 3–10×", rg / fl);
    }
}

/// Position-channel remainders with a floor of white noise (0.3 µm) plus
/// `shape(t)`, the torque channel's white noise plus `torque(t)`; the
/// nominal compliance `c` at every sample.
fn count_case(seed: u64, shape: &dyn Fn(f64) -> f64, torque: &dyn Fn(f64) -> f64) -> Vec<GenericFit> {
    let p = Physics::from_rig(&nominal_rig());
    let c = p.local_compliance(0.0, p.x0);
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let seg = |rng: &mut ChaCha8Rng| {
        let iq = current(rng);
        let n = iq.len();
        let tn = torque_nominal(&iq, &p);
        let tq: Vec<f64> = noise(rng, n, 1e-3).into_iter().enumerate().map(|(k, e)| e + torque(k as f64 * DT)).collect();
        let pos: Vec<f64> = noise(rng, n, 3e-7).into_iter().enumerate().map(|(k, e)| e + shape(k as f64 * DT)).collect();
        let mut s = segment(0.0, iq, &tn, tq, pos);
        (s.rod_from_scale, s.c_loc) = (true, vec![c; n]);
        s
    };
    let train = seg(&mut rng);
    let held = seg(&mut rng);
    diagnose_pair(train, held, &p)
}

/// Counts lost over 40 ms at `t0`: the scale − motor difference gains
/// `lost` from then on.
fn loss(t0: f64, lost: f64) -> impl Fn(f64) -> f64 {
    move |t| lost * ((t - t0) / 0.04).clamp(0.0, 1.0)
}

#[test]
fn counts_lost_once_are_named_with_their_size_and_nothing_else_is() {
    let p = Physics::from_rig(&nominal_rig());
    let c = p.local_compliance(0.0, p.x0);
    // 0.03 rad at the motor, 24 µm at the rod.
    let lost = 0.03 * p.k;
    let fits = count_case(51, &loss(4.3, lost), &|_| 0.0);
    let g = named(&fits).unwrap_or_else(|| panic!("nothing named: {fits:#?}"));
    assert_eq!(g.class, "count_loss", "{fits:#?}");
    assert!((g.params["lost_m"] / lost - 1.0).abs() <= 0.05, "lost {:.3e} m against {lost:.3e}", g.params["lost_m"]);
    assert!((g.params["time_s"] - 4.32).abs() <= 0.05, "at {:.3} s", g.params["time_s"]);
    let refused = |fits: &[GenericFit], why: &str| {
        let g = fits.iter().find(|g| g.class == "count_loss").expect("count loss fitted");
        assert!(g.refused.as_deref().is_some_and(|r| r.contains(why)), "{why}: {g:?}");
        assert!(named(fits).is_none_or(|n| n.class != "count_loss"), "{fits:#?}");
    };
    // A lost motion: the rod sits on the other flank after every reversal
    // (here every second), a step of the same size each time.
    refused(&count_case(52, &|t| if (t as i64) % 2 == 0 { 0.0 } else { lost }, &|_| 0.0), "not single");
    // A force step: the deflection steps, and the torque with it by
    // (L/2π) Δx / c.
    refused(&count_case(53, &loss(4.3, lost), &|t| p.k * loss(4.3, lost)(t) / c), "a force");
    // A drift of the same size over the run.
    refused(&count_case(54, &|t| lost * t / LEN_S, &|_| 0.0), "not sharp");
}

/// A rod moving back and forth over 0.1 m, the scale logging it rounded to
/// `step` (`None`: as it is), and a position remainder of that rounding
/// plus the nominal's own white floor of 0.3 µm × `floor_x`.
fn quantised_case(seed: u64, step: Option<f64>, floor_x: f64) -> Vec<GenericFit> {
    let p = Physics::from_rig(&nominal_rig());
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
    let mut seg = |phase: f64| {
        let iq = current(&mut rng);
        let n = iq.len();
        let x: Vec<f64> = (0..n).map(|k| 0.25 + 0.05 * (std::f64::consts::TAU * 0.4 * k as f64 * DT + phase).sin()).collect();
        let logged: Vec<f64> = x.iter().map(|v| step.map_or(*v, |q| q * (v / q).round())).collect();
        let floor = noise(&mut rng, n, 3e-7 * floor_x);
        let pos: Vec<f64> = (0..n).map(|k| floor[k] + logged[k] - x[k]).collect();
        let tn = torque_nominal(&iq, &p);
        let mut s = segment(0.0, iq, &tn, noise(&mut rng, n, 1e-3), pos);
        s.scale_logged = logged;
        s
    };
    let (train, held) = (seg(0.0), seg(1.0));
    diagnose_pair(train, held, &p)
}

#[test]
fn a_lattice_is_found_with_its_step_and_noise_has_none() {
    use host_sim::diagnose::generic::lattice;
    let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(61);
    let x: Vec<f64> = (0..8000).map(|k| 0.3 * (k as f64 * 1e-3).sin() + 1e-5 * rng.random::<f64>()).collect();
    for (q, offset) in [(7e-6, 0.0), (2.5e-5, 3.3e-6), (0.0126, 0.001)] {
        let v: Vec<f64> = x.iter().map(|x| offset + q * ((x - offset) / q).floor()).collect();
        let l = lattice(&v).unwrap_or_else(|| panic!("no lattice at {q}"));
        assert!((l.step / q - 1.0).abs() < 1e-3, "step {} against {q}", l.step);
        assert!(l.score > 0.99, "{l:?}");
    }
    assert_eq!(lattice(&x), None, "an unrounded, noisy signal sits on no lattice");
}

#[test]
fn a_scale_rounded_coarser_than_the_rig_is_named_quantisation_and_nothing_else_is() {
    // 8 µm where the rig file says 1 µm: named, with its step.
    let fits = quantised_case(62, Some(8e-6), 1.0);
    let g = named(&fits).unwrap_or_else(|| panic!("nothing named: {fits:#?}"));
    assert_eq!((g.class.as_str(), g.column.as_deref()), ("quantisation", Some("terminal_position_m")), "{fits:#?}");
    assert!((g.params["step"] / 8e-6 - 1.0).abs() < 0.01, "step {:.3e}", g.params["step"]);
    // The same rounding in the log at the rig's own 1 µm, or no rounding
    // at all: no quantisation is fitted.
    for (seed, step) in [(63, Some(1e-6)), (64, None)] {
        let fits = quantised_case(seed, step, 1.0);
        assert!(fits.iter().all(|g| g.class != "quantisation"), "{step:?}: {fits:#?}");
    }
    // A scale at 3× the rig's step under a floor of another cause 30× its
    // rounding: the lattice is there, but it accounts for little of the
    // remainder and names nothing.
    let fits = quantised_case(65, Some(3e-6), 10.0);
    let g = fits.iter().find(|g| g.class == "quantisation").expect("quantisation fitted");
    assert!(g.remainder_shrink_pct < 5.0, "{g:?}");
    assert!(named(&fits).is_none_or(|n| n.class != "quantisation"), "{fits:#?}");
}
