//! Limits per participant and per client address on the open internet, each a token bucket;
//! over the limit a request gets 429 with a sentence (JSON under `/api/`, a page elsewhere), a
//! `Retry-After` of the seconds until the bucket has a token again, and nothing is stored.
//!
//! - **Answers** are limited per participant (their id and the credentials they send), at a
//!   rate no person answering trials reaches, so however many people share one address (a lab,
//!   a university's NAT) none is refused for the others. Answers without credentials, and those
//!   refused for them (401, 403, 404), are limited per client address.
//! - **Joins and screen checks** are limited per client address, sized so that a class of 200
//!   behind one address can all start within a minute (see [`Limits::default`]).
//! - **Wrong admin tokens** are limited per client address; a request that carries the right
//!   admin token (header, session cookie or login link) is never refused or counted, so
//!   guessing from an address delays the guesses without locking the researcher out.
//!
//! The client address is the socket's peer ([`ClientAddr`], put on each request by
//! [`crate::serve`]), or behind a TLS proxy (`serve --behind-tls`) the last address of
//! `X-Forwarded-For`, the one the proxy added. A request without a [`ClientAddr`] (the router
//! driven in-process, as the tests do) is not limited.
//!
//! On PostgreSQL the buckets live in the database (table `rate_limit_buckets`, unlogged), so N
//! `serve` processes of one database allow the numbers once, not N times: each take is one
//! atomic upsert timed by the database's clock. The keys there are SHA-256 digests of a random
//! salt kept in the database and the address or the participant's credentials, never the
//! address itself; rows are dropped half an hour after their last use. Should the database not
//! answer, the process's own buckets decide (and a warning is logged). On sqlite (one process)
//! the buckets are the process's own.
//!
//! Admin API calls run one at a time (see [`limit`]).

use std::collections::HashMap;
use std::hash::{BuildHasher, Hash, RandomState};
use std::net::IpAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::AppState;
use crate::error::AppError;

/// The peer address of the connection a request came on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClientAddr(pub IpAddr);

/// How much one participant or client address may do; 0 turns a limit off. Also `mrstudy
/// serve`'s flags (the binary holds their clap definitions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Joins (new participants), and screen checks, per client address per minute, with bursts
    /// of twice that; 0: no limit.
    pub joins_per_minute: u32,
    /// Responses per participant per minute, with bursts of twice that (and per client address
    /// for answers without valid credentials); 0: no limit.
    pub responses_per_minute: u32,
    /// Wrong admin tokens (and admin calls refused with 403) per client address per 15 minutes
    /// before more are refused (429; the right token still works); 0: no limit.
    pub admin_failures: u32,
    /// Behind a TLS-terminating reverse proxy: the client address is the last X-Forwarded-For
    /// address, and the admin cookie is Secure.
    pub behind_tls: bool,
}

/// The defaults, sized for people (issue 46): 200 people behind one address (a lab, a
/// university's NAT) may all join within one minute (a burst of 240) and then 120 more a
/// minute; a participant may answer 120 trials a minute (bursts of 240: a person answers a
/// trial in a second or more, so no honest participant is refused however many share the
/// address); 10 wrong admin tokens per 15 minutes per address.
impl Default for Limits {
    fn default() -> Limits {
        Limits { joins_per_minute: 120, responses_per_minute: 120, admin_failures: 10, behind_tls: false }
    }
}

/// Which bucket a take counts against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Which {
    Joins,
    Screens,
    /// By the participant's id and the credentials the request carries (a stranger guessing
    /// tokens for someone's id never drains that participant's bucket).
    Responses,
    /// Answers without credentials, or refused for them, by client address.
    AnonymousResponses,
    AdminFailures,
}

impl Which {
    /// The name in `rate_limit_buckets.bucket`.
    fn name(self) -> &'static str {
        match self {
            Which::Joins => "joins",
            Which::Screens => "screens",
            Which::Responses => "responses",
            Which::AnonymousResponses => "anonymous_responses",
            Which::AdminFailures => "admin_failures",
        }
    }
}

