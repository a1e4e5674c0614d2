//! What keeps a client from holding `serve`'s connections ([`crate::serve::serve_connections`]
//! uses these, with the times and caps of [`crate::serve::Connections`]):
//!
//! - [`Clock`]: per connection, when its current request began (the connection's start or the
//!   end of its last response) and whether a request is being served, so that the accept loop
//!   closes a connection whose request (headers and body together) is not in by
//!   `--request-timeout`, or that sits idle longer than `--header-timeout`;
//! - [`DeadlineBody`]: a request body that fails once its deadline passes, however the bytes
//!   trickle in (tower-http's `TimeoutBody` restarts its clock at every frame, so 10 bytes
//!   every 20 s kept a connection for minutes);
//! - [`WriteDeadline`]: a socket whose writes fail when the client has not taken a byte for
//!   `--write-timeout` (a client that never reads its responses);
//! - [`Table`]: the open connections by client address, with a cap per address (IPv6 by /64)
//!   and a global cap that makes room for a newcomer by closing the oldest connection of the
//!   address holding the most, so one address (or a few) cannot keep others out.

use std::collections::HashMap;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::{Instant, Sleep};

/// A timeout flag's value that is not a whole number of seconds, at least 1.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[error("`{text}` is not a whole number of seconds, at least 1")]
pub struct SecondsError {
    pub text: String,
}

/// A timeout in whole seconds, at least 1 (`serve`'s timeout flags).
pub fn parse_seconds(text: &str) -> Result<Duration, SecondsError> {
    match text.trim().parse::<u64>() {
        Ok(seconds) if seconds >= 1 => Ok(Duration::from_secs(seconds)),
        _ => Err(SecondsError { text: text.to_string() }),
    }
}

/// When a connection's current request began, and how many of its requests are being served
/// (their responses not yet written whole).
#[derive(Debug)]
pub struct Clock {
    since: Mutex<Instant>,
    in_flight: AtomicUsize,
}

impl Clock {
    /// A clock for a connection accepted now.
    pub fn new() -> Arc<Clock> {
        Arc::new(Clock { since: Mutex::new(Instant::now()), in_flight: AtomicUsize::new(0) })
    }

    /// When the current request began: the connection's start or the end of its last response.
    pub fn since(&self) -> Instant {
        *self.since.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// A request's headers are in: it is served until [`Clock::response_written`].
    pub fn request_started(&self) {
        self.in_flight.fetch_add(1, Ordering::SeqCst);
    }

    /// A response has been written whole (its body dropped): the next request's clock starts.
    pub fn response_written(&self) {
        *self.since.lock().unwrap_or_else(|poisoned| poisoned.into_inner()) = Instant::now();
        self.in_flight.fetch_sub(1, Ordering::SeqCst);
    }

    /// Whether a request is being served.
    pub fn busy(&self) -> bool {
        self.in_flight.load(Ordering::SeqCst) > 0
    }
}

/// A response body that tells its connection's [`Clock`] when it is gone (written whole, or
/// dropped because the connection closed).
pub struct TrackedBody {
    inner: axum::body::Body,
    clock: Arc<Clock>,
}

impl TrackedBody {
    /// `inner`, telling `clock` when it is dropped; call [`Clock::request_started`] first.
    pub fn new(inner: axum::body::Body, clock: Arc<Clock>) -> TrackedBody {
        TrackedBody { inner, clock }
    }
}

impl Drop for TrackedBody {
    fn drop(&mut self) {
        self.clock.response_written();
    }
}

impl http_body::Body for TrackedBody {
    type Data = axum::body::Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// Why a request body stopped: it was not in by its deadline.
#[derive(Debug, thiserror::Error)]
#[error("the request was not received within {0:?}")]
pub struct TooSlow(pub Duration);

/// A request body that fails with [`TooSlow`] once `deadline` passes, however its bytes
/// trickle in.
pub struct DeadlineBody<B> {
    inner: B,
    deadline: Pin<Box<Sleep>>,
    allowed: Duration,
}

impl<B> DeadlineBody<B> {
    /// `inner`, cut off at `deadline`; `allowed` is the time the client had, for the error.
    pub fn new(inner: B, deadline: Instant, allowed: Duration) -> DeadlineBody<B> {
        DeadlineBody { inner, deadline: Box::pin(tokio::time::sleep_until(deadline)), allowed }
    }
}

impl<B> http_body::Body for DeadlineBody<B>
where
    B: http_body::Body + Unpin,
    B::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    type Data = B::Data;
    type Error = Box<dyn std::error::Error + Send + Sync>;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        if self.inner.is_end_stream() {
            return Poll::Ready(None);
        }
        if self.deadline.as_mut().poll(cx).is_ready() {
            return Poll::Ready(Some(Err(Box::new(TooSlow(self.allowed)))));
        }
        Pin::new(&mut self.inner).poll_frame(cx).map_err(Into::into)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// A socket whose writes (and flushes) fail with `TimedOut` when none of its bytes could be
/// sent for `timeout`: the client has stopped reading. Reads are untouched.
pub struct WriteDeadline<S> {
    inner: S,
    timeout: Duration,
    /// Armed while a write waits for the client to read.
    stall: Option<Pin<Box<Sleep>>>,
}

impl<S> WriteDeadline<S> {
    pub fn new(inner: S, timeout: Duration) -> WriteDeadline<S> {
        WriteDeadline { inner, timeout, stall: None }
    }

