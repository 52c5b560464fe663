//! Injected time: a real monotonic clock and a virtual clock for deterministic runs.
//!
//! Times are host microseconds since the clock was created (`u64`, no wrap in practice).

use std::fmt::Debug;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use async_trait::async_trait;

/// Which kind of clock drives a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockKind {
    /// Wall-clock time; sleeps really wait.
    Real,
    /// Virtual time; a sleep advances the clock at once.
    Virtual,
}

impl ClockKind {
    /// A new clock of this kind, starting now (real) or at zero (virtual).
    pub fn new_clock(self) -> Arc<dyn Clock> {
        match self {
            Self::Real => Arc::new(RealClock::new()),
            Self::Virtual => VirtualClock::new(),
        }
    }
}

/// A source of host time that can also wait.
#[async_trait]
pub trait Clock: Send + Sync + Debug {
    /// Host time now, in µs.
    fn now_us(&self) -> u64;
    /// Wait until `deadline_us` (an absolute time, so periodic loops do not drift).
    async fn sleep_until(&self, deadline_us: u64);
    /// Real or virtual.
    fn kind(&self) -> ClockKind;
}

/// Tokio's timer has a 1 ms resolution; the last stretch before a deadline is slept with the
/// OS sleep (about 60 µs precision on Linux), which blocks the calling worker for at most
/// this long.
const FINE_SLEEP_WINDOW_US: u64 = 1_500;

/// The host's monotonic clock.
#[derive(Debug, Clone)]
pub struct RealClock {
    start: Instant,
}

impl RealClock {
    /// A clock whose zero is now.
    pub fn new() -> Self {
        Self {
            start: Instant::now(),
        }
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

#[async_trait]
impl Clock for RealClock {
    fn now_us(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_micros()).unwrap_or(u64::MAX)
    }

    async fn sleep_until(&self, deadline_us: u64) {
        let now = self.now_us();
        if deadline_us > now + FINE_SLEEP_WINDOW_US {
            let coarse = self.start + Duration::from_micros(deadline_us - FINE_SLEEP_WINDOW_US);
            tokio::time::sleep_until(coarse.into()).await;
        }
        let now = self.now_us();
        if deadline_us > now {
            std::thread::sleep(Duration::from_micros(deadline_us - now));
        }
    }

    fn kind(&self) -> ClockKind {
        ClockKind::Real
    }
}

/// Virtual time: starts at 0 and only moves when someone sleeps or advances it.
#[derive(Debug, Default)]
pub struct VirtualClock {
    now_us: AtomicU64,
}

impl VirtualClock {
    /// A virtual clock at time 0.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Move time forward by `us`.
    pub fn advance(&self, us: u64) {
        self.now_us.fetch_add(us, Ordering::SeqCst);
    }
}

#[async_trait]
impl Clock for VirtualClock {
    fn now_us(&self) -> u64 {
        self.now_us.load(Ordering::SeqCst)
    }

    async fn sleep_until(&self, deadline_us: u64) {
        self.now_us.fetch_max(deadline_us, Ordering::SeqCst);
        tokio::task::yield_now().await;
    }

    fn kind(&self) -> ClockKind {
        ClockKind::Virtual
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn virtual_sleep_moves_time_without_waiting() {
        let clock = VirtualClock::new();
        let wall = Instant::now();
        clock.sleep_until(5_000_000).await;
        assert_eq!(clock.now_us(), 5_000_000);
        clock.sleep_until(1_000).await; // never goes backwards
        assert_eq!(clock.now_us(), 5_000_000);
        assert!(wall.elapsed() < Duration::from_secs(1));
    }

    #[tokio::test]
    async fn real_sleep_reaches_its_deadline() {
        let clock = RealClock::new();
        let deadline = clock.now_us() + 3_000;
        clock.sleep_until(deadline).await;
        assert!(clock.now_us() >= deadline);
    }
}
