//! Property tests of the files and bytes from outside this crate reads (issue 45):
//! gradient-model files (`GradientModel::load`, what `calibrate train`, `transfer` and
//! `bake` write and the pipelines load), press datasets (`PressDataset::load` and
//! `press_image`, what `calibrate collect` and `label` write and `calibrate train` reads)
//! and the sensors' JPEG frames (`JpegStage::decode`, the pipeline's first stage). Each gets
//! random bytes and mutations of a valid input; each must answer with a typed error or a
//! valid result, never a panic, within a bound of time, and without allocating what a
//! length field claims (a PNG that says it is 2^20 x 2^20 pixels).
//!
//! Case counts: `PROPTEST_CASES` (proptest's 256 when unset), capped per test so that
//! `scripts/test`'s 30 000-case step stays short; `GELGRIP_FUZZ_CASES` sets the exact count
//! for a long run outside CI (docs/reliability.md).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use proptest::prelude::*;

use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::decode::JpegStage;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::image::RgbImage;
use gelgrip_plugins::model_file::ModelFile;

/// Longest one case may take: far above a load's milliseconds, far below a hang.
const CASE_BUDGET: Duration = Duration::from_secs(5);

/// Cases per model-file test in CI (`PROPTEST_CASES` above it is capped).
const MODEL_CI_CASES: u32 = 1000;
/// Cases per dataset test in CI (each writes five files).
const DATASET_CI_CASES: u32 = 1000;

#[path = "../../testsupport/fuzz_runner.rs"]
mod fuzz_runner;
use fuzz_runner::check;

/// A scratch directory of this process and thread (made once; cases overwrite its files;
/// [`done`] removes it).
fn scratch(name: &str) -> PathBuf {
    let thread = format!("{:?}", std::thread::current().id());
    // Cargo's scratch space for integration tests (under target/), not the system's.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("gelgrip-fuzz-{}", std::process::id()))
        .join(format!(
            "{name}-{}",
            thread.replace(|c: char| !c.is_alphanumeric(), "")
        ));
    if !dir.is_dir() {
        std::fs::create_dir_all(&dir).expect("scratch dir");
    }
    dir
}

/// Remove this thread's scratch directory `name` (a test calls it when its cases are done).
fn done(name: &str) {
    let _ = std::fs::remove_dir_all(scratch(name));
}

// ---------------------------------------------------------------------------------------
// Model files

/// The metadata of a valid model file of `kind`.
fn metadata(kind: &str, extra: &[(&str, &str)]) -> HashMap<String, String> {
    let mut m: HashMap<String, String> = [
        ("format", "gelgrip-gradient-model"),
        ("version", "1"),
        ("kind", kind),
        ("input", "diff"),
        ("width", "8"),
        ("height", "6"),
        ("offset_rgb", "0,0,0"),
    ]
    .iter()
    .chain(extra)
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    m.insert("mm_per_px".into(), "0.1".into());
    m
}

/// A valid LUT file: 2 bins, one tile.
fn lut_file() -> ModelFile {
    let values = (0..16).map(|i| i as f32 * 0.01).collect();
    ModelFile {
        metadata: metadata("lut", &[("bins", "2"), ("tiles", "1,1"), ("blur_px", "1")]),
        tensors: vec![("lut".into(), vec![1, 2, 2, 2, 2], values)],
    }
}

/// A valid MLP file: 5 inputs, hidden width 2.
fn mlp_file() -> ModelFile {
    let sizes = [5, 2, 2, 2, 2];
    let mut tensors = Vec::new();
    for i in 0..4 {
        let (inputs, outputs) = (sizes[i], sizes[i + 1]);
        let w = (0..inputs * outputs)
            .map(|k| k as f32 * 0.05 - 0.2)
            .collect();
        tensors.push((format!("l{i}.weight"), vec![outputs, inputs], w));
        tensors.push((format!("l{i}.bias"), vec![outputs], vec![0.1; outputs]));
    }
    ModelFile {
        metadata: metadata("mlp", &[("hidden", "2"), ("gain_rgb", "1,1,1")]),
        tensors,
    }
}

