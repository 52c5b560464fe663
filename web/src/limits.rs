//! Who may command the gripper, and how often: a bearer token off loopback, and a token
//! bucket for command endpoints (e-stop is exempt: a stop is never delayed).

use std::sync::Mutex;
use std::time::Instant;

use axum::http::HeaderMap;

/// Command requests allowed in a burst.
pub const BURST: f64 = 10.0;
/// Sustained command requests per second.
pub const PER_S: f64 = 5.0;

/// The token check.
#[derive(Debug, Clone, Default)]
pub struct Auth {
    /// The token commands must carry; `None` when the server is on loopback (no check).
    pub required: Option<String>,
}

impl Auth {
    /// Whether `headers` carry the token (always true when none is required).
    pub fn allows(&self, headers: &HeaderMap) -> bool {
        let Some(token) = &self.required else {
            return true;
        };
        headers
            .get(axum::http::header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "))
            .is_some_and(|given| constant_time_eq(given.as_bytes(), token.as_bytes()))
    }
}

/// Compare without an early exit, so timing does not tell how much of a guess was right.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// A token bucket.
#[derive(Debug)]
pub struct RateLimiter {
    state: Mutex<(f64, Instant)>,
    burst: f64,
    per_s: f64,
}

impl Default for RateLimiter {
    fn default() -> Self {
        Self::new(BURST, PER_S)
    }
}

impl RateLimiter {
    /// `burst` requests at once, `per_s` sustained.
    pub fn new(burst: f64, per_s: f64) -> Self {
        Self {
            state: Mutex::new((burst, Instant::now())),
            burst,
            per_s,
        }
    }

    /// Take one request's token; false when none is left.
    pub fn try_take(&self) -> bool {
        let Ok(mut s) = self.state.lock() else {
            return false;
        };
        let now = Instant::now();
        let refill = now.duration_since(s.1).as_secs_f64() * self.per_s;
        s.0 = (s.0 + refill).min(self.burst);
        s.1 = now;
        if s.0 >= 1.0 {
            s.0 -= 1.0;
            true
        } else {
            false
        }
    }
}
