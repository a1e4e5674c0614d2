//! `mrstudy-server`: the study server — study files, trial scheduling, sqlite storage through
//! sqlx, the participant pages, the admin API and export, live-render WebSocket.
//!
//! Invariant: only this crate and the CLI touch the network and the database.
//!
//! Not built yet: see the web-survey issue. This crate holds only this documentation until then.
