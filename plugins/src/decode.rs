//! Stage `jpeg`: decode a frame's JPEG into a reused RGB buffer, optionally at a reduced
//! scale (2 or 4: box-averaged, for speed at the cost of resolution).

use thiserror::Error;
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// A frame that did not decode to the expected image.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// The JPEG itself is broken.
    #[error("JPEG decode failed: {detail}")]
    Jpeg {
        /// The decoder's message.
        detail: String,
    },
    /// The JPEG decoded, but not at the sensor's resolution.
    #[error(
        "JPEG is {actual_w}x{actual_h}, the sensor is configured for {expected_w}x{expected_h}"
    )]
    Size {
        /// Configured width.
        expected_w: usize,
        /// Configured height.
        expected_h: usize,
        /// Decoded width.
        actual_w: usize,
        /// Decoded height.
        actual_h: usize,
    },
}

/// Decodes frames of one sensor.
#[derive(Debug, Clone)]
pub struct JpegStage {
    width: usize,
    height: usize,
    scale: usize,
    full: Vec<u8>,
}

impl JpegStage {
    /// A decoder for `width × height` frames, output reduced by `scale` (1, 2 or 4).
    pub fn new(width: usize, height: usize, scale: usize) -> Self {
        let scale = if matches!(scale, 2 | 4) { scale } else { 1 };
        Self {
            width,
            height,
            scale,
            full: vec![0; width * height * 3],
        }
    }

    /// Output size `(width, height)` after scaling.
    pub fn output_size(&self) -> (usize, usize) {
        (self.width / self.scale, self.height / self.scale)
    }

    /// Decode `jpeg` into `out` (`output_size` × 3 bytes).
    pub fn decode(&mut self, jpeg: &[u8], out: &mut [u8]) -> Result<(), DecodeError> {
        let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
        let mut dec = JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
        dec.decode_headers().map_err(|e| DecodeError::Jpeg {
            detail: format!("{e:?}"),
        })?;
        let (w, h) = dec.dimensions().ok_or_else(|| DecodeError::Jpeg {
            detail: "no dimensions".into(),
        })?;
        if w != self.width || h != self.height {
            return Err(DecodeError::Size {
                expected_w: self.width,
                expected_h: self.height,
                actual_w: w,
                actual_h: h,
            });
        }
        let target: &mut [u8] = if self.scale == 1 { out } else { &mut self.full };
        dec.decode_into(target).map_err(|e| DecodeError::Jpeg {
            detail: format!("{e:?}"),
        })?;
        if self.scale > 1 {
            downsample(&self.full, self.width, self.height, self.scale, out);
        }
        Ok(())
    }
}

fn downsample(src: &[u8], w: usize, h: usize, s: usize, out: &mut [u8]) {
    let (ow, oh) = (w / s, h / s);
    let n = (s * s) as u32;
    for y in 0..oh {
        for x in 0..ow {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..s {
                    let row = (y * s + dy) * w;
                    for dx in 0..s {
                        sum += u32::from(src[(row + x * s + dx) * 3 + c]);
                    }
                }
                out[(y * ow + x) * 3 + c] = ((sum + n / 2) / n) as u8;
            }
        }
    }
}
