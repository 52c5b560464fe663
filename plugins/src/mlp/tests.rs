//! The network learns, runs, bakes and transfers as it should, on small synthetic data.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::bake::{BakeOptions, bake};
use super::train::{Samples, TrainOptions, train};
use super::transfer::{Fit, PressPixels, transfer};
use super::*;

/// The "physics" of the synthetic sensor: gradient from a difference colour.
fn truth(k: [f32; 3]) -> [f32; 2] {
    [0.8 * (k[0] / 60.0).tanh(), -0.5 * (k[1] / 60.0).tanh()]
}

/// An untrained 64×48 difference-input model, for its features.
fn shape() -> MlpModel {
    MlpModel {
        input: Input::Diff,
        width: 64,
        height: 48,
        hidden: 0,
        layers: Vec::new(),
        offset_rgb: [0.0; 3],
        gain_rgb: [1.0; 3],
        mm_per_px: None,
        slopes: crate::model_file::Slopes::Forward,
    }
}

fn model(rng_seed: u64, epochs: usize) -> MlpModel {
    let mut rng = Pcg64Mcg::seed_from_u64(rng_seed);
    let shape = shape();
    let mut samples = Samples::default();
    for _ in 0..3000 {
        let k = [0; 3].map(|_| rng.random_range(-100.0f32..100.0));
        let g = truth(k);
        samples.push(
            shape.features(k, rng.random_range(0..64), rng.random_range(0..48)),
            g[0],
            g[1],
        );
    }
    let opts = TrainOptions {
        hidden: 16,
        epochs,
        batch: 256,
        learning_rate: 1e-2,
        ..TrainOptions::default()
    };
    let mut losses = Vec::new();
    let m = train(&samples, Input::Diff, (64, 48), &opts, |e| {
        losses.push(e.loss)
    })
    .expect("trains");
    assert_eq!(losses.len(), epochs);
    assert!(losses.iter().all(|l| l.is_finite()));
    m
}

fn mae(m: &MlpModel, shift: [f32; 3]) -> f64 {
    let net = m.net().expect("net");
    let mut rng = Pcg64Mcg::seed_from_u64(99);
    let (mut e, mut n) = (0.0, 0);
    for _ in 0..500 {
        let k = [0; 3].map(|_| rng.random_range(-90.0f32..90.0));
        // The sensor sees every colour, its background's too, shifted.
        let seen = [k[0] + shift[0], k[1] + shift[1], k[2] + shift[2]];
        let (x, y) = (rng.random_range(0..64), rng.random_range(0..48));
        let out = net.forward(&m.features(seen, x, y)).expect("forward");
        let zero = net.forward(&m.features(shift, x, y)).expect("forward");
        let g = truth(k);
        e += f64::from((out[0] - zero[0] - g[0]).abs() + (out[1] - zero[1] - g[1]).abs());
        n += 2;
    }
    e / n as f64
}

#[test]
fn learns_a_smooth_map_reproducibly() {
    let a = model(1, 40);
    let err = mae(&a, [0.0; 3]);
    // Predicting zero everywhere scores about 0.35 on this map.
    assert!(err < 0.03, "mae {err}");
    assert_eq!(a, model(1, 40), "same seed, same weights");
}

#[test]
fn candle_forward_matches_a_scalar_forward() {
    let m = model(2, 3);
    let rows: Vec<[f32; INPUTS]> = vec![
        m.features([10.0, -20.0, 5.0], 3, 4),
        m.features([-128.0, 127.0, 0.0], 63, 47),
        m.features([f32::NAN, f32::INFINITY, -1e30], 0, 0),
    ];
    let flat: Vec<f32> = rows.iter().flatten().copied().collect();
    let out = m.net().expect("net").forward(&flat).expect("forward");
    for (r, row) in rows.iter().enumerate() {
        let mut h: Vec<f32> = row.to_vec();
        for (i, l) in m.layers.iter().enumerate() {
            h = (0..l.outputs)
                .map(|o| {
                    let z = l.bias[o]
                        + (0..l.inputs)
                            .map(|k| l.weight[o * l.inputs + k] * h[k])
                            .sum::<f32>();
                    if i + 1 < m.layers.len() { z.tanh() } else { z }
                })
                .collect();
        }
        for c in 0..2 {
            assert!((h[c] - out[r * 2 + c]).abs() < 1e-4, "{h:?} vs {out:?}");
            assert!(out[r * 2 + c].is_finite());
        }
    }
}

