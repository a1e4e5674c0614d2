//! Study files (`studies/*.toml`): parsing and validation.
//!
//! A study file is read into `StudyFile` (the raw TOML shape, unknown keys refused) and then
//! checked and resolved into a [`Study`]: condition names are unique, every condition gives a
//! level for every factor, every scene configuration has a stimulus for every condition, the
//! design names only defined conditions, and image files exist. Every refusal is a
//! [`StudyError`] naming the file, the key and what was expected, so `serve` can print it as one
//! sentence. The schema is documented for researchers in `studies/README.md`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use crate::study_file::StudyError;
pub(crate) use crate::study_file::{is_slug, one_line, sha256_hex};

/// What kind of study a file describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyKind {
    /// Forced-choice paired comparisons on the web.
    PairedComparison,
    /// Timed task trials in the lab against the live renderer (not served by the web survey).
    Task,
}

impl StudyKind {
    pub fn as_str(self) -> &'static str {
        match self {
            StudyKind::PairedComparison => "paired-comparison",
            StudyKind::Task => "task",
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The raw file shape.

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    slug: String,
    title: String,
    kind: StudyKind,
    question: String,
    #[serde(default = "default_true")]
    open: bool,
    texts: TextsFile,
    #[serde(default)]
    demographics: Vec<DemographicField>,
    #[serde(default = "default_url_params")]
    url_params: Vec<String>,
    factors: Vec<Factor>,
    conditions: Vec<ConditionFile>,
    #[serde(default)]
    render: Option<RenderDefaults>,
    scenes: Vec<SceneFile>,
    design: DesignFile,
    #[serde(default)]
    catch: Vec<CatchFile>,
    #[serde(default)]
    completion: Completion,
    #[serde(default = "default_min_response_ms")]
    min_response_ms: u32,
    #[serde(default)]
    unique_external_id: bool,
    #[serde(default)]
    min_viewport: Option<[u32; 2]>,
    #[serde(default)]
    devices: Option<Vec<Device>>,
    #[serde(default)]
    orientation: Option<Orientation>,
    #[serde(default)]
    display: Display,
    #[serde(default = "default_abandon_after_minutes")]
    abandon_after_minutes: u32,
}

fn default_min_response_ms() -> u32 {
    300
}

fn default_abandon_after_minutes() -> u32 {
    30
}

/// A kind of device a participant may use (`devices = ["desktop"]`); told apart on the client by
/// its pointer and screen (see `web/static/survey.js`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    Desktop,
    Tablet,
    Phone,
}

impl Device {
    /// The device as a participant reads it ("a desktop or laptop computer").
    pub fn described(self) -> &'static str {
        match self {
            Device::Desktop => "a desktop or laptop computer",
            Device::Tablet => "a tablet",
            Device::Phone => "a phone",
        }
    }
}

/// The screen orientation a study requires.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    Landscape,
    Portrait,
}

/// How stimuli are scaled on screen: `native` never enlarges them beyond one image pixel per
/// CSS pixel (they may shrink to fit); `fit` scales them to the space available.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Display {
    #[default]
    Native,
    Fit,
}

/// Who may take part and how answers are checked: the response-time floor, one run per
/// external id, the screen requirements, and when an unfinished participant counts as abandoned.
#[derive(Debug, Clone, Serialize)]
pub struct Participation {
    /// Responses faster than this (client response time or server time since serving the trial)
    /// are stored and flagged `too_fast`; the page accepts no answer before it.
    pub min_response_ms: u32,
    /// One run per value of the study's first URL parameter that is present (e.g.
    /// `PROLIFIC_PID`): a second join with the same value resumes the first run.
    pub unique_external_id: bool,
    /// Smallest viewport in CSS pixels, `[width, height]`.
    pub min_viewport: Option<[u32; 2]>,
    /// Devices allowed (all when empty).
    pub devices: Vec<Device>,
    pub orientation: Option<Orientation>,
    pub display: Display,
    /// An unfinished participant with no activity for this long counts as abandoned.
    pub abandon_after_minutes: u32,
}

fn default_true() -> bool {
    true
}

