//! Who may open a lab session: at most [`MAX_SESSIONS`] at once over all task studies and at
//! most [`super::Lab::sessions_per_address`] from one client address, counted by
//! a `SessionSlot` held for the session's life; the client address of an upgrade, behind a TLS
//! proxy too. The session itself is [`super::session`].

use std::sync::Arc;

use super::Lab;

/// Lab sessions at once, over all task studies.
pub const MAX_SESSIONS: usize = 64;

/// Counts a live session, in all and for its client address; uncounts it when dropped.
pub(super) struct SessionSlot {
    lab: Arc<Lab>,
    address: Option<std::net::IpAddr>,
}

/// Why no session slot was free.
pub(super) enum Full {
    Lab,
    Address(usize),
}

impl SessionSlot {
    pub(super) fn take(lab: &Arc<Lab>, address: Option<std::net::IpAddr>) -> Result<SessionSlot, Full> {
        use std::sync::atomic::Ordering;
        lab.sessions
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| (n < MAX_SESSIONS).then_some(n + 1))
            .map_err(|_| Full::Lab)?;
        if let Some(address) = address {
            let cap = lab.sessions_per_address();
            let mut open = lab.by_address.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            let count = open.entry(address).or_insert(0);
            if cap > 0 && *count >= cap {
                lab.sessions.fetch_sub(1, Ordering::AcqRel);
                return Err(Full::Address(cap));
            }
            *count += 1;
        }
        Ok(SessionSlot { lab: lab.clone(), address })
    }
}

impl Drop for SessionSlot {
    fn drop(&mut self) {
        self.lab.sessions.fetch_sub(1, std::sync::atomic::Ordering::AcqRel);
        if let Some(address) = self.address {
            let mut open = self.lab.by_address.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            if let Some(count) = open.get_mut(&address) {
                *count = count.saturating_sub(1);
                if *count == 0 {
                    open.remove(&address);
                }
            }
        }
    }
}

/// The client address of an upgrade: the socket's peer, or behind a TLS proxy the last
/// `X-Forwarded-For` address (as [`crate::limits::client`] finds it).
pub(super) fn client_address(
    peer: Option<crate::limits::ClientAddr>,
    headers: &axum::http::HeaderMap,
    behind_tls: bool,
) -> Option<std::net::IpAddr> {
    let peer = peer?.0;
    if !behind_tls {
        return Some(peer);
    }
    let forwarded = headers
        .get_all("x-forwarded-for")
        .iter()
        .filter_map(|value| value.to_str().ok())
        .flat_map(|value| value.split(','))
        .next_back()
        .and_then(|address| address.trim().parse().ok());
    Some(forwarded.unwrap_or(peer))
}
