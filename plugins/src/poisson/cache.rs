//! A bounded cache of Poisson plans keyed by window size: a contact window's size changes
//! from set to set over a long hold, and a plan per size ever seen would grow without bound
//! (over 200 plans in a two-minute grasp hold). The least recently used plan goes when a
//! new size comes and the cache is full, and its allocation serves the new plan; a plan
//! rebuilt later solves bit for bit as before. The plans solve in one set of buffers, the
//! cache's, grown to the largest window (a plan's own would be as large as its window, each).

use super::{PoissonPlan, Real, SolveBuffers, Solver};

/// Plans kept per cache: a hold's windows stay within a few sizes of each other.
pub const PLAN_CACHE_CAPACITY: usize = 8;

/// Up to [`PLAN_CACHE_CAPACITY`] plans, the least recently used evicted first.
#[derive(Debug)]
pub struct PlanCache<T: Real> {
    /// Each plan with its size `(height, width)` and the use it was last taken at.
    plans: Vec<((usize, usize), u64, PoissonPlan<T>)>,
    uses: u64,
    capacity: usize,
    /// The scratch every plan here solves in (one window at a time).
    buffers: SolveBuffers<T>,
}

impl<T: Real> Default for PlanCache<T> {
    fn default() -> Self {
        Self::with_capacity(PLAN_CACHE_CAPACITY)
    }
}

impl<T: Real> PlanCache<T> {
    /// A cache of at most `capacity` plans (at least one).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            plans: Vec::new(),
            uses: 0,
            capacity: capacity.max(1),
            buffers: SolveBuffers::default(),
        }
    }

    /// The plan of `solver` for a `height`×`width` window, built if it is not cached
    /// (evicting the least recently used when full).
    pub fn plan(&mut self, solver: Solver, height: usize, width: usize) -> &mut PoissonPlan<T> {
        let i = self.index_of(solver, height, width);
        &mut self.plans[i].2
    }

    /// Solve `height × width` gradients `gx`, `gy` into `z` with the cached plan of `solver`
    /// (planned if new), in the cache's own buffers: [`PoissonPlan::solve`]'s result, bit for
    /// bit, with no window-sized allocation once the buffers have grown to the largest
    /// window.
    pub fn solve(
        &mut self,
        solver: Solver,
        (height, width): (usize, usize),
        (gx, gy): (&[T], &[T]),
        z: &mut [T],
    ) {
        let i = self.index_of(solver, height, width);
        self.plans[i].2.solve_in(&mut self.buffers, gx, gy, z);
    }

    /// Where the plan of `solver` for `height × width` is, built if it was not cached.
    fn index_of(&mut self, solver: Solver, height: usize, width: usize) -> usize {
        self.uses += 1;
        let key = (height, width);
        let found = self
            .plans
            .iter()
            .position(|(k, _, p)| *k == key && p.solver() == solver);
        let i = match found {
            Some(i) => i,
            None => {
                let oldest = (self.plans.len() >= self.capacity)
                    .then(|| (0..self.plans.len()).min_by_key(|&i| self.plans[i].1))
                    .flatten();
                // The evicted plan's multipliers' allocation serves the new one.
                let plan = match oldest {
                    Some(i) => self.plans.swap_remove(i).2.replanned(solver, height, width),
                    None => PoissonPlan::new(solver, height, width),
                };
                tracing::debug!(height, width, cached = self.plans.len(), "new Poisson plan");
                self.plans.push((key, 0, plan));
                self.plans.len() - 1
            }
        };
        self.plans[i].1 = self.uses;
        i
    }

    /// Plans cached now.
    pub fn len(&self) -> usize {
        self.plans.len()
    }

    /// Whether none is cached.
    pub fn is_empty(&self) -> bool {
        self.plans.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cache_stays_bounded_and_a_rebuilt_plan_solves_as_before() {
        let mut cache = PlanCache::<f32>::with_capacity(3);
        let (h, w) = (9, 13);
        let gx: Vec<f32> = (0..h * w)
            .map(|i| ((i * 7) % 11) as f32 / 11.0 - 0.5)
            .collect();
        let gy: Vec<f32> = (0..h * w)
            .map(|i| ((i * 5) % 13) as f32 / 13.0 - 0.5)
            .collect();
        let mut first = vec![0.0f32; h * w];
        cache.plan(Solver::Dst, h, w).solve(&gx, &gy, &mut first);
        for size in 10..40 {
            cache.plan(Solver::Dst, size, size + 1);
            assert!(cache.len() <= 3, "{}", cache.len());
        }
        let mut again = vec![0.0f32; h * w];
        cache.solve(Solver::Dst, (h, w), (&gx, &gy), &mut again);
        assert!(
            first
                .iter()
                .zip(&again)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "bit for bit"
        );
        assert!(again.iter().all(|v| v.is_finite()));
        // The most recently used survive: (h, w) was just taken, so it stays.
        cache.plan(Solver::Dst, 50, 50);
        cache.plan(Solver::Dst, 51, 51);
        let before = cache.len();
        cache.plan(Solver::Dst, h, w);
        assert_eq!(cache.len(), before);
    }

    /// A plan made from another's buffers (smaller, larger, the other solver) solves as a
    /// fresh one, bit for bit.
    #[test]
    fn a_replanned_plan_solves_as_a_new_one() {
        let sizes = [(40, 56), (9, 13), (64, 48), (17, 17), (3, 5)];
        let mut reused = PoissonPlan::<f32>::new(Solver::Dct, 33, 21);
        for (k, &(h, w)) in sizes.iter().enumerate() {
            for solver in [Solver::Dst, Solver::Dct] {
                let gx: Vec<f32> = (0..h * w)
                    .map(|i| ((i * 7 + k) % 11) as f32 / 11.0 - 0.5)
                    .collect();
                let gy: Vec<f32> = (0..h * w)
                    .map(|i| ((i * 5 + k) % 13) as f32 / 13.0 - 0.5)
                    .collect();
                let (mut fresh, mut again) = (vec![0.0f32; h * w], vec![0.0f32; h * w]);
                PoissonPlan::new(solver, h, w).solve(&gx, &gy, &mut fresh);
                reused = reused.replanned(solver, h, w);
                reused.solve(&gx, &gy, &mut again);
                let same = fresh
                    .iter()
                    .zip(&again)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "{solver:?} {h}x{w}");
                assert!(again.iter().all(|v| v.is_finite()), "{solver:?} {h}x{w}");
            }
        }
    }
}
