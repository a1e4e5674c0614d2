//! The renderer's benchmarks, behind `mrstudy bench render`: the GPU renderer's frame time and
//! error against the path-traced ground truth ([`gpu`]), the reference path tracer's
//! convergence ([`reference`](mod@reference)), the accuracy of the `ca` ([`ca`]) and `cm` ([`cm`]) factors, and
//! the global-illumination methods a study can compare, DIR against EM, DIT and VCT ([`methods`]),
//! the thesis's real-time settings frame after frame ([`frame_rate`]), and Rohmer et al.'s
//! Tables 2–4 beside the paper's numbers ([`paper_tables`]).
//!
//! Each returns a typed [`Report`]: the adapter, one typed row per measurement (serialised as
//! the rows of docs/design.md's bench JSON, `{"adapter": "...", "rows": [...]}`, by
//! [`Report::to_json`]) and the curves to plot. While it runs it hands its table lines, notes
//! and the progress of each reference render to an [`Observer`]; it prints nothing itself.

pub mod ca;
pub mod cm;
pub mod frame_rate;
pub mod gpu;
pub mod methods;
pub mod paper_tables;
pub mod reference;

use serde::Serialize;

use crate::error::Result;
use crate::reference::{ReferenceOutput, ReferenceParams, render_reference};
use crate::scene::{self, Scene};

/// What a running benchmark reports as it goes.
pub trait Observer: Sync {
    /// One line of the benchmark's table (the CLI prints it to stdout).
    fn line(&self, text: &str);
    /// What is being done (the CLI prints it to stderr).
    fn note(&self, text: &str);
    /// `done` of `total` samples of a reference render labelled `label`; `done == total` ends it.
    fn progress(&self, label: &str, done: u32, total: u32);
}

/// One curve of a [`Plot`].
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// A line plot of a benchmark's curves, to be drawn into `file` (an SVG file name).
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    pub file: String,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x_log: bool,
    pub y_log: bool,
    pub series: Vec<Series>,
}

impl Series {
    fn new(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series { name: name.to_string(), points }
    }
}

/// A benchmark's result: the adapter it ran on, its rows and its plots.
#[derive(Clone, Debug)]
pub struct Report<R> {
    pub adapter: String,
    pub rows: Vec<R>,
    pub plots: Vec<Plot>,
}

impl<R: Serialize> Report<R> {
    /// docs/design.md's bench JSON: `{"adapter": "...", "rows": [...]}`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "adapter": self.adapter, "rows": self.rows })
    }
}

/// A scene by name or path at `width`×`height`.
fn load_sized(name: &str, width: u32, height: u32) -> Result<Scene> {
    scene::load_as(name, Some((width, height)), None)
}

/// The ground-truth composite of `scene` (16 samples per pass), its progress reported as
/// `reference`.
fn ground_truth(scene: &Scene, params: ReferenceParams, observer: &dyn Observer) -> Result<ReferenceOutput> {
    let total = 2 * params.spp;
    let params = ReferenceParams { pass_spp: 16, ..params };
    let output = render_reference(scene, &params, &|done, _| observer.progress("reference", done, total))?;
    observer.progress("reference", total, total);
    Ok(output)
}

/// The summed time of the passes (a GPU frame's or a coherent frame's) whose name `selects`.
fn pass_ms(passes: &[crate::gpu::PassTime], selects: impl Fn(&str) -> bool) -> f64 {
    // from +0.0: an empty f64 sum is -0.0, which would print as "-0.0 ms"
    passes.iter().filter(|p| selects(&p.pass)).map(|p| p.ms).fold(0.0, |a, b| a + b)
}
