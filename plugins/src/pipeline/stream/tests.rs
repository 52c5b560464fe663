//! Streaming against the direct path: the same results bit for bit, and nothing worked on
//! for a refused set handed out.

use std::sync::Arc;

use jpeg_encoder::{ColorType, Encoder};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::*;
use crate::config::SensorStages;
use crate::gradient::GradientModel;
use crate::lut::{Input, LutTrainer};
use crate::pipeline::{StageChoice, process_set};
use crate::poisson::Solver;

const W: usize = 96;
const H: usize = 64;
const SENSORS: usize = 3;

/// A grey frame with noise, and with `press` a dome at `(cx, cy)` whose slope tints it.
fn frame(seed: u64, press: Option<(f32, f32)>) -> Bytes {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut rgb = Vec::with_capacity(W * H * 3);
    for y in 0..H {
        for x in 0..W {
            let (mut dx, mut dy) = (0.0f32, 0.0f32);
            if let Some((cx, cy)) = press {
                let (u, v) = (x as f32 - cx, y as f32 - cy);
                if u * u + v * v < 15.0 * 15.0 {
                    (dx, dy) = (-u * 3.0, -v * 3.0);
                }
            }
            for c in [128.0 + dx, 128.0 + dy, 128.0 - 0.5 * (dx + dy)] {
                let n: f32 = rng.random_range(-2.0..2.0);
                rgb.push((c + n).clamp(0.0, 255.0) as u8);
            }
        }
    }
    let mut out = Vec::new();
    Encoder::new(&mut out, 90)
        .encode(&rgb, W as u16, H as u16, ColorType::Rgb)
        .expect("encodes");
    Bytes::from(out)
}

fn pipeline(alpha: f32) -> SensorPipeline {
    // Difference colour → gradient: the tint above is -3 × the offset from the dome's centre.
    let mut t = LutTrainer::new(Input::Diff, 32);
    for u in -45..=45 {
        for v in -45..=45 {
            let (dx, dy) = (u as f32, v as f32);
            t.add([dx, dy, -0.5 * (dx + dy)], dx / 200.0, dy / 200.0);
        }
    }
    let choice = StageChoice {
        stages: SensorStages {
            decode_scale: 1,
            undistort: None,
            reference_alpha: alpha,
            model: None,
            mlp: None,
            solver: Some(Solver::Dct),
            stiffness_n_per_mm3: 0.1,
        },
        model: GradientModel::Lut(Arc::new(t.finish(4, 4))),
    };
    let mut pipe = SensorPipeline::new(choice, W, H, 0.0625);
    let quiet: Vec<Bytes> = (0..6).map(|k| frame(1000 + k, None)).collect();
    let quiet: Vec<&[u8]> = quiet.iter().map(|b| b.as_ref()).collect();
    pipe.calibrate(&quiet).expect("reference");
    pipe
}

/// Sensor `s`'s frame of set `seq`: pressed at a place that moves with the set, or quiet.
fn set_frame(seq: u32, s: usize) -> Bytes {
    let pressed = !(seq + s as u32).is_multiple_of(3);
    let at = (30.0 + (seq * 7 % 30) as f32, 28.0 + (s * 5) as f32);
    frame(u64::from(seq) * 16 + s as u64, pressed.then_some(at))
}

fn fresh() -> Vec<Result<ContactSummary, PipelineError>> {
    (0..SENSORS)
        .map(|_| Ok(ContactSummary::default()))
        .collect()
}

/// Wait until every frame handed to the pool has been worked on (a frame's task that
/// found the lock taken by this very check is handed out again).
fn settle(s: &StreamingSensors) {
    for slot in &s.slots {
        while lock(slot).queued.is_some() {
            spawn_queued(slot, s.needs);
            std::thread::yield_now();
        }
    }
}

