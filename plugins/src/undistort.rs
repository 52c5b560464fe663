//! Stage `fisheye`: lens undistortion by a precomputed remap (stage `none` is the identity,
//! which the simulator uses).
//!
//! The sensor cameras have a 160° lens. Model: Kannala–Brandt equidistant fisheye, with
//! intrinsics `fx, fy, cx, cy` and distortion `k1…k4`. A pixel of the undistorted image at
//! normalised (x, y) has angle θ = atan(r) with r = √(x² + y²). It maps to
//! θ_d = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸) in the captured image. The table stores, for each
//! output pixel, the nearest source pixel (or none), so a frame is remapped with one read per
//! pixel and no allocation.

/// Fisheye camera parameters (pixels of the processed resolution).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fisheye {
    /// Focal lengths, px.
    pub fx: f64,
    /// Focal lengths, px.
    pub fy: f64,
    /// Principal point, px.
    pub cx: f64,
    /// Principal point, px.
    pub cy: f64,
    /// Distortion coefficients k1…k4.
    pub k: [f64; 4],
}

/// A precomputed remap.
#[derive(Debug, Clone)]
pub struct Remap {
    source: Vec<u32>,
}

const OUTSIDE: u32 = u32::MAX;

impl Remap {
    /// The table for `camera` on `width × height` images.
    pub fn fisheye(camera: &Fisheye, width: usize, height: usize) -> Self {
        let mut source = vec![OUTSIDE; width * height];
        for (k, slot) in source.iter_mut().enumerate() {
            let x = ((k % width) as f64 - camera.cx) / camera.fx;
            let y = ((k / width) as f64 - camera.cy) / camera.fy;
            let r = (x * x + y * y).sqrt();
            let theta = r.atan();
            let t2 = theta * theta;
            let [k1, k2, k3, k4] = camera.k;
            let theta_d = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
            let s = if r > 1e-12 { theta_d / r } else { 1.0 };
            let u = (camera.fx * x * s + camera.cx).round();
            let v = (camera.fy * y * s + camera.cy).round();
            if u.is_finite()
                && v.is_finite()
                && u >= 0.0
                && v >= 0.0
                && (u as usize) < width
                && (v as usize) < height
            {
                *slot = (v as usize * width + u as usize) as u32;
            }
        }
        Self { source }
    }

    /// Remap interleaved RGB `src` into `dst` (pixels with no source become black).
    pub fn apply(&self, src: &[u8], dst: &mut [u8]) {
        for (k, s) in self.source.iter().enumerate() {
            let px = if *s == OUTSIDE {
                [0; 3]
            } else {
                let i = *s as usize * 3;
                [src[i], src[i + 1], src[i + 2]]
            };
            dst[k * 3..k * 3 + 3].copy_from_slice(&px);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_distortion_at_the_centre_is_identity_there() {
        let cam = Fisheye {
            fx: 100.0,
            fy: 100.0,
            cx: 16.0,
            cy: 12.0,
            k: [0.0; 4],
        };
        let remap = Remap::fisheye(&cam, 32, 24);
        let src: Vec<u8> = (0..32 * 24 * 3).map(|i| (i % 251) as u8).collect();
        let mut dst = vec![0; src.len()];
        remap.apply(&src, &mut dst);
        let c = (12 * 32 + 16) * 3;
        assert_eq!(&dst[c..c + 3], &src[c..c + 3]);
    }
}
