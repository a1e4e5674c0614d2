//! Who may call: the bearer token of a request (the scheme in any case), the admin token (by
//! header, or an admin session by the HttpOnly SameSite=Strict cookie, which a change must back
//! with `X-Requested-With`), and tokens compared by their SHA-256 in constant time. Tokens are
//! stored only as their SHA-256.
//!
//! Admin sessions: logging in with the admin token (`GET /admin/login?token=…`) starts a
//! session: a random 256-bit id in the cookie (never the token itself), kept by the server as
//! its SHA-256 with an expiry ([`SESSION_LIFETIME`]); `POST /admin/logout` ends it. Sessions live
//! in the server's memory: a restart logs the admin out.

use axum::http::{HeaderMap, header};

use crate::AppState;
use crate::error::{AppError, AppResult};

/// The name of the admin cookie.
pub const COOKIE: &str = "mrstudy_admin";

/// The bearer token of a request: 401 if there is none.
pub(crate) fn bearer(headers: &HeaderMap) -> AppResult<&str> {
    headers
        .get(header::AUTHORIZATION)
        .and_then(|value| value.to_str().ok())
        .and_then(|value| value.trim_start().split_once(' '))
        // the scheme is case-insensitive (RFC 9110, 11.1)
        .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
        .map(|(_, token)| token.trim())
        .filter(|token| !token.is_empty())
        .ok_or_else(|| AppError::Unauthorized("This call needs the header Authorization: Bearer <token>.".into()))
}

/// How the admin token came.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Via {
    Header,
    Cookie,
}

/// The admin session id of the request's cookie, if any.
pub(crate) fn session_cookie(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|value| value.to_str().ok())
        .flat_map(|value| value.split(';'))
        .filter_map(|pair| pair.trim().split_once('='))
        .find(|(name, _)| *name == COOKIE)
        .map(|(_, value)| value)
}

/// How long an admin session lasts after login.
pub const SESSION_LIFETIME: std::time::Duration = std::time::Duration::from_secs(12 * 60 * 60);

/// The admin sessions: SHA-256 of the id → expiry.
#[derive(Debug, Default)]
pub struct Sessions {
    live: std::sync::Mutex<std::collections::HashMap<[u8; 32], std::time::Instant>>,
}

impl Sessions {
    /// Starts a session; returns its id (for the cookie).
    pub fn start(&self) -> String {
        let id = crate::random_hex(32);
        let now = std::time::Instant::now();
        let mut live = self.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        live.retain(|_, expiry| *expiry > now);
        live.insert(sha256(id.as_bytes()), now + SESSION_LIFETIME);
        id
    }

    /// Whether `id` is a session that has not expired.
    pub fn is_live(&self, id: &str) -> bool {
        let live = self.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        live.get(&sha256(id.as_bytes())).is_some_and(|expiry| *expiry > std::time::Instant::now())
    }

    /// Ends the session `id` (if there is one).
    pub fn end(&self, id: &str) {
        self.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).remove(&sha256(id.as_bytes()));
    }
}

/// The `Set-Cookie` value for a session id (`None`: the cookie that ends it), `Secure` when the
/// server is behind a TLS proxy.
pub(crate) fn session_set_cookie(id: Option<&str>, secure: bool) -> String {
    let secure = if secure { "; Secure" } else { "" };
    match id {
        Some(id) => {
            format!("{COOKIE}={id}; HttpOnly; SameSite=Strict; Path=/; Max-Age={}{secure}", SESSION_LIFETIME.as_secs())
        }
        None => format!("{COOKIE}=; HttpOnly; SameSite=Strict; Path=/; Max-Age=0{secure}"),
    }
}

/// Checks the admin token (header or cookie), for read-only admin calls of other modules.
pub(crate) fn authorize_admin(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    authorize_admin_via(state, headers).map(|_| ())
}

/// Checks the admin token sent as a bearer token, or the admin session of the cookie; says which.
pub(crate) fn authorize_admin_via(state: &AppState, headers: &HeaderMap) -> AppResult<Via> {
    let (token, via) = match bearer(headers) {
        Ok(token) => (token, Via::Header),
        Err(error) => match session_cookie(headers) {
            Some(token) => (token, Via::Cookie),
            None => {
                return Err(match error {
                    AppError::Unauthorized(_) => AppError::Unauthorized(
                        "This call needs the admin token: Authorization: Bearer <admin token>.".into(),
                    ),
                    other => other,
                });
            }
        },
    };
    match via {
        Via::Header if state.is_admin_token(token) => Ok(via),
        Via::Header => Err(AppError::Forbidden("The admin token is wrong.".into())),
        Via::Cookie if state.sessions().is_live(token) => Ok(via),
        Via::Cookie => Err(AppError::Unauthorized(
            "The admin session has ended; open the admin link that mrstudy serve printed to log in again.".into(),
        )),
    }
}

/// Checks the admin token for a change: with the cookie, the request must also carry
/// `X-Requested-With: mrstudy` (a cross-site form cannot).
pub(crate) fn authorize_admin_change(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    if authorize_admin_via(state, headers)? == Via::Cookie
        && headers.get("x-requested-with").and_then(|value| value.to_str().ok()) != Some("mrstudy")
    {
        return Err(AppError::Forbidden(
            "A change made with the admin cookie needs the header X-Requested-With: mrstudy.".into(),
        ));
    }
    Ok(())
}

/// SHA-256 of `bytes` (how tokens are stored).
pub(crate) fn sha256(bytes: &[u8]) -> [u8; 32] {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).into()
}

/// Whether two byte strings are equal, in time that depends only on their length.
pub(crate) fn constant_time_eq(first: &[u8], second: &[u8]) -> bool {
    first.len() == second.len() && first.iter().zip(second).fold(0u8, |acc, (a, b)| acc | (a ^ b)) == 0
}
