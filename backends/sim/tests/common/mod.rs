//! What the simulator's scene tests share: the three-finger layout.

use gelgrip_controller::layout::HandLayout;

/// The three-finger layout of `configs/layouts`.
pub fn layout() -> HandLayout {
    let text = include_str!("../../../../configs/layouts/three-finger.toml");
    HandLayout::from_toml("three-finger.toml", text).expect("layout")
}
