//! What the host asks of the device, counted by the GPU context ([`super::context::GpuContext`])
//! where it happens: submissions, waits, read-backs, uploads, allocations, and the host time
//! spent recording, submitting and waiting (issue 50, Deliver 3).

use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// The structure of the work the host gave the device, counted where it happens (every
/// submission, wait, read-back, upload and allocation of this crate goes through the context),
/// so the counts are exact on any adapter, lavapipe included (issue 50, Deliver 3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameCounters {
    /// Queue submissions.
    pub submits: u64,
    /// Command encoders finished (`encoder.finish()`: a frame's passes record into one encoder
    /// per submission, [`super::stream`]; timed passes one each, with their timestamps').
    pub encoders: u64,
    /// Blocking waits of the host for the device (a poll that waits, a buffer mapped for reading).
    pub host_waits: u64,
    /// Bytes mapped and copied back to the host.
    pub readback_bytes: u64,
    /// Bytes written from the host into buffers and textures (`write_buffer`, `write_texture`,
    /// buffers made with contents).
    pub upload_bytes: u64,
    /// Buffers and textures made anew (not taken from the pool), including uniform buffers.
    pub allocations: u64,
    /// Host time of the frame spent recording, on CPU steps and waiting for the device: the
    /// frame's wall-clock time on the host, the sum of `record_ms`, `submit_ms`, `wait_ms` and
    /// `host_steps_ms`.
    pub cpu_ms: f64,
    /// Of `cpu_ms`, the time blocked in host waits (on a software adapter this is the device's
    /// own work, run on the host's cores): `cpu_ms` − `wait_ms` is the renderer's own host time.
    pub wait_ms: f64,
    /// Of `cpu_ms`, the time recording commands: bind groups made and compute dispatches
    /// recorded through the context ([`super::context::GpuContext::record_dispatch`], [`super::context::GpuContext::bind_group`])
    /// and command encoders' `finish` (where wgpu encodes the recorded passes into the backend's
    /// command buffers; render passes' draws recorded before it count in `host_steps_ms`).
    pub record_ms: f64,
    /// Of `cpu_ms`, the time inside `queue.submit` (on lavapipe a submission made while earlier
    /// work runs waits for it there; a frame's one submission, made with the device idle,
    /// returns after the hand-off and its work shows as `wait_ms`).
    pub submit_ms: f64,
    /// The rest of `cpu_ms` (`cpu_ms` − `record_ms` − `submit_ms` − `wait_ms`): the frame's
    /// CPU steps — the scene's mesh, uniforms and uploads, CPU passes, the read-back's copies.
    pub host_steps_ms: f64,
}

impl FrameCounters {
    /// The header of a table of counters ([`FrameCounters::cells`]).
    pub const HEADER: &str =
        "submits encoders waits readback MB upload MB allocs  cpu ms  wait ms record ms submit ms host steps ms";

    /// The counters as table cells under [`FrameCounters::HEADER`].
    pub fn cells(&self) -> String {
        format!(
            "{:>7} {:>8} {:>5} {:>11.3} {:>9.3} {:>6} {:>7.2} {:>8.2} {:>9.2} {:>9.2} {:>13.2}",
            self.submits,
            self.encoders,
            self.host_waits,
            self.readback_bytes as f64 / 1e6,
            self.upload_bytes as f64 / 1e6,
            self.allocations,
            self.cpu_ms,
            self.wait_ms,
            self.record_ms,
            self.submit_ms,
            self.host_steps_ms
        )
    }

    /// The counters with the frame's wall-clock host time `cpu_ms` and what of it is neither
    /// recording, submitting nor waiting (`host_steps_ms`, never below 0).
    pub fn with_cpu_ms(self, cpu_ms: f64) -> FrameCounters {
        let host_steps_ms = (cpu_ms - self.record_ms - self.submit_ms - self.wait_ms).max(0.0);
        FrameCounters { cpu_ms, host_steps_ms, ..self }
    }
}

#[derive(Default)]
pub(super) struct CounterCells {
    pub(super) submits: AtomicU64,
    pub(super) encoders: AtomicU64,
    pub(super) host_waits: AtomicU64,
    pub(super) readback_bytes: AtomicU64,
    pub(super) upload_bytes: AtomicU64,
    pub(super) allocations: AtomicU64,
    pub(super) wait_ns: AtomicU64,
    pub(super) record_ns: AtomicU64,
    pub(super) submit_ns: AtomicU64,
}

/// Adds the nanoseconds since `start` to `cell`.
pub(super) fn add_elapsed(cell: &AtomicU64, start: Instant) {
    cell.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
}
