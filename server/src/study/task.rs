//! Task study files (`kind = "task"`): parsing and validation into a [`TaskStudy`].
//!
//! The raw TOML shape is read with unknown keys refused, then checked: the tasks and their
//! parameters, the rendering conditions ([`Condition`]: the live renderer's `gi` levels `none`,
//! `shadows`, `gi`, or a coherent method `em`, `dit`, `vct`), the counterbalancing rule, trial counts, the scene and its two cubes. Every
//! refusal is a [`StudyError`] naming the file, the key and what was expected. The schema is
//! documented for researchers in `studies/README.md` ("Task studies").

use std::collections::BTreeSet;
use std::path::Path;

use mrstudy_renderer::gpu::GiLevel;
use mrstudy_renderer::stimulus::CoherentLevel;
use serde::{Deserialize, Serialize};

use super::checks::{Fail, check_min_response_ms, check_slug, check_texts, resolve_scene};
use super::{StudyError, one_line};

/// A task study's rendering condition: how the live renderer lights the virtual cube and its
/// influence on the real scene — differential instant radiosity's `gi` levels on the GPU
/// (`none`, `shadows`, `gi`), or one of Rohmer et al.'s coherent methods (`em`, `dit`, `vct`,
/// at quality *med* or with `-low` / `-high`), its representation rebuilt where the cube now
/// is and its frame rendered on the CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Condition {
    Dir(GiLevel),
    Coherent(CoherentLevel),
}

/// The names a task study's condition takes, for messages.
pub const CONDITION_NAMES: &str = "none, shadows, gi, em, dit, vct (a coherent method may end in -low, -med or -high)";

impl Condition {
    /// The condition named `name` (see [`CONDITION_NAMES`]; `off` is `none` too).
    pub fn parse(name: &str) -> Option<Condition> {
        GiLevel::parse(name).map(Condition::Dir).or_else(|| CoherentLevel::parse(name).map(Condition::Coherent))
    }

    /// The name a study file gives it, stored with every trial and frame time.
    pub fn name(&self) -> String {
        match self {
            Condition::Dir(level) => level.name().to_string(),
            Condition::Coherent(level) => level.name(),
        }
    }
}

impl std::fmt::Display for Condition {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

impl Serialize for Condition {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.name())
    }
}

/// How condition orders are counterbalanced across participants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Counterbalance {
    /// A Williams design: each condition once per position and each ordered pair of conditions
    /// adjacent equally often (n sequences for an even number of conditions, 2n for an odd one).
    Williams,
    /// A cyclic Latin square: each condition once per position (n sequences), no carry-over
    /// balance.
    Latin,
}

/// The kinds of task a trial can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TaskKind {
    /// The virtual cube stands at a random position on the table, the real cube in the middle;
    /// the participant types the distance between them in cm.
    Distance,
    /// The virtual cube starts at a random position; the participant moves it with the arrow
    /// keys (in the table plane) onto the real cube and confirms.
    Placement,
    /// The virtual cube floats at a random height beside the real cube; the participant lowers
    /// or raises it (arrow keys up and down) until it rests on the table, and confirms.
    Contact,
}

impl TaskKind {
    pub fn as_str(self) -> &'static str {
        match self {
            TaskKind::Distance => "distance",
            TaskKind::Placement => "placement",
            TaskKind::Contact => "contact",
        }
    }

    /// The axes along which targets vary, so along which per-axis errors are measured.
    pub fn axes(self) -> &'static [char] {
        match self {
            TaskKind::Distance | TaskKind::Placement => &['x', 'z'],
            TaskKind::Contact => &['y'],
        }
    }
}

/// How the distance task places the virtual cube around the real one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Directions {
    /// Along the table's main axes (left, right, away, towards), as in the thesis.
    Main,
    /// In any direction in the table plane.
    Any,
}

/// Steps per second of a held arrow key unless a task says otherwise (`held_steps_per_second`).
pub const DEFAULT_HELD_STEPS_PER_SECOND: f64 = 10.0;

