//! Figures are written in both formats, with gaps and degenerate data.

use super::*;

fn fig(points: Vec<(f64, Option<f64>)>) -> Figure {
    Figure {
        title: "t".into(),
        x_label: "x (s)".into(),
        y_label: "y (mm³)".into(),
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
