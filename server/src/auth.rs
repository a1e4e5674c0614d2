//! Who may call: the bearer token of a request (the scheme in any case), the admin token (by
//! header, or an admin session by the HttpOnly SameSite=Strict cookie, which a change must back
//! with `X-Requested-With`), and tokens compared by their SHA-256 in constant time. Tokens are
//! stored only as their SHA-256. An admin token set by hand must be strong enough
//! ([`admin_token_strength`]).
//!
//! Admin sessions: logging in with the admin token (`GET /admin/login?token=…`) starts a
//! session: a random 256-bit id in the cookie (never the token itself), kept by the server as
//! its SHA-256 with an expiry ([`SESSION_LIFETIME`]) in the database (`admin_sessions`), so a
//! session is valid on every server process sharing the database and survives a restart;
//! `POST /admin/logout` ends it.

use axum::extract::FromRequestParts;
use axum::http::request::Parts;
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

/// Seconds since the Unix epoch, the clock of session expiry.
fn unix_now() -> i64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|since| since.as_secs() as i64).unwrap_or(0)
}

/// Starts an admin session, durable before this returns; returns its id (for the cookie).
pub(crate) async fn start_session(state: &AppState) -> AppResult<String> {
    let id = crate::random_hex(32);
    let now = unix_now();
    state.storage().start_admin_session(sha256(id.as_bytes()), now + SESSION_LIFETIME.as_secs() as i64, now).await?;
    Ok(id)
}

/// Ends the admin session `id` (if there is one).
pub(crate) async fn end_session(state: &AppState, id: &str) -> AppResult<()> {
    Ok(state.storage().end_admin_session(sha256(id.as_bytes())).await?)
}

/// Whether `id` is an admin session that has not expired.
async fn is_live_session(state: &AppState, id: &str) -> AppResult<bool> {
    Ok(state.storage().is_admin_session(&sha256(id.as_bytes()), unix_now()).await?)
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
pub(crate) async fn authorize_admin(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    authorize_admin_via(state, headers).await.map(|_| ())
}

/// A handler's argument that lets only the admin in ([`authorize_admin_via`]: the admin token
/// by header, or a live admin session by cookie) before the handler runs.
pub(crate) struct Admin;

impl FromRequestParts<AppState> for Admin {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> AppResult<Admin> {
        authorize_admin_via(state, &parts.headers).await.map(|_| Admin)
    }
}

/// A handler's argument that lets only the admin make a change ([`authorize_admin_change`]: by
/// cookie, only with `X-Requested-With: mrstudy`) before the handler runs.
pub(crate) struct AdminChange;

impl FromRequestParts<AppState> for AdminChange {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> AppResult<AdminChange> {
        authorize_admin_change(state, &parts.headers).await.map(|_| AdminChange)
    }
}

/// Checks the admin token sent as a bearer token, or the admin session of the cookie; says which.
pub(crate) async fn authorize_admin_via(state: &AppState, headers: &HeaderMap) -> AppResult<Via> {
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
        Via::Cookie if is_live_session(state, token).await? => Ok(via),
        Via::Cookie => Err(AppError::Unauthorized(
            "The admin session has ended; open the admin link that mrstudy serve printed to log in again.".into(),
        )),
    }
}

