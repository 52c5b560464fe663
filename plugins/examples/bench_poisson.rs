//! The depth solve's cost by window size: `cargo run --release -p gelgrip-plugins --example
//! bench_poisson`. For each size the runtime's f32 DCT-II solve (and the DST-I solve) runs
//! 300 times on fixed gradients after 20 warm-up solves; the table gives the median and
//! the 10th percentile in ms, and ns per cell. The sizes are the depth windows a grasp's
//! contacts make (multiples of 16 px) and the whole 320 × 240 frame.

use std::time::Instant;

use gelgrip_plugins::poisson::{PoissonPlan, Solver};

const SIZES: [(usize, usize); 8] = [
    (176, 192),
    (192, 192),
    (240, 240),
    (240, 256),
    (240, 272),
    (240, 288),
    (256, 256),
    (240, 320),
];

fn time_ms(solver: Solver, h: usize, w: usize) -> (f64, f64) {
    let mut plan = PoissonPlan::<f32>::new(solver, h, w);
    let gx: Vec<f32> = (0..h * w)
        .map(|i| ((i * 7919) % 101) as f32 * 1e-3)
        .collect();
    let gy: Vec<f32> = (0..h * w)
        .map(|i| ((i * 104_729) % 97) as f32 * 1e-3)
        .collect();
    let mut z = vec![0.0f32; h * w];
    for _ in 0..20 {
        plan.solve(&gx, &gy, &mut z);
    }
    let mut ms: Vec<f64> = (0..300)
        .map(|_| {
            let t = Instant::now();
            plan.solve(&gx, &gy, &mut z);
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    (ms[ms.len() / 2], ms[ms.len() / 10])
}

fn main() {
    println!(
        "| window (h × w) | DCT-II median (ms) | p10 (ms) | ns per cell | DST-I median (ms) |"
    );
    println!("|---|---|---|---|---|");
    for (h, w) in SIZES {
        let (dct, dct_p10) = time_ms(Solver::Dct, h, w);
        let (dst, _) = time_ms(Solver::Dst, h, w);
        println!(
            "| {h} × {w} | {dct:.3} | {dct_p10:.3} | {:.1} | {dst:.3} |",
            dct * 1e6 / (h * w) as f64
        );
    }
}
