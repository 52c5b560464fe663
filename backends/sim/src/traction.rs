//! Tangential load on the held object's contacts: how it is shared between the pads, how
//! much of each contact still sticks (partial slip), and how far the gel's surface moves.
//!
//! Each contact carries a normal load P and a tangential load Q along the scene's
//! `slip_dir`. The contacts share the object's tangential load in proportion to their
//! tangential stiffness (Mindlin: 8 G* a, so in proportion to the contact radius a), each
//! up to its friction limit μP (less the share of P that acts along `slip_dir`); what a
//! saturated contact cannot carry goes to the others. Below μP a contact sticks in a central
//! zone and slides in the annulus around it (Cattaneo–Mindlin): for a ball the stick radius
//! is c = a (1 − Q/μP)^(1/3). Other shapes use the same law with a the radius of a disc of
//! their contact area (an equivalent circle: the law is Hertzian, and the simulator's other
//! shapes press convex, smooth caps). Gross slip begins when the contacts together cannot
//! carry the load: the stick zones are gone and the object moves against the pads.
//!
//! The gel's surface under a contact moves with the object where it sticks, by Mindlin's
//! compliance δ = U (1 − (c/a)²) with U = 3μP(2 − ν)/(16 G a), the shift at full slip.
//! Cattaneo's traction is a Hertz-type traction over the contact less one over the stick
//! zone, and so is the shift: U/2 · (H(r/a) − (c/a)² H(r/c)), with H the surface profile of
//! an elastic half-space under a Hertz-type load of radius 1 ([`hertz_profile`], shared with
//! the pipeline's slip estimate; the
//! shift along the load, averaged over directions). It is δ, uniform, in the stick zone,
//! smaller where the contact slides, and falls off as 1/r outside the contact.

pub use gelgrip_controller::markers::hertz_profile;

/// The gel's shear modulus, N/mm² (a silicone elastomer of Young's modulus 0.3 MPa).
pub const GEL_SHEAR_MODULUS_N_PER_MM2: f64 = 0.1;
/// The gel's Poisson ratio (an elastomer: nearly incompressible).
pub const GEL_POISSON_RATIO: f64 = 0.5;
/// A contact slips incipiently once its stick ratio c/a is below this.
pub const INCIPIENT_STICK_RATIO: f64 = 0.9;
/// Gross slip: the object has moved this far against the pads since the load began, mm.
pub const GROSS_MOTION_MM: f64 = 0.1;

/// One contact's tangential state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Traction {
    /// Normal load P, N.
    pub normal_n: f64,
    /// Tangential load Q along `slip_dir`, N (its magnitude).
    pub tangential_n: f64,
    /// What friction can carry here, μP across `slip_dir`, N.
    pub capacity_n: f64,
    /// Contact radius a (of a disc of the contact's area), mm.
    pub contact_radius_mm: f64,
    /// Stick ratio c/a: 1 when unloaded, 0 when the whole contact slides.
    pub stick_ratio: f64,
    /// How far the gel's surface in the stick zone has moved with the object, mm (δ).
    pub shift_mm: f64,
}

impl Traction {
    /// The state of a contact of `contact_radius_mm` carrying `tangential_n` of its
    /// `capacity_n` under `normal_n`. Non-finite or negative inputs count as 0; no output
    /// is NaN or infinite.
    pub fn new(normal_n: f64, tangential_n: f64, capacity_n: f64, contact_radius_mm: f64) -> Self {
        let finite = |v: f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
        let (p, cap, a) = (
            finite(normal_n),
            finite(capacity_n),
            finite(contact_radius_mm),
        );
        let q = finite(tangential_n).min(cap);
        let load_share = if cap > 0.0 { q / cap } else { 0.0 };
        let stick_ratio = if cap > 0.0 && a > 0.0 {
            (1.0 - load_share).max(0.0).cbrt()
        } else {
            // No contact, or no friction: it sticks while unloaded, and slides once loaded.
            if q == 0.0 { 1.0 } else { 0.0 }
        };
        let shift_mm = full_slip_shift_mm(cap, a) * (1.0 - stick_ratio * stick_ratio);
        let stick_ratio = if shift_mm.is_finite() {
            stick_ratio
        } else {
            1.0
        };
        let shift_mm = if shift_mm.is_finite() { shift_mm } else { 0.0 };
        Self {
            normal_n: p,
            tangential_n: q,
            capacity_n: cap,
            contact_radius_mm: a,
            stick_ratio,
            shift_mm,
        }
    }