fn default_url_params() -> Vec<String> {
    ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID", "workerId", "assignmentId", "hitId"]
        .iter()
        .map(|name| name.to_string())
        .collect()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TextsFile {
    welcome: String,
    consent: String,
    instructions: String,
    #[serde(default = "default_thanks")]
    thanks: String,
}

fn default_thanks() -> String {
    "Thank you for taking part.".to_string()
}

/// The texts shown on the participant pages; blank lines separate paragraphs.
#[derive(Debug, Clone, Serialize)]
pub struct Texts {
    pub welcome: String,
    pub consent: String,
    pub instructions: String,
    pub thanks: String,
}

/// One demographic question on the entry screen.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemographicField {
    /// Column name in the export, `[a-z][a-z0-9_]*`.
    pub name: String,
    /// The question as shown.
    pub label: String,
    /// `choice`, `integer` or `text`.
    #[serde(rename = "type")]
    pub field_type: FieldType,
    /// For `choice`: the options, shown in this order.
    #[serde(default)]
    pub options: Vec<String>,
    /// For `integer`: the inclusive bounds.
    #[serde(default)]
    pub min: Option<i64>,
    #[serde(default)]
    pub max: Option<i64>,
    #[serde(default = "default_true")]
    pub required: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldType {
    Choice,
    Integer,
    Text,
}

/// A rendering feature that the study switches on or off.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Factor {
    pub name: String,
    #[serde(default)]
    pub label: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConditionFile {
    name: String,
    levels: BTreeMap<String, f64>,
}

/// One combination of factor levels.
#[derive(Debug, Clone, Serialize)]
pub struct Condition {
    pub name: String,
    /// One level per factor, in the order of [`Study::factors`].
    pub levels: Vec<f64>,
}

/// Defaults for scene configurations rendered by the renderer.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDefaults {
    /// Stimulus size in pixels, `[width, height]`.
    pub size: [u32; 2],
    /// Samples per pixel for path-traced parts, if the renderer needs them.
    #[serde(default)]
    pub spp: Option<u32>,
    /// Seed of the path-traced photograph (and its camera noise).
    #[serde(default)]
    pub seed: Option<u64>,
    /// VPL budget of the gi factor.
    #[serde(default)]
    pub vpls: Option<u32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: String,
    #[serde(default)]
    description: String,
    /// Rendered: a scene file (relative to the study file) or a built-in scene name.
    #[serde(default)]
    render: Option<String>,
    /// Image files: condition name → image path relative to the study file.
    #[serde(default)]
    images: Option<BTreeMap<String, String>>,
}

/// Where the stimuli of one scene configuration come from.
#[derive(Debug, Clone, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StimulusSource {
    /// One image file per condition, index-aligned with [`Study::conditions`].
    Images(Vec<PathBuf>),
    /// A scene for the renderer: a scene file path or a built-in scene name.
    Render(String),
}

/// One scene configuration: an arrangement of real and virtual objects with one camera pose.
#[derive(Debug, Clone, Serialize)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub source: StimulusSource,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DesignFile {
    pairs: String,
    #[serde(default)]
    anchors: Vec<String>,
    #[serde(default)]
    list: Vec<Vec<String>>,
    repetitions: u32,
    scenes: String,
    #[serde(default)]
    seed: Option<u64>,
}

/// How scene configurations are drawn for the two sides of a trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SceneDraw {
    /// Two different scene configurations, so the images are never directly comparable.
    Different,
    /// The same scene configuration on both sides.
    Same,
}

/// The design: condition pairs (indices into [`Study::conditions`]), repetitions, scene draw.
#[derive(Debug, Clone, Serialize)]
pub struct Design {
    /// `all`, `anchored` or `list`, as written in the file.
    pub pairs_rule: String,
    pub pairs: Vec<(usize, usize)>,
    pub repetitions: u32,
    pub scenes: SceneDraw,
    /// Study seed: when set, participant seeds are derived from it and the participant's
    /// ordinal, so a whole run of the study can be reproduced; when absent they are random.
    /// Either way each participant's seed is stored.
    pub seed: Option<u64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CatchFile {
    name: String,
    better: String,
    worse: String,
    #[serde(default = "default_one")]
    repetitions: u32,
}

fn default_one() -> u32 {
    1
}

/// A catch trial: a pair of images with a known answer (`better` should be chosen).
#[derive(Debug, Clone, Serialize)]
pub struct CatchTrial {
    pub name: String,
    pub better: PathBuf,
    pub worse: PathBuf,
    pub repetitions: u32,
}

/// The completion page: a fixed code (as crowdsourcing sites want), or a random code per
/// participant when absent, and an optional redirect URL. In `redirect`, `{code}` is replaced
/// by the completion code and `{NAME}` by the kept URL parameter `NAME`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Completion {
    #[serde(default)]
    pub code: Option<String>,
    #[serde(default)]
    pub redirect: Option<String>,
}

/// A checked study definition.
#[derive(Debug, Clone, Serialize)]
pub struct Study {
    pub slug: String,
    pub title: String,
    pub kind: StudyKind,
    pub question: String,
    /// Whether the study accepts participants when it is first loaded (the admin can change it).
    pub open: bool,
    pub texts: Texts,
    pub demographics: Vec<DemographicField>,
    pub url_params: Vec<String>,
    pub factors: Vec<Factor>,
    pub conditions: Vec<Condition>,
    pub render: Option<RenderDefaults>,
    pub scenes: Vec<Scene>,
    pub design: Design,
    pub catch: Vec<CatchTrial>,
    pub completion: Completion,
    pub participation: Participation,
    /// The file it was read from.
    pub file: PathBuf,
    /// SHA-256 of the file's bytes, hex; stored with each participant.
    pub file_sha256: String,
}

