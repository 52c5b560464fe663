//! `[hub.sim]` validation: the fault entries' ranges, each error naming its field.

use super::*;
use crate::pool::tests::three_finger_layout;
use gelgrip_controller::config::{DiskFiles, FieldCheck};

fn parse(toml_text: &str) -> Result<SimConfig, ConfigError> {
    let section = BackendSection {
        check: FieldCheck::new("test.toml"),
        prefix: "hub.sim".into(),
        table: toml::from_str(toml_text).expect("TOML"),
        base_dir: ".".into(),
        files: std::sync::Arc::new(DiskFiles),
    };
    SimConfig::from_section(&section, &three_finger_layout())
}

fn fault(keys: &str) -> Result<SimConfig, ConfigError> {
    parse(&format!("[[faults]]\nsensor = \"palm\"\n{keys}\n"))
}

#[test]
fn jitter_and_drift_reach_their_sensor() {
    let layout = three_finger_layout();
    let cfg = fault("capture_jitter_us = 300\nclock_drift_ppm = -250.5").expect("valid");
    let palm = layout.index_of("palm").expect("palm");
    assert_eq!(cfg.faults[palm].capture_jitter_us, 300);
    assert_eq!(cfg.faults[palm].clock_drift_ppm, -250.5);
    let mut others = cfg.faults.iter().enumerate().filter(|(i, _)| *i != palm);
    assert!(others.all(|(_, f)| *f == SensorFaults::default()));
    let edges = fault("capture_jitter_us = 1000000\nclock_drift_ppm = 1000").expect("valid");
    assert_eq!(edges.faults[palm].clock_drift_ppm, 1000.0);
    assert!(fault("clock_drift_ppm = -1000").is_ok());
}

#[test]
fn out_of_range_faults_name_the_field_and_the_range() {
    for (keys, field, range) in [
        ("capture_delay_us = -5", "capture_delay_us", "[0, 1000000]"),
        (
            "delivery_delay_us = -1",
            "delivery_delay_us",
            "[0, 10000000]",
        ),
        (
            "capture_jitter_us = -1",
            "capture_jitter_us",
            "[0, 1000000]",
        ),
        (
            "capture_jitter_us = 1000001",
            "capture_jitter_us",
            "[0, 1000000]",
        ),
        ("clock_drift_ppm = 1001", "clock_drift_ppm", "[-1000, 1000]"),
        (
            "clock_drift_ppm = -1001",
            "clock_drift_ppm",
            "[-1000, 1000]",
        ),
        ("clock_drift_ppm = nan", "clock_drift_ppm", "[-1000, 1000]"),
    ] {
        let err = fault(keys).expect_err(keys).to_string();
        assert!(
            err.contains(&format!("`hub.sim.faults[0].{field}`")),
            "{keys}: {err}"
        );
        assert!(err.contains(range), "{keys}: {err}");
        assert!(err.contains("test.toml"), "{keys}: {err}");
    }
}

#[test]
fn an_unknown_fault_key_is_named() {
    let err = fault("clock_drift = 5").expect_err("unknown").to_string();
    assert!(err.contains("unknown field `clock_drift`"), "{err}");
    assert!(err.contains("clock_drift_ppm"), "lists the keys: {err}");
    assert!(err.contains("faults"), "{err}");
}

#[test]
fn optics_are_nominal_unless_asked_for_and_realistic_brings_its_noise() {
    let nominal = parse("").expect("defaults");
    assert_eq!(nominal.optics, Optics::Nominal);
    assert_eq!(nominal.noise_sigma, DEFAULT_NOISE_SIGMA);
    assert_eq!(nominal.noise_rgb, [DEFAULT_NOISE_SIGMA; 3]);
    let realistic = parse("optics = \"realistic\"").expect("valid");
    assert_eq!(realistic.optics, Optics::Realistic(Box::new(MINI)));
    assert_eq!(realistic.noise_rgb, MINI.noise_rgb);
    let quiet = parse("optics = \"realistic\"\nnoise_sigma = 0.5").expect("valid");
    assert_eq!(quiet.noise_rgb, [0.5; 3]);
    let err = parse("optics = \"ideal\"")
        .expect_err("unknown optics")
        .to_string();
    assert!(
        err.contains("hub.sim.optics") && err.contains("realistic"),
        "{err}"
    );
    let err = parse("optics = \"realistic\"\nnoise_sigma = 100").expect_err("range");
    assert!(err.to_string().contains("hub.sim.noise_sigma"), "{err}");
}

#[test]
fn the_noise_seed_defaults_to_the_seed_and_can_be_set_alone() {
    let plain = parse("seed = 9").expect("valid");
    assert_eq!((plain.seed, plain.noise_seed), (9, 9));
    let redrawn = parse("seed = 9\nnoise_seed = 4").expect("valid");
    assert_eq!((redrawn.seed, redrawn.noise_seed), (9, 4));
    let err = parse("noise_seed = -1").expect_err("a negative seed");
    assert!(err.to_string().contains("noise_seed"), "{err}");
}
