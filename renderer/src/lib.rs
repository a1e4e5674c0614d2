//! `mrstudy-renderer`: scenes, the simulated camera, the CPU reference path tracer and the GPU
//! differential-rendering pipeline (differential instant radiosity, colour mapping, camera
//! artifacts).
//!
//! Invariant: the renderer knows nothing of studies, participants or HTTP. It turns a scene and a
//! condition into images, masks and timings.
//!
//! Not built yet: see the renderer issues. This crate holds only this documentation until then.