impl Study {
    /// Trials per participant: pairs × repetitions, plus the catch trials.
    pub fn trial_count(&self) -> usize {
        self.design.pairs.len() * self.design.repetitions as usize
            + self.catch.iter().map(|catch| catch.repetitions as usize).sum::<usize>()
    }

    /// Whether any stimulus must come from the renderer.
    pub fn needs_renderer(&self) -> bool {
        self.scenes.iter().any(|scene| matches!(scene.source, StimulusSource::Render(_)))
    }

    /// The conditions CSV of DESIGN.md: `condition,<factor>,…`, one row per condition.
    pub fn conditions_csv(&self) -> String {
        conditions_csv(
            self.factors.iter().map(|factor| factor.name.as_str()),
            self.conditions.iter().map(|condition| (condition.name.as_str(), condition.levels.as_slice())),
        )
    }
}

/// The conditions CSV of DESIGN.md from factor names and (condition, levels) rows; used for
/// study files and for the definitions stored with a study in the database.
pub(crate) fn conditions_csv<'a>(
    factors: impl Iterator<Item = &'a str>,
    conditions: impl Iterator<Item = (&'a str, &'a [f64])>,
) -> String {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["condition".to_string()];
    header.extend(factors.map(str::to_string));
    writer.write_record(&header).expect("writing to memory");
    for (name, levels) in conditions {
        let mut row = vec![name.to_string()];
        row.extend(levels.iter().map(|level| format_number(*level)));
        writer.write_record(&row).expect("writing to memory");
    }
    String::from_utf8(writer.into_inner().expect("writing to memory")).expect("UTF-8")
}

/// A number as CSV text: whole numbers without a decimal point.
pub(crate) fn format_number(value: f64) -> String {
    if value.fract() == 0.0 && value.abs() < 1e15 { format!("{}", value as i64) } else { format!("{value}") }
}

/// A study file of either kind.
#[derive(Debug, Clone)]
pub enum LoadedStudy {
    /// `kind = "paired-comparison"`: the web survey.
    Survey(Study),
    /// `kind = "task"`: the lab task study against the live renderer.
    Task(crate::task::study::TaskStudy),
}

impl LoadedStudy {
    pub fn slug(&self) -> &str {
        match self {
            LoadedStudy::Survey(study) => &study.slug,
            LoadedStudy::Task(study) => &study.slug,
        }
    }
    pub fn file(&self) -> &Path {
        match self {
            LoadedStudy::Survey(study) => &study.file,
            LoadedStudy::Task(study) => &study.file,
        }
    }
}

/// Reads and checks one study file of either kind (by its `kind` key).
pub fn load_any(file: &Path) -> Result<LoadedStudy, StudyError> {
    let bytes = std::fs::read(file).map_err(|error| StudyError {
        file: file.to_path_buf(),
        key: String::new(),
        expected: format!("cannot be read ({error})"),
    })?;
    let text = String::from_utf8(bytes.clone()).map_err(|_| StudyError {
        file: file.to_path_buf(),
        key: String::new(),
        expected: "expected UTF-8 text".to_string(),
    })?;
    let base = file.parent().unwrap_or(Path::new("."));
    let table: toml::Table = toml::from_str(&text).map_err(|error| StudyError {
        file: file.to_path_buf(),
        key: String::new(),
        expected: one_line(&error.to_string()),
    })?;
    if table.get("kind").and_then(|kind| kind.as_str()) == Some("task") {
        return crate::task::study::parse(&text, file, base, sha256_hex(&bytes)).map(LoadedStudy::Task);
    }
    let raw: StudyFile = toml::from_str(&text).map_err(|error| StudyError {
        file: file.to_path_buf(),
        key: String::new(),
        expected: one_line(&error.to_string()),
    })?;
    check(raw, file, base, sha256_hex(&bytes)).map(LoadedStudy::Survey)
}

/// Reads and checks one paired-comparison study file (a task study is refused: see
/// [`load_any`]).
pub fn load_study(file: &Path) -> Result<Study, StudyError> {
    match load_any(file)? {
        LoadedStudy::Survey(study) => Ok(study),
        LoadedStudy::Task(_) => Err(StudyError {
            file: file.to_path_buf(),
            key: "kind".into(),
            expected: "expected a paired-comparison study here, found a task study".into(),
        }),
    }
}