/// Checks the admin token for a change: with the cookie, the request must also carry
/// `X-Requested-With: mrstudy` (a cross-site form cannot).
pub(crate) async fn authorize_admin_change(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    if authorize_admin_via(state, headers).await? == Via::Cookie
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

/// Bits of a random token drawn from the characters `token` uses, if it was random.
pub const ADMIN_TOKEN_BITS: f64 = 128.0;

/// Whether an admin token set by hand is strong enough: only A-Z, a-z, 0-9, `-` and `_`, and at
/// least [`ADMIN_TOKEN_BITS`] bits as a random string of its alphabet would have (hexadecimal:
/// 32 characters; letters and digits: 22), at least 9 different characters (hexadecimal; 12
/// otherwise), no repeated part (`Password1Password1`), and at most a third of it in runs along
/// the alphabet, the digits or the keyboard (`0123456789abcdef…`, `qwertyuiop…`). A random token
/// (`openssl rand -hex 16`) passes. Says why not.
pub fn admin_token_strength(token: &str) -> Result<(), WeakToken> {
    if let Some(bad) = token.chars().find(|c| !(c.is_ascii_alphanumeric() || *c == '-' || *c == '_')) {
        return Err(WeakToken::Character { character: bad });
    }
    let hex = token.chars().all(|c| c.is_ascii_hexdigit()) && !token.chars().any(|c| c.is_ascii_uppercase());
    let alphabet = if hex {
        16.0
    } else {
        [
            (token.chars().any(|c| c.is_ascii_lowercase()), 26.0),
            (token.chars().any(|c| c.is_ascii_uppercase()), 26.0),
            (token.chars().any(|c| c.is_ascii_digit()), 10.0),
            (token.chars().any(|c| c == '-' || c == '_'), 2.0),
        ]
        .iter()
        .filter(|(used, _)| *used)
        .map(|(_, size)| size)
        .sum::<f64>()
    };
    let bits = token.len() as f64 * f64::log2(alphabet.max(1.0));
    if bits < ADMIN_TOKEN_BITS {
        return Err(WeakToken::Bits { characters: token.len(), kinds: alphabet, bits });
    }
    let distinct = token.chars().collect::<std::collections::BTreeSet<_>>().len();
    // a random token uses many: 32 random hex digits fewer than 9 about once in 10^8 draws
    let fewest = if hex { 9 } else { 12 };
    if distinct < fewest {
        return Err(WeakToken::Distinct { distinct, fewest });
    }
    let lower = token.to_ascii_lowercase().into_bytes();
    if let Some(period) = (1..=lower.len() / 2).find(|&p| (p..lower.len()).all(|i| lower[i] == lower[i - p])) {
        return Err(WeakToken::Repeats { period });
    }
    let walked = walked_characters(&lower);
    if walked * 3 > lower.len() {
        return Err(WeakToken::Runs { walked, characters: lower.len() });
    }
    Ok(())
}

/// Why an admin token set by hand is too weak (the clause after "MRSTUDY_ADMIN_TOKEN is too
/// weak:").
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum WeakToken {
    #[error("it may only hold A-Z, a-z, 0-9, - and _, not {character:?}")]
    Character { character: char },
    /// `characters` of an alphabet of `kinds` characters hold `bits` bits.
    #[error("{characters} characters of {kinds} kinds hold at most {bits:.0} bits, fewer than {ADMIN_TOKEN_BITS:.0}")]
    Bits { characters: usize, kinds: f64, bits: f64 },
    #[error("it uses only {distinct} different characters (at least {fewest})")]
    Distinct { distinct: usize, fewest: usize },
    #[error("it repeats its first {period} characters")]
    Repeats { period: usize },
    #[error("{walked} of its {characters} characters are runs such as abcd, 4321 or a keyboard walk (qwerty, 1qaz)")]
    Runs { walked: usize, characters: usize },
}

/// How many characters of `token` (lower case) lie in runs of at least 3 that walk one way along
/// a line: the alphabet, the digits, a keyboard row or column (`abc`, `987`, `qwer`, `1qaz`).
/// Random tokens have few (32 random hex digits: under 1 on average).
fn walked_characters(token: &[u8]) -> usize {
    const LINES: [&[u8]; 16] = [
        b"abcdefghijklmnopqrstuvwxyz",
        b"0123456789",
        b"1234567890-",
        b"qwertyuiop",
        b"asdfghjkl",
        b"zxcvbnm",
        b"1qaz",
        b"2wsx",
        b"3edc",
        b"4rfv",
        b"5tgb",
        b"6yhn",
        b"7ujm",
        b"8ik",
        b"9ol",
        b"0p",
    ];
    // the step from `a` to `b` along some line: +1 or -1 (0: none)
    let step = |a: u8, b: u8| -> Vec<(usize, isize)> {
        LINES
            .iter()
            .enumerate()
            .filter_map(|(line, text)| {
                let i = text.iter().position(|&c| c == a)? as isize;
                let j = text.iter().position(|&c| c == b)? as isize;
                (j - i).abs().eq(&1).then_some((line, j - i))
            })
            .collect()
    };
    let mut walked = vec![false; token.len()];
    let mut start = 0;
    while start + 2 < token.len() {
        let mut best = start + 1;
        for (line, direction) in step(token[start], token[start + 1]) {
            let mut end = start + 1;
            while end + 1 < token.len() && step(token[end], token[end + 1]).contains(&(line, direction)) {
                end += 1;
            }
            best = best.max(end);
        }
        if best - start >= 2 {
            walked[start..=best].iter_mut().for_each(|w| *w = true);
            start = best;
        } else {
            start += 1;
        }
    }
    walked.iter().filter(|&&w| w).count()
}
