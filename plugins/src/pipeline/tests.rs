//! Extremes: black, saturated, constant and pure-noise frames, and 1×1, 2×2 and 1024×1024
//! images, must give finite results (no NaN or Inf) and never panic.

use std::sync::Arc;

use jpeg_encoder::{ColorType, Encoder};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::*;
use crate::lut::{LutModel, LutTrainer};

fn jpeg(w: usize, h: usize, pixel: impl Fn(usize, usize, usize) -> u8) -> Vec<u8> {
    let rgb: Vec<u8> = (0..w * h * 3)
        .map(|k| pixel((k / 3) % w, (k / 3) / w, k % 3))
        .collect();
    let mut out = Vec::new();
    Encoder::new(&mut out, 85)
        .encode(&rgb, w as u16, h as u16, ColorType::Rgb)
        .expect("encodes");
    out
}

fn extreme_lut() -> Arc<LutModel> {
    // A model whose table holds huge gradients, the worst case for the solvers.
    let mut t = LutTrainer::new(Input::Diff, 8);
    t.add([0.0; 3], 0.0, 0.0);
    t.add([120.0, -120.0, 120.0], 1e6, -1e6);
    Arc::new(t.finish(4, 4))
}

fn pipeline(w: usize, h: usize, solver: Option<Solver>) -> SensorPipeline {
    let choice = StageChoice {
        stages: SensorStages {
            decode_scale: 1,
            undistort: None,
            reference_alpha: 0.05,
            model: None,
            mlp: None,
            solver,
            stiffness_n_per_mm3: 0.1,
        },
        model: GradientModel::Lut(extreme_lut()),
    };
    SensorPipeline::new(choice, w, h, 0.0625)
}

fn finite(s: &ContactSummary) -> bool {
    let opt = |v: Option<f64>| v.is_none_or(f64::is_finite);
    s.area_mm2.is_finite()
        && opt(s.max_depth_mm)
        && opt(s.mean_depth_mm)
        && opt(s.volume_mm3)
        && opt(s.force_n)
        && s.centroid_px
            .is_none_or(|(x, y)| x.is_finite() && y.is_finite())
}

#[test]
fn extreme_frames_give_finite_results() {
    let (w, h) = (64, 48);
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let noise: Vec<u8> = (0..w * h * 3).map(|_| rng.random()).collect();
    let frames = [
        jpeg(w, h, |_, _, _| 0),
        jpeg(w, h, |_, _, _| 255),
        jpeg(w, h, |_, _, _| 128),
        jpeg(w, h, |x, y, c| noise[(y * w + x) * 3 + c]),
        jpeg(w, h, |x, _, c| if x < w / 2 { 0 } else { [255, 0, 255][c] }),
    ];
    for solver in [Some(Solver::Dst), Some(Solver::Dct), None] {
        for reference in &frames {
            let mut p = pipeline(w, h, solver);
            p.calibrate(&[reference, reference]).expect("calibrates");
            for frame in &frames {
                for depth in [true, false] {
                    let s = p
                        .process(
                            frame,
                            Needs {
                                depth,
                                gradients: false,
                            },
                        )
                        .expect("processes");
                    assert!(finite(&s), "{solver:?} {s:?}");
                }
            }
        }
    }
}