/// Loads every `*.toml` directly under `dir`, sorted by file name; stops at the first invalid
/// file. Two files with the same slug are refused.
pub fn load_studies(dir: &Path) -> Result<Vec<LoadedStudy>, StudyError> {
    let entries = std::fs::read_dir(dir).map_err(|error| StudyError {
        file: dir.to_path_buf(),
        key: String::new(),
        expected: format!("the studies directory cannot be read ({error})"),
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.extension().is_some_and(|ext| ext == "toml") && path.is_file())
        .collect();
    files.sort();
    let mut studies: Vec<LoadedStudy> = Vec::new();
    for file in files {
        let study = load_any(&file)?;
        if let Some(other) = studies.iter().find(|other| other.slug() == study.slug()) {
            return Err(StudyError {
                file,
                key: "slug".into(),
                expected: format!(
                    "expected a slug not used by another study, but {} uses \"{}\" too",
                    other.file().display(),
                    study.slug()
                ),
            });
        }
        studies.push(study);
    }
    Ok(studies)
}

fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_lowercase())
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        && name.len() <= 64
}

/// Also scene names. The first character is no `+`, `-` or `.`, so that the name is never
/// neutralised as a spreadsheet formula in the trials CSV (`export::text_cell`).
fn is_condition_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || "+-_.".contains(c))
}