/// The bytes of the valid LUT file (`mlp` false) or MLP file, written once.
fn valid_model(mlp: bool) -> &'static [u8] {
    static FILES: OnceLock<[Vec<u8>; 2]> = OnceLock::new();
    let files = FILES.get_or_init(|| {
        let dir = scratch("model-valid-bytes");
        let files = [bytes_of(&lut_file(), &dir), bytes_of(&mlp_file(), &dir)];
        done("model-valid-bytes");
        files
    });
    &files[usize::from(mlp)]
}

/// `file`'s bytes as `ModelFile::write` writes them.
fn bytes_of(file: &ModelFile, dir: &Path) -> Vec<u8> {
    let path = dir.join("valid.safetensors");
    file.write(&path).expect("write a model file");
    std::fs::read(&path).expect("read it back")
}

/// Load `bytes` as a model file: an error, or a model whose predictions are finite.
fn load_model(dir: &Path, bytes: &[u8]) -> Result<GradientModel, String> {
    let path = dir.join("m.safetensors");
    std::fs::write(&path, bytes).expect("write case");
    let start = Instant::now();
    let loaded = GradientModel::load(&path, MlpMode::Dense);
    assert!(
        start.elapsed() < CASE_BUDGET,
        "load took {:?}",
        start.elapsed()
    );
    let model = loaded.map_err(|e| e.to_string())?;
    if let GradientModel::Lut(lut) = &model {
        let (w, h) = model.size();
        for (rgb, x, y) in [
            ([0.0; 3], 0, 0),
            ([255.0, -255.0, 40.0], w, h),
            ([1e9; 3], 3, 2),
        ] {
            let g = lut.predict_at(rgb, x, y);
            assert!(
                g.iter().all(|v| v.is_finite()),
                "{rgb:?} at ({x}, {y}): {g:?}"
            );
        }
    }
    Ok(model)
}

/// The 8-byte header length and the JSON header of a safetensors file.
fn split_header(bytes: &[u8]) -> (String, Vec<u8>) {
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
    let header = String::from_utf8(bytes[8..8 + n].to_vec()).expect("JSON header");
    (header, bytes[8 + n..].to_vec())
}

/// A file from `header` (its length recomputed) and `data`.
fn join_header(header: &str, data: &[u8]) -> Vec<u8> {
    let mut out = (header.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

/// Byte-level mutations: (position, new byte) writes, then a truncation or an extension.
fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8)], cut: Option<usize>, tail: &[u8]) -> Vec<u8> {
    for (at, b) in edits {
        if !bytes.is_empty() {
            let n = bytes.len();
            bytes[at % n] = *b;
        }
    }
    if let Some(c) = cut {
        bytes.truncate(c % (bytes.len() + 1));
    }
    bytes.extend_from_slice(tail);
    bytes
}

/// Text a header or a metadata value may take: numbers at the edges, JSON punctuation,
/// names.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("18446744073709551615".to_string()),
        Just("4294967296".to_string()),
        Just("-1".to_string()),
        Just("0".to_string()),
        Just("1e308".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        "[0-9]{1,20}",
        "[\\[\\]{},:\"]",
        "\"[a-z_0-9.]{0,12}\"",
        "[ -~]{0,12}",
    ]
}

/// Metadata edits: a key of either kind's files, and a value (or its removal).
fn meta_edits() -> impl Strategy<Value = Vec<(String, Option<String>)>> {
    let keys = [
        "format",
        "version",
        "kind",
        "input",
        "width",
        "height",
        "bins",
        "tiles",
        "offset_rgb",
        "gain_rgb",
        "blur_px",
        "mm_per_px",
        "hidden",
        "source",
    ];
    let value = prop_oneof![
        token().prop_map(Some),
        Just(None),
        Just(Some("64,64".to_string())),
        Just(Some("1,2,3".to_string())),
        Just(Some("lut".to_string())),
        Just(Some("mlp".to_string())),
        Just(Some("relative".to_string())),
        Just(Some("256".to_string())),
    ];
    proptest::collection::vec(
        (
            proptest::sample::select(keys.to_vec()).prop_map(str::to_string),
            value,
        ),
        0..5,
    )
}