/// The bytes that key an address's bucket.
fn address_key(address: IpAddr) -> Vec<u8> {
    match address {
        IpAddr::V4(v4) => v4.octets().to_vec(),
        IpAddr::V6(v6) => v6.octets().to_vec(),
    }
}

/// The bytes that key a participant's answers: their id and the credentials they sent.
fn participant_key(participant: &str, credentials: &[u8]) -> Vec<u8> {
    let mut key = Vec::with_capacity(participant.len() + 1 + credentials.len());
    key.extend_from_slice(participant.as_bytes());
    key.push(0);
    key.extend_from_slice(credentials);
    key
}

/// The buckets of each limit: the process's own, and on PostgreSQL the database's, which every
/// process of the database shares (see the module doc).
#[derive(Debug, Default)]
pub struct Buckets {
    local: Mutex<HashMap<(Which, u64), Bucket>>,
    hasher: RandomState,
    shared: Option<Shared>,
}

impl Buckets {
    /// Buckets kept in the database of `pool` (PostgreSQL), shared by every process using it.
    pub fn shared(pool: crate::storage::Pool) -> Buckets {
        Buckets {
            shared: Some(Shared { pool, salt: Default::default(), takes: Default::default() }),
            ..Default::default()
        }
    }

    /// Takes a token from the bucket of `key`; when it is empty, how long until it has one.
    async fn take(&self, which: Which, key: &[u8], rate: Rate, now: Instant) -> Result<(), Duration> {
        if let Some(shared) = &self.shared {
            match shared.take(which, key, rate).await {
                Ok(taken) => return taken,
                Err(error) => {
                    tracing::warn!(%error, bucket = which.name(), "the shared rate limit did not answer; this process's own bucket decides")
                }
            }
        }
        take(&self.local, (which, self.hasher.hash_one(key)), rate, now)
    }

    /// Whether the bucket of `key` has a token, without taking it; if not, how long until it has.
    async fn has_token(&self, which: Which, key: &[u8], rate: Rate, now: Instant) -> Result<(), Duration> {
        if let Some(shared) = &self.shared {
            match shared.has_token(which, key, rate).await {
                Ok(has) => return has,
                Err(error) => {
                    tracing::warn!(%error, bucket = which.name(), "the shared rate limit did not answer; this process's own bucket decides")
                }
            }
        }
        has_token(&self.local, &(which, self.hasher.hash_one(key)), rate, now)
    }
}

/// Buckets in the database (`rate_limit_buckets`), timed by the database's clock.
#[derive(Debug)]
struct Shared {
    pool: crate::storage::Pool,
    /// `rate_limit_salt.salt`, read on first use.
    salt: tokio::sync::OnceCell<Vec<u8>>,
    /// Takes so far; every 1024th also drops the rows unused for half an hour.
    takes: std::sync::atomic::AtomicU64,
}

/// The statements of [`Shared`]; `now` is the database's clock in Unix seconds.
const PRUNE: &str =
    "DELETE FROM rate_limit_buckets WHERE at < EXTRACT(EPOCH FROM clock_timestamp())::DOUBLE PRECISION - 1800";
const TAKE: &str = "WITH clock AS (SELECT EXTRACT(EPOCH FROM clock_timestamp())::DOUBLE PRECISION AS now), \
     taken AS (INSERT INTO rate_limit_buckets AS b (bucket, key, tokens, at) \
               SELECT $1, $2, $3 - 1, now FROM clock \
               ON CONFLICT (bucket, key) DO UPDATE \
               SET tokens = LEAST($3, b.tokens + (EXCLUDED.at - b.at) * $4) - 1, at = EXCLUDED.at \
               WHERE LEAST($3, b.tokens + (EXCLUDED.at - b.at) * $4) >= 1 \
               RETURNING 1) \
     SELECT (SELECT COUNT(*) FROM taken), \
            (SELECT LEAST($3, b.tokens + (clock.now - b.at) * $4) \
             FROM rate_limit_buckets b, clock WHERE b.bucket = $1 AND b.key = $2)";