fn check(raw: StudyFile, file: &Path, base: &Path, file_sha256: String) -> Result<Study, StudyError> {
    let fail = |key: &str, expected: String| StudyError { file: file.to_path_buf(), key: key.to_string(), expected };

    if !is_slug(&raw.slug) {
        return Err(fail("slug", format!("expected 1 to 64 characters of a-z, 0-9 and '-', found \"{}\"", raw.slug)));
    }
    for (key, value) in [("title", &raw.title), ("question", &raw.question)] {
        if value.trim().is_empty() {
            return Err(fail(key, "expected a non-empty text".into()));
        }
    }
    for (key, value) in [
        ("texts.welcome", &raw.texts.welcome),
        ("texts.consent", &raw.texts.consent),
        ("texts.instructions", &raw.texts.instructions),
    ] {
        if value.trim().is_empty() {
            return Err(fail(key, "expected a non-empty text".into()));
        }
    }

    // Demographics.
    let mut field_names = BTreeSet::new();
    for (index, field) in raw.demographics.iter().enumerate() {
        let key = format!("demographics[{index}]");
        if !is_identifier(&field.name) {
            return Err(fail(
                &format!("{key}.name"),
                format!("expected a lower-case identifier (a-z, 0-9, _), found \"{}\"", field.name),
            ));
        }
        if TRIALS_CSV_COLUMNS.contains(&field.name.as_str()) {
            return Err(fail(
                &format!("{key}.name"),
                format!(
                    "expected a name that is not an export column ({}), found \"{}\"",
                    TRIALS_CSV_COLUMNS.join(", "),
                    field.name
                ),
            ));
        }
        if !field_names.insert(field.name.clone()) {
            return Err(fail(
                &format!("{key}.name"),
                format!("expected a unique name, \"{}\" appears twice", field.name),
            ));
        }
        if field.label.trim().is_empty() {
            return Err(fail(&format!("{key}.label"), "expected a non-empty text".into()));
        }
        match field.field_type {
            FieldType::Choice if field.options.len() < 2 => {
                return Err(fail(&format!("{key}.options"), "expected at least two options for a choice".into()));
            }
            FieldType::Integer => {
                if let (Some(min), Some(max)) = (field.min, field.max)
                    && min > max
                {
                    return Err(fail(&format!("{key}.min"), format!("expected min ≤ max, found {min} > {max}")));
                }
            }
            _ => {}
        }
    }
    for (index, name) in raw.url_params.iter().enumerate() {
        if name.is_empty()
            || name.len() > 64
            || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(fail(
                &format!("url_params[{index}]"),
                format!("expected a URL parameter name (A-Z, a-z, 0-9, _, -), found \"{name}\""),
            ));
        }
        // Each external id is a column of the trials CSV.
        if TRIALS_CSV_COLUMNS.contains(&name.as_str()) || field_names.contains(name) {
            return Err(fail(
                &format!("url_params[{index}]"),
                format!("expected a name that is not an export column or a demographic field, found \"{name}\""),
            ));
        }
    }

    // Factors and conditions.
    if raw.factors.is_empty() {
        return Err(fail("factors", "expected at least one factor".into()));
    }
    let mut factor_names = BTreeSet::new();
    for (index, factor) in raw.factors.iter().enumerate() {
        if !is_identifier(&factor.name) || factor.name == "condition" {
            return Err(fail(
                &format!("factors[{index}].name"),
                format!("expected a lower-case identifier other than \"condition\", found \"{}\"", factor.name),
            ));
        }
        if !factor_names.insert(factor.name.clone()) {
            return Err(fail(
                &format!("factors[{index}].name"),
                format!("expected a unique name, \"{}\" appears twice", factor.name),
            ));
        }
    }
    if raw.conditions.len() < 2 {
        return Err(fail("conditions", "expected at least two conditions".into()));
    }
    let mut conditions = Vec::new();
    for (index, condition) in raw.conditions.iter().enumerate() {
        let key = format!("conditions[{index}]");
        if !is_condition_name(&condition.name) {
            return Err(fail(
                &format!("{key}.name"),
                format!(
                    "expected 1 to 64 characters of A-Z, a-z, 0-9 and + - _ ., starting with a letter, digit or _, found \"{}\"",
                    condition.name
                ),
            ));
        }
        if conditions.iter().any(|other: &Condition| other.name == condition.name) {
            return Err(fail(
                &format!("{key}.name"),
                format!("expected a unique name, \"{}\" appears twice", condition.name),
            ));
        }
        for level_name in condition.levels.keys() {
            if !factor_names.contains(level_name) {
                return Err(fail(
                    &format!("{key}.levels.{level_name}"),
                    format!(
                        "expected one of the factors ({}), found \"{level_name}\"",
                        raw.factors.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
        }
        let mut levels = Vec::new();
        for factor in &raw.factors {
            match condition.levels.get(&factor.name) {
                Some(level) if level.is_finite() => levels.push(*level),
                Some(_) => {
                    return Err(fail(&format!("{key}.levels.{}", factor.name), "expected a finite number".into()));
                }
                None => {
                    return Err(fail(
                        &format!("{key}.levels"),
                        format!("expected a level for factor \"{}\"", factor.name),
                    ));
                }
            }
        }
        conditions.push(Condition { name: condition.name.clone(), levels });
    }
    let condition_index = |key: &str, name: &str| -> Result<usize, StudyError> {
        conditions.iter().position(|condition| condition.name == name).ok_or_else(|| {
            fail(
                key,
                format!(
                    "expected a condition defined in [[conditions]] ({}), found \"{name}\"",
                    conditions.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            )
        })
    };

    // Scenes and their stimuli.
    if raw.scenes.is_empty() {
        return Err(fail("scenes", "expected at least one scene configuration".into()));
    }
    let mut scenes: Vec<Scene> = Vec::new();
    for (index, scene) in raw.scenes.iter().enumerate() {
        let key = format!("scenes[{index}]");
        if !is_condition_name(&scene.name) {
            return Err(fail(
                &format!("{key}.name"),
                format!(
                    "expected 1 to 64 characters of A-Z, a-z, 0-9 and + - _ ., starting with a letter, digit or _, found \"{}\"",
                    scene.name
                ),
            ));
        }
        if scenes.iter().any(|other| other.name == scene.name) {
            return Err(fail(
                &format!("{key}.name"),
                format!("expected a unique name, \"{}\" appears twice", scene.name),
            ));
        }
        let source = match (&scene.render, &scene.images) {
            (Some(render), None) => {
                if render.trim().is_empty() {
                    return Err(fail(
                        &format!("{key}.render"),
                        "expected a scene file or a built-in scene name".into(),
                    ));
                }
                let is_builtin = mrstudy_renderer::builtin::names().any(|name| name == render);
                if !is_builtin && !base.join(render).is_file() {
                    return Err(fail(
                        &format!("{key}.render"),
                        format!(
                            "expected a built-in scene of the renderer ({}) or an existing scene file, found \"{render}\"",
                            mrstudy_renderer::builtin::names().collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
                StimulusSource::Render(render.clone())
            }
            (None, Some(images)) => {
                for condition_name in images.keys() {
                    condition_index(&format!("{key}.images.{condition_name}"), condition_name)?;
                }
                let mut paths = Vec::new();
                for condition in &conditions {
                    let Some(relative) = images.get(&condition.name) else {
                        return Err(fail(
                            &format!("{key}.images"),
                            format!("expected an image file for condition \"{}\"", condition.name),
                        ));
                    };
                    paths.push(check_image(&fail, &format!("{key}.images.{}", condition.name), base, relative)?);
                }
                StimulusSource::Images(paths)
            }
            _ => {
                return Err(fail(
                    &key,
                    "expected exactly one of `render` (a scene for the renderer) or `images` (one image file per condition)".into(),
                ));
            }
        };
        scenes.push(Scene { name: scene.name.clone(), description: scene.description.clone(), source });
    }
    if let Some(render) = &raw.render
        && (render.size[0] == 0 || render.size[1] == 0 || render.size[0] > 8192 || render.size[1] > 8192)
    {
        return Err(fail("render.size", "expected [width, height], each 1 to 8192".into()));
    }
    if let Some(render) = &raw.render {
        if render.spp.is_some_and(|spp| spp == 0 || spp > 65_536) {
            return Err(fail("render.spp", "expected samples per pixel from 1 to 65536".into()));
        }
        if render.vpls.is_some_and(|vpls| vpls > 65_536) {
            return Err(fail("render.vpls", "expected a VPL budget from 0 to 65536".into()));
        }
    }
    // Rendered stimuli: every condition's factor levels must be ones the renderer renders.
    if scenes.iter().any(|scene| matches!(scene.source, StimulusSource::Render(_))) {
        for (index, condition) in conditions.iter().enumerate() {
            let levels = raw.factors.iter().map(|factor| factor.name.as_str()).zip(condition.levels.iter().copied());
            if let Err(reason) = mrstudy_renderer::stimulus::Factors::from_levels(levels) {
                return Err(fail(
                    &format!("conditions[{index}].levels"),
                    format!("levels the renderer can render: {reason}"),
                ));
            }
        }
    }

    // Design.
    let design = &raw.design;
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    match design.pairs.as_str() {
        "all" => {
            for first in 0..conditions.len() {
                for second in first + 1..conditions.len() {
                    pairs.push((first, second));
                }
            }
        }
        "anchored" => {
            if design.anchors.is_empty() {
                return Err(fail(
                    "design.anchors",
                    "expected at least one anchor condition for pairs = \"anchored\"".into(),
                ));
            }
            let mut anchors = Vec::new();
            for (index, name) in design.anchors.iter().enumerate() {
                let anchor = condition_index(&format!("design.anchors[{index}]"), name)?;
                if anchors.contains(&anchor) {
                    return Err(fail(
                        &format!("design.anchors[{index}]"),
                        format!("expected each anchor once, \"{name}\" appears twice"),
                    ));
                }
                anchors.push(anchor);
            }
            // Every anchor with every other anchor, then every other condition with each anchor.
            for (position, &first) in anchors.iter().enumerate() {
                for &second in &anchors[position + 1..] {
                    pairs.push((first, second));
                }
            }
            for &anchor in &anchors {
                for other in 0..conditions.len() {
                    if !anchors.contains(&other) {
                        pairs.push((anchor, other));
                    }
                }
            }
        }
        "list" => {
            if design.list.is_empty() {
                return Err(fail("design.list", "expected a list of condition pairs for pairs = \"list\"".into()));
            }
            for (index, pair) in design.list.iter().enumerate() {
                let key = format!("design.list[{index}]");
                if pair.len() != 2 {
                    return Err(fail(&key, "expected a pair of two condition names".into()));
                }
                let first = condition_index(&key, &pair[0])?;
                let second = condition_index(&key, &pair[1])?;
                if first == second {
                    return Err(fail(&key, "expected two different conditions".into()));
                }
                if pairs.iter().any(|&(a, b)| (a, b) == (first, second) || (a, b) == (second, first)) {
                    return Err(fail(&key, "expected each pair once".into()));
                }
                pairs.push((first, second));
            }
        }
        other => {
            return Err(fail("design.pairs", format!("expected \"all\", \"anchored\" or \"list\", found \"{other}\"")));
        }
    }
    if design.pairs != "anchored" && !design.anchors.is_empty() {
        return Err(fail("design.anchors", "expected only with pairs = \"anchored\"".into()));
    }
    if design.pairs != "list" && !design.list.is_empty() {
        return Err(fail("design.list", "expected only with pairs = \"list\"".into()));
    }
    if design.repetitions == 0 || design.repetitions > 100 {
        return Err(fail("design.repetitions", format!("expected 1 to 100, found {}", design.repetitions)));
    }
    let scene_draw = match design.scenes.as_str() {
        "different" => SceneDraw::Different,
        "same" => SceneDraw::Same,
        other => {
            return Err(fail("design.scenes", format!("expected \"different\" or \"same\", found \"{other}\"")));
        }
    };
    if scene_draw == SceneDraw::Different && scenes.len() < 2 {
        return Err(fail(
            "design.scenes",
            "expected at least two scene configurations for scenes = \"different\"".into(),
        ));
    }

    // Catch trials.
    let mut catch = Vec::new();
    for (index, catch_file) in raw.catch.iter().enumerate() {
        let key = format!("catch[{index}]");
        if !is_condition_name(&catch_file.name) || catch.iter().any(|other: &CatchTrial| other.name == catch_file.name)
        {
            return Err(fail(
                &format!("{key}.name"),
                format!("expected a unique name of A-Z, a-z, 0-9 and + - _ ., found \"{}\"", catch_file.name),
            ));
        }
        if catch_file.repetitions == 0 || catch_file.repetitions > 100 {
            return Err(fail(
                &format!("{key}.repetitions"),
                format!("expected 1 to 100, found {}", catch_file.repetitions),
            ));
        }
        catch.push(CatchTrial {
            name: catch_file.name.clone(),
            better: check_image(&fail, &format!("{key}.better"), base, &catch_file.better)?,
            worse: check_image(&fail, &format!("{key}.worse"), base, &catch_file.worse)?,
            repetitions: catch_file.repetitions,
        });
    }

    let trial_total =
        pairs.len() * design.repetitions as usize + catch.iter().map(|c| c.repetitions as usize).sum::<usize>();
    if trial_total > 1000 {
        return Err(fail(
            "design.repetitions",
            format!("expected at most 1000 trials per participant, the design gives {trial_total}"),
        ));
    }

    // Completion.
    if let Some(code) = &raw.completion.code
        && (code.is_empty()
            || code.len() > 64
            || !code.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'))
    {
        return Err(fail(
            "completion.code",
            format!("expected 1 to 64 characters of A-Z, a-z, 0-9, - and _, found \"{code}\""),
        ));
    }
    if let Some(redirect) = &raw.completion.redirect
        && !(redirect.starts_with("https://") || redirect.starts_with("http://"))
    {
        return Err(fail("completion.redirect", format!("expected an http:// or https:// URL, found \"{redirect}\"")));
    }

    let participation = check_participation(&raw, &fail)?;
    Ok(Study {
        slug: raw.slug,
        title: raw.title,
        kind: raw.kind,
        question: raw.question,
        open: raw.open,
        texts: Texts {
            welcome: raw.texts.welcome,
            consent: raw.texts.consent,
            instructions: raw.texts.instructions,
            thanks: raw.texts.thanks,
        },
        demographics: raw.demographics,
        url_params: raw.url_params,
        factors: raw.factors,
        conditions,
        render: raw.render,
        scenes,
        design: Design {
            pairs_rule: raw.design.pairs.clone(),
            pairs,
            repetitions: raw.design.repetitions,
            scenes: scene_draw,
            seed: raw.design.seed,
        },
        catch,
        completion: raw.completion,
        participation,
        file: file.to_path_buf(),
        file_sha256,
    })
}

/// The trials CSV's own columns, in order (DESIGN.md); the external ids and the demographic
/// fields follow them, so neither may be named like one. `export` writes this header.
pub const TRIALS_CSV_COLUMNS: &[&str] = &[
    "study",
    "participant",
    "trial",
    "left",
    "right",
    "chosen",
    "scene_left",
    "scene_right",
    "rt_ms",
    "shown_at",
    "answered_at",
    "catch_answered",
    "catch_failed",
    "viewport",
    "device_pixel_ratio",
    "completed",
    "status",
    "completion_code",
    "pilot",
    "excluded",
    "too_fast",
];

/// Image extensions a stimulus file may have, with their content types.
pub const IMAGE_TYPES: &[(&str, &str)] =
    &[("png", "image/png"), ("jpg", "image/jpeg"), ("jpeg", "image/jpeg"), ("webp", "image/webp")];

/// The participation keys: response-time floor, external ids, screen requirements.
fn check_participation(
    raw: &StudyFile,
    fail: &dyn Fn(&str, String) -> StudyError,
) -> Result<Participation, StudyError> {
    if raw.min_response_ms > 60_000 {
        return Err(fail("min_response_ms", format!("expected at most 60000 ms, found {}", raw.min_response_ms)));
    }
    if let Some([width, height]) = raw.min_viewport
        && (width == 0 || height == 0 || width > 10_000 || height > 10_000)
    {
        return Err(fail(
            "min_viewport",
            format!("expected [width, height] in CSS pixels from 1 to 10000, found [{width}, {height}]"),
        ));
    }
    if raw.unique_external_id && raw.url_params.is_empty() {
        return Err(fail(
            "unique_external_id",
            "expected `url_params` to name the external id (e.g. \"PROLIFIC_PID\"), found none".into(),
        ));
    }
    if raw.abandon_after_minutes == 0 {
        return Err(fail("abandon_after_minutes", "expected at least 1 minute, found 0".into()));
    }
    let devices = match &raw.devices {
        Some(devices) if devices.is_empty() => {
            return Err(fail("devices", "expected at least one of \"desktop\", \"tablet\", \"phone\"".into()));
        }
        Some(devices) => devices.clone(),
        None => Vec::new(),
    };
    Ok(Participation {
        min_response_ms: raw.min_response_ms,
        unique_external_id: raw.unique_external_id,
        min_viewport: raw.min_viewport,
        devices,
        orientation: raw.orientation,
        display: raw.display,
        abandon_after_minutes: raw.abandon_after_minutes,
    })
}

fn check_image(
    fail: &dyn Fn(&str, String) -> StudyError,
    key: &str,
    base: &Path,
    relative: &str,
) -> Result<PathBuf, StudyError> {
    let path = base.join(relative);
    let extension = path.extension().and_then(|ext| ext.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    if !IMAGE_TYPES.iter().any(|(ext, _)| *ext == extension) {
        return Err(fail(key, format!("expected a .png, .jpg, .jpeg or .webp image file, found \"{relative}\"")));
    }
    if !path.is_file() {
        return Err(fail(key, format!("expected an existing image file, but {} does not exist", path.display())));
    }
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_study(dir: &Path, body: &str) -> PathBuf {
        let file = dir.join("study.toml");
        std::fs::write(&file, body).unwrap();
        file
    }

    const MINIMAL: &str = r#"
slug = "s"
title = "T"
kind = "paired-comparison"
question = "Q?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "gi"
[[factors]]
name = "ca"
[[conditions]]
name = "LQ"
levels = { gi = 0, ca = 0 }
[[conditions]]
name = "GI"
levels = { gi = 1, ca = 0 }
[[conditions]]
name = "HQ"
levels = { gi = 1, ca = 1 }
[[scenes]]
name = "a"
render = "survey-1"
[[scenes]]
name = "b"
render = "survey-2"
[design]
pairs = "anchored"
anchors = ["LQ", "HQ"]
repetitions = 2
scenes = "different"
"#;

    #[test]
    fn a_level_the_renderer_cannot_render_names_the_condition_and_factor() {
        let dir = tempfile::tempdir().unwrap();
        let file =
            write_study(dir.path(), &MINIMAL.replace("levels = { gi = 1, ca = 1 }", "levels = { gi = 2, ca = 1 }"));
        let error = load_study(&file).unwrap_err();
        assert_eq!(error.key, "conditions[2].levels");
        assert!(error.expected.contains("`gi`") && error.expected.contains("level 2"), "{}", error.expected);
    }

    #[test]
    fn anchored_pairs_are_anchor_pairs_then_others_with_each_anchor() {
        let dir = tempfile::tempdir().unwrap();
        let study = load_study(&write_study(dir.path(), MINIMAL)).unwrap();
        assert_eq!(study.design.pairs, vec![(0, 2), (0, 1), (2, 1)]);
        assert_eq!(study.trial_count(), 6);
        assert!(study.needs_renderer());
        assert_eq!(study.conditions_csv(), "condition,gi,ca\nLQ,0,0\nGI,1,0\nHQ,1,1\n");
    }

    #[test]
    fn unknown_condition_in_anchors_names_file_key_and_expectation() {
        let dir = tempfile::tempdir().unwrap();
        let file = write_study(dir.path(), &MINIMAL.replace("[\"LQ\", \"HQ\"]", "[\"LQ\", \"XX\"]"));
        let error = load_study(&file).unwrap_err();
        assert_eq!(error.key, "design.anchors[1]");
        let message = error.to_string();
        assert!(message.contains("study.toml"), "{message}");
        assert!(message.contains("found \"XX\""), "{message}");
    }

    #[test]
    fn unknown_key_is_refused_with_its_name() {
        let dir = tempfile::tempdir().unwrap();
        let file = write_study(dir.path(), &MINIMAL.replace("repetitions = 2", "repetitions = 2\nrepetition = 3"));
        let message = load_study(&file).unwrap_err().to_string();
        assert!(message.contains("repetition"), "{message}");
    }

    #[test]
    fn wrong_type_is_refused_with_the_key() {
        let dir = tempfile::tempdir().unwrap();
        let file = write_study(dir.path(), &MINIMAL.replace("repetitions = 2", "repetitions = \"two\""));
        let message = load_study(&file).unwrap_err().to_string();
        assert!(message.contains("repetitions"), "{message}");
    }

    #[test]
    fn unknown_scene_for_the_renderer_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = write_study(dir.path(), &MINIMAL.replace("render = \"survey-2\"", "render = \"nowhere\""));
        let error = load_study(&file).unwrap_err();
        assert_eq!(error.key, "scenes[1].render");
        assert!(error.expected.contains("survey-1"), "{error}");
    }

    #[test]
    fn missing_image_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let body =
            MINIMAL.replace("render = \"survey-1\"", "images = { LQ = \"lq.png\", GI = \"gi.png\", HQ = \"hq.png\" }");
        let error = load_study(&write_study(dir.path(), &body)).unwrap_err();
        assert_eq!(error.key, "scenes[0].images.LQ");
    }
}