    /// Whether the contact slips incipiently (its stick ratio under [`INCIPIENT_STICK_RATIO`]).
    pub fn incipient(&self) -> bool {
        self.contact_radius_mm > 0.0 && self.stick_ratio < INCIPIENT_STICK_RATIO
    }

    /// The gel surface's shift along `slip_dir` at `r_mm` from the contact's centre, mm:
    /// δ inside the stick zone, less beyond it, falling off outside the contact.
    pub fn surface_shift_mm(&self, r_mm: f64) -> f64 {
        let a = self.contact_radius_mm;
        if !(r_mm.is_finite() && a > 0.0) {
            return 0.0;
        }
        let shape = gelgrip_controller::markers::cattaneo_shift(r_mm.abs() / a, self.stick_ratio);
        let shift = 0.5 * full_slip_shift_mm(self.capacity_n, a) * shape;
        if shift.is_finite() { shift } else { 0.0 }
    }
}

/// Mindlin's tangential shift at full slip, U = 3μP(2 − ν)/(16 G a), mm (`capacity_n` is
/// μP); 0 without a contact.
fn full_slip_shift_mm(capacity_n: f64, contact_radius_mm: f64) -> f64 {
    if contact_radius_mm <= 0.0 {
        return 0.0;
    }
    3.0 * capacity_n * (2.0 - GEL_POISSON_RATIO)
        / (16.0 * GEL_SHEAR_MODULUS_N_PER_MM2 * contact_radius_mm)
}

/// One contact's grip on the object, for [`share_load`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactGrip {
    /// What friction can carry, N.
    pub capacity_n: f64,
    /// Contact radius, mm (the tangential stiffness is in proportion to it).
    pub contact_radius_mm: f64,
}

/// The tangential load `load_n` shared between `contacts`: in proportion to their contact
/// radii, each up to its capacity, what a saturated contact cannot carry going to the
/// others. Returns each contact's share, N, and whether the contacts together cannot carry
/// the load (gross slip: then every contact carries its capacity).
pub fn share_load(load_n: f64, contacts: &[ContactGrip]) -> (Vec<f64>, bool) {
    let load = if load_n.is_finite() {
        load_n.abs()
    } else {
        0.0
    };
    let usable = |g: &ContactGrip| {
        let cap = if g.capacity_n.is_finite() {
            g.capacity_n.max(0.0)
        } else {
            0.0
        };
        let a = if g.contact_radius_mm.is_finite() {
            g.contact_radius_mm.max(0.0)
        } else {
            0.0
        };
        (cap, a)
    };
    let mut shares = vec![0.0; contacts.len()];
    let total_capacity: f64 = contacts.iter().map(|g| usable(g).0).sum();
    if load >= total_capacity {
        for (s, g) in shares.iter_mut().zip(contacts) {
            *s = usable(g).0;
        }
        return (
            shares,
            load > total_capacity || load > 0.0 && total_capacity == 0.0,
        );
    }
    // Water-filling: every round, the unsaturated contacts take the rest in proportion to
    // their radii; those it would overfill are capped and leave. At most one round per
    // contact.
    let mut open: Vec<usize> = (0..contacts.len())
        .filter(|&i| usable(&contacts[i]).0 > 0.0)
        .collect();
    let mut rest = load;
    while rest > 0.0 && !open.is_empty() {
        let weights: Vec<f64> = open.iter().map(|&i| usable(&contacts[i]).1).collect();
        let sum: f64 = weights.iter().sum();
        let weight = |k: usize| {
            if sum > 0.0 {
                weights[k] / sum
            } else {
                1.0 / open.len() as f64
            }
        };
        let full: Vec<usize> = (0..open.len())
            .filter(|&k| rest * weight(k) >= usable(&contacts[open[k]]).0)
            .collect();
        if full.is_empty() {
            for k in 0..open.len() {
                shares[open[k]] = rest * weight(k);
            }
            break;
        }
        for &k in &full {
            let cap = usable(&contacts[open[k]]).0;
            shares[open[k]] = cap;
            rest -= cap;
        }
        let mut k = 0;
        open.retain(|_| {
            k += 1;
            !full.contains(&(k - 1))
        });
    }
    (shares, false)
}

