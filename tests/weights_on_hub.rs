//! The tactile pipeline on a hardware hub: the CDC hub emulator, over a real
//! pseudo-terminal, shows known weights resting on a sensor (`emulate hub
//! --weights-on-stdin`). `calibrate force` prompts for each weight, as it would a user, and
//! a run takes its references from the first live sets and then feels a weight.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::press_hub::StdinHub;
use common::{gelgrip, ok, s, scratch};

/// A LUT for f1.tip, trained on simulated presses as a user trains one on a sensor's
/// presses (the emulator's boards are the simulator's default cameras).
fn f1_tip_lut(dir: &Path) -> PathBuf {
    let (data, model) = (dir.join("presses"), dir.join("f1-tip-lut.safetensors"));
    let collect = [
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        "40",
    ];
    ok(&gelgrip(&[&collect[..], &["--out", s(&data)]].concat()));
    ok(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--out",
        s(&model),
    ]));
    model
}

/// The CDC gripper config on `link`, with `pipeline` (TOML) added to its `[pipeline]`.
fn hardware_config(dir: &Path, link: &Path, pipeline: &str) -> PathBuf {
    let layout = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/layouts/three-finger.toml");
    let text = format!(
        "version = 1\nlayout = {:?}\n[hub]\ntransport = \"cdc\"\ntrigger = \"broadcast\"\n\
         [hub.cdc]\nport = {:?}\nusb = \"hs\"\n[gate]\npolicy = \"trigger\"\n\
         [servos]\nbus = \"sim\"\n[pipeline]\nstiffness_n_per_mm3 = 0.071\n{pipeline}",
        s(&layout),
        s(link)
    );
    let path = dir.join("hw.toml");
    std::fs::write(&path, text).expect("config");
    path
}

/// `[pipeline]` lines giving f1.tip the model file `model`.
fn f1_tip_model(model: &Path) -> String {
    format!(
        "[[pipeline.sensors]]\nid = \"f1.tip\"\nmodel = {:?}\n",
        s(model)
    )
}

/// `gelgrip emulate hub --weights-on-stdin` on `dir/hub`.
struct WeightHub(StdinHub);

impl WeightHub {
    fn start(dir: &Path) -> Self {
        Self(StdinHub::start(dir, "--weights-on-stdin"))
    }

    /// Rest `grams` on `sensor`; the emulator's JSON answer.
    fn place(&mut self, sensor: &str, grams: &str) -> serde_json::Value {
        self.0.ask(&format!("{sensor} {grams}"))
    }
}

/// Run `calibrate force` on `config`, answering its prompts: Enter for the untouched
/// sensor, and for each weight, the weight placed on the emulator and then Enter. With
/// `stop_after` prompts, stdin is closed instead of answering the next one.
fn calibrate(
    hub: &mut WeightHub,
    config: &Path,
    weights: &str,
    stop_after: Option<usize>,
) -> (std::process::Output, Vec<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args([
            "calibrate",
            "force",
            "--sensor",
            "f1.tip",
            "--config",
            s(config),
        ])
        .args(["--weights-g", weights, "--frames", "6", "--json"])
        .env("RUST_LOG", "warn")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("calibrate force starts");
    let mut stdin = child.stdin.take();
    let mut stderr = Vec::new();
    let mut prompts = 0;
    for line in BufReader::new(child.stderr.take().expect("stderr")).lines() {
        let line = line.expect("stderr line");
        if let Some(step) = line.strip_prefix("> ") {
            if stop_after == Some(prompts) {
                stdin = None;
            }
            prompts += 1;
            if let Some(rest) = step.strip_prefix("place ") {
                let grams = rest.split(' ').next().expect("grams");
                let answer = hub.place("f1.tip", grams);
                assert!(answer["force_n"].as_f64().is_some(), "{answer}");
            } else {
                assert!(step.starts_with("leave f1.tip untouched"), "{line}");
            }
            if let Some(w) = stdin.as_mut() {
                writeln!(w).expect("calibrate stdin");
            }
        }
        stderr.push(line);
    }
    let out = child.wait_with_output().expect("calibrate force exits");
    (out, stderr)
}

