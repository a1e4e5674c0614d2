//! Who may call: the bearer token of a request, the admin token (by header or by the HttpOnly
//! SameSite=Strict cookie, which a change must back with `X-Requested-With`), and tokens compared
//! by their SHA-256 in constant time. Tokens are stored only as their SHA-256.

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
        .and_then(|value| value.strip_prefix("Bearer "))
        .map(str::trim)
        .filter(|token| !token.is_empty())
        .ok_or_else(|| AppError::Unauthorized("This call needs the header Authorization: Bearer <token>.".into()))
}

/// How the admin token came.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Via {
    Header,
    Cookie,
}

fn cookie_token(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|value| value.to_str().ok())
        .flat_map(|value| value.split(';'))
        .filter_map(|pair| pair.trim().split_once('='))
        .find(|(name, _)| *name == COOKIE)
        .map(|(_, value)| value)
}

/// Checks the admin token (header or cookie), for read-only admin calls of other modules.
pub(crate) fn authorize_admin(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    authorize_admin_via(state, headers).map(|_| ())
}

/// Checks the admin token, sent as a bearer token or as the admin cookie; says which.
pub(crate) fn authorize_admin_via(state: &AppState, headers: &HeaderMap) -> AppResult<Via> {
    let (token, via) = match bearer(headers) {
        Ok(token) => (token, Via::Header),
        Err(error) => match cookie_token(headers) {
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
    if state.is_admin_token(token) { Ok(via) } else { Err(AppError::Forbidden("The admin token is wrong.".into())) }
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
