//! Image buffers and the PNG files of press datasets.

use std::path::Path;

use thiserror::Error;

/// An 8-bit RGB image, row-major, interleaved.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub data: Vec<u8>,
}

/// An image file could not be read or written.
#[derive(Debug, Error)]
pub enum ImageError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// PNG decoding failed.
    #[error("{path}: not a readable PNG: {detail}")]
    Png {
        /// The file.
        path: String,
        /// The decoder's message.
        detail: String,
    },
    /// JPEG decoding failed.
    #[error("{name}: not a readable JPEG: {detail}")]
    Jpeg {
        /// What was decoded.
        name: String,
        /// The decoder's message.
        detail: String,
    },
    /// A PNG whose header claims more than [`MAX_PNG_PIXELS`] pixels (refused before its
    /// buffer is allocated).
    #[error(
        "{path}: PNG claims {width}x{height} pixels, more than the {MAX_PNG_PIXELS} this reader takes"
    )]
    TooLarge {
        /// The file.
        path: String,
        /// Columns claimed.
        width: u32,
        /// Rows claimed.
        height: u32,
    },
    /// PNG with a layout this reader does not take.
    #[error("{path}: PNG is {actual}, expected 8-bit RGB or RGBA")]
    Format {
        /// The file.
        path: String,
        /// What it was.
        actual: String,
    },
}

/// Most pixels a PNG may have (4096 x 4096, a 64 MiB RGBA buffer): a press image is a
/// sensor's frame, far smaller; a header claiming more is refused before its buffer is
/// allocated.
pub const MAX_PNG_PIXELS: u64 = 1 << 24;

/// Largest box-blur radius a model may ask for, px.
pub const MAX_BLUR_PX: usize = 8;

/// Blur interleaved RGB bytes (`w × h × 3`) in place with a `(2r + 1)²` box, edges
/// replicated, so every output is the mean of the same number of samples (a flat image stays
/// flat, independent pixel noise shrinks by `2r + 1`). Separable running sums, each pass
/// rounded to nearest: O(1) work per byte whatever the radius, the vertical pass row by row
/// (contiguous, vectorised). `r = 0` (or bytes that are not `w × h × 3`) leaves them as
/// they are.
pub fn box_blur_rgb(data: &mut [u8], w: usize, h: usize, r: usize) {
    if r == 0 || w == 0 || h == 0 || data.len() != w * h * 3 {
        return;
    }
    // n is odd, so a mean is never exactly halfway: adding 0.5 and truncating rounds it.
    let scale = 1.0 / (2 * r + 1) as f32;
    let mean = |sum: u32| (sum as f32 * scale + 0.5) as u8;
    let row_len = w * 3;
    let last = |i: isize, len: usize| i.clamp(0, len as isize - 1) as usize;
    let ri = r as isize;
    // Horizontal: the three channels of a row together.
    let mut line = vec![0u8; row_len];
    for row in data.chunks_exact_mut(row_len) {
        line.copy_from_slice(row);
        let mut sum = [0u32; 3];
        for k in -ri..=ri {
            let x = last(k, w) * 3;
            for c in 0..3 {
                sum[c] += u32::from(line[x + c]);
            }
        }
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            let (add, sub) = (
                last(x as isize + ri + 1, w) * 3,
                last(x as isize - ri, w) * 3,
            );
            let (a, b) = (&line[add..add + 3], &line[sub..sub + 3]);
            for c in 0..3 {
                px[c] = mean(sum[c]);
                sum[c] = sum[c] + u32::from(a[c]) - u32::from(b[c]);
            }
        }
    }
    // Vertical: a running sum of 2r + 1 rows (edges replicated), one row in and one out.
    let src = data.to_vec();
    let row = |y: isize| {
        let y = last(y, h);
        &src[y * row_len..(y + 1) * row_len]
    };
    let mut acc = vec![0u32; row_len];
    for y in -ri..=ri {
        acc.iter_mut()
            .zip(row(y))
            .for_each(|(a, v)| *a += u32::from(*v));
    }
    for (y, out) in data.chunks_exact_mut(row_len).enumerate() {
        out.iter_mut().zip(&acc).for_each(|(o, a)| *o = mean(*a));
        let y = y as isize;
        for ((a, add), sub) in acc.iter_mut().zip(row(y + ri + 1)).zip(row(y - ri)) {
            *a = *a + u32::from(*add) - u32::from(*sub);
        }
    }
}