const TOKENS: &str = "SELECT LEAST($3, tokens + (EXTRACT(EPOCH FROM clock_timestamp())::DOUBLE PRECISION - at) * $4) \
     FROM rate_limit_buckets WHERE bucket = $1 AND key = $2";

impl Shared {
    async fn key(&self, key: &[u8]) -> Result<Vec<u8>, sqlx::Error> {
        use sha2::Digest;
        let salt = self
            .salt
            .get_or_try_init(|| async {
                sqlx::query_scalar::<_, Vec<u8>>("SELECT salt FROM rate_limit_salt").fetch_one(&self.pool).await
            })
            .await?;
        let mut digest = sha2::Sha256::new();
        digest.update(salt);
        digest.update(key);
        Ok(digest.finalize().to_vec())
    }

    /// One atomic upsert: the bucket refilled since its last take, less one token if it has one.
    /// The CTE's outer query sees the row as it was, so when nothing was taken it reads the
    /// tokens the bucket holds.
    async fn take(&self, which: Which, key: &[u8], rate: Rate) -> Result<Result<(), Duration>, sqlx::Error> {
        let key = self.key(key).await?;
        if self.takes.fetch_add(1, std::sync::atomic::Ordering::Relaxed) % 1024 == 1023 {
            sqlx::query(PRUNE).execute(&self.pool).await?;
        }
        let (taken, tokens): (i64, Option<f64>) = sqlx::query_as(TAKE)
            .bind(which.name())
            .bind(key)
            .bind(rate.burst)
            .bind(rate.per_second)
            .fetch_one(&self.pool)
            .await?;
        Ok(if taken > 0 { Ok(()) } else { Err(rate.wait(tokens.unwrap_or(0.0))) })
    }

    async fn has_token(&self, which: Which, key: &[u8], rate: Rate) -> Result<Result<(), Duration>, sqlx::Error> {
        let key = self.key(key).await?;
        let tokens: Option<f64> = sqlx::query_scalar(TOKENS)
            .bind(which.name())
            .bind(key)
            .bind(rate.burst)
            .bind(rate.per_second)
            .fetch_optional(&self.pool)
            .await?;
        let tokens = tokens.unwrap_or(rate.burst);
        Ok(if tokens >= 1.0 { Ok(()) } else { Err(rate.wait(tokens)) })
    }
}

/// A bucket's size and refill.
#[derive(Debug, Clone, Copy)]
struct Rate {
    burst: f64,
    per_second: f64,
}

impl Rate {
    /// `n` a minute, with bursts of twice that.
    fn per_minute(n: u32) -> Rate {
        Rate { burst: 2.0 * n as f64, per_second: n as f64 / 60.0 }
    }

    /// How long until a bucket holding `tokens` has one.
    fn wait(&self, tokens: f64) -> Duration {
        if self.per_second <= 0.0 {
            return Duration::from_secs(60);
        }
        Duration::from_secs_f64(((1.0 - tokens) / self.per_second).max(0.0))
    }
}

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    at: Instant,
}

impl Bucket {
    /// The tokens at `now`: refilled at `per_second` since the last take, at most `burst`.
    fn refilled(&self, now: Instant, rate: Rate) -> f64 {
        (self.tokens + now.saturating_duration_since(self.at).as_secs_f64() * rate.per_second).min(rate.burst)
    }
}