/// The truth of a hold under load: when the contacts began to slip, and how far the object
/// has moved against the pads since the load began.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SlipTruth {
    /// When a contact's stick ratio first fell below [`INCIPIENT_STICK_RATIO`], s.
    pub incipient_s: Option<f64>,
    /// When the object had first moved [`GROSS_MOTION_MM`] against the pads, s.
    pub gross_s: Option<f64>,
    /// The object's slip when the load began (the first loaded step), mm.
    pub slip_at_load_mm: Option<f64>,
    /// The object's motion against the pads since the load began, mm.
    pub motion_mm: f64,
}

impl SlipTruth {
    /// One step at `t_s`: the object's slip `slip_mm` and its contacts' `traction`.
    pub fn observe(&mut self, t_s: f64, slip_mm: f64, traction: &[Traction]) {
        let loaded = traction.iter().any(|t| t.tangential_n > 0.0);
        let from = match self.slip_at_load_mm {
            Some(from) => from,
            None if loaded => *self.slip_at_load_mm.insert(slip_mm),
            None => return,
        };
        self.motion_mm = if (slip_mm - from).is_finite() {
            (slip_mm - from).abs()
        } else {
            0.0
        };
        if self.incipient_s.is_none() && traction.iter().any(Traction::incipient) {
            self.incipient_s = Some(t_s);
        }
        if self.gross_s.is_none() && self.motion_mm > GROSS_MOTION_MM {
            self.gross_s = Some(t_s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stick_ratio_follows_cattaneo_mindlin_from_full_stick_to_none() {
        let free = Traction::new(1.0, 0.0, 0.9, 2.0);
        assert_eq!((free.stick_ratio, free.shift_mm), (1.0, 0.0));
        assert!(!free.incipient());
        let half = Traction::new(1.0, 0.45, 0.9, 2.0);
        assert!((half.stick_ratio - 0.5f64.cbrt()).abs() < 1e-12);
        let u = 3.0 * 0.9 * 1.5 / (16.0 * GEL_SHEAR_MODULUS_N_PER_MM2 * 2.0);
        assert!((half.shift_mm - u * (1.0 - 0.5f64.powf(2.0 / 3.0))).abs() < 1e-12);
        let limit = Traction::new(1.0, 0.9, 0.9, 2.0);
        assert_eq!(limit.stick_ratio, 0.0);
        assert!((limit.shift_mm - u).abs() < 1e-12);
        // A stick ratio of 0.9 is a load of 1 − 0.9³ = 27.1% of the limit.
        assert!(!Traction::new(1.0, 0.9 * 0.27, 0.9, 2.0).incipient());
        assert!(Traction::new(1.0, 0.9 * 0.272, 0.9, 2.0).incipient());
    }

    #[test]
    fn extremes_give_no_nan_or_infinity() {
        let odd = [
            0.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e-300,
            1e300,
        ];
        for p in odd {
            for q in odd {
                for cap in odd {
                    for a in odd {
                        let t = Traction::new(p, q, cap, a);
                        let all = [
                            t.normal_n,
                            t.tangential_n,
                            t.capacity_n,
                            t.stick_ratio,
                            t.shift_mm,
                        ];
                        assert!(
                            all.iter().all(|v| v.is_finite()),
                            "{p} {q} {cap} {a}: {t:?}"
                        );
                        assert!((0.0..=1.0).contains(&t.stick_ratio));
                        for r in odd {
                            assert!(t.surface_shift_mm(r).is_finite(), "{t:?} at {r}");
                        }
                    }
                }
            }
        }
        for g in odd {
            let grips = [ContactGrip {
                capacity_n: g,
                contact_radius_mm: g,
            }; 3];
            for load in odd {
                let (shares, _) = share_load(load, &grips);
                assert!(shares.iter().all(|s| s.is_finite() && *s >= 0.0));
            }
        }
    }

    #[test]
    fn the_surface_moves_with_the_object_where_it_sticks_and_less_beyond() {
        let t = Traction::new(1.0, 0.6, 0.9, 2.0);
        let c = t.stick_ratio * 2.0;
        for r in [0.0, 0.5 * c, 0.99 * c] {
            assert!((t.surface_shift_mm(r) - t.shift_mm).abs() < 1e-12, "{r}");
        }
        let (in_slip, at_rim, outside, far) = (
            t.surface_shift_mm(0.5 * (c + 2.0)),
            t.surface_shift_mm(2.0),
            t.surface_shift_mm(4.0),
            t.surface_shift_mm(400.0),
        );
        assert!(t.shift_mm > in_slip && in_slip > at_rim && at_rim > outside);
        assert!(outside > far && far > 0.0);
        // At full slip the whole contact carries μp: U at the centre, U/2 at the rim.
        let full = Traction::new(1.0, 0.9, 0.9, 2.0);
        assert!((full.surface_shift_mm(0.0) - full.shift_mm).abs() < 1e-12);
        assert!((full.surface_shift_mm(2.0) - 0.5 * full.shift_mm).abs() < 1e-12);
        // The profile: continuous and smooth at 1, and 8/(3πρ) far away.
        assert!((hertz_profile(1.0 + 1e-9) - 1.0).abs() < 1e-6);
        let slope = |r: f64| (hertz_profile(r + 1e-6) - hertz_profile(r - 1e-6)) / 2e-6;
        assert!((slope(1.0 - 1e-4) - slope(1.0 + 1e-4)).abs() < 0.05);
        let rho = 1e3;
        assert!((hertz_profile(rho) * rho - 8.0 / (3.0 * std::f64::consts::PI)).abs() < 1e-3);
    }

    #[test]
    fn the_truth_times_incipient_then_gross_slip_from_the_load_on() {
        let mut truth = SlipTruth::default();
        truth.observe(0.0, 5.0, &[Traction::default()]);
        assert_eq!(truth, SlipTruth::default());
        truth.observe(1.0, 5.0, &[Traction::new(1.0, 0.1, 0.9, 2.0)]);
        assert_eq!(
            (truth.slip_at_load_mm, truth.incipient_s),
            (Some(5.0), None)
        );
        truth.observe(2.0, 5.05, &[Traction::new(1.0, 0.5, 0.9, 2.0)]);
        assert_eq!((truth.incipient_s, truth.gross_s), (Some(2.0), None));
        truth.observe(3.0, 4.8, &[Traction::new(1.0, 0.9, 0.9, 2.0)]);
        assert_eq!((truth.incipient_s, truth.gross_s), (Some(2.0), Some(3.0)));
        assert!((truth.motion_mm - 0.2).abs() < 1e-12);
    }

    #[test]
    fn the_load_is_shared_by_stiffness_up_to_each_contacts_limit() {
        let grips = [
            ContactGrip {
                capacity_n: 1.0,
                contact_radius_mm: 1.0,
            },
            ContactGrip {
                capacity_n: 0.2,
                contact_radius_mm: 3.0,
            },
            ContactGrip {
                capacity_n: 2.0,
                contact_radius_mm: 0.0,
            },
        ];
        // 0.4 N: in proportion 1:3 (the third has no radius): 0.1 and 0.3, but the second
        // can carry 0.2, so the first takes the rest.
        let (shares, gross) = share_load(0.4, &grips);
        assert!(!gross);
        assert!((shares[1] - 0.2).abs() < 1e-12);
        assert!((shares.iter().sum::<f64>() - 0.4).abs() < 1e-12);
        let (shares, gross) = share_load(-5.0, &grips);
        assert!(gross);
        assert_eq!(shares, vec![1.0, 0.2, 2.0]);
        let (shares, gross) = share_load(3.2, &grips);
        assert!(!gross);
        assert!((shares.iter().sum::<f64>() - 3.2).abs() < 1e-9);
        assert_eq!(share_load(0.0, &grips), (vec![0.0, 0.0, 0.0], false));
        assert_eq!(share_load(1.0, &[]), (vec![], true));
    }
}
