//! `gelgrip calibrate label` and the contact detection under it: accuracy on the
//! simulator's presses across ball sizes and depths, every bad-input case, and `calibrate
//! collect` over the emulated CDC hub (presses on request) into a LUT.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Command, Output};

use common::press_hub::{PressHub, collect_command};
use common::{gelgrip, json, ok, s, scratch};
use gelgrip::wiring;
use gelgrip_plugins::calibrate::collect::{decode_frame, mean_background};
use gelgrip_plugins::calibrate::label::detect;
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::image::RgbImage;
use gelgrip_sim::press_camera::sensor_camera;
use gelgrip_sim::scene::HeightMap;
use rand::{Rng, SeedableRng};

/// How a set of simulated presses is drawn.
struct PressPlan<'a> {
    config: Option<&'a Path>,
    balls_mm: &'a [f64],
    per_ball: u64,
    /// Contact radius as a share of the ball's, drawn uniformly in this range; the press is
    /// never deeper than `max_depth_mm`.
    contact_share: std::ops::Range<f64>,
    max_depth_mm: f64,
    seed: u64,
}

/// Labels `plan`'s presses; returns (within 1 px and 5%, presses, worst centre error px,
/// worst radius error, worst centre error before JPEG px).
fn label_accuracy(plan: &PressPlan<'_>) -> (usize, usize, f64, f64, f64) {
    let config = wiring::load_config(plan.config, &wiring::registry()).expect("the config loads");
    let (cam, _) = sensor_camera(&config, "f1.tip").expect("camera");
    let background = mean_background(&cam).expect("the background");
    let flat = RgbImage {
        width: cam.width,
        height: cam.height,
        data: cam.rgb(&HeightMap::flat(cam.width, cam.height), 1),
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(plan.seed);
    let (mut good, mut total, mut worst_c, mut worst_r, mut worst_raw) =
        (0, 0, 0.0f64, 0.0f64, 0.0f64);
    for &ball_mm in plan.balls_mm {
        let r_mm: f64 = ball_mm / 2.0;
        let ball_px = r_mm / cam.mm_per_px;
        for i in 0..plan.per_ball {
            let share: f64 = rng.random_range(plan.contact_share.clone());
            let depth =
                (r_mm - (r_mm * r_mm * (1.0 - share * share)).sqrt()).min(plan.max_depth_mm);
            let a_px = (r_mm * r_mm - (r_mm - depth).powi(2)).sqrt() / cam.mm_per_px;
            let m = a_px + 4.0;
            let cx = rng.random_range(m..cam.width as f64 - m);
            let cy = rng.random_range(m..cam.height as f64 - m);
            // The camera's gel: realistic optics bring their skirt around the contact.
            let map = cam.ball_press_map((cx, cy), ball_mm, depth);
            let jpeg = cam.jpeg(&map, 2_000_000 + i).expect("render");
            let img = decode_frame(&cam, &jpeg).expect("decode");
            total += 1;
            let line = format!(
                "ball {ball_mm} mm, {depth:.2} mm deep: truth ({cx:.2}, {cy:.2}) r {a_px:.2} ({:.2} of the ball's)",
                a_px / ball_px
            );
            // The same press before JPEG: the decoded frames' colour sits about half a
            // pixel right and down of the geometry (chroma siting), the rendered RGB does not.
            let raw = RgbImage {
                width: cam.width,
                height: cam.height,
                data: cam.rgb(&map, 2_000_000 + i),
            };
            match detect(&raw, &flat, ball_px) {
                Ok(c) => {
                    worst_raw = worst_raw.max((c.center_x_px - cx).hypot(c.center_y_px - cy));
                }
                Err(e) => eprintln!("{line}: before JPEG: rejected: {e}"),
            }
            match detect(&img, &background, ball_px) {
                Ok(c) => {
                    let dc = (c.center_x_px - cx).hypot(c.center_y_px - cy);
                    let dr = (c.contact_radius_px / a_px - 1.0).abs();
                    worst_c = worst_c.max(dc);
                    worst_r = worst_r.max(dr);
                    good += usize::from(dc <= 1.0 && dr <= 0.05);
                    eprintln!(
                        "{line}: found ({:.2}, {:.2}) r {:.2}, score {:.2}: {dc:.2} px, {:.1}%",
                        c.center_x_px,
                        c.center_y_px,
                        c.contact_radius_px,
                        c.score,
                        dr * 100.0
                    );
                }
                Err(e) => eprintln!("{line}: rejected: {e}"),
            }
        }
    }
    eprintln!(
        "{good} of {total} within 1 px and 5%; worst {worst_c:.2} px, {:.1}%",
        worst_r * 100.0
    );
    eprintln!("before JPEG: worst centre error {worst_raw:.2} px");
    (good, total, worst_c, worst_r, worst_raw)
}

/// Simulator presses (nominal optics) of balls of 4, 6 and 10 mm, shallow to a contact
/// radius of 0.9 of the ball's, anywhere on the pad: the centre within 1 px and the radius
/// within 5% of the truth on at least 95%.
#[test]
fn simulator_presses_are_labelled_to_a_pixel() {
    let (good, total, _, _, worst_raw) = label_accuracy(&PressPlan {
        config: None,
        balls_mm: &[4.0, 6.0, 10.0],
        per_ball: 12,
        contact_share: 0.2..0.9,
        max_depth_mm: 2.0,
        seed: 27,
    });
    assert!(good as f64 >= 0.95 * total as f64, "{good} of {total}");
    assert!(worst_raw < 0.25, "{worst_raw}");
}

/// Deep presses on the realistic optics (fitted to the real Mini: LED falloff, shadowing at
/// steep slopes, gamma, its noise): balls of 3 to 6 mm, pressed from a contact radius of 0.3
/// to 0.95 of the ball's or 2 mm deep, whichever is shallower: the centre within 1 px and
/// the radius within 5% of the truth on at least 95% (the issue's acceptance; `gelgrip
/// bench label` runs 120 of these), and every press within 2 px and 8%.
#[test]
fn deep_presses_on_realistic_optics_are_labelled_to_a_pixel() {
    let (good, total, worst_c, worst_r, _) = label_accuracy(&PressPlan {
        config: Some(Path::new("configs/gelgripper-sim-realistic.toml")),
        balls_mm: &[3.0, 4.5, 6.0],
        per_ball: 8,
        contact_share: 0.3..0.95,
        max_depth_mm: 2.0,
        seed: 41,
    });
    assert!(good as f64 >= 0.95 * total as f64, "{good} of {total}");
    assert!(worst_c <= 2.0 && worst_r <= 0.08, "{worst_c} px, {worst_r}");
}

/// On a gel whose surface sinks around the contact (`realistic-gel`: the skirt fitted to the
/// real Mini), the visible imprint is far wider than the contact (its fall read +63% to
/// +96% in the median before). Collected and labelled as a user would: the dataset's
/// colour turns grow with its imprints, so its rims are read there, and the labels find the
/// contact: the median radius within 10% of the truth, some presses within 1 px and 5%
/// (measured: 4 of 12, radius errors 3% in the median).
#[test]
fn a_gel_with_a_skirt_is_labelled_at_its_contact_not_its_imprint() {
    let dir = scratch("label-skirt");
    let (data, out) = (dir.join("presses"), dir.join("labels"));
    ok(&gelgrip(&[
        "calibrate",
        "collect",
        "--config",
        "configs/gelgripper-sim-realistic-gel.toml",
        "--sensor",
        "f1.tip",
        "--presses",
        "12",
        "--ball-mm",
        "6",
        "--out",
        s(&data),
    ]));
    let report = json(&gelgrip(&[
        "calibrate",
        "label",
        "--in",
        s(&data),
        "--out",
        s(&out),
        "--ball-mm",
        "6",
        "--mm-per-px",
        "0.0625",
        "--json",
    ]));
    let truth = PressDataset::load(&data).expect("the collected truth");
    let labels = PressDataset::load(&out).expect("the labels");
    let mut radius_errors = Vec::new();
    let mut within = 0;
    for label in &labels.presses {
        let t = truth
            .presses
            .iter()
            .find(|t| t.file == label.file)
            .expect("a true press");
        let dc = (label.center_x_px - t.center_x_px).hypot(label.center_y_px - t.center_y_px);
        let dr = label.contact_radius_px / t.contact_radius_px - 1.0;
        eprintln!("{}: {dc:.2} px, {:+.1}%", label.file, dr * 100.0);
        within += usize::from(dc <= 1.0 && dr.abs() <= 0.05);
        radius_errors.push(dr.abs());
        assert!(label.contact_radius_px < 48.0, "{label:?}");
    }
    radius_errors.sort_by(f64::total_cmp);
    assert!(labels.presses.len() >= 8, "{report}");
    assert!(
        radius_errors[radius_errors.len() / 2] <= 0.1,
        "{radius_errors:?}"
    );
    assert!(within >= 3, "{within} within 1 px and 5%");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Collect `n` simulator presses (with their true labels) into `dir`.
fn sim_presses(dir: &std::path::Path, n: &str) {
    ok(&gelgrip(&[
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        n,
        "--out",
        s(dir),
    ]));
}

/// A label run on a folder of simulator presses with three bad images among them: the good
/// ones become a dataset near their true labels, the bad ones are listed with their reason.
#[test]
fn label_writes_a_dataset_the_rejected_and_a_contact_sheet() {
    let dir = scratch("label");
    let (sim, input, out) = (dir.join("sim"), dir.join("in"), dir.join("out"));
    sim_presses(&sim, "6");
    std::fs::create_dir_all(&input).expect("in");
    for f in std::fs::read_dir(&sim).expect("sim").flatten() {
        let name = f.file_name().into_string().expect("name");
        if name.ends_with(".png") {
            std::fs::copy(f.path(), input.join(&name)).expect("copy");
        }
    }
    std::fs::write(input.join("garbage.png"), b"not a png at all").expect("garbage");
    RgbImage::new(32, 24)
        .write_png(&input.join("small.png"))
        .expect("small");
    std::fs::copy(sim.join("background.png"), input.join("untouched.png")).expect("copy");
    let report = json(&gelgrip(&[
        "calibrate",
        "label",
        "--in",
        s(&input),
        "--out",
        s(&out),
        "--ball-mm",
        "6",
        "--mm-per-px",
        "0.0625",
        "--json",
    ]));
    assert_eq!(report["labelled"], 6, "{report}");
    let rejected = report["rejected"].as_array().expect("rejected");
    let reason = |file: &str| {
        rejected
            .iter()
            .find(|r| r["file"] == file)
            .and_then(|r| r["reason"].as_str())
            .map(str::to_string)
            .unwrap_or_default()
    };
    let code = |file: &str| {
        rejected
            .iter()
            .find(|r| r["file"] == file)
            .and_then(|r| r["code"].as_str())
            .map(str::to_string)
            .unwrap_or_default()
    };
    assert_eq!(code("garbage.png"), "unreadable", "{report}");
    assert_eq!(code("small.png"), "wrong_size", "{report}");
    assert_eq!(code("untouched.png"), "no_contact", "{report}");
    assert!(
        report["camera_noise"].as_f64().is_some_and(|n| n > 0.0),
        "{report}"
    );
    assert!(reason("garbage.png").starts_with("unreadable"), "{report}");
    assert!(reason("small.png").starts_with("wrong size"), "{report}");
    assert!(
        reason("untouched.png").starts_with("no contact"),
        "{report}"
    );
    assert_eq!(rejected.len(), 3, "{report}");
    let truth = PressDataset::load(&sim).expect("sim dataset");
    let labelled = PressDataset::load(&out).expect("the output is a press dataset");
    assert_eq!(labelled.info.ball_diameter_mm, 6.0);
    for (t, l) in truth.presses.iter().zip(&labelled.presses) {
        assert_eq!(t.file, l.file);
        let dc = (t.center_x_px - l.center_x_px).hypot(t.center_y_px - l.center_y_px);
        assert!(
            dc < 1.0 && (l.contact_radius_px / t.contact_radius_px - 1.0).abs() < 0.05,
            "{t:?} {l:?}"
        );
        labelled
            .press_image(l)
            .expect("the press image is in the dataset");
    }
    for p in report["presses"].as_array().expect("presses") {
        let score = p["score"].as_f64().expect("score");
        assert!(
            (0.0..=1.0).contains(&score) && p["center_x_px"].is_f64(),
            "{p}"
        );
    }
    let csv = std::fs::read_to_string(out.join("rejected.csv")).expect("rejected.csv");
    assert!(
        csv.starts_with("file,reason\n") && csv.lines().count() == 4,
        "{csv}"
    );
    assert!(
        csv.contains("\ngarbage.png,") || csv.contains("\ngarbage.png,\""),
        "{csv}"
    );
    let sheet = RgbImage::read_png(&out.join("contact-sheet.png")).expect("contact sheet");
    assert!(sheet.width > 100 && sheet.height > 100);
}

/// A missing or unreadable background, or a folder without press images: exit 2 naming it.
#[test]
fn label_without_a_background_or_presses_exits_2() {
    let dir = scratch("label-bad");
    let args = |input: &std::path::Path| {
        gelgrip(&[
            "calibrate",
            "label",
            "--in",
            s(input),
            "--out",
            s(&dir.join("out")),
            "--ball-mm",
            "6",
            "--mm-per-px",
            "0.0625",
        ])
    };
    let input = dir.join("in");
    std::fs::create_dir_all(&input).expect("in");
    RgbImage::new(32, 24)
        .write_png(&input.join("press_000.png"))
        .expect("press");
    let out = args(&input);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("background.png"), "{stderr}");
    std::fs::write(input.join("background.png"), b"garbage").expect("bad background");
    let out = args(&input);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("background.png"), "{stderr}");
    std::fs::remove_file(input.join("press_000.png")).expect("rm");
    RgbImage::new(32, 24)
        .write_png(&input.join("background.png"))
        .expect("background");
    let out = args(&input);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no press images") && stderr.contains(s(&input)),
        "{stderr}"
    );
    let out = args(&dir.join("missing"));
    assert_eq!(out.status.code(), Some(2));
}