/// Takes one token from `key`'s bucket at `now`; when it is empty, how long until it has one.
/// Full, idle buckets are dropped now and then so the map stays small.
fn take<K: Hash + Eq>(map: &Mutex<HashMap<K, Bucket>>, key: K, rate: Rate, now: Instant) -> Result<(), Duration> {
    let mut map = map.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if map.len() > 100_000 {
        map.retain(|_, bucket| bucket.refilled(now, Rate { burst: f64::INFINITY, ..rate }) < rate.burst);
    }
    let bucket = map.entry(key).or_insert(Bucket { tokens: rate.burst, at: now });
    bucket.tokens = bucket.refilled(now, rate);
    bucket.at = now;
    if bucket.tokens >= 1.0 {
        bucket.tokens -= 1.0;
        Ok(())
    } else {
        Err(rate.wait(bucket.tokens))
    }
}

/// Whether `key` still has a token at `now`, without taking it; if not, how long until it has.
fn has_token<K: Hash + Eq>(map: &Mutex<HashMap<K, Bucket>>, key: &K, rate: Rate, now: Instant) -> Result<(), Duration> {
    let map = map.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let tokens = map.get(key).map_or(rate.burst, |bucket| bucket.refilled(now, rate));
    if tokens >= 1.0 { Ok(()) } else { Err(rate.wait(tokens)) }
}

const ADMIN_WINDOW: Duration = Duration::from_secs(15 * 60);

/// Which limit a request falls under.
#[derive(Debug, PartialEq, Eq)]
enum Kind<'a> {
    Join,
    Screen,
    /// An answer of the participant with this id.
    Response(&'a str),
    Admin,
    None,
}

fn kind<'a>(method: &Method, path: &'a str) -> Kind<'a> {
    let parts: Vec<&str> = path.trim_end_matches('/').split('/').collect();
    match (method, parts.as_slice()) {
        (&Method::POST, ["", "api", "studies", _, "participants"]) => Kind::Join,
        // a lab participant (task::join) joins under the same limit
        (&Method::POST, ["", "api", "lab", _, "participants"]) => Kind::Join,
        (&Method::POST, ["", "api", "studies", _, "screen"]) => Kind::Screen,
        (&Method::POST, ["", "api", "participants", id, "responses"]) => Kind::Response(id),
        (_, ["", "api", "admin", ..]) | (_, ["", "admin", ..]) => Kind::Admin,
        _ => Kind::None,
    }
}

/// The client address of a request (see the module doc), if it came over a socket.
pub fn client(request: &Request, behind_tls: bool) -> Option<IpAddr> {
    let peer = request.extensions().get::<ClientAddr>()?.0;
    if behind_tls {
        // the last address is the one the proxy added; the ones before it came from the client
        let forwarded = request
            .headers()
            .get_all("x-forwarded-for")
            .iter()
            .filter_map(|value| value.to_str().ok())
            .flat_map(|value| value.split(','))
            .next_back()
            .and_then(|address| address.trim().parse::<IpAddr>().ok());
        return Some(forwarded.unwrap_or(peer));
    }
    Some(peer)
}

/// Whether the request carries the right admin token: by header or session cookie, or as the
/// login link's `token`.
async fn is_admin(state: &AppState, headers: &axum::http::HeaderMap, uri: &axum::http::Uri) -> bool {
    if crate::auth::authorize_admin(state, headers).await.is_ok() {
        return true;
    }
    uri.path() == "/admin/login"
        && url::form_urlencoded::parse(uri.query().unwrap_or("").as_bytes())
            .any(|(name, value)| name == "token" && state.is_admin_token(&value))
}

