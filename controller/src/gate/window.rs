//! The capture spread the control can tolerate: the `auto` value of `[gate]
//! max_spread_us`, derived from the hand instead of from the bus's ideal timing.
//!
//! Frames fused into one set describe one instant only as far as the fingers stood still
//! between their captures. A pad in contact that moves by less than one pixel of its
//! sensor between the earliest and the latest capture of a set is, for the sensor, in the
//! same place: the set is as good as synchronous. So the spread a set may have is the time
//! the fastest pad in contact takes to travel one pixel:
//!
//! ```text
//! spread = min over pads ( mm_per_px / v_pad ),
//! v_pad  = ω_contact × r_pulley × pad_offset / moment_arm
//! ```
//!
//! where `ω_contact` is the fastest the controller turns a servo once a finger is in
//! contact (the servo's no-load speed, the largest approach speed a grasp may ask for,
//! times the controller's contact speed share), and a pad's speed per unit of servo angle
//! is the cable's pull (`r_pulley`) turning the pad's own joint (`1 / moment_arm`) at the
//! pad's distance from it (`pad_offset`): the fastest the pad can move, when its joint
//! alone takes the cable's travel. Numbers for the shipped hand are in docs/config.md.

use crate::fingers::FingerSpec;
use crate::layout::HandLayout;

/// What sets the tolerated spread: the fastest pad in contact and its pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlSpread {
    /// The tolerated spread, µs.
    pub spread_us: f64,
    /// The pad that sets it (`f1.tip`).
    pub pad: String,
    /// That pad's fastest speed in contact, mm/s.
    pub pad_speed_mm_s: f64,
    /// That pad's pixel size, mm.
    pub pixel_mm: f64,
}

/// The spread `layout`'s fastest pad in contact takes to move one pixel, with servos
/// turning at most `servo_deg_s` in contact; `None` for a layout without finger mechanics
/// (nothing moves the pads) or with no sensor on a phalanx.
pub fn control_spread(layout: &HandLayout, servo_deg_s: f64) -> Option<ControlSpread> {
    if !(servo_deg_s.is_finite() && servo_deg_s > 0.0) {
        return None;
    }
    let servo_rad_s = servo_deg_s.to_radians();
    layout
        .fingers
        .iter()
        .flat_map(|f| pads(f, layout))
        .filter_map(|(pad, mm_per_rad, pixel_mm)| {
            let pad_speed_mm_s = mm_per_rad * servo_rad_s;
            let spread_us = pixel_mm / pad_speed_mm_s * 1e6;
            (spread_us.is_finite() && spread_us > 0.0).then_some(ControlSpread {
                spread_us,
                pad,
                pad_speed_mm_s,
                pixel_mm,
            })
        })
        .min_by(|a, b| a.spread_us.total_cmp(&b.spread_us))
}

/// Each sensor-carrying phalanx of `finger`: its sensor id, the pad's travel per radian of
/// servo (mm/rad) and the sensor's pixel size (mm).
fn pads<'a>(
    finger: &'a FingerSpec,
    layout: &'a HandLayout,
) -> impl Iterator<Item = (String, f64, f64)> + 'a {
    finger.phalanges.iter().filter_map(move |p| {
        let id = format!("{}.{}", finger.id, p.link.as_str());
        let sensor = layout.sensors.iter().find(|s| s.id.to_string() == id)?;
        let mm_per_rad = finger.pulley_radius_mm * p.pad_offset_mm / p.moment_arm_mm;
        Some((id, mm_per_rad, sensor.mm_per_px))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> HandLayout {
        let text = include_str!("../../../configs/layouts/three-finger.toml");
        HandLayout::from_toml("three-finger.toml", text).expect("the shipped layout")
    }

    #[test]
    fn the_shipped_hand_tolerates_about_a_millisecond_at_full_speed() {
        // XM430-W350 no-load 276 deg/s, contact speed share 0.25: 69 deg/s in contact.
        let s = control_spread(&shipped(), 69.0).expect("fingers with sensors");
        // The tip: 10 mm pulley x 16 mm / 3.5 mm = 45.7 mm of pad travel per radian.
        assert_eq!(s.pad, "f1.tip");
        let v = 10.0 * 16.0 / 3.5 * 69f64.to_radians();
        assert!((s.pad_speed_mm_s - v).abs() < 1e-9, "{s:?}");
        assert!((s.spread_us - 0.0625 / v * 1e6).abs() < 1e-6, "{s:?}");
        assert!((1100.0..1150.0).contains(&s.spread_us), "{s:?}");
        // Slower closing tolerates proportionally more.
        let slow = control_spread(&shipped(), 3.75).expect("fingers");
        assert!((slow.spread_us / s.spread_us - 69.0 / 3.75).abs() < 1e-9);
    }

    #[test]
    fn no_fingers_or_no_speed_means_no_control_bound() {
        let mut layout = shipped();
        assert_eq!(control_spread(&layout, 0.0), None);
        assert_eq!(control_spread(&layout, f64::NAN), None);
        assert_eq!(control_spread(&layout, f64::INFINITY), None);
        layout.fingers.clear();
        assert_eq!(control_spread(&layout, 69.0), None);
    }
}