/// How a collect session is driven: keep every press, or end it after `after` kept
/// presses by SIGINT or by closing stdin.
#[derive(Clone, Copy, PartialEq)]
enum End {
    Complete,
    Sigint { after: usize },
    CloseStdin { after: usize },
}

/// Run `calibrate collect` of `presses` on the hub into `out`, pressing a 6 mm ball at
/// random places and depths on f1.tip at each prompt and keeping each press but the first
/// (redone).
fn collect_on_hub(hub: &mut PressHub, out: &Path, presses: &str, end: End) -> (Output, String) {
    let mut child = collect_command(&hub.config, out, presses)
        .arg("--headless")
        .spawn()
        .expect("calibrate collect starts");
    let mut stdin = child.stdin.take();
    // A session that stops making progress fails the test instead of hanging it.
    let watchdog = common::Watchdog::new(child.id(), std::time::Duration::from_secs(180));
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    let (mut kept, mut redone, mut log) = (0, false, String::new());
    for line in BufReader::new(child.stderr.take().expect("stderr")).lines() {
        let line = line.expect("stderr line");
        log += &line;
        log.push('\n');
        let Some(step) = line.strip_prefix("> ") else {
            if line.trim_start().starts_with("kept ") {
                kept += 1;
            }
            continue;
        };
        match end {
            End::Sigint { after } if kept == after && step.starts_with("press") => {
                let pid = child.id().to_string();
                Command::new("kill")
                    .args(["-INT", &pid])
                    .status()
                    .expect("kill");
                continue;
            }
            End::CloseStdin { after } if kept == after && step.starts_with("press") => {
                stdin = None;
                continue;
            }
            _ => {}
        }
        if step.starts_with("leave") {
            assert_eq!(hub.ask("f1.tip lift")["lifted"], true);
        }
        if step.starts_with("press") {
            let depth: f64 = rng.random_range(0.15..0.9);
            let a_px = (9.0 - (3.0 - depth).powi(2)).sqrt() / 0.0625;
            let m = a_px + 4.0;
            let (x, y) = (
                rng.random_range(m..320.0 - m),
                rng.random_range(m..240.0 - m),
            );
            let answer = hub.ask(&format!("f1.tip {x:.2} {y:.2} {depth:.3}"));
            assert!(answer["contact_radius_px"].is_f64(), "{answer}");
        }
        let reply = if step.starts_with("keep") && !redone {
            redone = true;
            "r"
        } else {
            ""
        };
        if let Some(w) = stdin.as_mut() {
            writeln!(w, "{reply}").expect("collect stdin");
        }
    }
    let out = child.wait_with_output().expect("collect exits");
    drop(watchdog);
    (out, log)
}