#[test]
fn tiny_and_large_images_work() {
    for (w, h) in [(1, 1), (2, 2), (1024, 1024)] {
        let frame = jpeg(w, h, |x, y, c| ((x * 7 + y * 3 + c * 50) % 256) as u8);
        let flat = jpeg(w, h, |_, _, _| 100);
        for solver in [Solver::Dst, Solver::Dct] {
            let mut p = pipeline(w, h, Some(solver));
            p.calibrate(&[&flat]).expect("calibrates");
            let s = p.process(&frame, Needs::DEPTH).expect("processes");
            assert!(finite(&s), "{w}x{h} {solver:?} {s:?}");
        }
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let mut p = pipeline(64, 48, Some(Solver::Dct));
    let frame = jpeg(64, 48, |_, _, _| 9);
    assert_eq!(
        p.process(&frame, Needs::DEPTH),
        Err(PipelineError::NoReference)
    );
    p.calibrate(&[&frame]).expect("calibrates");
    assert!(matches!(
        p.process(b"not a jpeg", Needs::DEPTH),
        Err(PipelineError::Decode(_))
    ));
    let wrong = jpeg(32, 32, |_, _, _| 9);
    assert!(matches!(
        p.process(&wrong, Needs::DEPTH),
        Err(PipelineError::Decode(DecodeError::Size { .. }))
    ));
    let truncated = &frame[..frame.len() / 2];
    let _ = p.process(truncated, Needs::DEPTH); // an error or a partial image, never a panic
}

#[test]
fn reference_never_drifts_during_contact() {
    let (w, h) = (64, 48);
    let flat = jpeg(w, h, |_, _, _| 100);
    let pressed = jpeg(w, h, |x, y, _| {
        if (24..40).contains(&x) && (16..32).contains(&y) {
            200
        } else {
            100
        }
    });
    let mut p = pipeline(w, h, Some(Solver::Dct));
    p.calibrate(&[&flat, &flat]).expect("calibrates");
    for _ in 0..200 {
        let s = p.process(&pressed, Needs::AREA).expect("processes");
        assert!(s.in_contact, "contact faded: the reference absorbed it");
    }
}

/// A LUT whose key maps linearly to gx: red up, green down (0.01 per 5 key units).
fn ridge_lut(input: Input) -> Arc<LutModel> {
    let mut t = LutTrainer::new(input, 64);
    for k in 0..=16 {
        t.add([5.0 * k as f32, 0.0, 0.0], 0.01 * k as f32, 0.0);
        t.add([0.0, 5.0 * k as f32, 0.0], -0.01 * k as f32, 0.0);
    }
    Arc::new(t.finish(160, 96))
}

/// The volume a press reads: a ridge 16 px square, its left half 40 grey levels redder
/// (rising along x) and its right half 40 greener (falling), 4 px from the right edge of
/// a pad darkened by lens vignetting `v` (`1 − v·r²`, r = 1 at the corners) in both the
/// frame and the reference, as a camera's lens does.
fn vignetted_press_volume(input: Input, v: f64) -> f64 {
    let (w, h, x0) = (160, 96, 140);
    let vignette = |x: usize, y: usize| {
        let (dx, dy) = (x as f64 / 80.0 - 1.0, y as f64 / 80.0 - 0.6);
        1.0 - v * (dx * dx + dy * dy) / 1.36
    };
    let image = |press: bool| -> Vec<u8> {
        (0..w * h * 3)
            .map(|k| {
                let (x, y, c) = ((k / 3) % w, (k / 3) / w, k % 3);
                let inside = press && (x0..x0 + 16).contains(&x) && (40..56).contains(&y);
                let lit = if x < x0 + 8 { 0 } else { 1 };
                let base = 150.0 + if inside && c == lit { 40.0 } else { 0.0 };
                (base * vignette(x, y)).round() as u8
            })
            .collect()
    };
    let choice = StageChoice {
        stages: SensorStages {
            decode_scale: 1,
            undistort: None,
            reference_alpha: 0.0,
            model: None,
            mlp: None,
            solver: Some(Solver::Dct),
            stiffness_n_per_mm3: 0.08,
        },
        model: GradientModel::Lut(ridge_lut(input)),
    };
    let mut p = SensorPipeline::new(choice, w, h, 0.05);
    let flat = image(false);
    p.calibrate_rgb(&[&flat, &flat]).expect("calibrates");
    let s = p
        .process_rgb(&image(true), Needs::DEPTH)
        .expect("processes");
    s.volume_mm3.expect("depth was asked for")
}

#[test]
fn a_relative_key_reads_a_press_at_the_vignetted_edge_as_without_vignetting() {
    // The press sits where vignetting of 0.35 darkens the pad by about a fifth.
    let ratio = |input| vignetted_press_volume(input, 0.35) / vignetted_press_volume(input, 0.0);
    let relative = ratio(Input::Relative);
    let diff = ratio(Input::Diff);
    assert!(
        (relative - 1.0).abs() < 0.03,
        "relative key: volume with vignetting over without {relative:.3}"
    );
    // The difference key reads the darker pad's smaller difference as a shallower slope.
    assert!(
        diff < 0.9,
        "difference key: volume with vignetting over without {diff:.3}"
    );
}

#[test]
fn a_relative_key_is_the_difference_as_a_share_of_the_reference() {
    use crate::lut::{RELATIVE_FLOOR, relative_key};
    // A gain on frame and reference alike cancels.
    assert_eq!(relative_key(190.0, 150.0), relative_key(95.0, 75.0));
    assert!((relative_key(160.0, 128.0) - 32.0).abs() < 1e-6);
    // A black reference channel does not blow its noise up.
    assert_eq!(relative_key(3.0, 0.0), 3.0 * 128.0 / RELATIVE_FLOOR);
    for (f, r) in [(255.0, 0.0), (0.0, 255.0), (f32::NAN, 10.0)] {
        let k = relative_key(f, r);
        assert!(
            k.is_nan() || k.abs() <= 128.0 * 255.0 / RELATIVE_FLOOR,
            "{k}"
        );
    }
}

/// A large press processed with its stages in two halves gives the one-pass readings and
/// depth bit for bit.
#[test]
fn a_frame_in_halves_reads_as_in_one_pass() {
    let (w, h) = (320, 240);
    let reference = jpeg(w, h, |x, y, c| (60 + (x + 2 * y + 30 * c) % 40) as u8);
    let press = jpeg(w, h, |x, y, c| {
        let (dx, dy) = (x as f64 - 170.0, y as f64 - 120.0);
        let bump = (110.0 - (dx * dx + dy * dy).sqrt()).max(0.0) * [0.9, 0.5, 0.2][c];
        (60.0 + ((x + 2 * y + 30 * c) % 40) as f64 + bump).min(255.0) as u8
    });
    let run = |split: bool| {
        let process = || {
            let mut p = pipeline(w, h, Some(Solver::Dct));
            p.calibrate(&[&reference, &reference]).expect("calibrates");
            let s = p
                .process(
                    &press,
                    Needs {
                        gradients: true,
                        depth: true,
                    },
                )
                .expect("processes");
            let (depth, window) = p.last_depth_mm();
            let bits: Vec<u32> = depth.iter().map(|d| d.to_bits()).collect();
            (format!("{s:?}"), window, bits)
        };
        if split {
            crate::halves::with_stages_split(process)
        } else {
            // Inside the pool a stage is never split.
            rayon::scope(|_| process())
        }
    };
    let (one, two) = (run(false), run(true));
    assert!(
        one.1.2 * one.1.3 >= crate::halves::SPLIT_MIN_PX,
        "window {:?}",
        one.1
    );
    assert_eq!(one, two);
}

/// The block activity from the frame's exact block sums less the reference's kept sums
/// equals |mean(frame − reference)| per channel, summed, computed pixel by pixel, on noise,
/// black and saturated frames (a 100 × 70 image: partial blocks at the edges), also after
/// the reference drifted.
#[test]
fn block_activity_is_the_mean_difference_per_block() {
    let (w, h) = (100, 70);
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let noise: Vec<u8> = (0..w * h * 3).map(|_| rng.random()).collect();
    let reference = jpeg(w, h, |x, y, c| (40 + (3 * x + y + 50 * c) % 120) as u8);
    let frames = [
        jpeg(w, h, |x, y, c| noise[(y * w + x) * 3 + c]),
        jpeg(w, h, |_, _, _| 0),
        jpeg(w, h, |_, _, _| 255),
        reference.clone(),
    ];
    let mut p = pipeline(w, h, Some(Solver::Dct));
    p.calibrate(&[&reference, &frames[0]]).expect("calibrates");
    for frame in frames.iter().chain(frames.iter()) {
        let needs = Needs {
            depth: false,
            gradients: false,
        };
        // The activity is measured against the reference before the frame (a quiet frame
        // then moves it: the pipeline's reference drifts).
        let reference = p.reference.clone().expect("a reference");
        p.process(frame, needs).expect("processes");
        let bw = w.div_ceil(BLOCK_PX);
        for (k, got) in p.blocks.iter().enumerate() {
            let (bx, by) = (k % bw, k / bw);
            let mut sum = [0.0f64; 3];
            let mut n = 0.0;
            for y in by * BLOCK_PX..((by + 1) * BLOCK_PX).min(h) {
                for x in bx * BLOCK_PX..((bx + 1) * BLOCK_PX).min(w) {
                    for (c, s) in sum.iter_mut().enumerate() {
                        let i = (y * w + x) * 3 + c;
                        *s += f64::from(p.rgb[i]) - f64::from(reference[i]);
                    }
                    n += 1.0;
                }
            }
            let want: f64 = sum.iter().map(|s| (s / n).abs()).sum();
            assert!(
                (f64::from(*got) - want).abs() <= 1e-4 * want.max(1.0),
                "block {k}: {got} against {want}"
            );
        }
    }
}

/// The depth window covers a contact's blocks and the active blocks near them, not a lone
/// block of noise far away; where every active block is alone, all of them.
#[test]
fn a_lone_active_block_far_from_a_contact_does_not_stretch_the_window() {
    let (w, h) = (320, 240);
    let mut p = pipeline(w, h, Some(Solver::Dct));
    let bw = w / BLOCK_PX;
    let mut window_of = |active: &[(usize, usize)]| {
        p.blocks.fill(0.0);
        for (bx, by) in active {
            p.blocks[by * bw + bx] = 2.0;
        }
        p.active_window(1.0).expect("a window")
    };
    let contact: Vec<(usize, usize)> = (20..23)
        .flat_map(|bx| (20..23).map(move |by| (bx, by)))
        .collect();
    let alone = window_of(&contact);
    let with = |extra: (usize, usize)| {
        let mut blocks = contact.clone();
        blocks.push(extra);
        blocks
    };
    // A block in the far corner: noise, the window is the contact's.
    assert_eq!(window_of(&with((0, 0))), alone);
    // A block two blocks from the contact (a broken rim): part of it.
    let (x, _, ww, _) = window_of(&with((24, 21)));
    assert!(x + ww >= 25 * BLOCK_PX, "{x} + {ww}");
    // One block further: noise again.
    assert_eq!(window_of(&with((25, 21))), alone);
    // Only lone blocks: every one counts (the whole frame here).
    assert_eq!(window_of(&[(0, 0), (39, 29)]), (0, 0, w, h));
    let (x0, y0, _, _) = alone;
    assert!(x0 <= 20 * BLOCK_PX - WINDOW_MARGIN_PX && y0 <= 20 * BLOCK_PX - WINDOW_MARGIN_PX);
}
