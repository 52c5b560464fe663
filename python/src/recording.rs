//! Recordings from Python: `Recording(dir)` with `.info()` (`record info --json`'s object)
//! and `.frames(sensor=None)`, which reads the segments in order, one in memory at a time,
//! yielding each frame's sensor, capture time and JPEG bytes (`.image()` decodes them).

use std::path::PathBuf;
use std::sync::Mutex;

use pyo3::exceptions::{PyKeyError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use gelgrip_plugins::image::RgbImage;
use gelgrip_record::format::{Meta, Record};
use gelgrip_record::info::RecordingInfo;
use gelgrip_record::reader::Recording as RustRecording;
use gelgrip_record::replay::RecordStream;

use crate::arrays::{self, ColorOrder};
use crate::calibration::to_py;
use crate::errors::{self, RecordingError};

fn recording_error(e: &gelgrip_record::RecordError) -> PyErr {
    RecordingError::new_err(e.to_string())
}

/// A recording (`gelgrip run --record DIR`) on disk.
#[pyclass(frozen, module = "gelgrip")]
pub struct Recording {
    inner: RustRecording,
    sensors: Vec<String>,
}

#[pymethods]
impl Recording {
    /// Open the recording in `dir` (`FileNotFoundError` when there is no such directory,
    /// `RecordingError` when it is not a readable recording).
    #[new]
    fn new(py: Python<'_>, dir: PathBuf) -> PyResult<Self> {
        errors::require_dir(&dir, "recording")?;
        let (inner, header) = py
            .detach(|| {
                let r = RustRecording::open(&dir)?;
                let header = r.header()?;
                Ok::<_, gelgrip_record::RecordError>((r, header))
            })
            .map_err(|e| recording_error(&e))?;
        let sensors = match header {
            Meta::Header { sensors, .. } => sensors,
            _ => Vec::new(),
        };
        Ok(Self { inner, sensors })
    }

    /// What the recording holds and whether it is whole: `record info --json`'s object.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let info = py
            .detach(|| RecordingInfo::of(&self.inner))
            .map_err(|e| recording_error(&e))?;
        to_py(py, &info)
    }

    /// The sensor ids, in index order.
    #[getter]
    fn sensors(&self) -> Vec<String> {
        self.sensors.clone()
    }

    /// The frames in recorded order, of one sensor (its index or id) or of all (None).
    #[pyo3(signature = (sensor=None))]
    fn frames(&self, sensor: Option<&Bound<'_, PyAny>>) -> PyResult<Frames> {
        let only = match sensor {
            None => None,
            Some(s) => Some(self.sensor_index(s)?),
        };
        Ok(Frames {
            stream: Mutex::new(RecordStream::new(&self.inner)),
            sensors: self.sensors.clone(),
            only,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Recording({:?}, sensors={:?})",
            self.inner.dir().display().to_string(),
            self.sensors
        )
    }
}

impl Recording {
    /// A sensor given by index or id, checked against the header's sensors.
    fn sensor_index(&self, s: &Bound<'_, PyAny>) -> PyResult<u8> {
        let index = if let Ok(i) = s.extract::<i64>() {
            usize::try_from(i).ok().filter(|i| *i < self.sensors.len())
        } else if let Ok(id) = s.extract::<String>() {
            self.sensors.iter().position(|x| *x == id)
        } else {
            return Err(PyTypeError::new_err(
                "sensor: expected an index (int) or an id (str)",
            ));
        };
        index.and_then(|i| u8::try_from(i).ok()).ok_or_else(|| {
            PyKeyError::new_err(format!(
                "sensor {s}: the recording's sensors are {:?}",
                self.sensors
            ))
        })
    }
}

/// The frames of a recording, one at a time.
#[pyclass(module = "gelgrip")]
pub struct Frames {
    stream: Mutex<RecordStream>,
    sensors: Vec<String>,
    only: Option<u8>,
}

#[pymethods]
impl Frames {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Option<RecordedFrame>> {
        let only = self.only;
        let next = py.detach(|| {
            let mut stream =
                self.stream
                    .lock()
                    .map_err(|_| gelgrip_record::RecordError::Format {
                        path: String::new(),
                        detail: "the frame reader failed in another thread".into(),
                    })?;
            loop {
                match stream.next_record()? {
                    None => return Ok(None),
                    Some(Record::Frame(f)) if only.is_none_or(|s| s == f.sensor) => {
                        return Ok(Some(f));
                    }
                    Some(_) => {}
                }
            }
        });
        let Some(f) = next.map_err(|e| recording_error(&e))? else {
            return Ok(None);
        };
        Ok(Some(RecordedFrame {
            sensor: usize::from(f.sensor),
            sensor_id: self.sensors.get(usize::from(f.sensor)).cloned(),
            trigger_seq: f.trigger_seq,
            capture_us: f.capture_host_us,
            jpeg: PyBytes::new(py, &f.jpeg).unbind(),
        }))
    }
}

/// One recorded frame.
#[pyclass(frozen, module = "gelgrip")]
pub struct RecordedFrame {
    /// The sensor's index.
    #[pyo3(get)]
    sensor: usize,
    /// The sensor's id (None when the header does not list it).
    #[pyo3(get)]
    sensor_id: Option<String>,
    /// The trigger sequence.
    #[pyo3(get)]
    trigger_seq: u32,
    /// Capture time on the host clock, µs.
    #[pyo3(get)]
    capture_us: u64,
    /// The JPEG bytes, as the hub sent them.
    #[pyo3(get)]
    jpeg: Py<PyBytes>,
}

#[pymethods]
impl RecordedFrame {
    /// The frame decoded: H×W×3 uint8, read-only, in `color_order`.
    #[pyo3(signature = (color_order="rgb"))]
    fn image<'py>(
        &self,
        py: Python<'py>,
        color_order: &str,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<u8>>> {
        let order = ColorOrder::parse(color_order)?;
        let bytes = self.jpeg.bind(py).as_bytes().to_vec();
        let mut img = py
            .detach(|| RgbImage::from_jpeg("recorded frame", &bytes))
            .map_err(|e| errors::image(&e))?;
        if order == ColorOrder::Bgr {
            img.data.chunks_exact_mut(3).for_each(|p| p.swap(0, 2));
        }
        arrays::readonly(py, img.data, &[img.height, img.width, 3])
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "RecordedFrame(sensor={}, sensor_id={:?}, trigger_seq={}, capture_us={}, jpeg=<{} bytes>)",
            self.sensor,
            self.sensor_id,
            self.trigger_seq,
            self.capture_us,
            self.jpeg.bind(py).as_bytes().len()
        )
    }
}