fn eval_json(model: &Path, data: &Path) -> serde_json::Value {
    json(&gelgrip(&[
        "calibrate",
        "eval",
        "--model",
        s(model),
        "--data",
        s(data),
        "--solver",
        "none",
        "--json",
    ]))
}

fn train_lut(data: &Path, model: &Path) {
    ok(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(data),
        "--model",
        "lut",
        "--out",
        s(model),
    ]));
}

/// 20 presses collected over the emulated CDC hub on a pseudo-terminal, labelled as they
/// come and trained into a LUT, read simulator presses as well as a LUT trained on 20
/// simulator-collected presses with true labels: gx_mae and gy_mae within 10%.
#[test]
fn presses_collected_through_the_cdc_hub_train_a_lut_as_good_as_the_simulators() {
    let dir = scratch("collect-hub");
    let mut hub = PressHub::start(&dir);
    let hub_data = dir.join("hub-presses");
    let (out, log) = collect_on_hub(&mut hub, &hub_data, "20", End::Complete);
    assert!(out.status.success(), "{:?}\n{log}", out.status);
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("20 presses kept"),
        "{out:?}"
    );
    assert!(log.contains("redo"), "{log}");
    assert_eq!(
        PressDataset::load(&hub_data)
            .expect("dataset")
            .presses
            .len(),
        20
    );

    let sim_data = dir.join("sim-presses");
    sim_presses(&sim_data, "20");
    let eval_cfg = dir.join("eval.toml");
    let default = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/gelgripper-sim.toml"),
    )
    .expect("sim config")
    .replace("seed = 1\n", "seed = 5\n")
    .replace(
        "\"layouts/",
        &format!("\"{}/configs/layouts/", env!("CARGO_MANIFEST_DIR")),
    );
    std::fs::write(&eval_cfg, default).expect("eval config");
    let eval_data = dir.join("eval-presses");
    ok(&gelgrip(&[
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        "10",
        "--config",
        s(&eval_cfg),
        "--out",
        s(&eval_data),
    ]));
    let (hub_lut, sim_lut) = (dir.join("hub.safetensors"), dir.join("sim.safetensors"));
    train_lut(&hub_data, &hub_lut);
    train_lut(&sim_data, &sim_lut);
    let (h, m) = (
        eval_json(&hub_lut, &eval_data),
        eval_json(&sim_lut, &eval_data),
    );
    eprintln!("hub-collected LUT: {h}\nsimulator-collected LUT: {m}");
    for k in ["gx_mae", "gy_mae"] {
        let (a, b) = (h[k].as_f64().expect(k), m[k].as_f64().expect(k));
        assert!(
            (a / b - 1.0).abs() <= 0.1,
            "{k}: hub {a:.4}, simulator {b:.4}"
        );
    }
}