    /// After a write returned `Pending`: Pending while the stall is within the timeout, else
    /// the error that closes the connection.
    fn stalled<T>(&mut self, cx: &mut Context<'_>) -> Poll<std::io::Result<T>> {
        let timeout = self.timeout;
        let stall = self.stall.get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
        match stall.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("the client read nothing for {timeout:?}"),
            ))),
            Poll::Pending => Poll::Pending,
        }
    }

    fn progressed<T>(&mut self, result: Poll<std::io::Result<T>>, cx: &mut Context<'_>) -> Poll<std::io::Result<T>> {
        match result {
            Poll::Pending => self.stalled(cx),
            ready => {
                self.stall = None;
                ready
            }
        }
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for WriteDeadline<S> {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for WriteDeadline<S> {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<std::io::Result<usize>> {
        let result = Pin::new(&mut self.inner).poll_write(cx, buf);
        self.progressed(result, cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let result = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        self.progressed(result, cx)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        let result = Pin::new(&mut self.inner).poll_flush(cx);
        self.progressed(result, cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        let result = Pin::new(&mut self.inner).poll_shutdown(cx);
        self.progressed(result, cx)
    }
}

/// The address a connection counts under: an IPv4 address, or the /64 of an IPv6 address
/// (one host usually holds a whole /64).
fn address_key(address: IpAddr) -> IpAddr {
    match address {
        IpAddr::V4(_) => address,
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => IpAddr::V4(v4),
            None => {
                let segments = v6.segments();
                IpAddr::V6(std::net::Ipv6Addr::new(segments[0], segments[1], segments[2], segments[3], 0, 0, 0, 0))
            }
        },
    }
}

/// The open connections by client address (see the module doc).
#[derive(Debug)]
pub struct Table {
    max_total: usize,
    /// 0: no cap per address.
    max_per_address: usize,
    inner: Mutex<TableInner>,
}

#[derive(Debug, Default)]
struct TableInner {
    next_id: u64,
    total: usize,
    /// Per address, its connections oldest first: id and the sender that closes it.
    by_address: HashMap<IpAddr, Vec<(u64, tokio::sync::oneshot::Sender<()>)>>,
}

/// Why a connection was not admitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// Its address already holds `--max-connections-per-address`.
    PerAddress,
    /// The server is full and its address holds as many connections as any other.
    Full,
}

/// An admitted connection: removes itself from the table when dropped; `closed` resolves when
/// the table closes it to make room for another address.
#[derive(Debug)]
pub struct Admitted {
    table: Arc<Table>,
    key: IpAddr,
    id: u64,
    pub closed: tokio::sync::oneshot::Receiver<()>,
}

impl Drop for Admitted {
    fn drop(&mut self) {
        let mut inner = self.table.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let inner = &mut *inner;
        if let Some(connections) = inner.by_address.get_mut(&self.key)
            && let Some(index) = connections.iter().position(|(id, _)| *id == self.id)
        {
            connections.remove(index);
            inner.total -= 1;
            if connections.is_empty() {
                inner.by_address.remove(&self.key);
            }
        }
    }
}

impl Table {
    /// At most `max_total` connections (at least 1), `max_per_address` from one address (0: no cap).
    pub fn new(max_total: usize, max_per_address: usize) -> Arc<Table> {
        Arc::new(Table { max_total: max_total.max(1), max_per_address, inner: Mutex::default() })
    }

    /// Connections open now.
    pub fn open(&self) -> usize {
        self.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).total
    }

    /// Admits a connection from `address`, or says why not. When the server is full, the
    /// oldest connection of the address holding the most is closed to make room, unless the
    /// newcomer's address holds as many.
    pub fn admit(self: &Arc<Table>, address: IpAddr) -> Result<Admitted, Refused> {
        let key = address_key(address);
        let mut inner = self.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let held = inner.by_address.get(&key).map_or(0, Vec::len);
        if self.max_per_address > 0 && held >= self.max_per_address {
            return Err(Refused::PerAddress);
        }
        if inner.total >= self.max_total {
            let heaviest = inner
                .by_address
                .iter()
                .max_by_key(|(_, connections)| connections.len())
                .map(|(key, connections)| (*key, connections.len()));
            match heaviest {
                Some((heaviest, count)) if count > held + 1 => {
                    let connections = inner.by_address.get_mut(&heaviest).expect("the address was just found");
                    let (_, close) = connections.remove(0);
                    if connections.is_empty() {
                        inner.by_address.remove(&heaviest);
                    }
                    inner.total -= 1;
                    let _ = close.send(());
                }
                _ => return Err(Refused::Full),
            }
        }
        let (close, closed) = tokio::sync::oneshot::channel();
        let id = inner.next_id;
        inner.next_id += 1;
        inner.total += 1;
        inner.by_address.entry(key).or_default().push((id, close));
        Ok(Admitted { table: self.clone(), key, id, closed })
    }
}

/// What a refused connection is sent before it is closed (if its socket takes it at once).
pub fn refusal_response(refused: Refused) -> Vec<u8> {
    let sentence = match refused {
        Refused::PerAddress => "Too many connections from this address; wait a little and try again.",
        Refused::Full => "The server is busy; wait a little and try again.",
    };
    let body = serde_json::json!({ "error": sentence }).to_string();
    format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\nretry-after: 5\r\nconnection: close\r\ncontent-length: {}\r\n\r\n{body}",
        body.len()
    )
    .into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(text: &str) -> IpAddr {
        text.parse().unwrap()
    }

    #[tokio::test]
    async fn the_cap_per_address_refuses_and_a_closed_connection_frees_its_place() {
        let table = Table::new(100, 2);
        let first = table.admit(ip("192.0.2.1")).unwrap();
        let _second = table.admit(ip("192.0.2.1")).unwrap();
        assert_eq!(table.admit(ip("192.0.2.1")).unwrap_err(), Refused::PerAddress);
        assert!(table.admit(ip("192.0.2.2")).is_ok(), "another address has its own cap");
        drop(first);
        assert!(table.admit(ip("192.0.2.1")).is_ok());
        // one host of an IPv6 /64 counts as one address
        let _a = table.admit(ip("2001:db8::1")).unwrap();
        let _b = table.admit(ip("2001:db8::2")).unwrap();
        assert_eq!(table.admit(ip("2001:db8::3")).unwrap_err(), Refused::PerAddress);
        assert!(table.admit(ip("2001:db8:0:1::1")).is_ok());
    }

    #[tokio::test]
    async fn a_full_server_closes_the_oldest_connection_of_the_heaviest_address() {
        let table = Table::new(4, 0);
        let mut flood: Vec<Admitted> = (0..3).map(|_| table.admit(ip("192.0.2.1")).unwrap()).collect();
        let _one = table.admit(ip("192.0.2.2")).unwrap();
        // full: a newcomer from a third address takes the flood's oldest place
        let newcomer = table.admit(ip("192.0.2.3")).unwrap();
        assert_eq!(table.open(), 4);
        assert!(flood[0].closed.try_recv().is_ok(), "the oldest of the heaviest address is closed");
        assert!(flood[1].closed.try_recv().is_err());
        // the flood's address cannot take places from others holding fewer
        assert_eq!(table.admit(ip("192.0.2.1")).unwrap_err(), Refused::Full);
        drop(newcomer);
        assert!(table.admit(ip("192.0.2.1")).is_ok(), "a free place is anybody's");
        drop(flood);
    }
}
