//! Study files (`studies/*.toml`): each read once, checked, and resolved into one study — a
//! web survey ([`Study`], `kind = "paired-comparison"`, in [`survey`]) or a lab task study
//! ([`TaskStudy`], `kind = "task"`, in [`task`]) — that everything after loading uses.
//!
//! A study file is read into its raw TOML shape (unknown keys refused), then checked by named
//! functions, one per part of the file; the checks both kinds share are in [`checks`]. Every
//! refusal is a [`StudyError`] naming the file, the key and what was expected, so `serve` can
//! print it as one sentence. The schema is documented for researchers in `studies/README.md`.
//! The resolved survey study is also the one schema of the definition stored in the database
//! (`studies.definition`, read back by the export and the admin pages).

use std::fmt;
use std::path::{Path, PathBuf};

use mrstudy_renderer::stimulus::Factors;

pub mod checks;
mod made;
pub mod rating;
pub mod rating_design;
#[cfg(test)]
pub mod rating_tests;
pub mod survey;
pub mod task;
#[cfg(test)]
mod tests;
pub mod threshold;
pub mod threshold_design;
#[cfg(test)]
pub(crate) mod threshold_tests;

pub use checks::IMAGE_TYPES;
pub(crate) use survey::format_number;
pub use survey::{
    ActiveDesign, ActivePrior, ActiveTarget, CatchTrial, Completion, Condition, DemographicField, Design,
    DesignReference, Device, Display, Factor, FieldType, GROUND_TRUTH, Orientation, PairsRule, Participation,
    RenderDefaults, SceneConfiguration, SceneDraw, StimulusSource, Study, StudyKind, TRIALS_CSV_COLUMNS, Texts,
    active_target,
};
pub use task::TaskStudy;
pub use threshold::ThresholdDesign;

/// Why a study file was refused: the file, the key (a dotted path such as `design.pairs`) and
/// what was expected there.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct StudyError {
    pub file: PathBuf,
    pub key: String,
    pub expected: String,
}

impl fmt::Display for StudyError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.key.is_empty() {
            write!(formatter, "{}: {}", self.file.display(), self.expected)
        } else {
            write!(formatter, "{}: key `{}`: {}", self.file.display(), self.key, self.expected)
        }
    }
}

impl std::error::Error for StudyError {}

/// A TOML parser's message in one line (its source excerpt and markers dropped).
pub(crate) fn one_line(message: &str) -> String {
    let lines: Vec<&str> = message
        .lines()
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.chars().all(|c| c == '|' || c == '^' || c == ' '))
        .collect();
    lines.join(" ")
}

/// SHA-256 of `bytes`, hex-encoded: the study file's fingerprint stored with each participant,
/// and the name of a stimulus in the content-addressed store.
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

/// Why a study's conditions cannot go on a contact sheet ([`sheet_conditions`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SheetConditionsError {
    #[error(transparent)]
    Study(#[from] StudyError),
    /// A condition whose levels the renderer has not.
    #[error("{condition}: {reason}")]
    Unrenderable { condition: String, reason: String },
    #[error("{} is a task study; name a paired-comparison study", file.display())]
    TaskStudy { file: PathBuf },
}

/// The conditions (name, factors) of the study in `file`, for `mrstudy render --contact-sheet`.
pub fn sheet_conditions(file: &Path) -> Result<Vec<(String, Factors)>, SheetConditionsError> {
    match load_any(file)? {
        LoadedStudy::Survey(study) => study
            .conditions
            .into_iter()
            .map(|c| {
                c.factors
                    .map(|f| (c.name.clone(), f))
                    .map_err(|reason| SheetConditionsError::Unrenderable { condition: c.name, reason })
            })
            .collect(),
        LoadedStudy::Task(_) => Err(SheetConditionsError::TaskStudy { file: file.to_path_buf() }),
    }
}

/// A study file of either kind.
#[derive(Debug, Clone)]
pub enum LoadedStudy {
    /// `kind = "paired-comparison"`: the web survey.
    Survey(Study),
    /// `kind = "task"`: the lab task study against the live renderer.
    Task(TaskStudy),
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
    // One arm per kind; each kind's module parses and checks its own file shape.
    let file_sha256 = sha256_hex(&bytes);
    match table.get("kind").and_then(|kind| kind.as_str()) {
        Some("task") => task::parse(&text, file, base, file_sha256).map(LoadedStudy::Task),
        Some("threshold") => threshold::parse(table, file, base, file_sha256).map(LoadedStudy::Survey),
        Some("rating") => rating::parse(table, file, base, file_sha256).map(LoadedStudy::Survey),
        _ => survey::parse(&text, file, base, file_sha256).map(LoadedStudy::Survey),
    }
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
/// file. Two files with the same slug are refused, and so is an image file outside `dir`
/// ([`Study::check_images_inside`]): `serve` hands these to anyone.
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
        if let LoadedStudy::Survey(survey) = &study {
            survey.check_images_inside(dir)?;
        }
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