/// Tensor edits: a tensor of either kind's files, a new shape (at most 4096 values) and
/// values that may be non-finite.
fn tensor_edits() -> impl Strategy<Value = Vec<(String, Vec<usize>, Vec<f32>)>> {
    let names = [
        "lut",
        "l0.weight",
        "l0.bias",
        "l3.weight",
        "l3.bias",
        "extra",
    ];
    let shape = proptest::collection::vec(0usize..9, 0..6);
    (
        proptest::sample::select(names.to_vec()).prop_map(str::to_string),
        shape,
        any::<f32>(),
    )
        .prop_map(|(name, shape, v)| {
            let n: usize = shape.iter().product::<usize>().min(4096);
            (name, shape, vec![v; n])
        })
        .prop_map(|t| vec![t])
}

/// `file` with `meta` and `tensors` applied (a tensor whose shape disagrees with its
/// values is dropped: the writer would refuse it).
fn edited(
    mut file: ModelFile,
    meta: Vec<(String, Option<String>)>,
    tensors: Vec<(String, Vec<usize>, Vec<f32>)>,
) -> ModelFile {
    for (k, v) in meta {
        match v {
            Some(v) => file.metadata.insert(k, v),
            None => file.metadata.remove(&k),
        };
    }
    for (name, shape, values) in tensors {
        if shape.iter().product::<usize>() != values.len() {
            continue;
        }
        file.tensors.retain(|(n, _, _)| *n != name);
        file.tensors.push((name, shape, values));
    }
    file
}

#[test]
fn the_valid_model_files_load() {
    let dir = scratch("model-valid");
    for (file, kind) in [(lut_file(), "lut"), (mlp_file(), "mlp")] {
        let model = load_model(&dir, &bytes_of(&file, &dir)).expect(kind);
        assert_eq!(model.size(), (8, 6), "{kind}");
        assert_eq!(model.mm_per_px(), Some(0.1), "{kind}");
    }
    done("model-valid");
}

#[test]
fn a_header_length_of_4_gib_or_more_is_an_error_not_an_allocation() {
    let dir = scratch("model-huge");
    let valid = bytes_of(&lut_file(), &dir);
    for n in [1u64 << 32, u64::MAX, u64::MAX / 2, (valid.len() as u64) + 1] {
        let mut b = valid.clone();
        b[..8].copy_from_slice(&n.to_le_bytes());
        let err = load_model(&dir, &b).expect_err("a header longer than the file");
        assert!(err.contains("m.safetensors"), "{err}");
    }
    done("model-huge");
}

/// Random bytes, with or without a plausible header length in front.
#[test]
fn random_bytes_are_not_a_model() {
    let len = prop_oneof![
        Just(None),
        (0u64..600).prop_map(Some),
        any::<u64>().prop_map(Some)
    ];
    let strategy = (proptest::collection::vec(any::<u8>(), 0..512), len);
    check(MODEL_CI_CASES, strategy, |(body, len)| {
        let dir = scratch("model-random");
        let mut bytes = len.map(|n| n.to_le_bytes().to_vec()).unwrap_or_default();
        bytes.extend_from_slice(&body);
        let _ = load_model(&dir, &bytes);
    });
    done("model-random");
}

/// Valid files with bytes changed, cut or extended.
#[test]
fn mutated_model_bytes_load_or_fail_cleanly() {
    let strategy = (
        any::<bool>(),
        proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        proptest::option::of(any::<usize>()),
        proptest::collection::vec(any::<u8>(), 0..8),
    );
    check(MODEL_CI_CASES, strategy, |(mlp, edits, cut, tail)| {
        let dir = scratch("model-bytes");
        let valid = valid_model(mlp).to_vec();
        let _ = load_model(&dir, &mutate(valid, &edits, cut, &tail));
    });
    done("model-bytes");
}