/// SIGINT after two kept presses, or stdin closing after one: what was kept stays on disk
/// and in presses.csv, and the command says how many.
#[test]
fn an_interrupted_collect_keeps_what_it_kept() {
    let dir = scratch("collect-stop");
    let mut hub = PressHub::start(&dir);
    for (end, kept, code, said) in [
        (
            End::Sigint { after: 2 },
            2,
            0,
            "interrupted: 2 of 5 presses kept",
        ),
        (
            End::CloseStdin { after: 1 },
            1,
            1,
            "stdin closed: 1 of 5 presses kept",
        ),
    ] {
        let data = dir.join(format!("kept-{kept}"));
        let (out, log) = collect_on_hub(&mut hub, &data, "5", end);
        assert_eq!(out.status.code(), Some(code), "{log}");
        assert!(
            String::from_utf8_lossy(&out.stdout).contains(said),
            "{out:?}\n{log}"
        );
        let ds = PressDataset::load(&data).expect("the kept presses are a dataset");
        assert_eq!(ds.presses.len(), kept);
        for p in &ds.presses {
            ds.press_image(p).expect("each kept press is on disk");
        }
    }
}

#[test]
fn the_press_emulator_answers_bad_lines_with_errors() {
    let dir = scratch("press-emu");
    let mut hub = PressHub::start(&dir);
    for (line, says) in [
        ("f9.tip 100 100 0.5", "no sensor `f9.tip`"),
        ("f1.tip 1e6 100 0.5", "off the"),
        ("f1.tip 100 100 5", "deep"),
        ("f1.tip here there 0.5", "SENSOR X_PX Y_PX DEPTH_MM"),
    ] {
        let answer = hub.ask(line);
        let error = answer["error"].as_str().unwrap_or_default();
        assert!(error.contains(says), "{line}: {answer}");
    }
    let good = hub.ask("palm 160 120 0.5 10");
    assert_eq!(good["ball_mm"].as_f64(), Some(10.0), "{good}");
    let r = good["contact_radius_px"].as_f64().expect("radius");
    assert!(
        (r - (25.0f64 - 4.5 * 4.5).sqrt() / 0.0625).abs() < 1e-6,
        "{good}"
    );
    assert_eq!(hub.ask("palm lift")["lifted"], true);
}

