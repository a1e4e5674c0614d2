//! Limits per client on the open internet: how often one client address may join a study,
//! answer trials, and give a wrong admin token, each a token bucket; over the limit a request
//! gets 429 with a sentence (JSON under `/api/`, a page elsewhere) and nothing is stored.
//!
//! The client address is the socket's peer ([`ClientAddr`], put on each request by
//! [`crate::serve`]), or behind a TLS proxy (`serve --behind-tls`) the last address of
//! `X-Forwarded-For`, the one the proxy added. A request without a [`ClientAddr`] (the router
//! driven in-process, as the tests do) is not limited.
//!
//! Admin API calls run one at a time (see [`limit`]).

use std::collections::HashMap;
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

/// How much one client address may do; 0 turns a limit off. Also `mrstudy serve`'s flags (the
/// doc comments are its help).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct Limits {
    /// Joins (new participants) per client address per minute, with bursts of twice that; 0: no limit.
    #[arg(long = "join-limit", default_value_t = Limits::default().joins_per_minute)]
    pub joins_per_minute: u32,
    /// Responses per client address per minute, with bursts of twice that; 0: no limit.
    #[arg(long = "response-limit", default_value_t = Limits::default().responses_per_minute)]
    pub responses_per_minute: u32,
    /// Wrong admin tokens (and admin calls refused with 403) per client address per 15 minutes
    /// before it is refused (429); 0: no limit.
    #[arg(long = "admin-failure-limit", default_value_t = Limits::default().admin_failures)]
    pub admin_failures: u32,
    /// Behind a TLS-terminating reverse proxy: the client address is the last X-Forwarded-For
    /// address, and the admin cookie is Secure.
    #[arg(long)]
    pub behind_tls: bool,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits { joins_per_minute: 30, responses_per_minute: 600, admin_failures: 10, behind_tls: false }
    }
}

/// Buckets by client address for each limit.
#[derive(Debug, Default)]
pub struct Buckets {
    joins: Mutex<HashMap<IpAddr, Bucket>>,
    responses: Mutex<HashMap<IpAddr, Bucket>>,
    admin_failures: Mutex<HashMap<IpAddr, Bucket>>,
}

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    at: Instant,
}

impl Bucket {
    /// The tokens at `now`: refilled at `per_second` since the last take, at most `burst`.
    fn refilled(&self, now: Instant, burst: f64, per_second: f64) -> f64 {
        (self.tokens + now.duration_since(self.at).as_secs_f64() * per_second).min(burst)
    }
}

/// Takes one token from `client`'s bucket (capacity `burst`, refilled at `per_second`); false
/// when it is empty. Full, idle buckets are dropped now and then so the map stays small.
fn take(map: &Mutex<HashMap<IpAddr, Bucket>>, client: IpAddr, burst: f64, per_second: f64, cost: f64) -> bool {
    let now = Instant::now();
    let mut map = map.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if map.len() > 100_000 {
        map.retain(|_, bucket| bucket.refilled(now, f64::INFINITY, per_second) < burst);
    }
    let bucket = map.entry(client).or_insert(Bucket { tokens: burst, at: now });
    bucket.tokens = bucket.refilled(now, burst, per_second);
    bucket.at = now;
    if bucket.tokens >= cost {
        bucket.tokens -= cost;
        true
    } else {
        false
    }
}

/// Whether `client` still has a token, without taking it.
fn has_token(map: &Mutex<HashMap<IpAddr, Bucket>>, client: IpAddr, burst: f64, per_second: f64) -> bool {
    let map = map.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    map.get(&client).is_none_or(|bucket| bucket.refilled(Instant::now(), burst, per_second) >= 1.0)
}

const ADMIN_WINDOW: Duration = Duration::from_secs(15 * 60);

/// Which limit a request falls under.
enum Kind {
    Join,
    Response,
    Admin,
    None,
}

