//! The stimulus metrics CSV (`stimulus,scene,condition,metric,region,value`) read strictly:
//! the metrics, the regions and one record of values per stimulus.

use std::collections::HashMap;

use serde::Serialize;

use crate::error::{AnalysisError, Result};

/// An image metric of a stimulus against its ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    FlipMean,
    FlipP95,
    RmseLinear,
    RmseDisplay,
    Ssim,
    #[serde(rename = "ciede2000_mean")]
    Ciede2000Mean,
    #[serde(rename = "ciede2000_p95")]
    Ciede2000P95,
    RenderMs,
}

/// What a metric measures: an image error (or similarity) against the ground truth, which the
/// ranking compares, or a cost of making the image (a timing), which it lists apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MetricKind {
    /// An image error or similarity against the ground truth: ranked.
    ImageError,
    /// A cost such as a time in milliseconds (`render_ms`): listed apart, never ranked.
    Timing,
}

/// Which way a metric points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// An error: higher is further from the ground truth.
    Error,
    /// A similarity: higher is closer to the ground truth (`ssim`).
    Similarity,
    /// Neither (`render_ms`): ranked by the size of its correlation alone.
    None,
}

impl Metric {
    /// Every metric, in the order of docs/design.md.
    pub const ALL: [Metric; 8] = [
        Metric::FlipMean,
        Metric::FlipP95,
        Metric::RmseLinear,
        Metric::RmseDisplay,
        Metric::Ssim,
        Metric::Ciede2000Mean,
        Metric::Ciede2000P95,
        Metric::RenderMs,
    ];

    /// The name in the CSV and the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Metric::FlipMean => "flip_mean",
            Metric::FlipP95 => "flip_p95",
            Metric::RmseLinear => "rmse_linear",
            Metric::RmseDisplay => "rmse_display",
            Metric::Ssim => "ssim",
            Metric::Ciede2000Mean => "ciede2000_mean",
            Metric::Ciede2000P95 => "ciede2000_p95",
            Metric::RenderMs => "render_ms",
        }
    }

    pub fn parse(name: &str) -> Option<Metric> {
        Metric::ALL.into_iter().find(|metric| metric.name() == name)
    }

    /// Its kind, by name: a name ending in `_ms` (`render_ms`) is a timing, every other metric
    /// an image error.
    pub fn kind(self) -> MetricKind {
        if self.name().ends_with("_ms") { MetricKind::Timing } else { MetricKind::ImageError }
    }

    pub fn direction(self) -> Direction {
        match self {
            Metric::Ssim => Direction::Similarity,
            Metric::RenderMs => Direction::None,
            _ => Direction::Error,
        }
    }

    /// The correlation signed so that higher means it predicts preference better: −ρ for an
    /// error, +ρ for a similarity, |ρ| without a direction.
    pub fn agreement(self, rho: f64) -> f64 {
        match self.direction() {
            Direction::Error => -rho,
            Direction::Similarity => rho,
            Direction::None => rho.abs(),
        }
    }

    pub(crate) fn index(self) -> usize {
        self as usize
    }
}

/// The part of the image a metric was computed over.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Region {
    /// The whole image.
    Image,
    /// Where the virtual objects change the real scene (shadows, indirect light) or cover it.
    Affected,
    /// The virtual objects themselves.
    Virtual,
}

impl Region {
    pub const ALL: [Region; 3] = [Region::Image, Region::Affected, Region::Virtual];

    pub fn name(self) -> &'static str {
        match self {
            Region::Image => "image",
            Region::Affected => "affected",
            Region::Virtual => "virtual",
        }
    }

    pub fn parse(name: &str) -> Option<Region> {
        Region::ALL.into_iter().find(|region| region.name() == name)
    }

    pub(crate) fn index(self) -> usize {
        self as usize
    }
}

/// One value per metric and region, where given (`values[metric][region]`).
pub type MetricValues = [[Option<f64>; 3]; 8];

/// One stimulus of the metrics CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct StimulusRecord {
    /// The stimulus's file name in the store (its content hash).
    pub stimulus: String,
    pub scene: String,
    pub condition: String,
    pub values: MetricValues,
}

impl StimulusRecord {
    pub fn value(&self, metric: Metric, region: Region) -> Option<f64> {
        self.values[metric.index()][region.index()]
    }
}

/// The parsed stimulus metrics CSV: one record per (scene, condition), in order of first
/// appearance.
#[derive(Debug, Clone, Default)]
pub struct StimulusMetrics {
    pub stimuli: Vec<StimulusRecord>,
    index: HashMap<(String, String), usize>,
}

