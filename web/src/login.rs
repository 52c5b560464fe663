//! The token off loopback, for every route: [`require_token`] guards the page, the state,
//! the events, the streams, the frames and the commands alike; `GET /login` is a form that
//! takes the token once, and `POST /login` checks it and sets an `HttpOnly`,
//! `SameSite=Strict` session cookie, so a browser's streams and images work without a
//! header. On loopback nothing is checked.

use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use crate::routes::{ApiError, AppState};

/// What a request without the token is told.
pub const NEEDS_TOKEN: &str = "this server is bound off loopback: every route needs the token, \
     as `Authorization: Bearer <token>` or by logging in at /login";

/// The login routes (outside the guard).
pub(crate) fn routes() -> Router<AppState> {
    Router::new().route("/login", get(login_page).post(log_in))
}

/// The guard: pass a request that carries the token or the session, refuse the rest with
/// 401 (the page's route answers with the login form, still 401).
pub(crate) async fn require_token(State(s): State<AppState>, req: Request, next: Next) -> Response {
    if s.auth.allows(req.headers()) {
        return next.run(req).await;
    }
    if req.uri().path() == "/" {
        return form(StatusCode::UNAUTHORIZED, "");
    }
    ApiError::new(StatusCode::UNAUTHORIZED, NEEDS_TOKEN).into_response()
}

async fn login_page(State(s): State<AppState>) -> Response {
    if !s.auth.is_required() {
        return redirect_home(None);
    }
    form(StatusCode::OK, "")
}

struct LoginForm {
    token: String,
}

async fn log_in(State(s): State<AppState>, body: axum::body::Bytes) -> Response {
    if !s.auth.is_required() {
        return redirect_home(None);
    }
    // Guesses are rate-limited like commands.
    if !s.limiter.try_take() {
        return form(
            StatusCode::TOO_MANY_REQUESTS,
            "Too many attempts: wait a few seconds.",
        );
    }
    let Ok(f) = parse_form(&body) else {
        return form(
            StatusCode::BAD_REQUEST,
            "Expected a form with a `token` field.",
        );
    };
    if !s.auth.is_token(&f.token) {
        return form(StatusCode::UNAUTHORIZED, "Wrong token.");
    }
    match s.auth.session_cookie() {
        Some(cookie) => redirect_home(Some(cookie)),
        None => form(
            StatusCode::SERVICE_UNAVAILABLE,
            "No random source for a session: use the Authorization header instead.",
        ),
    }
}

fn parse_form(body: &[u8]) -> Result<LoginForm, ()> {
    let text = std::str::from_utf8(body).map_err(|_| ())?;
    let token = text
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == "token")
        .map(|(_, v)| percent_decode(v))
        .ok_or(())??;
    Ok(LoginForm { token })
}

/// Decode `application/x-www-form-urlencoded` text (`+` is a space, `%XX` a byte).
fn percent_decode(s: &str) -> Result<String, ()> {
    let mut out = Vec::with_capacity(s.len());
    let mut bytes = s.bytes();
    while let Some(b) = bytes.next() {
        match b {
            b'+' => out.push(b' '),
            b'%' => {
                let hex = [bytes.next().ok_or(())?, bytes.next().ok_or(())?];
                let hex = std::str::from_utf8(&hex).map_err(|_| ())?;
                out.push(u8::from_str_radix(hex, 16).map_err(|_| ())?);
            }
            b => out.push(b),
        }
    }
    String::from_utf8(out).map_err(|_| ())
}

fn redirect_home(cookie: Option<String>) -> Response {
    let mut r = (StatusCode::SEE_OTHER, [(header::LOCATION, "/")]).into_response();
    if let Some(c) = cookie.and_then(|c| HeaderValue::from_str(&c).ok()) {
        r.headers_mut().insert(header::SET_COOKIE, c);
    }
    r
}

/// The login form, with `message` above it.
fn form(status: StatusCode, message: &str) -> Response {
    let html = format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>gelgrip: log in</title>\
         <style>body{{font-family:sans-serif;margin:3em}}</style></head>\
         <body><main><h1>gelgrip</h1>\
         <p>This dashboard is served off loopback: it needs the token \
         (<code>[http] token</code> or <code>GELGRIP_HTTP_TOKEN</code>).</p>\
         <p id=\"login-message\" role=\"alert\">{message}</p>\
         <form method=\"post\" action=\"/login\">\
         <label>token <input id=\"login-token\" name=\"token\" type=\"password\" autofocus></label>\
         <button id=\"login\" type=\"submit\">Log in</button></form></main></body></html>"
    );
    let mut r = (
        status,
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        html,
    )
        .into_response();
    if status == StatusCode::UNAUTHORIZED {
        r.headers_mut()
            .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
    }
    r
}

#[cfg(test)]
mod tests {
    use super::percent_decode;

    #[test]
    fn form_values_decode() {
        assert_eq!(percent_decode("a+b%2Fc%3D").as_deref(), Ok("a b/c="));
        assert!(percent_decode("%4").is_err());
        assert!(percent_decode("%zz").is_err());
        assert!(percent_decode("%ff").is_err(), "not UTF-8");
    }
}
