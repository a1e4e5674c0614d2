//! Web-survey study files (`kind = "paired-comparison"`), one concept per file: `file` the raw
//! TOML shape (unknown keys refused), `check` its checks, one named function per part of the
//! file, resolving it into a [`Study`], and `model` that resolved study, which is also the schema
//! of the definition stored in the database.

mod active;
mod check;
mod file;
mod model;

pub(crate) use active::default_repetitions;
pub(super) use check::parse;
pub(crate) use check::{all_pairs, anchored_pair_indices};
pub(crate) use model::format_number;
pub use model::{
    ActiveDesign, ActivePrior, ActiveTarget, CatchTrial, Completion, Condition, DemographicField, Design,
    DesignReference, Device, Display, Factor, FieldType, GROUND_TRUTH, MAX_REALISATIONS, Orientation, PairsRule,
    Participation, RenderDefaults, SceneConfiguration, SceneDraw, StimulusSource, Study, StudyKind, TRIALS_CSV_COLUMNS,
    Texts, active_target,
};