fn kind(method: &Method, path: &str) -> Kind {
    let parts: Vec<&str> = path.trim_end_matches('/').split('/').collect();
    match (method, parts.as_slice()) {
        (&Method::POST, ["", "api", "studies", _, "participants"]) => Kind::Join,
        // a lab participant (task::join) joins under the same limit
        (&Method::POST, ["", "api", "lab", _, "participants"]) => Kind::Join,
        (&Method::POST, ["", "api", "participants", _, "responses"]) => Kind::Response,
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

/// The middleware: refuses a request over its limit with 429, counts admin refusals, and runs
/// admin API calls (exports, analyses: work that takes a worker thread for a while) one at a
/// time, so that however many an admin starts, participants' requests find free workers.
pub async fn limit(State(state): State<AppState>, request: Request, next: Next) -> Response {
    // only calls that carry a valid admin token or session wait for the one slot: a request
    // without one is refused by its handler at once and must not hold the slot meanwhile
    let _admin_work = if request.uri().path().starts_with("/api/admin/")
        && crate::auth::authorize_admin(&state, request.headers()).await.is_ok()
    {
        Some(state.admin_work().acquire().await.expect("the semaphore is never closed"))
    } else {
        None
    };
    let limits = state.limits();
    let Some(client) = client(&request, limits.behind_tls) else { return next.run(request).await };
    let buckets = state.buckets();
    let is_api = request.uri().path().starts_with("/api/");
    let per_minute = |n: u32| (2.0 * n as f64, n as f64 / 60.0);
    match kind(request.method(), request.uri().path()) {
        Kind::Join if limits.joins_per_minute > 0 => {
            let (burst, rate) = per_minute(limits.joins_per_minute);
            if !take(&buckets.joins, client, burst, rate, 1.0) {
                return too_many(is_api, "joins", limits.joins_per_minute, "a minute");
            }
            next.run(request).await
        }
        Kind::Response if limits.responses_per_minute > 0 => {
            let (burst, rate) = per_minute(limits.responses_per_minute);
            if !take(&buckets.responses, client, burst, rate, 1.0) {
                return too_many(is_api, "answers", limits.responses_per_minute, "a minute");
            }
            next.run(request).await
        }
        Kind::Admin if limits.admin_failures > 0 => {
            let burst = limits.admin_failures as f64;
            let rate = burst / ADMIN_WINDOW.as_secs_f64();
            if !has_token(&buckets.admin_failures, client, burst, rate) {
                return too_many(is_api, "wrong admin tokens", limits.admin_failures, "15 minutes");
            }
            let response = next.run(request).await;
            if response.status() == StatusCode::FORBIDDEN {
                take(&buckets.admin_failures, client, burst, rate, 1.0);
            }
            response
        }
        _ => next.run(request).await,
    }
}

fn too_many(is_api: bool, what: &str, limit: u32, window: &str) -> Response {
    let sentence =
        format!("Too many {what} from this address (at most {limit} in {window}); wait a little and try again.");
    let mut response = if is_api {
        AppError::TooManyRequests(sentence).into_response()
    } else {
        crate::pages::message_page(StatusCode::TOO_MANY_REQUESTS, "Too many requests", &sentence)
    };
    response.headers_mut().insert(header::RETRY_AFTER, axum::http::HeaderValue::from_static("60"));
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
    fn a_bucket_allows_its_burst_then_refuses_then_refills() {
        let map = Mutex::new(HashMap::new());
        let client: IpAddr = "192.0.2.1".parse().unwrap();
        let other: IpAddr = "192.0.2.2".parse().unwrap();
        for _ in 0..4 {
            assert!(take(&map, client, 4.0, 1000.0 / 60.0 / 1000.0, 1.0));
        }
        assert!(!take(&map, client, 4.0, 0.0, 1.0));
        assert!(take(&map, other, 4.0, 0.0, 1.0), "another address has its own bucket");
        // refilled at 1000 per second, one millisecond is a token
        std::thread::sleep(Duration::from_millis(5));
        assert!(take(&map, client, 4.0, 1000.0, 1.0));
    }

    #[test]
    fn requests_fall_under_their_limit_by_method_and_path() {
        assert!(matches!(kind(&Method::POST, "/api/studies/s/participants"), Kind::Join));
        assert!(matches!(kind(&Method::GET, "/api/studies/s/participants"), Kind::None));
        assert!(matches!(kind(&Method::POST, "/api/lab/s/participants"), Kind::Join));
        assert!(matches!(kind(&Method::POST, "/api/participants/p/responses"), Kind::Response));
        assert!(matches!(kind(&Method::GET, "/admin/login"), Kind::Admin));
        assert!(matches!(kind(&Method::GET, "/api/admin/studies"), Kind::Admin));
        assert!(matches!(kind(&Method::GET, "/administrator"), Kind::None));
    }
}