/// The middleware: refuses a request over its limit with 429, counts admin refusals, and runs
/// admin API calls (exports, analyses: work that takes a worker thread for a while) one at a
/// time, so that however many an admin starts, participants' requests find free workers.
pub async fn limit(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let path = request.uri().path().to_string();
    let kind = kind(request.method(), &path);
    let admin = kind == Kind::Admin && is_admin(&state, request.headers(), request.uri()).await;
    // only calls that carry a valid admin token or session wait for the one slot: a request
    // without one is refused by its handler at once and must not hold the slot meanwhile
    let _admin_work = if admin && path.starts_with("/api/admin/") {
        Some(state.admin_work().acquire().await.expect("the semaphore is never closed"))
    } else {
        None
    };
    let limits = state.limits();
    let Some(client) = client(&request, limits.behind_tls) else { return next.run(request).await };
    let buckets = state.buckets();
    let is_api = path.starts_with("/api/");
    let now = Instant::now();
    match kind {
        Kind::Join | Kind::Screen if limits.joins_per_minute > 0 => {
            let (which, what) =
                if kind == Kind::Join { (Which::Joins, "joins") } else { (Which::Screens, "screen checks") };
            if let Err(wait) =
                buckets.take(which, &address_key(client), Rate::per_minute(limits.joins_per_minute), now).await
            {
                return too_many(
                    is_api,
                    &format!("{what} from this address"),
                    limits.joins_per_minute,
                    "a minute",
                    wait,
                );
            }
            next.run(request).await
        }
        Kind::Response(participant) if limits.responses_per_minute > 0 => {
            let rate = Rate::per_minute(limits.responses_per_minute);
            let anonymous = |wait| {
                too_many(
                    is_api,
                    "answers without a valid participant token from this address",
                    limits.responses_per_minute,
                    "a minute",
                    wait,
                )
            };
            let address = address_key(client);
            if let Err(wait) = buckets.has_token(Which::AnonymousResponses, &address, rate, now).await {
                return anonymous(wait);
            }
            let Some(credentials) = request.headers().get(header::AUTHORIZATION) else {
                if let Err(wait) = buckets.take(Which::AnonymousResponses, &address, rate, now).await {
                    return anonymous(wait);
                }
                return next.run(request).await;
            };
            let key = participant_key(participant, credentials.as_bytes());
            if let Err(wait) = buckets.take(Which::Responses, &key, rate, now).await {
                return too_many(
                    is_api,
                    "answers from this participant",
                    limits.responses_per_minute,
                    "a minute",
                    wait,
                );
            }
            let response = next.run(request).await;
            if matches!(response.status(), StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN | StatusCode::NOT_FOUND) {
                let _ = buckets.take(Which::AnonymousResponses, &address, rate, Instant::now()).await;
            }
            response
        }
        // the right token is never refused nor counted (not even a change refused for a
        // missing X-Requested-With)
        Kind::Admin if limits.admin_failures > 0 && !admin => {
            let burst = limits.admin_failures as f64;
            let rate = Rate { burst, per_second: burst / ADMIN_WINDOW.as_secs_f64() };
            let address = address_key(client);
            if let Err(wait) = buckets.has_token(Which::AdminFailures, &address, rate, now).await {
                return too_many(
                    is_api,
                    "wrong admin tokens from this address",
                    limits.admin_failures,
                    "15 minutes",
                    wait,
                );
            }
            let response = next.run(request).await;
            if response.status() == StatusCode::FORBIDDEN {
                let _ = buckets.take(Which::AdminFailures, &address, rate, Instant::now()).await;
            }
            response
        }
        _ => next.run(request).await,
    }
}

