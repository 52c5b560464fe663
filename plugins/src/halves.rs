//! One frame's work in two halves side by side, for the frame on the critical path.
//!
//! A set's last frame is processed on the run loop's thread while, as a rule, the other
//! cores are idle: the sensors' earlier frames were worked on as they arrived. The stages
//! whose rows are independent (block activity, LUT gradients, the depth solve's row and
//! column passes) split their rows in two ([`run_halves`]), the caller's thread taking one
//! half and a rayon worker the other. Each half computes its rows exactly as one pass over
//! all of them would, so the results are bit for bit those of one thread.
//!
//! What it takes for a worker to start a half within a few µs, measured on the 2-core VM
//! (docs/control.md, "The last frame on two cores"): a worker already awake, on another
//! core than the caller's.
//! - [`keep_a_worker_awake`]: waking a sleeping worker takes 30–40 µs as a rule and, on a
//!   VM whose idle virtual CPU the host has descheduled, up to milliseconds. So while the
//!   caller works on the frame, a worker on another CPU polls the pool (yielding its CPU
//!   to any thread that wants it), and the caller splits a stage only once one polls:
//!   until then it does the whole stage itself, as before. A worker on the caller's own
//!   CPU steps aside: polling there would only take the CPU from the caller.
//! - [`pin_global_pool`]: the kernel may queue a waking worker behind the busy caller on its
//!   core until a scheduler tick, while the other core idles (with unpinned workers, under
//!   4 in 10 halves were taken by the other worker within 300 µs; pinned, 99%).
//! - The caller spins, not parks, while the other half finishes (being woken costs tens of
//!   µs again), but only while that half is under way.
//!
//! Inside the pool (frames worked on ahead, the sensors of a set processed side by side,
//! `bench pipeline`) the stages are not split: the other workers have frames of their own
//! (`bench pipeline` measured 2% slower with its stages split).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Below this many pixels a stage keeps to one thread: handing half to a worker costs more
/// than it saves.
pub const SPLIT_MIN_PX: usize = 16_384;

/// How long a worker is kept awake at most (a frame takes 1–2 ms; a guard kept longer
/// lets the worker sleep).
const AWAKE_AT_MOST: Duration = Duration::from_millis(10);

/// Workers polling the pool now ([`keep_a_worker_awake`]).
static POLLING: AtomicUsize = AtomicUsize::new(0);

/// How long the caller waits, spinning, for a worker to start the other half before it
/// parks instead (a pool busy with other work takes it later).
const START_WAIT: Duration = Duration::from_micros(100);

/// How long the caller spins for a half under way before it parks instead.
const FINISH_WAIT: Duration = Duration::from_millis(2);

/// Whether a stage over `px` pixels is worth splitting: a large one, on a thread outside
/// the pool while a worker polls it.
pub fn worth_splitting(px: usize) -> bool {
    px >= SPLIT_MIN_PX
        && rayon::current_num_threads() > 1
        && rayon::current_thread_index().is_none()
        && (POLLING.load(Ordering::Acquire) > 0 || forced())
}

