//! `bench render --paper-tables`: Rohmer et al.'s Tables 2–4 (the seed paper
//! `002_600bda72b6c7b899`, Sec. 8, GTX 980 and i7-4790S) measured on this implementation, each
//! cell beside the paper's number:
//!
//! - **Table 2** (performance of the rendering phase): EM low and med, DIT med, VCT med and DIT
//!   high — the representation's build, the virtual object, material estimation and the
//!   differential background.
//! - **Table 3** (environment query timings): N = 16, 32, 64 samples for the object, material
//!   estimation and the differential background (cache 32), each method with and without the
//!   object's visibility (self-shadow) test; the three passes accumulated.
//! - **Table 4** (computing the virtual influence): the differential background alone over
//!   N = 8 … 128 directions and caches of 8, 16 and 32.
//!
//! Every frame is 640×360, the paper's differential image (its G-buffer is 320×180, its camera
//! 1280×720). Frames run on the CPU reference ([`crate::coherent`], all of rayon's threads); the
//! representations are built on the GPU where one opens, as in studies. One capture and, per
//! method, one representation serve Tables 3 and 4 (the representation does not depend on N or
//! the cache). No ground truth is rendered: the error of the settings is in
//! `bench render --gi-methods`. The paper's scenes (the toy car in an office, the Buddha) are
//! not available: the built-in scene (default survey-1) stands in for both.

use serde::Serialize;

use super::{Observer, Plot, Report, Series, load_sized, pass_ms};
use crate::coherent::render::CapturedScene;
use crate::coherent::{CoherentFrame, CoherentParams, Method, Quality, Settings};
use crate::error::Result;
use crate::gpu::{DirRenderer, PassTime};
use crate::reference::{ReferenceParams, render_photo};

/// One cell of one of the paper's tables, measured.
#[derive(Clone, Debug, Serialize)]
pub struct PaperRow {
    /// 2, 3 or 4.
    pub table: u32,
    pub scene: String,
    /// `em`, `dit` or `vct`.
    pub method: String,
    /// Table 2's quality setting (`low`, `med`, `high`).
    pub quality: Option<String>,
    /// Directions of the differential background (N of eqs. 8 and 9); in Table 3 also the
    /// object's and material estimation's samples.
    pub samples: u32,
    pub object_samples: u32,
    pub material_samples: u32,
    /// |H_a| of eq. 9.
    pub cache: u32,
    /// Whether the object's rays are tested against its solid volume (self-shadows).
    pub visibility: bool,
    /// Table 2: the representation's build (light probe, impostors or volume, solid volumes).
    pub representation_ms: Option<f64>,
    pub object_ms: f64,
    pub material_ms: f64,
    pub background_ms: f64,
    /// Every pass of the frame.
    pub frame_ms: f64,
    /// The measure the table reports: Table 2 object + material + background, Table 3 the
    /// same three accumulated, Table 4 the background.
    pub ms: f64,
    /// The paper's number for that measure on its PC (GTX 980); none where the paper gives it
    /// only on the Tango (EM in Table 2).
    pub paper_ms: Option<f64>,
    pub width: u32,
    pub height: u32,
    /// Where the frame ran and where the representation was built.
    pub device: String,
    pub passes: Vec<PassTime>,
}

/// Table 2's PC columns: object, material estimation, differential background (ms).
const TABLE2: [(Method, Quality, Option<[f64; 3]>); 5] = [
    (Method::Em, Quality::Low, None),
    (Method::Em, Quality::Med, None),
    (Method::Dit, Quality::Med, Some([5.1, 1.1, 0.8])),
    (Method::Vct, Quality::Med, Some([8.6, 1.2, 2.0])),
    (Method::Dit, Quality::High, Some([133.2, 18.6, 16.9])),
];

/// Table 3 (N = 16, 32, 64): without and with the visibility test, per method.
const TABLE3: [(Method, [f64; 3], [f64; 3]); 3] = [
    (Method::Em, [0.27, 0.48, 0.99], [9.88, 20.49, 42.12]),
    (Method::Dit, [3.57, 6.91, 13.82], [12.81, 25.81, 51.86]),
    (Method::Vct, [6.43, 12.14, 27.01], [18.97, 37.72, 79.24]),
];