/// Valid files whose JSON header has tokens inserted or replaced (shapes, data offsets,
/// dtypes and metadata that lie), its length kept consistent.
#[test]
fn mutated_model_headers_load_or_fail_cleanly() {
    let strategy = (
        any::<bool>(),
        proptest::collection::vec((any::<usize>(), 0usize..4, token()), 1..4),
    );
    check(MODEL_CI_CASES, strategy, |(mlp, edits)| {
        let dir = scratch("model-header");
        let (mut header, data) = split_header(valid_model(mlp));
        for (at, width, text) in edits {
            let mut at = at % (header.len() + 1);
            while !header.is_char_boundary(at) {
                at -= 1;
            }
            let end = (at + width).min(header.len());
            let end = (end..=header.len())
                .find(|&e| header.is_char_boundary(e))
                .unwrap_or(at);
            header.replace_range(at..end, &text);
        }
        let _ = load_model(&dir, &join_header(&header, &data));
    });
    done("model-header");
}

/// Well-formed files whose metadata and tensors say what they should not: sizes at the
/// edges of an integer, tiles and bins out of range, shapes that disagree, non-finite
/// weights. Every one that loads predicts finite gradients.
#[test]
fn model_files_with_wrong_metadata_or_tensors_load_or_fail_cleanly() {
    let strategy = (any::<bool>(), meta_edits(), tensor_edits());
    check(MODEL_CI_CASES, strategy, |(mlp, meta, tensors)| {
        let dir = scratch("model-meta");
        let file = edited(if mlp { mlp_file() } else { lut_file() }, meta, tensors);
        let _ = load_model(&dir, &bytes_of(&file, &dir));
    });
    done("model-meta");
}

// ---------------------------------------------------------------------------------------
// Press datasets

/// CRC-32 (IEEE) as PNG chunks carry it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG of `w × h` (RGB) as the dataset writer writes it.
fn png_bytes(dir: &Path, w: usize, h: usize) -> Vec<u8> {
    let mut img = RgbImage::new(w, h);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = (i * 37 % 251) as u8;
    }
    let path = dir.join("valid.png");
    img.write_png(&path).expect("write png");
    std::fs::read(&path).expect("read png")
}

/// `png` with its header (IHDR, the first chunk) claiming `w × h` at `colour` and
/// `depth`, the chunk's CRC fixed so that the decoder believes it.
fn png_claiming(mut png: Vec<u8>, w: u32, h: u32, depth: u8, colour: u8) -> Vec<u8> {
    // Signature (8), length (4), "IHDR" (4), then width, height, depth, colour.
    png[16..20].copy_from_slice(&w.to_be_bytes());
    png[20..24].copy_from_slice(&h.to_be_bytes());
    png[24] = depth;
    png[25] = colour;
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    png
}

/// The names of a dataset's files (two presses).
const DATASET_FILES: [&str; 5] = [
    "dataset.toml",
    "background.png",
    "presses.csv",
    "press_000.png",
    "press_001.png",
];

/// The files of a valid dataset of two presses.
fn dataset_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    static PNG: OnceLock<Vec<u8>> = OnceLock::new();
    let png = PNG.get_or_init(|| png_bytes(dir, 6, 4)).clone();
    vec![
        (
            "dataset.toml".into(),
            b"version = 1\nball_diameter_mm = 6\nmm_per_px = 0.1\n".to_vec(),
        ),
        ("background.png".into(), png.clone()),
        (
            "presses.csv".into(),
            b"file,center_x_px,center_y_px,contact_radius_px\npress_000.png,3,2,1.5\npress_001.png,1,1,0.5\n".to_vec(),
        ),
        ("press_000.png".into(), png.clone()),
        ("press_001.png".into(), png),
    ]
}

/// Load the dataset `files` make: an error, or a dataset whose presses each read as an
/// image of the background's size or fail to.
fn load_dataset(dir: &Path, files: &[(String, Vec<u8>)]) -> Result<usize, String> {
    for name in DATASET_FILES {
        match files.iter().find(|(n, _)| n == name) {
            Some((_, bytes)) => std::fs::write(dir.join(name), bytes).expect("write case"),
            None => {
                let _ = std::fs::remove_file(dir.join(name));
            }
        }
    }
    let start = Instant::now();
    let data = PressDataset::load(dir).map_err(|e| e.to_string());
    let mut read = 0;
    if let Ok(d) = &data {
        assert!(d.ball_radius_px().is_finite() && d.ball_radius_px() > 0.0);
        for press in d.presses.iter().take(4) {
            if let Ok(img) = d.press_image(press) {
                assert_eq!(img.data.len(), img.width * img.height * 3);
                read += 1;
            }
        }
    }
    assert!(
        start.elapsed() < CASE_BUDGET,
        "load took {:?}",
        start.elapsed()
    );
    data.map(|_| read)
}

