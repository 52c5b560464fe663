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
    /// PNG with a layout this reader does not take.
    #[error("{path}: PNG is {actual}, expected 8-bit RGB or RGBA")]
    Format {
        /// The file.
        path: String,
        /// What it was.
        actual: String,
    },
}

impl RgbImage {
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
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| ImageError::Format {
                path: p.clone(),
                actual: "too large".into(),
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