/// `bench label` runs end to end and reports every press it made, and its sphere check
/// holds every labelled press out once (a LUT trained on the others).
#[test]
fn bench_label_reports_every_press() {
    let report = json(&gelgrip(&[
        "bench",
        "label",
        "--presses",
        "3",
        "--balls-mm",
        "4,6",
        "--json",
    ]));
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2, "{report}");
    for row in rows {
        let refused: u64 = row["refused"]
            .as_object()
            .expect("refused")
            .values()
            .map(|n| n.as_u64().unwrap_or(0))
            .sum();
        assert_eq!(row["labelled"].as_u64().unwrap_or(0) + refused, 3, "{row}");
        let sphere = &row["sphere"];
        assert_eq!(sphere["held_out"], row["labelled"], "{row}");
        let radii = sphere["radii_mm"].as_array().expect("radii");
        assert_eq!(radii.len() as u64, sphere["held_out"].as_u64().unwrap_or(0));
        assert!(
            radii
                .iter()
                .all(|r| r.is_null() || r.as_f64().is_some_and(f64::is_finite))
        );
        assert!(
            sphere["within_10pct"].as_u64() <= sphere["held_out"].as_u64(),
            "{row}"
        );
        // Each held-out press's true contact share, in the radii's order: within the
        // bench's range of 0.3 to 0.95 of the ball's radius.
        let shares = sphere["contact_shares"].as_array().expect("contact_shares");
        assert_eq!(shares.len(), radii.len(), "{row}");
        assert!(
            shares
                .iter()
                .all(|s| s.as_f64().is_some_and(|s| (0.29..0.951).contains(&s))),
            "{row}"
        );
    }
    assert_eq!(report["presses"], 6, "{report}");
    let share = report["sphere_within_share"].as_f64().expect("share");
    assert!((0.0..=1.0).contains(&share), "{report}");
}