#[test]
fn the_valid_dataset_loads_and_its_presses_read() {
    let dir = scratch("dataset-valid");
    assert_eq!(load_dataset(&dir, &dataset_files(&dir)), Ok(2));
    done("dataset-valid");
}

#[test]
fn a_png_claiming_a_terabyte_is_an_error_not_an_allocation() {
    let dir = scratch("dataset-huge");
    let valid = png_bytes(&dir, 6, 4);
    for (w, h, depth, colour) in [
        (1 << 20, 1 << 20, 8, 6),
        (0x7fff_ffff, 0x7fff_ffff, 16, 6),
        (1 << 16, 1 << 16, 8, 2),
        (0, 4, 8, 2),
    ] {
        let png = png_claiming(valid.clone(), w, h, depth, colour);
        std::fs::write(dir.join("big.png"), &png).expect("write");
        let err = RgbImage::read_png(&dir.join("big.png")).expect_err("too large");
        assert!(err.to_string().contains("big.png"), "{err}");
        let mut files = dataset_files(&dir);
        files[1].1 = png;
        assert!(load_dataset(&dir, &files).is_err(), "{w}x{h}");
    }
    done("dataset-huge");
}

/// Which file of the dataset a case changes, and how.
#[derive(Debug, Clone)]
enum DatasetEdit {
    /// Replace the file with these bytes.
    Replace(usize, Vec<u8>),
    /// Byte writes, a cut and a tail on the file.
    Bytes(usize, Vec<(usize, u8)>, Option<usize>, Vec<u8>),
    /// A text line (of the CSV or the TOML) inserted at a line index.
    Line(usize, usize, String),
    /// The file removed.
    Remove(usize),
    /// The PNG's header claims another size, depth or colour type.
    Ihdr(usize, u32, u32, u8, u8),
}

fn dataset_edit() -> impl Strategy<Value = DatasetEdit> {
    let line = prop_oneof![
        "[a-z_0-9.,/\\\\ -]{0,40}",
        (token(), token(), token()).prop_map(|(a, b, c)| format!("press_000.png,{a},{b},{c}")),
        token().prop_map(|t| format!("mm_per_px = {t}")),
        token().prop_map(|t| format!("ball_diameter_mm = {t}")),
        Just("..,1,1,1".to_string()),
        Just("press_001.png,1,1".to_string()),
    ];
    let dims = prop_oneof![0u32..64, any::<u32>(), Just(1 << 20)];
    prop_oneof![
        (0usize..5, proptest::collection::vec(any::<u8>(), 0..64))
            .prop_map(|(f, b)| DatasetEdit::Replace(f, b)),
        (
            0usize..5,
            proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4),
            proptest::option::of(any::<usize>()),
            proptest::collection::vec(any::<u8>(), 0..4),
        )
            .prop_map(|(f, e, c, t)| DatasetEdit::Bytes(f, e, c, t)),
        (prop_oneof![Just(0usize), Just(2usize)], 0usize..4, line)
            .prop_map(|(f, at, l)| DatasetEdit::Line(f, at, l)),
        (0usize..5).prop_map(DatasetEdit::Remove),
        (
            prop_oneof![Just(1usize), Just(3usize)],
            dims.clone(),
            dims,
            prop_oneof![Just(8u8), Just(16u8), any::<u8>()],
            prop_oneof![Just(2u8), Just(6u8), any::<u8>()],
        )
            .prop_map(|(f, w, h, d, c)| DatasetEdit::Ihdr(f, w, h, d, c)),
    ]
}

