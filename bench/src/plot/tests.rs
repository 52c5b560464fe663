//! Figures are written in both formats, with gaps and degenerate data.

use super::*;

fn fig(points: Vec<(f64, Option<f64>)>) -> Figure {
    Figure {
        title: "t".into(),
        x_label: "x (s)".into(),
        y_label: "y (mm³)".into(),
        x_unit: "s".into(),
        y_unit: "mm³".into(),
        series: vec![Series {
            name: "s".into(),
            points,
        }],
        bands: vec![Band {
            from: 0.0,
            to: 1.0,
            label: "1 rest".into(),
        }],
        markers: true,
        legend: None,
    }
}

#[test]
fn svg_and_png_are_written_with_gaps_and_flat_or_empty_data() {
    let dir = std::env::temp_dir().join(format!("gelgrip-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let cases = [
        vec![
            (0.0, Some(1.0)),
            (1.0, None),
            (2.0, Some(3.0)),
            (3.0, Some(2.0)),
        ],
        vec![(0.0, Some(5.0)), (1.0, Some(5.0))],
        vec![],
        vec![(0.0, Some(f64::NAN)), (1.0, Some(f64::INFINITY))],
    ];
    for (i, points) in cases.into_iter().enumerate() {
        for ext in ["svg", "png"] {
            let out = dir.join(format!("f{i}.{ext}"));
            save(&fig(points.clone()), &out).expect("drawn");
            let bytes = std::fs::read(&out).expect("written");
            match ext {
                "svg" => assert!(String::from_utf8_lossy(&bytes).contains("<svg")),
                _ => assert_eq!(&bytes[1..4], b"PNG"),
            }
        }
    }
    let svg = std::fs::read_to_string(dir.join("f0.svg")).expect("svg");
    assert!(
        svg.contains("1 rest") && svg.contains("y (mm³)"),
        "labels drawn as text"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_unknown_extension_is_a_usage_error() {
    let e = Format::of(Path::new("fig.jpg")).expect_err("refused");
    assert!(e.to_string().contains(".svg or .png"), "{e}");
    assert_eq!(
        Format::of(Path::new("a/FIG.SVG")).expect("svg"),
        Format::Svg
    );
}

#[test]
fn tick_labels_carry_their_unit_and_enough_decimals() {
    let dir = std::env::temp_dir().join(format!("gelgrip-plot-ticks-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let out = dir.join("ticks.svg");
    // The signal: 0-1 mm³ (its y axis read `1, 1, 1, 0, 0`).
    let points = (0..=20).map(|i| (f64::from(i), Some(f64::from(i) / 20.0)));
    save(&fig(points.collect()), &out).expect("drawn");
    let svg = std::fs::read_to_string(&out).expect("svg");
    let texts: Vec<&str> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| {
            t.split_once('>')?
                .1
                .split_once("</text>")
                .map(|t| t.0.trim())
        })
        .collect();
    let ticks = |unit: &str| -> Vec<String> {
        texts
            .iter()
            .filter(|t| t.ends_with(unit))
            .map(|t| t.to_string())
            .collect()
    };
    let y = ticks(" mm³");
    let x = ticks(" s");
    assert_eq!(
        y,
        [
            "0.0 mm³", "0.2 mm³", "0.4 mm³", "0.6 mm³", "0.8 mm³", "1.0 mm³"
        ]
    );
    assert_eq!(x.first().map(String::as_str), Some("0.0 s"), "{x:?}");
    assert_eq!(x.last().map(String::as_str), Some("20.0 s"), "{x:?}");
    let mut distinct = x.clone();
    distinct.dedup();
    assert_eq!(distinct, x);
    let _ = std::fs::remove_dir_all(&dir);
}