/// Table 4 (N = 8, 16, 32, 64, 128) per method and cache 8, 16, 32.
const TABLE4: [(Method, [[f64; 5]; 3]); 3] = [
    (Method::Em, [[2.15, 2.62, 3.33, 3.85, 4.46], [2.16, 3.10, 4.90, 6.44, 7.36], [2.19, 3.11, 5.88, 9.51, 12.48]]),
    (Method::Dit, [[2.25, 3.27, 4.16, 4.67, 5.51], [2.74, 3.86, 6.05, 7.87, 9.86], [2.76, 3.85, 7.14, 11.56, 15.50]]),
    (Method::Vct, [[8.37, 3.98, 5.10, 5.73, 6.49], [8.34, 4.71, 7.56, 9.92, 11.10], [8.45, 4.71, 8.77, 14.57, 19.23]]),
];

const TABLE3_N: [u32; 3] = [16, 32, 64];
const TABLE4_N: [u32; 5] = [8, 16, 32, 64, 128];
const CACHES: [u32; 3] = [8, 16, 32];

/// Runs the three tables on `scene_name` (default survey-1); `quick`: 160×90 and the first
/// and last column of each table (a check that it runs, not a measurement).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<PaperRow>> {
    let name = scene_name.unwrap_or("survey-1");
    let (w, h) = if quick { (160, 90) } else { (640, 360) };
    let scene = load_sized(name, w, h)?;
    let renderer = DirRenderer::new().ok();
    let cpu = format!("CPU, {} threads", rayon::current_num_threads());
    let adapter = renderer.as_ref().map_or("no GPU (representations on the CPU)".to_string(), |r| r.ctx.adapter_name());
    let device = format!("frame {cpu}; representation {adapter}");
    observer.note(&format!("bench render --paper-tables: {name} at {w}×{h}; {device}"));
    let (linear, _, _) = render_photo(&scene, &ReferenceParams { spp: 4, ..ReferenceParams::default() }, &|_, _| {})?;
    observer.note(&format!("{name}: capture ({} poses) …", crate::coherent::render::POSES));
    let captured = CapturedScene::new(&scene, 1, &|done, total| observer.progress("capture", done, total));
    observer.line(&format!(
        "{:<5} {:<4} {:<5} {:>4} {:>5} {:<4} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>8}",
        "table", "gi", "set", "N", "cache", "vis", "repr.", "object", "material", "backgr.", "ms", "paper ms", "ratio"
    ));
    let mut rows = Vec::new();
    let frame = |params: &CoherentParams, rep: &crate::coherent::query::Representation| -> Result<CoherentFrame> {
        captured.frame(&scene, rep, params, &linear, &|_, _| {})
    };
    let pick =
        |values: &[u32]| -> Vec<usize> { if quick { vec![0, values.len() - 1] } else { (0..values.len()).collect() } };

    // Table 2: each setting with its own representation
    let table2: Vec<_> = if quick { vec![TABLE2[2], TABLE2[4]] } else { TABLE2.to_vec() };
    for (method, quality, paper) in table2 {
        let params = CoherentParams::new(method, quality);
        let (rep, build) = captured.representation(&scene, &params, renderer.as_ref());
        let out = frame(&params, &rep)?;
        let representation_ms = build.iter().map(|p| p.ms).sum::<f64>();
        let mut row = measured(2, name, &params, &out, &device, w, h);
        row.quality = Some(quality.name().into());
        row.representation_ms = Some(representation_ms);
        row.ms = row.object_ms + row.material_ms + row.background_ms;
        row.paper_ms = paper.map(|p| p.iter().sum());
        row.passes = build.into_iter().chain(row.passes).collect();
        print_row(observer, &row);
        rows.push(row);
    }

    // Tables 3 and 4: one representation per method (med's sizes, solid volumes built)
    for ((method, without, with), (_, table4)) in TABLE3.iter().zip(TABLE4.iter()) {
        let base = CoherentParams::new(*method, Quality::Med);
        let (rep, _) = captured.representation(&scene, &base, renderer.as_ref());
        for k in pick(&TABLE3_N) {
            let n = TABLE3_N[k];
            for visibility in [false, true] {
                let settings = Settings {
                    object_samples: n,
                    material_samples: n,
                    background_samples: n,
                    cache: 32,
                    self_shadow: visibility,
                    secondary_bounce: false,
                    ..base.settings
                };
                let params = CoherentParams { settings, ..base };
                let mut row = measured(3, name, &params, &frame(&params, &rep)?, &device, w, h);
                row.ms = row.object_ms + row.material_ms + row.background_ms;
                row.paper_ms = Some(if visibility { with[k] } else { without[k] });
                print_row(observer, &row);
                rows.push(row);
            }
        }
        for (c, &cache) in CACHES.iter().enumerate() {
            for k in pick(&TABLE4_N) {
                let n = TABLE4_N[k];
                let settings = Settings { background_samples: n, cache, ..base.settings };
                let params = CoherentParams { settings, ..base };
                let mut row = measured(4, name, &params, &frame(&params, &rep)?, &device, w, h);
                row.ms = row.background_ms;
                row.paper_ms = Some(table4[c][k]);
                print_row(observer, &row);
                rows.push(row);
            }
        }
    }
    let plots = vec![table4_plot(&rows, name, w, h)];
    Ok(Report { adapter: device, rows, plots })
}