#[test]
fn streamed_results_equal_the_direct_path_bit_for_bit() {
    let mut direct: Vec<SensorPipeline> = (0..SENSORS).map(|_| pipeline(0.0)).collect();
    let mut streamed =
        StreamingSensors::new((0..SENSORS).map(|_| pipeline(0.0)).collect(), Needs::DEPTH);
    let mut contacts = 0;
    for seq in 1..=8u32 {
        let frames: Vec<Bytes> = (0..SENSORS).map(|s| set_frame(seq, s)).collect();
        // All but the last sensor arrive ahead (on odd sets, none do).
        if seq.is_multiple_of(2) {
            for (s, f) in frames.iter().enumerate().take(SENSORS - 1) {
                streamed.arrive(
                    s,
                    FrameKey {
                        trigger_seq: seq,
                        jpeg: f.clone(),
                    },
                );
            }
        }
        let (mut want, mut got) = (fresh(), fresh());
        let refs: Vec<&[u8]> = frames.iter().map(|b| b.as_ref()).collect();
        process_set(&mut direct, &refs, Needs::DEPTH, &mut want);
        let keys: Vec<Option<FrameKey>> = frames
            .iter()
            .map(|f| {
                Some(FrameKey {
                    trigger_seq: seq,
                    jpeg: f.clone(),
                })
            })
            .collect();
        streamed.process(&keys, &mut got);
        for (s, (w, g)) in want.iter().zip(&got).enumerate() {
            let (w, g) = (w.as_ref().expect("direct"), g.as_ref().expect("streamed"));
            assert_eq!(w, g, "set {seq}, sensor {s}");
            contacts += usize::from(w.in_contact);
        }
    }
    assert!(contacts > 0, "the presses are seen");
}

#[test]
fn a_refused_sets_work_never_reaches_the_caller() {
    let mut streamed =
        StreamingSensors::new((0..SENSORS).map(|_| pipeline(0.0)).collect(), Needs::DEPTH);
    // Set 1's frames (every pad pressed) arrive and are worked on; the gate refuses it.
    let pressed: Vec<Bytes> = (0..SENSORS)
        .map(|s| frame(50 + s as u64, Some((48.0, 32.0))))
        .collect();
    for (s, f) in pressed.iter().enumerate() {
        streamed.arrive(
            s,
            FrameKey {
                trigger_seq: 1,
                jpeg: f.clone(),
            },
        );
    }
    settle(&streamed);
    assert!(
        streamed.slots.iter().all(|s| lock(s)
            .done
            .as_ref()
            .is_some_and(|(_, r)| r.as_ref().is_ok_and(|c| c.in_contact))),
        "set 1 was worked on ahead, and is a contact"
    );
    // Set 2 is quiet; sensor 0 never arrived ahead, and sensor 1's set-2 frame carries
    // set 1's very bytes (only the sequence tells them apart).
    let mut quiet: Vec<Bytes> = (0..SENSORS).map(|s| frame(70 + s as u64, None)).collect();
    quiet[1] = pressed[1].clone();
    for (s, f) in quiet.iter().enumerate().skip(2) {
        streamed.arrive(
            s,
            FrameKey {
                trigger_seq: 2,
                jpeg: f.clone(),
            },
        );
    }
    let keys: Vec<Option<FrameKey>> = quiet
        .iter()
        .map(|f| {
            Some(FrameKey {
                trigger_seq: 2,
                jpeg: f.clone(),
            })
        })
        .collect();
    let mut got = fresh();
    streamed.process(&keys, &mut got);
    let mut direct: Vec<SensorPipeline> = (0..SENSORS).map(|_| pipeline(0.0)).collect();
    let mut want = fresh();
    let refs: Vec<&[u8]> = quiet.iter().map(|b| b.as_ref()).collect();
    process_set(&mut direct, &refs, Needs::DEPTH, &mut want);
    for (s, (w, g)) in want.iter().zip(&got).enumerate() {
        assert_eq!(
            w.as_ref().expect("direct"),
            g.as_ref().expect("streamed"),
            "sensor {s}"
        );
    }
    assert!(!got[0].as_ref().expect("sensor 0").in_contact);
    assert!(!got[2].as_ref().expect("sensor 2").in_contact);
    // Set 1's results are gone, and every pipeline shows its set-2 frame.
    for (s, slot) in streamed.slots.iter().enumerate() {
        let slot = lock(slot);
        assert!(slot.done.is_none() && slot.queued.is_none(), "sensor {s}");
        assert_eq!(slot.committed.as_ref().map(|k| k.trigger_seq), Some(2));
    }
    assert!(streamed.with_committed_pipe(0, |_| ()).is_some());
}

#[test]
fn a_drifting_reference_is_not_worked_on_ahead() {
    let streamed = StreamingSensors::new(vec![pipeline(0.05), pipeline(0.0)], Needs::DEPTH);
    for s in 0..2 {
        streamed.arrive(
            s,
            FrameKey {
                trigger_seq: 1,
                jpeg: set_frame(1, s),
            },
        );
    }
    settle(&streamed);
    assert!(lock(&streamed.slots[0]).done.is_none());
    assert!(lock(&streamed.slots[1]).done.is_some());
}