/// One task of the study with its parameters (lengths in cm).
#[derive(Debug, Clone, Serialize)]
pub struct TaskSpec {
    /// Unique name, used in the export's `task` column (defaults to the kind).
    pub name: String,
    pub kind: TaskKind,
    /// Shown before the task's first trial; blank lines separate paragraphs.
    pub instructions: String,
    /// Distance of the virtual cube's start (or, for `distance`, its position) from the real
    /// cube, drawn uniformly from [min_cm, max_cm].
    pub min_cm: f64,
    pub max_cm: f64,
    /// `distance`: directions of the virtual cube from the real cube.
    pub directions: Directions,
    /// `distance`: largest answer accepted.
    pub answer_max_cm: f64,
    /// `placement`, `contact`: how far one arrow key press moves the cube.
    pub step_cm: f64,
    /// `placement`, `contact`: while an arrow key is held, the page sends this many steps per
    /// second, at a fixed rate (the system's auto-repeat is ignored).
    pub held_steps_per_second: f64,
    /// `contact`: the floating height of the cube's bottom above the table, uniform in
    /// [min_height_cm, max_height_cm].
    pub min_height_cm: f64,
    pub max_height_cm: f64,
}

/// Rendering settings of the live frames.
#[derive(Debug, Clone, Serialize)]
pub struct LabRender {
    /// Frame size; `None`: on a software adapter the largest size of a ladder at which the
    /// slowest condition keeps `min_fps` (measured at start-up, `crate::lab::size`), 320×240 on a GPU.
    pub size: Option<[u32; 2]>,
    /// JPEG quality of the streamed frames (1–100).
    pub jpeg_quality: u8,
    /// VPL budget (condition `gi`).
    pub vpls: u32,
    pub shadow_map_size: u32,
    pub env_lights: u32,
    /// Samples per pixel of the photograph (CPU path tracer, once, cached in the data dir).
    pub photo_spp: u32,
    /// Frames per second below which the adapter is reported as too slow for interactive use.
    pub min_fps: f64,
    /// Frame pacing across conditions (`pace`, top level or under `[render]`).
    pub pace: Pace,
}

/// Whether every condition's frames are paced to the same frame time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pace {
    /// Each frame is sent as soon as it is rendered: a slower condition shows more lag.
    None,
    /// Every condition's frames are held until the slowest condition's frame time has passed
    /// since they were requested, so conditions cannot be told apart by lag.
    Equal,
}

impl Pace {
    pub fn as_str(self) -> &'static str {
        match self {
            Pace::None => "none",
            Pace::Equal => "equal",
        }
    }
}

/// The texts of the lab pages.
#[derive(Debug, Clone, Serialize)]
pub struct TaskTexts {
    pub welcome: String,
    pub instructions: String,
    pub thanks: String,
}

/// A checked task study.
#[derive(Debug, Clone, Serialize)]
pub struct TaskStudy {
    pub slug: String,
    pub title: String,
    pub open: bool,
    pub texts: TaskTexts,
    /// Built-in scene name or scene file (resolved against the study file's directory).
    pub scene: String,
    pub real_object: String,
    pub virtual_object: String,
    /// Rendering conditions, in file order.
    pub conditions: Vec<Condition>,
    pub counterbalance: Counterbalance,
    pub trials_per_condition: u32,
    /// Practice trials per task, before its first counted trial (not analysed).
    pub practice: u32,
    /// Study seed: participant seeds derive from it and the ordinal; else random per participant.
    pub seed: Option<u64>,
    pub tasks: Vec<TaskSpec>,
    pub render: LabRender,
    /// Answers sooner than this after the trial's first frame was shown (and instructions
    /// acknowledged sooner than this after they appeared) are refused, ms.
    pub min_response_ms: u32,
    /// A participant with no activity for this long who has not finished gives up their
    /// counterbalancing slot to the next participant to join (minutes; fractions allowed).
    pub abandon_after_minutes: f64,
    pub file: std::path::PathBuf,
    pub file_sha256: String,
}

impl TaskStudy {
    /// Trials per participant, practice included.
    pub fn trial_count(&self) -> usize {
        self.tasks.len() * (self.practice as usize + self.conditions.len() * self.trials_per_condition as usize)
    }

