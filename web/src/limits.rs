//! Who may use the dashboard, and how often: off loopback a bearer token or the session
//! cookie its login sets, for every route; and a token bucket for command endpoints and the
//! login (e-stop is exempt: a stop is never delayed).

use std::sync::Mutex;
use std::time::Instant;

use axum::http::HeaderMap;

/// Command requests allowed in a burst.
pub const BURST: f64 = 10.0;
/// Sustained command requests per second.
pub const PER_S: f64 = 5.0;

/// Name of the session cookie the login sets.
pub const SESSION_COOKIE: &str = "gelgrip_session";

/// The token check: off loopback, a request carries the token (`Authorization: Bearer`) or
/// the session cookie that logging in with it set.
#[derive(Debug, Clone, Default)]
pub struct Auth {
    /// The token; `None` when the server is on loopback (no check).
    token: Option<String>,
    /// The session cookie's value: random, made when the server starts, so the cookie is
    /// not the token (`None`: no random source, so no login; the header still works).
    session: Option<String>,
}

impl Auth {
    /// Require `token`.
    pub fn with_token(token: String) -> Self {
        Self {
            token: Some(token),
            session: random_hex(16),
        }
    }

    /// Whether a token is required.
    pub fn is_required(&self) -> bool {
        self.token.is_some()
    }

    /// Whether `given` is the token.
    pub fn is_token(&self, given: &str) -> bool {
        self.token
            .as_ref()
            .is_some_and(|t| constant_time_eq(given.as_bytes(), t.as_bytes()))
    }

    /// The `Set-Cookie` value that logs a browser in (`None`: no login possible).
    pub fn session_cookie(&self) -> Option<String> {
        self.session
            .as_ref()
            .map(|v| format!("{SESSION_COOKIE}={v}; HttpOnly; SameSite=Strict; Path=/"))
    }

    /// Whether `headers` carry the token or the session cookie (always true when none is
    /// required).
    pub fn allows(&self, headers: &HeaderMap) -> bool {
        if self.token.is_none() {
            return true;
        }
        let bearer = headers
            .get_all(axum::http::header::AUTHORIZATION)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .filter_map(|v| v.strip_prefix("Bearer "))
            .any(|given| self.is_token(given));
        bearer || self.has_session(headers)
    }

    fn has_session(&self, headers: &HeaderMap) -> bool {
        let Some(session) = &self.session else {
            return false;
        };
        headers
            .get_all(axum::http::header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .filter_map(|c| c.trim().split_once('='))
            .any(|(k, v)| k == SESSION_COOKIE && constant_time_eq(v.as_bytes(), session.as_bytes()))
    }
}

/// `bytes` random bytes as hex, from the operating system.
fn random_hex(bytes: usize) -> Option<String> {
    let mut buf = vec![0u8; bytes];
    getrandom::fill(&mut buf).ok()?;
    Some(buf.iter().map(|b| format!("{b:02x}")).collect())
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