/// A 429 with a sentence and `Retry-After: wait` (whole seconds, at least one).
fn too_many(is_api: bool, what: &str, limit: u32, window: &str, wait: Duration) -> Response {
    let sentence = format!("Too many {what} (at most {limit} in {window}); wait a little and try again.");
    let mut response = if is_api {
        AppError::TooManyRequests(sentence).into_response()
    } else {
        crate::pages::message_page(StatusCode::TOO_MANY_REQUESTS, "Too many requests", &sentence)
    };
    let seconds = wait.as_secs_f64().ceil().max(1.0) as u64;
    response.headers_mut().insert(header::RETRY_AFTER, axum::http::HeaderValue::from(seconds));
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bucket_allows_its_burst_then_refuses_with_the_wait_then_refills() {
        let map = Mutex::new(HashMap::new());
        let client: IpAddr = "192.0.2.1".parse().unwrap();
        let other: IpAddr = "192.0.2.2".parse().unwrap();
        let rate = Rate { burst: 4.0, per_second: 2.0 };
        let start = Instant::now();
        for _ in 0..4 {
            assert_eq!(take(&map, client, rate, start), Ok(()));
        }
        assert_eq!(take(&map, client, rate, start), Err(Duration::from_millis(500)), "a token every half second");
        assert_eq!(has_token(&map, &client, rate, start), Err(Duration::from_millis(500)));
        assert_eq!(take(&map, other, rate, start), Ok(()), "another address has its own bucket");
        assert_eq!(has_token(&map, &client, rate, start + Duration::from_millis(500)), Ok(()));
        assert_eq!(take(&map, client, rate, start + Duration::from_millis(500)), Ok(()));
    }

    /// Issue 46's sizing, on a simulated clock: 200 people behind one address (a lab, a
    /// university's NAT) join within one minute and answer a trial every 2 seconds for 10
    /// minutes under the default limits; none is refused. (Before, with the answers' bucket
    /// per address, 100 people at 2–4 s per answer got 633 refusals.)
    #[test]
    fn two_hundred_people_behind_one_address_at_two_seconds_an_answer_are_never_refused() {
        let limits = Limits::default();
        let (joins, screens, responses, anonymous) = (
            Mutex::new(HashMap::new()),
            Mutex::new(HashMap::new()),
            Mutex::new(HashMap::new()),
            Mutex::new(HashMap::new()),
        );
        let address: IpAddr = "203.0.113.9".parse().unwrap();
        let start = Instant::now();
        let people = 200u64;
        let mut refused = 0;
        for person in 0..people {
            // the class starts together: everyone joins within the first minute
            let at = start + Duration::from_millis(person * 300);
            refused += take(&screens, address, Rate::per_minute(limits.joins_per_minute), at).is_err() as u32;
            refused += take(&joins, address, Rate::per_minute(limits.joins_per_minute), at).is_err() as u32;
        }
        let rate = Rate::per_minute(limits.responses_per_minute);
        for step in 0..300u64 {
            for person in 0..people {
                let at = start + Duration::from_secs(60) + Duration::from_millis(step * 2000 + person * 7);
                let key = participant_key(&format!("participant-{person}"), b"Bearer t");
                assert_eq!(has_token(&anonymous, &address, rate, at), Ok(()));
                refused += take(&responses, key, rate, at).is_err() as u32;
            }
        }
        assert_eq!(refused, 0);
        // one script answering without pause as one participant is refused after its burst
        let key = participant_key("script", b"Bearer s");
        let at = start + Duration::from_secs(700);
        let allowed = (0..1000).filter(|_| take(&responses, key.clone(), rate, at).is_ok()).count();
        assert_eq!(allowed, 2 * limits.responses_per_minute as usize);
    }

    #[test]
    fn requests_fall_under_their_limit_by_method_and_path() {
        assert_eq!(kind(&Method::POST, "/api/studies/s/participants"), Kind::Join);
        assert_eq!(kind(&Method::GET, "/api/studies/s/participants"), Kind::None);
        assert_eq!(kind(&Method::POST, "/api/lab/s/participants"), Kind::Join);
        assert_eq!(kind(&Method::POST, "/api/studies/s/screen"), Kind::Screen);
        assert_eq!(kind(&Method::POST, "/api/participants/p/responses"), Kind::Response("p"));
        assert_eq!(kind(&Method::GET, "/admin/login"), Kind::Admin);
        assert_eq!(kind(&Method::GET, "/api/admin/studies"), Kind::Admin);
        assert_eq!(kind(&Method::GET, "/administrator"), Kind::None);
    }
}