impl RgbImage {
    /// This image blurred with [`box_blur_rgb`] of radius `r`.
    pub fn blurred(&self, r: usize) -> RgbImage {
        let mut out = self.clone();
        box_blur_rgb(&mut out.data, out.width, out.height, r);
        out
    }

    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0; width * height * 3],
        }
    }

    /// Read an 8-bit RGB or RGBA PNG.
    pub fn read_png(path: &Path) -> Result<Self, ImageError> {
        let p = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|source| ImageError::Io {
            path: p.clone(),
            source,
        })?;
        let png_err = |e: png::DecodingError| ImageError::Png {
            path: p.clone(),
            detail: e.to_string(),
        };
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .map_err(png_err)?;
        // Before the buffer: a header claiming 2^20 x 2^20 pixels must not allocate 4 TiB.
        let (w, h) = (reader.info().width, reader.info().height);
        let size = reader
            .output_buffer_size()
            .filter(|_| u64::from(w) * u64::from(h) <= MAX_PNG_PIXELS)
            .ok_or_else(|| ImageError::TooLarge {
                path: p.clone(),
                width: w,
                height: h,
            })?;
        let mut buf = vec![0; size];
        let info = reader.next_frame(&mut buf).map_err(png_err)?;
        let (w, h) = (info.width as usize, info.height as usize);
        let data = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => buf[..w * h * 3].to_vec(),
            (png::ColorType::Rgba, png::BitDepth::Eight) => buf[..w * h * 4]
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect(),
            (c, d) => {
                return Err(ImageError::Format {
                    path: p,
                    actual: format!("{c:?} at {d:?}"),
                });
            }
        };
        Ok(Self {
            width: w,
            height: h,
            data,
        })
    }

    /// Decode a JPEG (`name` for errors) at its own size.
    pub fn from_jpeg(name: &str, jpeg: &[u8]) -> Result<Self, ImageError> {
        use zune_jpeg::JpegDecoder;
        use zune_jpeg::zune_core::bytestream::ZCursor;
        use zune_jpeg::zune_core::colorspace::ColorSpace;
        use zune_jpeg::zune_core::options::DecoderOptions;
        let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
        let mut dec = JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
        let bad = |detail: String| ImageError::Jpeg {
            name: name.to_string(),
            detail,
        };
        let data = dec.decode().map_err(|e| bad(format!("{e:?}")))?;
        let (width, height) = dec
            .dimensions()
            .ok_or_else(|| bad("no dimensions".into()))?;
        if data.len() != width * height * 3 {
            return Err(bad(format!(
                "{} bytes for {width}x{height} RGB",
                data.len()
            )));
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Write as an 8-bit RGB PNG.
    pub fn write_png(&self, path: &Path) -> Result<(), ImageError> {
        let p = path.display().to_string();
        let file = std::fs::File::create(path).map_err(|source| ImageError::Io {
            path: p.clone(),
            source,
        })?;
        let mut enc = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let png_err = |e: png::EncodingError| ImageError::Png {
            path: p.clone(),
            detail: e.to_string(),
        };
        let mut writer = enc.write_header().map_err(png_err)?;
        writer.write_image_data(&self.data).map_err(png_err)?;
        writer.finish().map_err(png_err)
    }
}

#[cfg(test)]
mod blur_tests {
    use super::box_blur_rgb;

    #[test]
    fn a_flat_image_stays_flat_and_an_impulse_spreads_over_the_box() {
        let (w, h) = (9, 7);
        let mut flat = vec![200u8; w * h * 3];
        box_blur_rgb(&mut flat, w, h, 2);
        assert!(flat.iter().all(|v| *v == 200));
        let mut img = vec![0u8; w * h * 3];
        img[(3 * w + 4) * 3 + 1] = 250; // green at (4, 3)
        box_blur_rgb(&mut img, w, h, 1);
        for y in 0..h {
            for x in 0..w {
                let inside = x.abs_diff(4) <= 1 && y.abs_diff(3) <= 1;
                let p = (y * w + x) * 3;
                assert_eq!(img[p + 1], if inside { 28 } else { 0 }, "({x}, {y})");
                assert_eq!((img[p], img[p + 2]), (0, 0));
            }
        }
    }

    #[test]
    fn edges_replicate_and_extremes_stay_in_range() {
        // A saturated image with a black first column: the border keeps its own value's
        // weight (replicated), nothing wraps, nothing overflows.
        let (w, h) = (5, 3);
        let mut img = vec![255u8; w * h * 3];
        for y in 0..h {
            img[y * w * 3..y * w * 3 + 3].fill(0);
        }
        box_blur_rgb(&mut img, w, h, 1);
        assert_eq!(img[0], 85); // (0 + 0 + 255) / 3 at the left edge
        assert_eq!(img[3], 170);
        assert_eq!(img[(w - 1) * 3], 255);
        let mut one = vec![7u8; 3];
        box_blur_rgb(&mut one, 1, 1, 8);
        assert_eq!(one, vec![7, 7, 7]);
        let mut odd = vec![1u8; 5]; // not w × h × 3: left alone
        box_blur_rgb(&mut odd, 2, 2, 1);
        assert_eq!(odd, vec![1u8; 5]);
    }
}
#[cfg(test)]
mod blur_speed {
    #[test]
    #[ignore]
    fn speed() {
        let (w, h) = (320, 240);
        let mut img: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let t = std::time::Instant::now();
        for _ in 0..100 {
            super::box_blur_rgb(&mut img, w, h, 4);
        }
        eprintln!("blur {:?} per frame", t.elapsed() / 100);
    }
}
