//! The contact sheet of a labelling run: every press's difference from the background,
//! shrunk into a grid, with its detected circle drawn on it (or a red cross when it was
//! rejected), so a person can check every label at a glance.

use crate::image::RgbImage;

use super::label::ContactCircle;

/// Widest a tile may be, px (presses are shrunk by a whole factor to fit).
pub const TILE_MAX_PX: usize = 240;
/// Gap between tiles, px.
const GAP_PX: usize = 4;
/// Gain of the difference image (128 + gain × (press − background)).
const DIFF_GAIN: f64 = 2.0;
const CIRCLE_RGB: [u8; 3] = [255, 255, 0];
const REJECTED_RGB: [u8; 3] = [255, 0, 0];

/// One tile: the press, its background, and its circle (`None`: rejected). A press whose
/// size differs from the background's shows as a blank tile with a red cross.
#[derive(Debug, Clone, Copy)]
pub struct Tile<'a> {
    /// The press.
    pub press: Option<&'a RgbImage>,
    /// The detected circle, or `None` when the press was rejected.
    pub circle: Option<ContactCircle>,
}

/// The sheet of `tiles` for presses of `background`'s size, in a near-square grid.
pub fn contact_sheet(background: &RgbImage, tiles: &[Tile<'_>]) -> RgbImage {
    let (w, h) = (background.width.max(1), background.height.max(1));
    let shrink = w.div_ceil(TILE_MAX_PX).max(1);
    let (tw, th) = ((w / shrink).max(1), (h / shrink).max(1));
    let n = tiles.len().max(1);
    let cols = (n as f64).sqrt().ceil() as usize;
    let rows = n.div_ceil(cols);
    let mut sheet = RgbImage::new(cols * (tw + GAP_PX) + GAP_PX, rows * (th + GAP_PX) + GAP_PX);
    sheet.data.fill(40);
    for (i, tile) in tiles.iter().enumerate() {
        let (x0, y0) = (
            GAP_PX + (i % cols) * (tw + GAP_PX),
            GAP_PX + (i / cols) * (th + GAP_PX),
        );
        let press = tile
            .press
            .filter(|p| (p.width, p.height) == (background.width, background.height));
        for y in 0..th {
            for x in 0..tw {
                let rgb = match press {
                    Some(p) => mean_diff(p, background, x * shrink, y * shrink, shrink),
                    None => [128; 3],
                };
                put(&mut sheet, x0 + x, y0 + y, rgb);
            }
        }
        match (tile.circle, press) {
            (Some(c), Some(_)) => {
                let s = shrink as f64;
                let centre = (
                    (c.center_x_px + 0.5) / s - 0.5,
                    (c.center_y_px + 0.5) / s - 0.5,
                );
                draw_circle(
                    &mut sheet,
                    (x0, y0, tw, th),
                    centre,
                    c.contact_radius_px / s,
                );
            }
            _ => draw_cross(&mut sheet, (x0, y0, tw, th)),
        }
    }
    sheet
}

/// One press's difference from `background` at full size, with `circle` drawn on it when
/// there is one (the live view of `calibrate collect`). A press of another size than the
/// background shows grey.
pub fn difference_view(
    press: &RgbImage,
    background: &RgbImage,
    circle: Option<ContactCircle>,
) -> RgbImage {
    let (w, h) = (background.width, background.height);
    let mut out = RgbImage::new(w, h);
    let same = (press.width, press.height) == (w, h);
    for y in 0..h {
        for x in 0..w {
            let rgb = if same {
                mean_diff(press, background, x, y, 1)
            } else {
                [128; 3]
            };
            put(&mut out, x, y, rgb);
        }
    }
    if let Some(c) = circle.filter(|_| same) {
        let centre = (c.center_x_px, c.center_y_px);
        draw_circle(&mut out, (0, 0, w, h), centre, c.contact_radius_px);
    }
    out
}

fn mean_diff(p: &RgbImage, bg: &RgbImage, x0: usize, y0: usize, k: usize) -> [u8; 3] {
    let mut sum = [0.0f64; 3];
    let mut n = 0.0;
    for y in y0..(y0 + k).min(p.height) {
        for x in x0..(x0 + k).min(p.width) {
            let i = 3 * (y * p.width + x);
            for (c, s) in sum.iter_mut().enumerate() {
                *s += f64::from(p.data[i + c]) - f64::from(bg.data[i + c]);
            }
            n += 1.0;
        }
    }
    sum.map(|s| (128.0 + DIFF_GAIN * s / f64::max(n, 1.0)).clamp(0.0, 255.0) as u8)
}

fn put(img: &mut RgbImage, x: usize, y: usize, rgb: [u8; 3]) {
    if x < img.width && y < img.height {
        let i = 3 * (y * img.width + x);
        img.data[i..i + 3].copy_from_slice(&rgb);
    }
}

/// The circle and a small cross at its centre, clipped to the tile.
fn draw_circle(
    img: &mut RgbImage,
    (x0, y0, tw, th): (usize, usize, usize, usize),
    (cx, cy): (f64, f64),
    r: f64,
) {
    let mut plot = |x: f64, y: f64| {
        let (x, y) = (x.round(), y.round());
        if x >= 0.0 && y >= 0.0 && (x as usize) < tw && (y as usize) < th {
            put(img, x0 + x as usize, y0 + y as usize, CIRCLE_RGB);
        }
    };
    let steps = ((std::f64::consts::TAU * r * 2.0).ceil() as usize).clamp(8, 4096);
    for k in 0..steps {
        let (s, c) = (std::f64::consts::TAU * k as f64 / steps as f64).sin_cos();
        plot(cx + r * c, cy + r * s);
    }
    for d in -2..=2 {
        plot(cx + f64::from(d), cy);
        plot(cx, cy + f64::from(d));
    }
}

/// A red cross over the whole tile: rejected.
fn draw_cross(img: &mut RgbImage, (x0, y0, tw, th): (usize, usize, usize, usize)) {
    let n = tw.max(th);
    for k in 0..n {
        let x = k * tw / n;
        let y = k * th / n;
        put(img, x0 + x, y0 + y, REJECTED_RGB);
        put(img, x0 + tw - 1 - x, y0 + y, REJECTED_RGB);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_are_laid_out_with_circles_and_crosses() {
        let bg = RgbImage::new(480, 120);
        let c = ContactCircle {
            center_x_px: 240.0,
            center_y_px: 60.0,
            contact_radius_px: 40.0,
            score: 1.0,
        };
        let tiles = [
            Tile {
                press: Some(&bg),
                circle: Some(c),
            },
            Tile {
                press: Some(&bg),
                circle: None,
            },
            Tile {
                press: None,
                circle: None,
            },
        ];
        let sheet = contact_sheet(&bg, &tiles);
        // Shrunk by 2 to 240 x 60, two columns, two rows.
        assert_eq!((sheet.width, sheet.height), (2 * 244 + 4, 2 * 64 + 4));
        let px = |x: usize, y: usize| {
            &sheet.data[3 * (y * sheet.width + x)..3 * (y * sheet.width + x) + 3]
        };
        // The circle's rightmost point: centre (120, 30) + r 20 in the first tile.
        assert_eq!(px(4 + 140, 4 + 30), CIRCLE_RGB);
        // The second tile's cross starts at its corner.
        assert_eq!(px(4 + 244, 4), REJECTED_RGB);
        assert!(contact_sheet(&RgbImage::new(0, 0), &[]).width > 0);
    }

    #[test]
    fn the_difference_view_is_full_size_with_its_circle() {
        let bg = RgbImage::new(40, 30);
        let mut press = bg.clone();
        press.data[0] = 10;
        let c = ContactCircle {
            center_x_px: 20.0,
            center_y_px: 15.0,
            contact_radius_px: 10.0,
            score: 1.0,
        };
        let view = difference_view(&press, &bg, Some(c));
        assert_eq!((view.width, view.height), (40, 30));
        assert_eq!(view.data[0], 148, "128 + 2 x 10");
        let px = |x: usize, y: usize| &view.data[3 * (y * 40 + x)..3 * (y * 40 + x) + 3];
        assert_eq!(px(30, 15), CIRCLE_RGB);
        assert_eq!(px(5, 5), [128; 3]);
        let plain = difference_view(&press, &bg, None);
        assert_eq!(plain.data[3 * (15 * 40 + 30)..][..3], [128; 3], "no circle");
        let other = difference_view(&RgbImage::new(3, 3), &bg, Some(c));
        assert!(other.data.iter().all(|v| *v == 128), "another size: grey");
    }
}
