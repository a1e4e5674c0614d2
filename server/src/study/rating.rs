//! Rating study files (`kind = "rating"`): each stimulus rated on a 5-point scale by ITU-T
//! P.910's methods. The `[rating]` table names the method (`acr`, `dcr`, `acr-hr`), the
//! presentation (`stimulus_ms`, `grey_ms`, `vote_after`, `layout`), the `repetitions` of each
//! stimulus, the `seed` and the catch trials (`[[rating.catch]]`); the factors, conditions and
//! scene configurations are declared as in a paired-comparison study.
//!
//! A rating study is resolved into the survey's [`Study`] so that everything after loading
//! (stimuli, preparing, joining, screen requirements, pilots, exclusion, deletion, the admin
//! page) is the paired comparisons' own code. Its design is made from `[rating]`: a detection
//! design against the ground truth when every scene configuration is rendered (so each scene
//! configuration's ground truth is rendered with its stimuli: DCR's reference, ACR-HR's hidden
//! reference, a ground-truth catch trial), else (ACR of image files) every condition once. Its
//! trials are not pairs: [`Study::rating`] keeps the [`RatingDesign`] from which
//! `crate::rating` plans each participant's trials.

use std::path::Path;

use serde::Deserialize;

use super::StudyError;
use super::checks::{Fail, check_image, is_condition_name, kind_table};
use super::made::{check_export_fits, parse_made};
pub use super::rating_design::{
    CATCH_TOLERANCE, CatchSource, Layout, Method, Presentation, RatingCatch, RatingDesign, RatingScale,
};
use super::survey::{GROUND_TRUTH, Study, StudyKind};

/// The raw `[rating]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RatingFile {
    method: String,
    #[serde(default)]
    repetitions: Option<i64>,
    #[serde(default)]
    seed: Option<u64>,
    #[serde(default)]
    stimulus_ms: Option<i64>,
    #[serde(default)]
    grey_ms: Option<i64>,
    #[serde(default)]
    vote_after: Option<bool>,
    #[serde(default)]
    layout: Option<String>,
    #[serde(default)]
    catch: Vec<CatchFile>,
}

/// One raw `[[rating.catch]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CatchFile {
    name: String,
    expected: i64,
    #[serde(default)]
    repetitions: Option<i64>,
    #[serde(default)]
    image: Option<String>,
    #[serde(default)]
    reference: Option<String>,
    #[serde(default)]
    scene: Option<String>,
}

/// The keys of a paired-comparison file a rating study makes itself from `[rating]`.
const MADE_FROM_RATING: [(&str, &str); 3] = [
    ("design", "its design is [rating]"),
    ("catch", "its catch trials are [[rating.catch]]"),
    ("allow_tie", "a rating has no \"not sure\""),
];

/// The rating export's own columns, after the trials CSV's (docs/design.md).
pub const CSV_COLUMNS: [&str; 8] =
    ["scene", "condition", "rating", "method", "reference", "scale", "catch", "expected"];

/// The longest display time a study may set, in ms.
const MAX_MS: i64 = 60_000;