/// A row of `table` from a frame: its passes' times by name.
fn measured(
    table: u32,
    scene: &str,
    params: &CoherentParams,
    frame: &CoherentFrame,
    device: &str,
    w: u32,
    h: u32,
) -> PaperRow {
    let pass = |prefix: &str| pass_ms(&frame.report.passes, |p| p.starts_with(prefix));
    let s = &params.settings;
    PaperRow {
        table,
        scene: scene.to_string(),
        method: params.method.name().into(),
        quality: None,
        samples: s.background_samples,
        object_samples: s.object_samples,
        material_samples: s.material_samples,
        cache: s.cache,
        visibility: s.self_shadow,
        representation_ms: None,
        object_ms: pass("virtual object"),
        material_ms: pass("material estimation"),
        background_ms: pass("differential background"),
        frame_ms: frame.report.total_ms(),
        ms: 0.0,
        paper_ms: None,
        width: w,
        height: h,
        device: device.to_string(),
        passes: frame.report.passes.clone(),
    }
}

fn print_row(observer: &dyn Observer, row: &PaperRow) {
    let optional = |value: Option<f64>, digits: usize| value.map_or("–".to_string(), |v| format!("{v:.digits$}"));
    let ratio = row.paper_ms.filter(|&p| p > 0.0).map(|p| format!("{:.1}×", row.ms / p));
    observer.line(&format!(
        "{:<5} {:<4} {:<5} {:>4} {:>5} {:<4} {:>8} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>9} {:>8}",
        row.table,
        row.method,
        row.quality.as_deref().unwrap_or("–"),
        row.samples,
        row.cache,
        if row.visibility { "yes" } else { "no" },
        optional(row.representation_ms, 1),
        row.object_ms,
        row.material_ms,
        row.background_ms,
        row.ms,
        optional(row.paper_ms, 2),
        ratio.unwrap_or_else(|| "–".into()),
    ));
}

/// Table 4 at cache 32: the differential background's time against N, per method, measured
/// and the paper's.
fn table4_plot(rows: &[PaperRow], scene: &str, w: u32, h: u32) -> Plot {
    let mut series = Vec::new();
    for method in ["em", "dit", "vct"] {
        let cells: Vec<&PaperRow> =
            rows.iter().filter(|r| r.table == 4 && r.method == method && r.cache == 32).collect();
        series.push(Series::new(method, cells.iter().map(|r| (r.samples as f64, r.ms)).collect()));
        series.push(Series::new(
            &format!("{method} (paper, GTX 980)"),
            cells.iter().filter_map(|r| r.paper_ms.map(|p| (r.samples as f64, p))).collect(),
        ));
    }
    Plot {
        file: "render_paper_table4.svg".into(),
        title: format!("Rohmer et al. Table 4, cache 32: differential background against N ({scene}, {w}x{h})"),
        x_label: "directions N".into(),
        y_label: "ms".into(),
        x_log: true,
        y_log: true,
        series,
    }
}
