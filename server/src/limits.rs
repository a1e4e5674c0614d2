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
//! driven in-process, as the tests do) is not limited. The buckets are each process's own: N
//! `serve` processes behind one balancer allow N times the numbers.
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
/// serve`'s flags (the doc comments are its help).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct Limits {
    /// Joins (new participants), and screen checks, per client address per minute, with bursts
    /// of twice that; 0: no limit.
    #[arg(long = "join-limit", default_value_t = Limits::default().joins_per_minute)]
    pub joins_per_minute: u32,
    /// Responses per participant per minute, with bursts of twice that (and per client address
    /// for answers without valid credentials); 0: no limit.
    #[arg(long = "response-limit", default_value_t = Limits::default().responses_per_minute)]
    pub responses_per_minute: u32,
    /// Wrong admin tokens (and admin calls refused with 403) per client address per 15 minutes
    /// before more are refused (429; the right token still works); 0: no limit.
    #[arg(long = "admin-failure-limit", default_value_t = Limits::default().admin_failures)]
    pub admin_failures: u32,
    /// Behind a TLS-terminating reverse proxy: the client address is the last X-Forwarded-For
    /// address, and the admin cookie is Secure.
    #[arg(long)]
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

/// The buckets of each limit: by client address, or for answers by participant.
#[derive(Debug, Default)]
pub struct Buckets {
    joins: Mutex<HashMap<IpAddr, Bucket>>,
    screens: Mutex<HashMap<IpAddr, Bucket>>,
    /// By a hash of the participant's id and the credentials the request carries (a stranger
    /// guessing tokens for someone's id never drains that participant's bucket).
    responses: Mutex<HashMap<u64, Bucket>>,
    /// Answers without credentials, or refused for them, by client address.
    anonymous_responses: Mutex<HashMap<IpAddr, Bucket>>,
    admin_failures: Mutex<HashMap<IpAddr, Bucket>>,
    hasher: RandomState,
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
            let (map, what) =
                if kind == Kind::Join { (&buckets.joins, "joins") } else { (&buckets.screens, "screen checks") };
            if let Err(wait) = take(map, client, Rate::per_minute(limits.joins_per_minute), now) {
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
            if let Err(wait) = has_token(&buckets.anonymous_responses, &client, rate, now) {
                return anonymous(wait);
            }
            let Some(credentials) = request.headers().get(header::AUTHORIZATION) else {
                if let Err(wait) = take(&buckets.anonymous_responses, client, rate, now) {
                    return anonymous(wait);
                }
                return next.run(request).await;
            };
            let key = buckets.hasher.hash_one((participant, credentials.as_bytes()));
            if let Err(wait) = take(&buckets.responses, key, rate, now) {
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
                let _ = take(&buckets.anonymous_responses, client, rate, Instant::now());
            }
            response
        }
        // the right token is never refused nor counted (not even a change refused for a
        // missing X-Requested-With)
        Kind::Admin if limits.admin_failures > 0 && !admin => {
            let burst = limits.admin_failures as f64;
            let rate = Rate { burst, per_second: burst / ADMIN_WINDOW.as_secs_f64() };
            if let Err(wait) = has_token(&buckets.admin_failures, &client, rate, now) {
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
                let _ = take(&buckets.admin_failures, client, rate, Instant::now());
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

    #[derive(clap::Parser)]
    struct Flags {
        #[command(flatten)]
        limits: Limits,
        #[command(flatten)]
        connections: crate::serve::Connections,
    }

    #[test]
    fn the_flags_default_to_the_defaults_and_refuse_zero_seconds() {
        use clap::Parser;
        let flags = Flags::try_parse_from(["serve"]).unwrap();
        assert_eq!(flags.limits, Limits::default());
        assert_eq!(flags.connections, crate::serve::Connections::default());
        let flags = Flags::try_parse_from(["serve", "--join-limit", "0", "--header-timeout", "5"]).unwrap();
        assert_eq!(flags.limits.joins_per_minute, 0);
        assert_eq!(flags.connections.header_timeout, Duration::from_secs(5));
        let error = Flags::try_parse_from(["serve", "--body-timeout", "0"]).map(|_| ()).unwrap_err().to_string();
        assert!(error.contains("`0` is not a whole number of seconds"), "{error}");
    }

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
        let buckets = Buckets::default();
        let address: IpAddr = "203.0.113.9".parse().unwrap();
        let start = Instant::now();
        let people = 200u64;
        let mut refused = 0;
        for person in 0..people {
            // the class starts together: everyone joins within the first minute
            let at = start + Duration::from_millis(person * 300);
            refused += take(&buckets.screens, address, Rate::per_minute(limits.joins_per_minute), at).is_err() as u32;
            refused += take(&buckets.joins, address, Rate::per_minute(limits.joins_per_minute), at).is_err() as u32;
        }
        let rate = Rate::per_minute(limits.responses_per_minute);
        for step in 0..300u64 {
            for person in 0..people {
                let at = start + Duration::from_secs(60) + Duration::from_millis(step * 2000 + person * 7);
                let key = buckets.hasher.hash_one((format!("participant-{person}").as_str(), b"Bearer t".as_slice()));
                assert_eq!(has_token(&buckets.anonymous_responses, &address, rate, at), Ok(()));
                refused += take(&buckets.responses, key, rate, at).is_err() as u32;
            }
        }
        assert_eq!(refused, 0);
        // one script answering without pause as one participant is refused after its burst
        let key = buckets.hasher.hash_one(("script", b"Bearer s".as_slice()));
        let at = start + Duration::from_secs(700);
        let allowed = (0..1000).filter(|_| take(&buckets.responses, key, rate, at).is_ok()).count();
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