/// Reads a `kind = "rating"` file (already parsed as TOML into `table`) into a [`Study`].
pub(super) fn parse(
    mut table: toml::Table,
    file: &Path,
    base: &Path,
    file_sha256: String,
) -> Result<Study, StudyError> {
    let fail = Fail(file);
    let raw: RatingFile =
        kind_table(&mut table, fail, "rating", &MADE_FROM_RATING, "method = \"acr\", \"dcr\" or \"acr-hr\", …")?;
    let method = Method::parse(&raw.method).ok_or_else(|| {
        fail.at("rating.method", format!("expected \"acr\", \"dcr\" or \"acr-hr\", found \"{}\"", raw.method))
    })?;
    let repetitions = raw.repetitions.unwrap_or(1);
    if !(1..=20).contains(&repetitions) {
        return Err(
            fail.at("rating.repetitions", format!("expected 1 to 20 ratings of each stimulus, found {repetitions}"))
        );
    }
    let presentation = check_presentation(fail, method, &raw)?;
    // every scene configuration rendered: a detection design, so that each one's ground truth
    // is rendered with its stimuli; image files: ACR only, the conditions as they are
    let image_scene = image_scene(&table);
    let mut design = toml::Table::new();
    match image_scene {
        None => {
            design.insert("reference".into(), toml::Value::String(GROUND_TRUTH.into()));
        }
        Some(_) if method == Method::Acr => {
            design.insert("pairs".into(), toml::Value::String("all".into()));
        }
        Some((index, name)) => {
            return Err(fail.at(
                &format!("scenes[{index}]"),
                format!(
                    "expected `render` with method \"{}\": it shows each scene configuration's ground truth, and \"{name}\" shows image files, which have none",
                    method.name()
                ),
            ));
        }
    }
    design.insert("repetitions".into(), toml::Value::Integer(1));
    design.insert("scenes".into(), toml::Value::String("same".into()));
    if let Some(seed) = raw.seed {
        design.insert("seed".into(), toml::Value::Integer(seed as i64));
    }
    table.insert("design".into(), toml::Value::Table(design));
    let mut study = parse_made(fail, &table, "rating", file, base, file_sha256)?;
    let catch = check_catch(fail, base, method, &study, &raw.catch)?;
    let rating = RatingDesign { method, repetitions: repetitions as u32, presentation, catch };
    let trials = rating.trial_count(study.scenes.len(), study.conditions.len());
    check_export_fits(fail, &study, "rating.repetitions", trials, "rating", &CSV_COLUMNS)?;
    study.kind = StudyKind::Rating;
    study.rating = Some(rating);
    Ok(study)
}

/// The first scene configuration that shows image files (not `render`), with its name.
fn image_scene(table: &toml::Table) -> Option<(usize, String)> {
    let scenes = table.get("scenes")?.as_array()?;
    scenes.iter().enumerate().find_map(|(index, scene)| {
        let scene = scene.as_table()?;
        (!scene.contains_key("render"))
            .then(|| (index, scene.get("name").and_then(|name| name.as_str()).unwrap_or_default().to_string()))
    })
}

/// `stimulus_ms`, `grey_ms`, `vote_after` and `layout`, each where the method has it.
fn check_presentation(fail: Fail, method: Method, raw: &RatingFile) -> Result<Presentation, StudyError> {
    let layout = match (raw.layout.as_deref(), method) {
        (None, _) => Layout::Sequential,
        (Some("sequential"), Method::Dcr) => Layout::Sequential,
        (Some("side-by-side"), Method::Dcr) => Layout::SideBySide,
        (Some(other), Method::Dcr) => {
            return Err(
                fail.at("rating.layout", format!("expected \"sequential\" or \"side-by-side\", found \"{other}\""))
            );
        }
        (Some(_), _) => {
            return Err(fail.at(
                "rating.layout",
                format!("expected only with method = \"dcr\" (method \"{}\" shows one image)", method.name()),
            ));
        }
    };
    let sequential = method == Method::Dcr && layout == Layout::Sequential;
    // sequential DCR must take the reference away: 5 s each by default
    let stimulus_ms = raw.stimulus_ms.unwrap_or(if sequential { 5000 } else { 0 });
    if stimulus_ms != 0 && !(500..=MAX_MS).contains(&stimulus_ms) {
        return Err(fail.at(
            "rating.stimulus_ms",
            format!("expected 0 (shown until the vote) or 500 to {MAX_MS} milliseconds, found {stimulus_ms}"),
        ));
    }
    if sequential && stimulus_ms == 0 {
        return Err(fail.at(
            "rating.stimulus_ms",
            "expected 500 to 60000 milliseconds with method \"dcr\" shown in sequence: the reference must give way to the stimulus",
        ));
    }
    let grey_ms = match (raw.grey_ms, sequential) {
        (None, true) => 2000,
        (None, false) => 0,
        (Some(grey), true) if (0..=10_000).contains(&grey) => grey,
        (Some(grey), true) => {
            return Err(fail.at("rating.grey_ms", format!("expected 0 to 10000 milliseconds, found {grey}")));
        }
        (Some(_), false) => {
            return Err(fail.at(
                "rating.grey_ms",
                "expected only with method = \"dcr\" in sequence (the grey between the reference and the stimulus)",
            ));
        }
    };
    let vote_after = raw.vote_after.unwrap_or(false);
    if vote_after && stimulus_ms == 0 {
        return Err(fail.at(
            "rating.vote_after",
            "expected a `stimulus_ms` above 0 with vote_after = true: the vote comes when the stimulus has gone",
        ));
    }
    Ok(Presentation { stimulus_ms: stimulus_ms as u32, grey_ms: grey_ms as u32, vote_after, layout })
}