impl StimulusMetrics {
    /// The stimulus of a scene configuration under a condition.
    pub fn get(&self, scene: &str, condition: &str) -> Option<&StimulusRecord> {
        self.index.get(&(scene.to_string(), condition.to_string())).map(|&k| &self.stimuli[k])
    }

    /// Every stimulus of a condition.
    pub fn of_condition<'a>(&'a self, condition: &'a str) -> impl Iterator<Item = &'a StimulusRecord> + 'a {
        self.stimuli.iter().filter(move |record| record.condition == condition)
    }
}

/// Parses a stimulus metrics CSV (docs/design.md: `stimulus,scene,condition,metric,region,value`, in
/// any column order, other columns ignored). Every error names the source, line and column.
pub fn parse_stimulus_metrics(text: &str, source_name: &str) -> Result<StimulusMetrics> {
    let mut reader = crate::data::reader(text);
    let headers = reader.headers().map_err(|e| crate::data::csv_error(source_name, e))?.clone();
    let column = |name: &str| crate::data::header_index(source_name, &headers, name);
    let columns = [column("stimulus")?, column("scene")?, column("condition")?, column("metric")?, column("region")?];
    let value_column = column("value")?;
    let bad = |line: u64, column: &str, message: String| AnalysisError::BadValue {
        source_name: source_name.to_string(),
        line,
        column: column.to_string(),
        message,
    };
    let mut metrics = StimulusMetrics::default();
    // First line of each stimulus and of each (stimulus, metric, region).
    let mut stimulus_lines: Vec<u64> = Vec::new();
    let mut value_lines: HashMap<(usize, Metric, Region), u64> = HashMap::new();
    for record in reader.records() {
        let record = record.map_err(|e| crate::data::csv_error(source_name, e))?;
        let line = record.position().map_or(0, |p| p.line());
        let cell = |k: usize| record.get(k).unwrap_or("").trim();
        let [stimulus, scene, condition, metric_name, region_name] = columns.map(cell);
        for (name, value) in [("stimulus", stimulus), ("scene", scene), ("condition", condition)] {
            if value.is_empty() {
                return Err(bad(line, name, format!("the {name} is empty")));
            }
        }
        let metric = Metric::parse(metric_name).ok_or_else(|| {
            let names: Vec<&str> = Metric::ALL.iter().map(|m| m.name()).collect();
            bad(line, "metric", format!("`{metric_name}` is not a metric (metrics: {})", names.join(", ")))
        })?;
        let region = Region::parse(region_name).ok_or_else(|| {
            let names: Vec<&str> = Region::ALL.iter().map(|r| r.name()).collect();
            bad(line, "region", format!("`{region_name}` is not a region (regions: {})", names.join(", ")))
        })?;
        if metric == Metric::RenderMs && region != Region::Image {
            return Err(bad(
                line,
                "region",
                format!("`render_ms` is the time of the whole image: its region is `image`, not `{region_name}`"),
            ));
        }
        let value_text = cell(value_column);
        let value: f64 = value_text
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(line, "value", format!("`{value_text}` is not a finite number")))?;
        let key = (scene.to_string(), condition.to_string());
        let k = match metrics.index.get(&key) {
            Some(&k) => {
                let record = &metrics.stimuli[k];
                if record.stimulus != stimulus {
                    return Err(bad(
                        line,
                        "stimulus",
                        format!(
                            "scene `{scene}` under condition `{condition}` is stimulus `{}` on line {}, not `{stimulus}`",
                            record.stimulus, stimulus_lines[k]
                        ),
                    ));
                }
                k
            }
            None => {
                let k = metrics.stimuli.len();
                metrics.stimuli.push(StimulusRecord {
                    stimulus: stimulus.to_string(),
                    scene: scene.to_string(),
                    condition: condition.to_string(),
                    values: [[None; 3]; 8],
                });
                metrics.index.insert(key, k);
                stimulus_lines.push(line);
                k
            }
        };
        if let Some(&first_line) = value_lines.get(&(k, metric, region)) {
            return Err(AnalysisError::DuplicateRow {
                source_name: source_name.to_string(),
                line,
                what: format!(
                    "`{}` in region `{}` of scene `{scene}` under condition `{condition}`",
                    metric.name(),
                    region.name()
                ),
                first_line,
            });
        }
        value_lines.insert((k, metric, region), line);
        metrics.stimuli[k].values[metric.index()][region.index()] = Some(value);
    }
    if metrics.stimuli.is_empty() {
        return Err(AnalysisError::Empty(format!("{source_name}: there are no metrics in the file")));
    }
    Ok(metrics)
}
