//! Geometric primitives of scene objects and their signed distance (mm): negative inside.
//!
//! Scene objects are unions of these, so contact needs nothing but a distance query: a gel
//! point whose distance is negative is indented by minus that distance. The ellipsoid uses
//! the standard first-order bound (exact on the axes, slightly conservative between them).

use glam::{DQuat, DVec3};

/// A primitive in its own frame (centred at the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// A ball.
    Sphere {
        /// Radius, mm.
        radius_mm: f64,
    },
    /// An ellipsoid with semi-axes along x, y, z.
    Ellipsoid {
        /// Semi-axes, mm.
        radii_mm: DVec3,
    },
    /// A capped cylinder along z.
    Cylinder {
        /// Radius, mm.
        radius_mm: f64,
        /// Length along z, mm.
        length_mm: f64,
    },
    /// A box.
    Cuboid {
        /// Edge lengths along x, y, z, mm.
        size_mm: DVec3,
    },
}

impl Primitive {
    /// Signed distance from `p` (in the primitive's frame), mm.
    pub fn distance_mm(&self, p: DVec3) -> f64 {
        match *self {
            Primitive::Sphere { radius_mm } => p.length() - radius_mm,
            Primitive::Ellipsoid { radii_mm } => {
                let k0 = (p / radii_mm).length();
                let k1 = (p / (radii_mm * radii_mm)).length();
                if k1 <= f64::EPSILON {
                    -radii_mm.min_element()
                } else {
                    k0 * (k0 - 1.0) / k1
                }
            }
            Primitive::Cylinder {
                radius_mm,
                length_mm,
            } => {
                let radial = (p.x * p.x + p.y * p.y).sqrt() - radius_mm;
                let axial = p.z.abs() - length_mm / 2.0;
                let outside = (radial.max(0.0).powi(2) + axial.max(0.0).powi(2)).sqrt();
                outside + radial.max(axial).min(0.0)
            }
            Primitive::Cuboid { size_mm } => {
                let q = p.abs() - size_mm / 2.0;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }

    /// Radius of a sphere about the origin that contains the primitive, mm.
    pub fn bounding_radius_mm(&self) -> f64 {
        match *self {
            Primitive::Sphere { radius_mm } => radius_mm,
            Primitive::Ellipsoid { radii_mm } => radii_mm.max_element(),
            Primitive::Cylinder {
                radius_mm,
                length_mm,
            } => (radius_mm * radius_mm + length_mm * length_mm / 4.0).sqrt(),
            Primitive::Cuboid { size_mm } => (size_mm / 2.0).length(),
        }
    }
}

/// A primitive placed in a parent frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// The shape.
    pub primitive: Primitive,
    /// Its centre in the parent frame, mm.
    pub offset_mm: DVec3,
    /// Its orientation in the parent frame.
    pub rotation: DQuat,
}

impl Placed {
    /// Signed distance from `p` (parent frame), mm.
    pub fn distance_mm(&self, p: DVec3) -> f64 {
        self.primitive
            .distance_mm(self.rotation.inverse() * (p - self.offset_mm))
    }

    /// Bounding sphere (centre, radius) in the parent frame.
    pub fn bounds(&self) -> (DVec3, f64) {
        (self.offset_mm, self.primitive.bounding_radius_mm())
    }
}

/// Rotation from roll, pitch, yaw in degrees (applied x, then y, then z).
pub fn rotation_from_rpy_deg(rpy: [f64; 3]) -> DQuat {
    DQuat::from_euler(
        glam::EulerRot::ZYX,
        rpy[2].to_radians(),
        rpy[1].to_radians(),
        rpy[0].to_radians(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_are_exact_on_the_axes() {
        let s = Primitive::Sphere { radius_mm: 10.0 };
        assert!((s.distance_mm(DVec3::new(0.0, 0.0, 12.0)) - 2.0).abs() < 1e-12);
        assert!((s.distance_mm(DVec3::ZERO) + 10.0).abs() < 1e-12);
        let e = Primitive::Ellipsoid {
            radii_mm: DVec3::new(10.0, 20.0, 30.0),
        };
        assert!((e.distance_mm(DVec3::new(12.0, 0.0, 0.0)) - 2.0).abs() < 1e-9);
        assert!((e.distance_mm(DVec3::new(0.0, 0.0, 29.0)) + 1.0).abs() < 0.1);
        assert!(e.distance_mm(DVec3::ZERO) < 0.0);
        let c = Primitive::Cylinder {
            radius_mm: 5.0,
            length_mm: 20.0,
        };
        assert!((c.distance_mm(DVec3::new(7.0, 0.0, 0.0)) - 2.0).abs() < 1e-12);
        assert!((c.distance_mm(DVec3::new(0.0, 0.0, 13.0)) - 3.0).abs() < 1e-12);
        assert!((c.distance_mm(DVec3::new(4.0, 0.0, 0.0)) + 1.0).abs() < 1e-12);
        let b = Primitive::Cuboid {
            size_mm: DVec3::new(2.0, 4.0, 6.0),
        };
        assert!((b.distance_mm(DVec3::new(0.0, 3.0, 0.0)) - 1.0).abs() < 1e-12);
        assert!((b.distance_mm(DVec3::ZERO) + 1.0).abs() < 1e-12);
    }

    #[test]
    fn placement_moves_and_turns_the_shape() {
        let p = Placed {
            primitive: Primitive::Cylinder {
                radius_mm: 5.0,
                length_mm: 100.0,
            },
            offset_mm: DVec3::new(0.0, 0.0, 50.0),
            rotation: rotation_from_rpy_deg([0.0, 90.0, 0.0]),
        };
        // Turned to lie along x: a point 40 mm along x is inside, 8 mm above the axis is not.
        assert!(p.distance_mm(DVec3::new(40.0, 0.0, 50.0)) < 0.0);
        assert!((p.distance_mm(DVec3::new(0.0, 0.0, 58.0)) - 3.0).abs() < 1e-9);
    }
}