/// `[[rating.catch]]`: unique names, an expected rating 1–5, exactly one of `image` (a file) and
/// `scene` (its ground truth, rendered scene configurations only), `reference` for an image in
/// DCR (and only there).
fn check_catch(
    fail: Fail,
    base: &Path,
    method: Method,
    study: &Study,
    raw: &[CatchFile],
) -> Result<Vec<RatingCatch>, StudyError> {
    let mut catch: Vec<RatingCatch> = Vec::new();
    for (index, item) in raw.iter().enumerate() {
        let key = format!("rating.catch[{index}]");
        if !is_condition_name(&item.name) || catch.iter().any(|other| other.name == item.name) {
            return Err(fail.at(
                &format!("{key}.name"),
                format!("expected a unique name of A-Z, a-z, 0-9 and + - _ ., found \"{}\"", item.name),
            ));
        }
        if !(1..=5).contains(&item.expected) {
            return Err(
                fail.at(&format!("{key}.expected"), format!("expected a rating from 1 to 5, found {}", item.expected))
            );
        }
        let repetitions = item.repetitions.unwrap_or(1);
        if !(1..=100).contains(&repetitions) {
            return Err(fail.at(&format!("{key}.repetitions"), format!("expected 1 to 100, found {repetitions}")));
        }
        let source = match (&item.image, &item.scene) {
            (Some(image), None) => {
                let image = check_image(fail, &format!("{key}.image"), base, image)?;
                let reference = match (&item.reference, method) {
                    (Some(reference), Method::Dcr) => {
                        Some(check_image(fail, &format!("{key}.reference"), base, reference)?)
                    }
                    (None, Method::Dcr) => {
                        return Err(fail.at(
                            &format!("{key}.reference"),
                            "expected the image shown before it (method \"dcr\" rates a stimulus against a reference)",
                        ));
                    }
                    (Some(_), _) => {
                        return Err(fail.at(
                            &format!("{key}.reference"),
                            format!("expected only with method = \"dcr\", not \"{}\"", method.name()),
                        ));
                    }
                    (None, _) => None,
                };
                CatchSource::Image { image, reference }
            }
            (None, Some(scene)) => {
                if item.reference.is_some() {
                    return Err(fail.at(
                        &format!("{key}.reference"),
                        "expected no reference with `scene`: the scene configuration's ground truth is its own reference",
                    ));
                }
                let Some(position) = study.scenes.iter().position(|known| known.name == *scene) else {
                    return Err(fail.at(
                        &format!("{key}.scene"),
                        format!(
                            "expected one of the scene configurations ({}), found \"{scene}\"",
                            study.scenes.iter().map(|known| known.name.as_str()).collect::<Vec<_>>().join(", ")
                        ),
                    ));
                };
                if study.design.reference.is_none() {
                    return Err(fail.at(
                        &format!("{key}.scene"),
                        "expected rendered scene configurations: one of image files has no ground truth",
                    ));
                }
                CatchSource::GroundTruth { scene: position }
            }
            _ => {
                return Err(fail.at(
                    &key,
                    "expected exactly one of `image` (an image file) and `scene` (the scene configuration whose ground truth is rated)",
                ));
            }
        };
        catch.push(RatingCatch {
            name: item.name.clone(),
            source,
            expected: item.expected as u8,
            repetitions: repetitions as u32,
        });
    }
    Ok(catch)
}