/// `files` with `edit` applied.
fn apply(files: &mut Vec<(String, Vec<u8>)>, edit: DatasetEdit) {
    match edit {
        DatasetEdit::Replace(f, b) => files[f].1 = b,
        DatasetEdit::Bytes(f, e, c, t) => files[f].1 = mutate(files[f].1.clone(), &e, c, &t),
        DatasetEdit::Line(f, at, l) => {
            let text = String::from_utf8_lossy(&files[f].1).into_owned();
            let mut lines: Vec<&str> = text.lines().collect();
            lines.insert(at.min(lines.len()), &l);
            files[f].1 = lines.join("\n").into_bytes();
        }
        DatasetEdit::Remove(f) => {
            files.remove(f);
        }
        DatasetEdit::Ihdr(f, w, h, d, c) => {
            if files[f].1.len() >= 33 {
                files[f].1 = png_claiming(files[f].1.clone(), w, h, d, c);
            }
        }
    }
}

/// Valid datasets with up to three of their files changed, cut, extended, given extra
/// lines, removed, or with PNG headers that lie about the image.
#[test]
fn mutated_datasets_load_or_fail_cleanly() {
    let strategy = proptest::collection::vec(dataset_edit(), 1..4);
    check(DATASET_CI_CASES, strategy, |edits| {
        let dir = scratch("dataset-mutated");
        let mut files = dataset_files(&dir);
        for e in edits {
            // A removal shifts the indices: edit only while all five are there.
            if files.len() == DATASET_FILES.len() {
                apply(&mut files, e);
            }
        }
        let _ = load_dataset(&dir, &files);
    });
    done("dataset-mutated");
}

/// Random bytes in every file of a dataset.
#[test]
fn random_dataset_files_fail_cleanly() {
    let strategy = proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..128), 5);
    check(DATASET_CI_CASES, strategy, |files| {
        let dir = scratch("dataset-random");
        let files: Vec<_> = DATASET_FILES
            .iter()
            .map(|n| n.to_string())
            .zip(files)
            .collect();
        assert!(load_dataset(&dir, &files).is_err());
    });
    done("dataset-random");
}

// ---------------------------------------------------------------------------------------
// Sensor frames (the hub's JPEG bytes)

/// Cases per frame-decode test in CI (a decode of a 32 × 24 frame takes microseconds).
const FRAME_CI_CASES: u32 = 5000;

/// A valid 32 × 24 frame.
fn jpeg_frame() -> &'static [u8] {
    static JPEG: OnceLock<Vec<u8>> = OnceLock::new();
    JPEG.get_or_init(|| {
        let rgb: Vec<u8> = (0..32 * 24 * 3).map(|i| (i * 7 % 256) as u8).collect();
        let mut out = Vec::new();
        jpeg_encoder::Encoder::new(&mut out, 90)
            .encode(&rgb, 32, 24, jpeg_encoder::ColorType::Rgb)
            .expect("encode");
        out
    })
}

/// Decode `jpeg` as a 32 × 24 sensor's frame at every scale: a frame, or a typed error.
fn decode_frame(jpeg: &[u8]) -> bool {
    let start = Instant::now();
    let mut ok = true;
    for scale in [1, 2, 4] {
        let mut stage = JpegStage::new(32, 24, scale);
        let (w, h) = stage.output_size();
        let mut out = vec![0; w * h * 3];
        ok &= stage.decode(jpeg, &mut out).is_ok();
    }
    assert!(
        start.elapsed() < CASE_BUDGET,
        "decode took {:?}",
        start.elapsed()
    );
    ok
}

#[test]
fn the_valid_frame_decodes() {
    assert!(decode_frame(jpeg_frame()));
}

/// Random bytes, and valid frames with bytes changed (sizes in the header included), cut
/// or extended: a frame or a typed error, never a panic.
#[test]
fn random_and_mutated_frames_decode_or_fail_cleanly() {
    let strategy = prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..256).prop_map(|b| (b, vec![], None, vec![])),
        (
            Just(Vec::new()),
            proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
            proptest::option::of(any::<usize>()),
            proptest::collection::vec(any::<u8>(), 0..8),
        ),
    ];
    check(FRAME_CI_CASES, strategy, |(random, edits, cut, tail)| {
        let bytes = if random.is_empty() {
            mutate(jpeg_frame().to_vec(), &edits, cut, &tail)
        } else {
            random
        };
        let _ = decode_frame(&bytes);
    });
}