#[cfg(test)]
thread_local! {
    static FORCED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Tests: run `f` with every large stage split on this thread, polling worker or not.
#[cfg(test)]
pub(crate) fn with_stages_split<R>(f: impl FnOnce() -> R) -> R {
    FORCED.set(true);
    let out = f();
    FORCED.set(false);
    out
}

fn forced() -> bool {
    #[cfg(test)]
    {
        FORCED.get()
    }
    #[cfg(not(test))]
    {
        false
    }
}

/// The first half's share of `rows` rows, a multiple of `multiple` (so that rows
/// processed in pairs stay paired): about half, or all of them when not `split`.
pub fn first_half(rows: usize, multiple: usize, split: bool) -> usize {
    if split {
        (rows / 2) / multiple * multiple
    } else {
        rows
    }
}

/// Run `a` and `b`, side by side when `split` (the caller's thread takes `a`), else one
/// after the other; returns when both are done.
pub fn run_halves<A, B>(split: bool, a: A, b: B)
where
    A: FnOnce() + Send,
    B: FnOnce() + Send,
{
    if !split {
        a();
        b();
        return;
    }
    if rayon::current_thread_index().is_some() {
        rayon::join(a, b);
        return;
    }
    // Outside the pool `rayon::join` would hand both halves to the pool and park this
    // thread; here it works on `a` while a worker takes `b`.
    const QUEUED: u8 = 0;
    const RUNNING: u8 = 1;
    const DONE: u8 = 2;
    let state = AtomicU8::new(QUEUED);
    rayon::in_place_scope(|s| {
        s.spawn(|_| {
            state.store(RUNNING, Ordering::Release);
            b();
            state.store(DONE, Ordering::Release);
        });
        a();
        let since = Instant::now();
        loop {
            match state.load(Ordering::Acquire) {
                DONE => break,
                QUEUED if since.elapsed() > START_WAIT => break,
                _ if since.elapsed() > FINISH_WAIT => break,
                _ => std::hint::spin_loop(),
            }
        }
        // Leaving the scope waits (parked) for whatever is still under way.
    });
}

/// Keeps one rayon worker polling the pool (not asleep) until dropped, so the halves a
/// non-pool thread hands over start at once. Does nothing inside the pool or with one
/// thread.
#[derive(Debug)]
#[must_use = "the worker is kept awake until this is dropped"]
pub struct AwakeWorker {
    stop: Option<Arc<AtomicBool>>,
}

/// Keep a worker awake while the caller processes a frame (see [`AwakeWorker`]): every
/// worker is asked; those on the caller's own CPU step aside at once (one polling there
/// would only take the CPU from the caller), the others poll.
pub fn keep_a_worker_awake() -> AwakeWorker {
    if rayon::current_thread_index().is_some() || rayon::current_num_threads() < 2 {
        return AwakeWorker { stop: None };
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let caller_cpu = current_cpu();
    rayon::spawn_broadcast(move |_| {
        // Let go already (a broadcast that waited behind other work), or on the caller's
        // CPU: nothing to do.
        if flag.load(Ordering::Acquire) || (caller_cpu.is_some() && current_cpu() == caller_cpu) {
            return;
        }
        let since = Instant::now();
        let _polling = Polling::start();
        while !flag.load(Ordering::Acquire) && since.elapsed() < AWAKE_AT_MOST {
            // Work found in the pool (a half, another sensor's frame) is done meanwhile;
            // else the CPU is offered to any other thread that wants it, and polling goes
            // on at once when none does.
            if rayon::yield_now() != Some(rayon::Yield::Executed) {
                std::thread::yield_now();
            }
        }
    });
    AwakeWorker { stop: Some(stop) }
}

/// The CPU this thread runs on now, where the platform says.
fn current_cpu() -> Option<usize> {
    #[cfg(target_os = "linux")]
    {
        nix::sched::sched_getcpu().ok()
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Counts a worker in [`POLLING`] while it lives.
struct Polling;

impl Polling {
    fn start() -> Self {
        POLLING.fetch_add(1, Ordering::AcqRel);
        Self
    }
}

impl Drop for Polling {
    fn drop(&mut self) {
        POLLING.fetch_sub(1, Ordering::AcqRel);
    }
}

impl Drop for AwakeWorker {
    fn drop(&mut self) {
        if let Some(stop) = &self.stop {
            stop.store(true, Ordering::Release);
        }
    }
}

/// Errors from [`pin_global_pool`].
#[derive(Debug, thiserror::Error)]
pub enum PinError {
    /// The global pool was already built (it must be set up before any parallel work).
    #[error("rayon's global pool was already built: {0}")]
    AlreadyBuilt(#[from] rayon::ThreadPoolBuildError),
    /// The process's CPU set could not be read.
    #[error("reading the process's CPU affinity: {0}")]
    Affinity(String),
}

/// Build rayon's global pool with one worker per CPU the process may run on, each pinned
/// to its own CPU (see the module's notes). Call it before any parallel work; a program
/// that embeds the pipelines may call it or build its own pool. Returns the CPUs used.
#[cfg(target_os = "linux")]
pub fn pin_global_pool() -> Result<Vec<usize>, PinError> {
    use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
    use nix::unistd::Pid;
    let allowed =
        sched_getaffinity(Pid::from_raw(0)).map_err(|e| PinError::Affinity(e.to_string()))?;
    let cpus: Vec<usize> = (0..CpuSet::count())
        .filter(|c| allowed.is_set(*c).unwrap_or(false))
        .collect();
    let pinned = cpus.clone();
    rayon::ThreadPoolBuilder::new()
        .num_threads(cpus.len().max(1))
        .thread_name(|i| format!("gelgrip-pool-{i}"))
        .start_handler(move |i| {
            let mut one = CpuSet::new();
            if let Some(cpu) = pinned.get(i)
                && one.set(*cpu).is_ok()
            {
                // Unpinned is still correct, only slower to start a half: say so, once.
                if let Err(e) = sched_setaffinity(Pid::from_raw(0), &one) {
                    tracing::warn!(cpu, error = %e, "could not pin a pool worker");
                }
            }
        })
        .build_global()?;
    Ok(cpus)
}

/// Without CPU affinity (not Linux): the global pool as rayon builds it.
#[cfg(not(target_os = "linux"))]
pub fn pin_global_pool() -> Result<Vec<usize>, PinError> {
    rayon::ThreadPoolBuilder::new().build_global()?;
    Ok(Vec::new())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    fn count_both(split: bool) -> usize {
        let n = AtomicUsize::new(0);
        run_halves(
            split,
            || {
                n.fetch_add(1, Ordering::SeqCst);
            },
            || {
                n.fetch_add(10, Ordering::SeqCst);
            },
        );
        n.load(Ordering::SeqCst)
    }

    #[test]
    fn both_halves_run_inside_and_outside_the_pool() {
        for split in [false, true] {
            assert_eq!(count_both(split), 11);
            let _awake = keep_a_worker_awake();
            assert_eq!(count_both(split), 11);
            assert_eq!(rayon::scope(|_| count_both(split)), 11);
        }
    }

    #[test]
    fn stages_split_only_outside_the_pool_when_asked() {
        let px = SPLIT_MIN_PX;
        assert!(!rayon::scope(|_| with_stages_split(|| worth_splitting(px))));
        assert!(!with_stages_split(|| worth_splitting(px - 1)));
        assert_eq!(
            with_stages_split(|| worth_splitting(px)),
            rayon::current_num_threads() > 1
        );
    }

    #[test]
    fn the_first_half_keeps_pairs_together() {
        assert_eq!(first_half(240, 2, true), 120);
        assert_eq!(first_half(242, 2, true), 120);
        assert_eq!(first_half(7, 2, true), 2);
        assert_eq!(first_half(1, 2, true), 0);
        assert_eq!(first_half(240, 2, false), 240);
    }
}