#[test]
fn baked_lut_matches_the_network_at_bin_centres() {
    let m = model(3, 10);
    let lut = bake(
        &m,
        BakeOptions {
            bins: 16,
            tiles: [2, 2],
        },
    )
    .expect("bakes");
    let net = m.net().expect("net");
    // At a tile centre and a bin centre, the table is the network exactly.
    let (x, y) = (16, 12);
    for rgb in [
        [-120.0, -120.0, -120.0],
        [8.0, -24.0, 40.0],
        [120.0, 120.0, 120.0],
    ] {
        let out = net.forward(&m.features(rgb, x, y)).expect("forward");
        let zero = net.forward(&m.features([0.0; 3], x, y)).expect("forward");
        let t = lut.predict_at(rgb, x, y);
        assert!(
            (t[0] - (out[0] - zero[0])).abs() < 1e-4,
            "{t:?} {out:?} {zero:?}"
        );
        assert!((t[1] - (out[1] - zero[1])).abs() < 1e-4);
    }
    let mut raw = m.clone();
    raw.input = Input::Raw;
    assert!(
        bake(&raw, BakeOptions::default()).is_err(),
        "raw models cannot be baked"
    );
}

#[test]
fn transfer_recovers_a_colour_offset() {
    let m = model(4, 40);
    // The sibling sensor sees every colour 12 grey levels lower in red and 9 higher in
    // green.
    let shift = [-12.0, 9.0, 0.0];
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let mut press = PressPixels::default();
    for _ in 0..800 {
        let k = [0; 3].map(|_| rng.random_range(-80.0f32..80.0));
        press
            .keys
            .push([k[0] + shift[0], k[1] + shift[1], k[2] + shift[2]]);
        press.background_keys.push(shift);
        press
            .positions
            .push((rng.random_range(0..64), rng.random_range(0..48)));
        press.targets.push(truth(k));
    }
    let before = mae(&m, shift);
    let (t, report) = transfer(&m, &press, Fit::Offset).expect("transfers");
    let after = mae(&t, shift);
    assert!(report.mae_after < report.mae_before, "{report:?}");
    assert!(after < before * 0.6, "before {before}, after {after}");
    assert!((t.offset_rgb[0] - 12.0).abs() < 4.0, "{:?}", t.offset_rgb);
    assert!((t.offset_rgb[1] + 9.0).abs() < 4.0, "{:?}", t.offset_rgb);
    assert_eq!(t.gain_rgb, [1.0; 3]);
    assert!(transfer(&m, &PressPixels::default(), Fit::Offset).is_err());
}

/// Validation samples whose targets are the truth negated: the better the network fits
/// the training samples, the worse its validation loss, so the first epochs are best.
#[test]
fn early_stopping_keeps_the_best_epochs_weights() {
    use super::train::train_validated;
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    let shape = shape();
    let (mut samples, mut validation) = (Samples::default(), Samples::default());
    for i in 0..2000 {
        let k = [0; 3].map(|_| rng.random_range(-100.0f32..100.0));
        let g = truth(k);
        let f = shape.features(k, rng.random_range(0..64), rng.random_range(0..48));
        samples.push(f, g[0], g[1]);
        if i % 4 == 0 {
            validation.push(f, -g[0], -g[1]);
        }
    }
    let opts = TrainOptions {
        hidden: 8,
        epochs: 30,
        batch: 256,
        learning_rate: 1e-2,
        patience: 3,
        ..TrainOptions::default()
    };
    let mut seen = Vec::new();
    let (m, v) = train_validated(&samples, &validation, Input::Diff, (64, 48), &opts, |e| {
        seen.push(e.validation_loss)
    })
    .expect("trains");
    assert!(v.stopped_at < opts.epochs, "{v:?}");
    assert_eq!(v.stopped_at, v.best_epoch + opts.patience, "{v:?}");
    assert_eq!(v.curve.len(), v.stopped_at);
    assert_eq!(seen.len(), v.stopped_at);
    assert!(seen.iter().all(|l| l.is_some_and(f64::is_finite)));
    let lowest = v.curve.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    assert_eq!(v.validation_loss, lowest);
    // The returned weights are the best epoch's: their validation loss is the summary's.
    let out = m
        .net()
        .expect("net")
        .forward(&validation.features)
        .expect("runs");
    let l1 = out
        .iter()
        .zip(&validation.targets)
        .map(|(p, t)| f64::from((p - t).abs()))
        .sum::<f64>()
        / out.len() as f64;
    assert!((l1 - v.validation_loss).abs() < 1e-4, "{l1} vs {v:?}");
    let last = v.curve.last().expect("curve").1;
    assert!(last > v.validation_loss + 1e-4, "{last} vs {v:?}");

    // Patience 0 runs every epoch; no validation pixels is an error.
    let all = TrainOptions {
        patience: 0,
        epochs: 4,
        ..opts
    };
    let (_, v) = train_validated(&samples, &validation, Input::Diff, (64, 48), &all, |_| {})
        .expect("trains");
    assert_eq!(v.stopped_at, 4);
    assert!(
        train_validated(
            &samples,
            &Samples::default(),
            Input::Diff,
            (64, 48),
            &all,
            |_| {}
        )
        .is_err()
    );
}