#[test]
fn known_weights_on_the_cdc_hub_emulator_fit_the_gels_stiffness() {
    let dir = scratch("force-hw");
    let model = f1_tip_lut(&dir);
    let mut hub = WeightHub::start(&dir);
    let config = hardware_config(&dir, &hub.0.link.clone(), &f1_tip_model(&model));
    let (out, stderr) = calibrate(&mut hub, &config, "50,100,200", None);
    let stderr = stderr.join("\n");
    assert!(out.status.success(), "{:?}\n{stderr}", out.status);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let weights = report["per_weight"].as_array().expect("per_weight");
    assert_eq!(weights.len(), 3, "{report}");
    let mut last_volume = 0.0;
    for (w, grams) in weights.iter().zip([50.0, 100.0, 200.0]) {
        assert_eq!(w["weight_g"].as_f64(), Some(grams), "{w}");
        assert_eq!(w["frames"], 6, "{w}");
        assert_eq!(w["contact_frames"], 6, "{w}");
        let v = w["volume_mm3"].as_f64().expect("volume");
        assert!(
            v.is_finite() && v > last_volume,
            "volume grows with the weight: {report}"
        );
        last_volume = v;
        let err = w["err_pct"].as_f64().expect("err_pct");
        assert!(err.abs() < 15.0, "{w}");
    }
    // The emulator's gel is the simulator's, 0.08 N/mm³ per mm of depth. This LUT, trained
    // on 6 mm presses only, reads the 30 mm ball's volume about 12% high: 0.071 N/mm³.
    let k = report["stiffness_n_per_mm3"].as_f64().expect("stiffness");
    assert!((0.06..0.1).contains(&k), "{report}");
    assert!(report["r2"].as_f64().expect("r2") > 0.95, "{report}");
    assert_eq!(report["per_indenter"][0]["indenter"], "known weights");

    // stdin closing before the second weight: an error naming the step, nothing fitted.
    let (out, stderr) = calibrate(&mut hub, &config, "50,100", Some(2));
    assert_eq!(out.status.code(), Some(1), "{stderr:?}");
    assert!(out.stdout.is_empty());
    assert!(
        stderr
            .join("\n")
            .contains("stdin closed before the step `place 100 g"),
        "{stderr:?}"
    );
    // A sensor without a model file on a hardware hub is a configuration error.
    let bare = hardware_config(&dir, &hub.0.link.clone(), "");
    let out = gelgrip(&[
        "calibrate",
        "force",
        "--sensor",
        "f1.tip",
        "--config",
        s(&bare),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("no gradient model file"),
        "{out:?}"
    );
}

#[test]
fn the_weights_emulator_answers_bad_lines_with_errors() {
    let dir = scratch("weights-emu");
    let mut hub = WeightHub::start(&dir);
    let bad = hub.place("f9.tip", "10");
    assert!(
        bad["error"]
            .as_str()
            .expect("error")
            .contains("no sensor `f9.tip`")
    );
    let bad = hub.place("f1.tip", "heavy");
    assert!(
        bad["error"]
            .as_str()
            .expect("error")
            .contains("SENSOR GRAMS")
    );
    let bad = hub.place("f1.tip", "1e6");
    assert!(bad["error"].as_str().expect("error").contains("not a load"));
    let good = hub.place("palm", "100");
    let depth = good["depth_mm"].as_f64().expect("depth");
    assert!(depth > 0.1 && depth < 1.5, "{good}");
    assert_eq!(hub.place("palm", "0")["depth_mm"].as_f64(), Some(0.0));
}

/// A gentle grasp on the hardware hub: the references are taken on the first live sets,
/// before the loop; then the untouched sensors read nothing, and a 100 g weight placed on
/// f1.tip is felt there alone, as about 1 N on finger f1.
#[test]
fn a_run_on_the_hardware_hub_references_live_frames_and_feels_a_weight() {
    let dir = scratch("run-hw");
    let model = f1_tip_lut(&dir);
    let mut hub = WeightHub::start(&dir);
    let everyone = format!("model = {:?}\n", s(&model));
    let config = hardware_config(&dir, &hub.0.link.clone(), &everyone);
    let log = dir.join("grasp.csv");
    let mut run = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(["run", "--config", s(&config), "--headless", "--json"])
        .args([
            "--task",
            "gentle-grasp",
            "--duration",
            "6",
            "--log",
            s(&log),
        ])
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run starts");
    let mut stderr = BufReader::new(run.stderr.take().expect("stderr")).lines();
    let mut seen = Vec::new();
    for line in stderr.by_ref() {
        let line = line.expect("stderr line");
        let referenced = line.contains("sensors referenced on live untouched frames");
        seen.push(line);
        if referenced {
            break;
        }
    }
    let placed = hub.place("f1.tip", "100");
    assert!(placed["force_n"].as_f64().is_some(), "{placed}\n{seen:?}");
    seen.extend(stderr.map_while(Result::ok));
    let out = run.wait_with_output().expect("run exits");
    assert!(
        out.status.success(),
        "{:?}\n{}",
        out.status,
        seen.join("\n")
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(report["end_reason"], "duration", "{report}");
    // The simulated servos' world is not what the hub's sensors see: no ground truth.
    assert!(report["true_peak_force_n"].is_null(), "{report}");

    let csv = std::fs::read_to_string(&log).expect("the log");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert!(
        !header.iter().any(|h| h.ends_with("_true_force_n")),
        "{header:?}"
    );
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (tip, f1) = (col("f1.tip_deformation_mm3"), col("f1_force_n"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // The references were taken before the loop: every logged set has readings.
    let read: Vec<&Vec<&str>> = rows.iter().collect();
    assert!(read.iter().all(|r| !r[tip].is_empty()), "{csv}");
    let value = |r: &Vec<&str>, c: usize| r[c].parse::<f64>().expect("a number");
    let sensors: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| h.ends_with("_deformation_mm3"))
        .map(|(i, _)| i)
        .collect();
    for r in &read {
        for &c in &sensors {
            assert!(value(r, c).is_finite(), "{r:?}");
        }
    }
    // Untouched at first: every sensor reads nothing.
    for &c in &sensors {
        assert_eq!(value(read[0], c), 0.0, "{}: {:?}", header[c], read[0]);
    }
    // At the end the weight is on f1.tip alone.
    let last = read.last().expect("rows after the reference");
    for &c in &sensors {
        let v = value(last, c);
        if c == tip {
            assert!(v > 5.0, "f1.tip under 100 g: {v} mm³");
        } else {
            assert_eq!(v, 0.0, "{}: {last:?}", header[c]);
        }
    }
    let force = value(last, f1);
    assert!(
        (0.8..1.2).contains(&force),
        "finger f1 under 100 g (0.98 N): {force} N"
    );

    // Without model files a hardware hub's pipelines cannot be built: exit 2, said so.
    let bare = hardware_config(&dir, &hub.0.link.clone(), "");
    let out = gelgrip(&[
        "run",
        "--config",
        s(&bare),
        "--headless",
        "--task",
        "gentle-grasp",
    ]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("no gradient model file"),
        "{out:?}"
    );
    // The dashboard on it still serves the cameras, sync and servos, without the grasp.
    let args = [
        "run",
        "--config",
        s(&bare),
        "--http",
        "127.0.0.1:0",
        "--duration",
        "1",
    ];
    let out = gelgrip(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{out:?}");
    assert!(err.contains("without the grasp"), "{err}");
}