    pub fn task(&self, name: &str) -> Option<&TaskSpec> {
        self.tasks.iter().find(|task| task.name == name)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskStudyFile {
    slug: String,
    title: String,
    #[allow(dead_code)]
    kind: String,
    #[serde(default = "default_true")]
    open: bool,
    texts: TextsFile,
    #[serde(default)]
    scene: SceneFile,
    #[serde(default)]
    design: DesignFile,
    #[serde(default)]
    render: RenderFile,
    #[serde(default = "default_min_response_ms")]
    min_response_ms: i64,
    #[serde(default = "default_abandon_after_minutes")]
    abandon_after_minutes: f64,
    #[serde(default)]
    pace: Option<Pace>,
    tasks: Vec<TaskFile>,
}

fn default_true() -> bool {
    true
}

fn default_min_response_ms() -> i64 {
    300
}

fn default_abandon_after_minutes() -> f64 {
    30.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TextsFile {
    welcome: String,
    instructions: String,
    #[serde(default = "default_thanks")]
    thanks: String,
}

fn default_thanks() -> String {
    "Thank you for taking part.".into()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct SceneFile {
    name: String,
    real_object: String,
    virtual_object: String,
}

impl Default for SceneFile {
    fn default() -> Self {
        SceneFile { name: "lab-task".into(), real_object: "real-cube".into(), virtual_object: "virtual-cube".into() }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct DesignFile {
    conditions: Vec<String>,
    counterbalance: Counterbalance,
    trials_per_condition: u32,
    practice: u32,
    seed: Option<u64>,
}

impl Default for DesignFile {
    fn default() -> Self {
        DesignFile {
            conditions: vec!["none".into(), "shadows".into(), "gi".into()],
            counterbalance: Counterbalance::Williams,
            trials_per_condition: 3,
            practice: 1,
            seed: None,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RenderFile {
    size: Option<[u32; 2]>,
    jpeg_quality: u8,
    vpls: u32,
    shadow_map_size: u32,
    env_lights: u32,
    photo_spp: u32,
    min_fps: f64,
    pace: Option<Pace>,
}

impl Default for RenderFile {
    fn default() -> Self {
        RenderFile {
            size: None,
            jpeg_quality: 80,
            vpls: 64,
            shadow_map_size: 256,
            env_lights: 8,
            photo_spp: 32,
            min_fps: 10.0,
            pace: None,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskFile {
    kind: TaskKind,
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    instructions: Option<String>,
    #[serde(default)]
    min_cm: Option<f64>,
    #[serde(default)]
    max_cm: Option<f64>,
    #[serde(default)]
    directions: Option<Directions>,
    #[serde(default)]
    answer_max_cm: Option<f64>,
    #[serde(default)]
    step_cm: Option<f64>,
    #[serde(default)]
    held_steps_per_second: Option<f64>,
    #[serde(default)]
    min_height_cm: Option<f64>,
    #[serde(default)]
    max_height_cm: Option<f64>,
}

fn default_instructions(kind: TaskKind) -> &'static str {
    match kind {
        TaskKind::Distance => {
            "A virtual green cube appears somewhere on the table; the real green cube stands in the middle. Type the distance between the two cubes (centre to centre) in centimetres and press Enter."
        }
        TaskKind::Placement => {
            "Move the virtual green cube onto the real green cube with the arrow keys (left/right, up = away from you, down = towards you). Press Enter when it sits exactly where the real cube is."
        }
        TaskKind::Contact => {
            "The virtual green cube floats above the table. Lower or raise it with the up and down arrow keys until it rests exactly on the table, then press Enter."
        }
    }
}

/// Reads and checks a task study from its text (`file` names it in errors, `base` resolves a
/// scene file).
pub fn parse(text: &str, file: &Path, base: &Path, file_sha256: String) -> Result<TaskStudy, StudyError> {
    let fail = Fail(file);
    let raw: TaskStudyFile = toml::from_str(text).map_err(|error| fail.at("", one_line(&error.to_string())))?;
    check_slug(fail, "slug", &raw.slug)?;
    check_texts(
        fail,
        &[
            ("title", &raw.title),
            ("texts.welcome", &raw.texts.welcome),
            ("texts.instructions", &raw.texts.instructions),
        ],
    )?;
    let scene = resolve_scene(fail, "scene.name", base, &raw.scene.name)?;
    for (key, value) in
        [("scene.real_object", &raw.scene.real_object), ("scene.virtual_object", &raw.scene.virtual_object)]
    {
        if value.trim().is_empty() {
            return Err(fail.at(key, "expected the name of an object of the scene"));
        }
    }
    // design
    let design = &raw.design;
    if design.conditions.len() < 2 {
        return Err(
            fail.at("design.conditions", format!("expected at least two rendering conditions ({CONDITION_NAMES})"))
        );
    }
    let mut conditions = Vec::new();
    for (index, name) in design.conditions.iter().enumerate() {
        let condition = Condition::parse(name).ok_or_else(|| {
            fail.at(
                &format!("design.conditions[{index}]"),
                format!("expected one of {CONDITION_NAMES}, found \"{name}\""),
            )
        })?;
        if conditions.contains(&condition) {
            return Err(fail.at(
                &format!("design.conditions[{index}]"),
                format!("expected each condition once, \"{}\" appears twice", condition.name()),
            ));
        }
        conditions.push(condition);
    }
    if !(1..=50).contains(&design.trials_per_condition) {
        return Err(
            fail.at("design.trials_per_condition", format!("expected 1 to 50, found {}", design.trials_per_condition))
        );
    }
    if design.practice > 20 {
        return Err(fail.at("design.practice", format!("expected 0 to 20, found {}", design.practice)));
    }
    // render
    let render = &raw.render;
    if let Some([width, height]) = render.size
        && !(16..=1920).contains(&width) | !(16..=1440).contains(&height)
    {
        return Err(fail.at(
            "render.size",
            format!("expected [width, height] within 16×16 to 1920×1440, found [{width}, {height}]"),
        ));
    }
    if !(1..=100).contains(&render.jpeg_quality) {
        return Err(fail.at("render.jpeg_quality", format!("expected 1 to 100, found {}", render.jpeg_quality)));
    }
    if !(1..=4096).contains(&render.vpls) {
        return Err(fail.at("render.vpls", format!("expected 1 to 4096, found {}", render.vpls)));
    }
    if !(16..=4096).contains(&render.shadow_map_size) {
        return Err(fail.at("render.shadow_map_size", format!("expected 16 to 4096, found {}", render.shadow_map_size)));
    }
    if render.env_lights > 256 {
        return Err(fail.at("render.env_lights", format!("expected 0 to 256, found {}", render.env_lights)));
    }
    if !(1..=4096).contains(&render.photo_spp) {
        return Err(fail.at("render.photo_spp", format!("expected 1 to 4096, found {}", render.photo_spp)));
    }
    if !(render.min_fps.is_finite() && render.min_fps > 0.0 && render.min_fps <= 240.0) {
        return Err(fail.at(
            "render.min_fps",
            format!("expected a number of frames per second in (0, 240], found {}", render.min_fps),
        ));
    }
    let pace = match (raw.pace, render.pace) {
        (Some(top), Some(under)) if top != under => {
            return Err(fail.at(
                "render.pace",
                format!(
                    "expected the same value as the top-level pace (\"{}\"), found \"{}\"; give pace once",
                    top.as_str(),
                    under.as_str()
                ),
            ));
        }
        (Some(pace), _) | (None, Some(pace)) => pace,
        (None, None) => Pace::None,
    };
    // participation
    let min_response_ms = check_min_response_ms(fail, raw.min_response_ms)?;
    if !(raw.abandon_after_minutes.is_finite()
        && raw.abandon_after_minutes > 0.0
        && raw.abandon_after_minutes <= 10_080.0)
    {
        return Err(fail.at(
            "abandon_after_minutes",
            format!("expected a number of minutes in (0, 10080], found {}", raw.abandon_after_minutes),
        ));
    }
    // tasks
    if raw.tasks.is_empty() {
        return Err(fail.at("tasks", "expected at least one [[tasks]] entry (distance, placement or contact)"));
    }
    let mut names = BTreeSet::new();
    let mut tasks = Vec::new();
    for (index, task) in raw.tasks.iter().enumerate() {
        let key = format!("tasks[{index}]");
        let name = task.name.clone().unwrap_or_else(|| task.kind.as_str().to_string());
        check_slug(fail, &format!("{key}.name"), &name)?;
        if !names.insert(name.clone()) {
            return Err(fail.at(
                &format!("{key}.name"),
                format!("expected a unique task name, \"{name}\" appears twice (give each task a `name`)"),
            ));
        }
        let not_for = |field: &str, present: bool| -> Result<(), StudyError> {
            if present {
                Err(fail.at(&format!("{key}.{field}"), format!("is not a parameter of a {} task", task.kind.as_str())))
            } else {
                Ok(())
            }
        };
        let (min_default, max_default) = match task.kind {
            TaskKind::Distance => (8.0, 25.0),
            TaskKind::Placement => (8.0, 20.0),
            TaskKind::Contact => (8.0, 15.0),
        };
        let min_cm = task.min_cm.unwrap_or(min_default);
        let max_cm = task.max_cm.unwrap_or(max_default);
        if !(min_cm.is_finite() && max_cm.is_finite() && 0.0 <= min_cm && min_cm <= max_cm && max_cm <= 30.0) {
            return Err(fail.at(
                &format!("{key}.min_cm"),
                format!(
                    "expected 0 ≤ min_cm ≤ max_cm ≤ 30 (the cube must stay on the table), found {min_cm} and {max_cm}"
                ),
            ));
        }
        match task.kind {
            TaskKind::Distance => {
                not_for("step_cm", task.step_cm.is_some())?;
                not_for("held_steps_per_second", task.held_steps_per_second.is_some())?;
                not_for("min_height_cm", task.min_height_cm.is_some())?;
                not_for("max_height_cm", task.max_height_cm.is_some())?;
                if min_cm < 6.0 {
                    // the cubes are 5 cm wide: closer centres would intersect
                    return Err(fail.at(
                        &format!("{key}.min_cm"),
                        format!("expected at least 6 (the cubes are 5 cm wide), found {min_cm}"),
                    ));
                }
            }
            TaskKind::Placement | TaskKind::Contact => {
                not_for("directions", task.directions.is_some())?;
                not_for("answer_max_cm", task.answer_max_cm.is_some())?;
                if task.kind == TaskKind::Placement {
                    not_for("min_height_cm", task.min_height_cm.is_some())?;
                    not_for("max_height_cm", task.max_height_cm.is_some())?;
                }
            }
        }
        let step_cm = task.step_cm.unwrap_or(if task.kind == TaskKind::Contact { 0.25 } else { 0.5 });
        if !(step_cm.is_finite() && (0.05..=5.0).contains(&step_cm)) {
            return Err(fail.at(&format!("{key}.step_cm"), format!("expected 0.05 to 5, found {step_cm}")));
        }
        let held_steps_per_second = task.held_steps_per_second.unwrap_or(DEFAULT_HELD_STEPS_PER_SECOND);
        if !(held_steps_per_second.is_finite() && (1.0..=60.0).contains(&held_steps_per_second)) {
            return Err(fail.at(
                &format!("{key}.held_steps_per_second"),
                format!("expected 1 to 60 steps per second, found {held_steps_per_second}"),
            ));
        }
        let answer_max_cm = task.answer_max_cm.unwrap_or(200.0);
        if !(answer_max_cm.is_finite() && (max_cm..=10_000.0).contains(&answer_max_cm)) {
            return Err(
                fail.at(&format!("{key}.answer_max_cm"), format!("expected max_cm to 10000, found {answer_max_cm}"))
            );
        }
        let min_height_cm = task.min_height_cm.unwrap_or(1.0);
        let max_height_cm = task.max_height_cm.unwrap_or(8.0);
        if !(min_height_cm.is_finite()
            && max_height_cm.is_finite()
            && 0.0 < min_height_cm
            && min_height_cm <= max_height_cm
            && max_height_cm <= 30.0)
        {
            return Err(fail.at(
                &format!("{key}.min_height_cm"),
                format!("expected 0 < min_height_cm ≤ max_height_cm ≤ 30, found {min_height_cm} and {max_height_cm}"),
            ));
        }
        let instructions = task.instructions.clone().unwrap_or_else(|| default_instructions(task.kind).to_string());
        if instructions.trim().is_empty() {
            return Err(fail.at(&format!("{key}.instructions"), "expected a non-empty text"));
        }
        tasks.push(TaskSpec {
            name,
            kind: task.kind,
            instructions,
            min_cm,
            max_cm,
            directions: task.directions.unwrap_or(Directions::Main),
            answer_max_cm,
            step_cm,
            held_steps_per_second,
            min_height_cm,
            max_height_cm,
        });
    }
    let study = TaskStudy {
        slug: raw.slug,
        title: raw.title,
        open: raw.open,
        texts: TaskTexts { welcome: raw.texts.welcome, instructions: raw.texts.instructions, thanks: raw.texts.thanks },
        scene,
        real_object: raw.scene.real_object,
        virtual_object: raw.scene.virtual_object,
        conditions,
        counterbalance: design.counterbalance,
        trials_per_condition: design.trials_per_condition,
        practice: design.practice,
        seed: design.seed,
        tasks,
        render: LabRender {
            size: render.size,
            jpeg_quality: render.jpeg_quality,
            vpls: render.vpls,
            shadow_map_size: render.shadow_map_size,
            env_lights: render.env_lights,
            photo_spp: render.photo_spp,
            min_fps: render.min_fps,
            pace,
        },
        min_response_ms,
        abandon_after_minutes: raw.abandon_after_minutes,
        file: file.to_path_buf(),
        file_sha256,
    };
    if study.trial_count() > 1000 {
        return Err(
            fail.at("design", format!("expected at most 1000 trials per participant, found {}", study.trial_count()))
        );
    }
    Ok(study)
}

#[cfg(test)]
mod tests;
