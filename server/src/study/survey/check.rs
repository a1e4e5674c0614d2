//! The checks of a web-survey study file, one named function per part of the file, resolving
//! the raw shape ([`file`](super::file)) into a [`Study`]: condition names are unique, every
//! condition gives a level for every factor and carries the renderer's [`Factors`] for them,
//! every scene configuration has a stimulus for every condition, the design names only defined
//! conditions, and image files exist. The design's pair rules are here too.

use std::collections::BTreeSet;
use std::path::Path;

use mrstudy_renderer::stimulus::{FactorLevel, Factors};

use super::file::{CatchFile, ConditionFile, DesignFile, SceneFile, StudyFile};
use super::model::*;
use crate::study::checks::{
    Fail, check_image, check_inside, check_min_response_ms, check_name, check_slug, check_texts, is_condition_name,
    is_identifier, resolve_scene,
};
use crate::study::{StudyError, one_line};

/// Reads and checks the text of a web-survey study file (`kind = "paired-comparison"`).
pub(in crate::study) fn parse(text: &str, file: &Path, base: &Path, file_sha256: String) -> Result<Study, StudyError> {
    let raw: StudyFile = toml::from_str(text).map_err(|error| StudyError {
        file: file.to_path_buf(),
        key: String::new(),
        expected: one_line(&error.to_string()),
    })?;
    check(raw, file, base, file_sha256)
}

/// Checks the raw file and resolves it into a [`Study`], part by part.
fn check(raw: StudyFile, file: &Path, base: &Path, file_sha256: String) -> Result<Study, StudyError> {
    let fail = Fail(file);
    check_slug(fail, "slug", &raw.slug)?;
    check_texts(
        fail,
        &[
            ("title", &raw.title),
            ("question", &raw.question),
            ("texts.welcome", &raw.texts.welcome),
            ("texts.consent", &raw.texts.consent),
            ("texts.instructions", &raw.texts.instructions),
        ],
    )?;
    let field_names = check_demographics(fail, &raw.demographics)?;
    let url_params_declared = raw.url_params.is_some();
    let url_params = raw.url_params.clone().unwrap_or_else(default_url_params);
    check_url_params(fail, &url_params, &field_names)?;
    let mut factors = raw.factors.clone();
    let conditions = check_conditions(fail, &mut factors, &raw.conditions)?;
    let scenes = check_scenes(fail, base, &raw.scenes, &conditions)?;
    check_render(fail, raw.render.as_ref())?;
    if scenes.iter().any(|scene| matches!(scene.source, StimulusSource::Render(_))) {
        // Rendered stimuli: every condition's factor levels must be ones the renderer renders.
        if let Some(index) = conditions.iter().position(|condition| condition.factors.is_err()) {
            let reason = conditions[index].factors.as_ref().err().cloned().unwrap_or_default();
            return Err(
                fail.at(&format!("conditions[{index}].levels"), format!("levels the renderer can render: {reason}"))
            );
        }
    }
    let design = check_design(fail, &raw.design, &conditions, &scenes)?;
    let catch = check_catch(fail, base, &raw.catch)?;
    let trial_total = design.pairs.len() * design.repetitions as usize
        + design.active.as_ref().map_or(0, |active| active.trials as usize)
        + catch.iter().map(|c| c.repetitions as usize).sum::<usize>();
    if trial_total > 1000 {
        return Err(fail.at(
            "design.repetitions",
            format!("expected at most 1000 trials per participant, the design gives {trial_total}"),
        ));
    }
    check_completion(fail, &raw.completion)?;
    let participation = check_participation(fail, &raw)?;
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
        url_params,
        url_params_declared,
        factors,
        conditions,
        render: raw.render,
        scenes,
        design,
        catch,
        completion: raw.completion,
        participation,
        file: file.to_path_buf(),
        file_sha256,
        threshold: None,
        rating: None,
    })
}

/// The demographic questions: identifiers, unique, not export columns; returns their names.
fn check_demographics(fail: Fail, fields: &[DemographicField]) -> Result<BTreeSet<String>, StudyError> {
    let mut field_names = BTreeSet::new();
    for (index, field) in fields.iter().enumerate() {
        let key = format!("demographics[{index}]");
        if !is_identifier(&field.name) {
            return Err(fail.at(
                &format!("{key}.name"),
                format!("expected a lower-case identifier (a-z, 0-9, _), found \"{}\"", field.name),
            ));
        }
        if TRIALS_CSV_COLUMNS.contains(&field.name.as_str()) {
            return Err(fail.at(
                &format!("{key}.name"),
                format!(
                    "expected a name that is not an export column ({}), found \"{}\"",
                    TRIALS_CSV_COLUMNS.join(", "),
                    field.name
                ),
            ));
        }
        if !field_names.insert(field.name.clone()) {
            return Err(
                fail.at(&format!("{key}.name"), format!("expected a unique name, \"{}\" appears twice", field.name))
            );
        }
        if field.label.trim().is_empty() {
            return Err(fail.at(&format!("{key}.label"), "expected a non-empty text"));
        }
        match field.field_type {
            FieldType::Choice if field.options.len() < 2 => {
                return Err(fail.at(&format!("{key}.options"), "expected at least two options for a choice"));
            }
            FieldType::Integer => {
                if let (Some(min), Some(max)) = (field.min, field.max)
                    && min > max
                {
                    return Err(fail.at(&format!("{key}.min"), format!("expected min ≤ max, found {min} > {max}")));
                }
            }
            _ => {}
        }
    }
    Ok(field_names)
}

/// The URL parameters kept as external ids: each becomes a column of the trials CSV.
fn check_url_params(fail: Fail, url_params: &[String], field_names: &BTreeSet<String>) -> Result<(), StudyError> {
    for (index, name) in url_params.iter().enumerate() {
        if name.is_empty()
            || name.len() > 64
            || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(fail.at(
                &format!("url_params[{index}]"),
                format!("expected a URL parameter name (A-Z, a-z, 0-9, _, -), found \"{name}\""),
            ));
        }
        if TRIALS_CSV_COLUMNS.contains(&name.as_str()) || field_names.contains(name) {
            return Err(fail.at(
                &format!("url_params[{index}]"),
                format!("expected a name that is not an export column or a demographic field, found \"{name}\""),
            ));
        }
    }
    Ok(())
}

/// Factors and conditions: unique names, one level per factor (a finite number, or a name for
/// a factor whose levels are all names), each condition coded as its row of the design matrix
/// and resolved into the renderer's [`Factors`] (or why it cannot be). Fills in the named
/// levels of each factor that has them ([`Factor::levels`]).
fn check_conditions(fail: Fail, factors: &mut [Factor], raw: &[ConditionFile]) -> Result<Vec<Condition>, StudyError> {
    if factors.is_empty() {
        return Err(fail.at("factors", "expected at least one factor"));
    }
    let mut factor_names = BTreeSet::new();
    for (index, factor) in factors.iter().enumerate() {
        if !is_identifier(&factor.name) || factor.name == "condition" {
            return Err(fail.at(
                &format!("factors[{index}].name"),
                format!("expected a lower-case identifier other than \"condition\", found \"{}\"", factor.name),
            ));
        }
        if !factor_names.insert(factor.name.clone()) {
            return Err(fail.at(
                &format!("factors[{index}].name"),
                format!("expected a unique name, \"{}\" appears twice", factor.name),
            ));
        }
    }
    if raw.len() < 2 {
        return Err(fail.at("conditions", "expected at least two conditions"));
    }
    for (index, condition) in raw.iter().enumerate() {
        let key = format!("conditions[{index}]");
        check_name(fail, &key, &condition.name, raw[..index].iter().map(|other| other.name.as_str()))?;
        if condition.name == GROUND_TRUTH {
            return Err(fail.at(
                &format!("{key}.name"),
                format!(
                    "expected a name other than \"{GROUND_TRUTH}\" (it names the ground truth in detection designs)"
                ),
            ));
        }
        if let Some(level_name) = condition.levels.keys().find(|name| !factor_names.contains(*name)) {
            return Err(fail.at(
                &format!("{key}.levels.{level_name}"),
                format!(
                    "expected one of the factors ({}), found \"{level_name}\"",
                    factors.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            ));
        }
        for factor in factors.iter() {
            match condition.levels.get(&factor.name) {
                Some(FactorLevel::Number(level)) if level.is_finite() => {}
                Some(FactorLevel::Number(_)) => {
                    return Err(fail.at(&format!("{key}.levels.{}", factor.name), "expected a finite number"));
                }
                Some(FactorLevel::Name(name)) if !is_level_name(name) => {
                    return Err(fail.at(
                        &format!("{key}.levels.{}", factor.name),
                        format!("expected a number or a level name (a-z, 0-9, -), found \"{name}\""),
                    ));
                }
                Some(FactorLevel::Name(_)) => {}
                None => {
                    return Err(
                        fail.at(&format!("{key}.levels"), format!("expected a level for factor \"{}\"", factor.name))
                    );
                }
            }
        }
    }
    named_levels(fail, factors, raw)?;
    let mut conditions: Vec<Condition> = Vec::new();
    for condition in raw {
        let mut levels = Vec::new();
        for factor in factors.iter() {
            match &condition.levels[&factor.name] {
                FactorLevel::Number(level) => levels.push(*level),
                FactorLevel::Name(name) => {
                    levels.extend(factor.levels[1..].iter().map(|level| if level == name { 1.0 } else { 0.0 }))
                }
            }
        }
        let resolved = Factors::from_study_levels(
            factors.iter().map(|factor| (factor.name.as_str(), &condition.levels[&factor.name])),
        )
        .map_err(|error| error.to_string());
        conditions.push(Condition { name: condition.name.clone(), levels, factors: resolved, knob: None });
    }
    let columns: Vec<String> = factors.iter().flat_map(Factor::columns).collect();
    if let Some(column) = columns.iter().enumerate().find(|(k, column)| columns[..*k].contains(column)).map(|(_, c)| c)
    {
        return Err(fail.at(
            "factors",
            format!("expected distinct design columns, \"{column}\" names both a factor and a named level of another"),
        ));
    }
    Ok(conditions)
}

/// A level name: 1–32 of a-z, 0-9 and `-`, starting with a letter.
fn is_level_name(name: &str) -> bool {
    name.len() <= 32
        && name.starts_with(|c: char| c.is_ascii_lowercase())
        && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
}

/// Each factor's named levels: a factor's conditions give all numbers or all names; the names
/// are the file's `levels` list (which must hold every name used, once) or, by default, the
/// order of first use with `off` first.
fn named_levels(fail: Fail, factors: &mut [Factor], raw: &[ConditionFile]) -> Result<(), StudyError> {
    for (index, factor) in factors.iter_mut().enumerate() {
        let used: Vec<(usize, &FactorLevel)> = raw.iter().map(|c| &c.levels[&factor.name]).enumerate().collect();
        let named: Vec<(usize, &str)> = used
            .iter()
            .filter_map(|(c, level)| match level {
                FactorLevel::Name(name) => Some((*c, name.as_str())),
                FactorLevel::Number(_) => None,
            })
            .collect();
        if named.is_empty() {
            if !factor.levels.is_empty() {
                return Err(fail.at(
                    &format!("factors[{index}].levels"),
                    format!(
                        "expected no level names for factor \"{}\": its conditions give numbers (levels lists the names of a factor whose conditions name them)",
                        factor.name
                    ),
                ));
            }
            continue;
        }
        if named.len() < used.len() {
            // the first condition that differs in kind from the first condition
            let first_named = matches!(used[0].1, FactorLevel::Name(_));
            let (c, level) = used
                .iter()
                .find(|(_, level)| matches!(level, FactorLevel::Name(_)) != first_named)
                .expect("a level of the other kind");
            let wanted = if first_named { "a level name" } else { "a number" };
            return Err(fail.at(
                &format!("conditions[{c}].levels.{}", factor.name),
                format!(
                    "expected {wanted} for factor \"{}\" as conditions[0] gives ({}), found {level}; a factor's levels are all numbers or all names",
                    factor.name, used[0].1
                ),
            ));
        }
        if factor.levels.is_empty() {
            let mut order: Vec<String> = Vec::new();
            for (_, name) in &named {
                if !order.iter().any(|n| n == name) {
                    order.push(name.to_string());
                }
            }
            if let Some(off) = order.iter().position(|n| n == "off") {
                let off = order.remove(off);
                order.insert(0, off);
            }
            factor.levels = order;
        } else {
            for (k, level) in factor.levels.iter().enumerate() {
                if !is_level_name(level) {
                    return Err(fail.at(
                        &format!("factors[{index}].levels[{k}]"),
                        format!("expected a level name (a-z, 0-9, -), found \"{level}\""),
                    ));
                }
                if factor.levels[..k].contains(level) {
                    return Err(fail.at(
                        &format!("factors[{index}].levels[{k}]"),
                        format!("expected each level once, \"{level}\" appears twice"),
                    ));
                }
            }
            if let Some((c, name)) = named.iter().find(|(_, name)| !factor.levels.iter().any(|l| l == name)) {
                return Err(fail.at(
                    &format!("conditions[{c}].levels.{}", factor.name),
                    format!(
                        "expected one of the levels of factor \"{}\" ({}), found \"{name}\"",
                        factor.name,
                        factor.levels.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The index of the condition called `name`, or a refusal at `key` listing the conditions.
fn condition_index(fail: Fail, conditions: &[Condition], key: &str, name: &str) -> Result<usize, StudyError> {
    conditions.iter().position(|condition| condition.name == name).ok_or_else(|| {
        fail.at(
            key,
            format!(
                "expected a condition defined in [[conditions]] ({}), found \"{name}\"",
                conditions.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
            ),
        )
    })
}

/// Scene configurations and where their stimuli come from: a scene for the renderer (built-in
/// or a file next to the study), or one image file per condition.
fn check_scenes(
    fail: Fail,
    base: &Path,
    raw: &[SceneFile],
    conditions: &[Condition],
) -> Result<Vec<SceneConfiguration>, StudyError> {
    if raw.is_empty() {
        return Err(fail.at("scenes", "expected at least one scene configuration"));
    }
    let mut scenes: Vec<SceneConfiguration> = Vec::new();
    for (index, scene) in raw.iter().enumerate() {
        let key = format!("scenes[{index}]");
        check_name(fail, &key, &scene.name, scenes.iter().map(|other| other.name.as_str()))?;
        let source = match (&scene.render, &scene.images) {
            (Some(render), None) => {
                StimulusSource::Render(resolve_scene(fail, &format!("{key}.render"), base, render)?)
            }
            (None, Some(images)) => {
                for condition_name in images.keys() {
                    condition_index(fail, conditions, &format!("{key}.images.{condition_name}"), condition_name)?;
                }
                let mut paths = Vec::new();
                for condition in conditions {
                    let Some(relative) = images.get(&condition.name) else {
                        return Err(fail.at(
                            &format!("{key}.images"),
                            format!("expected an image file for condition \"{}\"", condition.name),
                        ));
                    };
                    paths.push(check_image(fail, &format!("{key}.images.{}", condition.name), base, relative)?);
                }
                StimulusSource::Images(paths)
            }
            _ => {
                return Err(fail.at(
                    &key,
                    "expected exactly one of `render` (a scene for the renderer) or `images` (one image file per condition)",
                ));
            }
        };
        scenes.push(SceneConfiguration { name: scene.name.clone(), description: scene.description.clone(), source });
    }
    Ok(scenes)
}

/// The `[render]` table: stimulus size, samples per pixel, VPL budget.
fn check_render(fail: Fail, render: Option<&RenderDefaults>) -> Result<(), StudyError> {
    let Some(render) = render else { return Ok(()) };
    if render.size[0] == 0 || render.size[1] == 0 || render.size[0] > 8192 || render.size[1] > 8192 {
        return Err(fail.at("render.size", "expected [width, height], each 1 to 8192"));
    }
    if render.spp.is_some_and(|spp| spp == 0 || spp > 65_536) {
        return Err(fail.at("render.spp", "expected samples per pixel from 1 to 65536"));
    }
    if render.vpls.is_some_and(|vpls| vpls > 65_536) {
        return Err(fail.at("render.vpls", "expected a VPL budget from 0 to 65536"));
    }
    Ok(())
}

/// The `[design]` table: the condition pairs by its rule, repetitions and the scene draw; for
/// `pairs = "active"` its keys and the warm-up's pairs.
fn check_design(
    fail: Fail,
    design: &DesignFile,
    conditions: &[Condition],
    scenes: &[SceneConfiguration],
) -> Result<Design, StudyError> {
    let scene_count = scenes.len();
    if let Some(reference) = &design.reference {
        return check_detection(fail, design, reference, conditions, scenes);
    }
    let Some(pairs_rule) = &design.pairs else {
        return Err(fail.at(
            "design.pairs",
            "expected \"all\", \"anchored\", \"list\" or \"active\" (or reference = \"ground-truth\" for a detection design)",
        ));
    };
    let active = pairs_rule == "active";
    // the default warm-up (`target` "both" or omitted, `warmup` omitted): docs/design.md
    let default_warmup = active && super::active::default_warmup(design);
    let rule = match (active, design.warmup.as_deref()) {
        (false, _) => pairs_rule.as_str(),
        (true, Some(warmup)) => warmup,
        (true, None) if default_warmup => "anchored",
        (true, None) => "none",
    };
    let rule_key = if active { "design.warmup" } else { "design.pairs" };
    let (pairs, fixed_rule) = match rule {
        "all" => (all_pairs(conditions.len()), PairsRule::All),
        "anchored" if default_warmup && design.anchors.is_empty() => {
            (first_and_last_anchored(conditions.len()), PairsRule::Anchored)
        }
        "anchored" => (anchored_pairs(fail, &design.anchors, conditions)?, PairsRule::Anchored),
        "list" => (listed_pairs(fail, &design.list, conditions)?, PairsRule::List),
        "none" if active => (Vec::new(), PairsRule::Active),
        other if active => {
            return Err(
                fail.at(rule_key, format!("expected \"none\", \"all\", \"anchored\" or \"list\", found \"{other}\""))
            );
        }
        other => {
            return Err(
                fail.at(rule_key, format!("expected \"all\", \"anchored\", \"list\" or \"active\", found \"{other}\""))
            );
        }
    };
    for (key, given) in [
        ("design.realisations", design.realisations.is_some()),
        ("design.reference_label", design.reference_label.is_some()),
    ] {
        if given {
            return Err(fail.at(key, "expected only with reference = \"ground-truth\" (a detection design)"));
        }
    }
    if rule != "anchored" && !design.anchors.is_empty() {
        return Err(fail.at("design.anchors", format!("expected only with {} = \"anchored\"", &rule_key[7..])));
    }
    if rule != "list" && !design.list.is_empty() {
        return Err(fail.at("design.list", format!("expected only with {} = \"list\"", &rule_key[7..])));
    }
    let repetitions = match (design.repetitions, active) {
        (Some(repetitions), _) => repetitions,
        (None, true) if default_warmup => super::active::default_repetitions(design.trials, pairs.len()),
        (None, true) => 1,
        (None, false) => return Err(fail.at("design.repetitions", "expected the number of times each pair is shown")),
    };
    if repetitions == 0 || repetitions > 100 {
        return Err(fail.at("design.repetitions", format!("expected 1 to 100, found {repetitions}")));
    }
    let scenes = match design.scenes.as_str() {
        "different" => SceneDraw::Different,
        "same" => SceneDraw::Same,
        other => {
            return Err(fail.at("design.scenes", format!("expected \"different\" or \"same\", found \"{other}\"")));
        }
    };
    if scenes == SceneDraw::Different && scene_count < 2 {
        return Err(fail.at("design.scenes", "expected at least two scene configurations for scenes = \"different\""));
    }
    let active = if active { Some(super::active::check_active(fail, design, &pairs, conditions)?) } else { None };
    if active.is_none() {
        for (key, given) in active_keys_given(design) {
            if given {
                return Err(fail.at(key, "expected only with pairs = \"active\""));
            }
        }
    }
    Ok(Design {
        pairs_rule: if active.is_some() { PairsRule::Active } else { fixed_rule },
        pairs,
        repetitions,
        scenes,
        seed: design.seed,
        active,
        reference: None,
        realisations: 1,
        reference_label: None,
    })
}

/// The keys of an active design (`pairs = "active"`), each with whether the file gives it.
fn active_keys_given(design: &DesignFile) -> [(&'static str, bool); 6] {
    [
        ("design.trials", design.trials.is_some()),
        ("design.batch", design.batch.is_some()),
        ("design.target", design.target.is_some()),
        ("design.warmup", design.warmup.is_some()),
        ("design.prior_sd", design.prior_sd.is_some()),
        ("design.prior", design.prior.is_some()),
    ]
}

/// `reference = "ground-truth"`: every condition against the ground truth of the same scene
/// configuration, `repetitions` times; every scene configuration must be one the renderer
/// synthesises (its ground truth exists), scenes drawn "same".
fn check_detection(
    fail: Fail,
    design: &DesignFile,
    reference: &str,
    conditions: &[Condition],
    scenes: &[SceneConfiguration],
) -> Result<Design, StudyError> {
    if reference != GROUND_TRUTH {
        return Err(fail.at("design.reference", format!("expected \"{GROUND_TRUTH}\", found \"{reference}\"")));
    }
    let pairing = [
        ("design.pairs", design.pairs.is_some()),
        ("design.anchors", !design.anchors.is_empty()),
        ("design.list", !design.list.is_empty()),
    ];
    for (key, given) in pairing.into_iter().chain(active_keys_given(design)) {
        if given {
            return Err(fail.at(
                key,
                "expected no pairing rule with reference = \"ground-truth\" (every condition is paired with the ground truth)",
            ));
        }
    }
    if design.scenes != "same" {
        return Err(fail.at(
            "design.scenes",
            format!(
                "expected \"same\" with reference = \"ground-truth\" (a stimulus is shown beside the ground truth of its own scene configuration), found \"{}\"",
                design.scenes
            ),
        ));
    }
    if let Some((index, scene)) =
        scenes.iter().enumerate().find(|(_, scene)| !matches!(scene.source, StimulusSource::Render(_)))
    {
        return Err(fail.at(
            &format!("scenes[{index}]"),
            format!(
                "expected `render` with reference = \"ground-truth\": scene configuration \"{}\" shows image files, which have no ground truth",
                scene.name
            ),
        ));
    }
    let repetitions = design
        .repetitions
        .ok_or_else(|| fail.at("design.repetitions", "expected the number of times each condition is shown"))?;
    if repetitions == 0 || repetitions > 100 {
        return Err(fail.at("design.repetitions", format!("expected 1 to 100, found {repetitions}")));
    }
    let realisations = design.realisations.unwrap_or(1);
    if realisations == 0 || realisations > MAX_REALISATIONS {
        return Err(fail.at("design.realisations", format!("expected 1 to {MAX_REALISATIONS}, found {realisations}")));
    }
    if let Some(label) = &design.reference_label
        && label.trim().is_empty()
    {
        return Err(fail.at("design.reference_label", "expected a non-empty text saying what the reference image is"));
    }
    let truth = conditions.len();
    Ok(Design {
        pairs_rule: PairsRule::GroundTruth,
        pairs: (0..truth).map(|condition| (condition, truth)).collect(),
        repetitions,
        scenes: SceneDraw::Same,
        seed: design.seed,
        active: None,
        reference: Some(DesignReference::GroundTruth),
        realisations,
        reference_label: design.reference_label.clone(),
    })
}

/// The default warm-up's pairs without `anchors`: the anchored rule with the first and the last
/// condition as anchors (the first alone with fewer than two conditions).
fn first_and_last_anchored(count: usize) -> Vec<(usize, usize)> {
    let anchors: Vec<usize> = if count < 2 { vec![0] } else { vec![0, count - 1] };
    anchored_pair_indices(&anchors, count)
}

/// `pairs = "all"`: every pair of `count` conditions, `(i, j)` with i < j.
pub fn all_pairs(count: usize) -> Vec<(usize, usize)> {
    (0..count).flat_map(|first| (first + 1..count).map(move |second| (first, second))).collect()
}

/// `pairs = "anchored"`: every anchor with every other anchor, then every other condition with
/// each anchor.
fn anchored_pairs(fail: Fail, names: &[String], conditions: &[Condition]) -> Result<Vec<(usize, usize)>, StudyError> {
    if names.is_empty() {
        return Err(fail.at("design.anchors", "expected at least one anchor condition for pairs = \"anchored\""));
    }
    let mut anchors = Vec::new();
    for (index, name) in names.iter().enumerate() {
        let anchor = condition_index(fail, conditions, &format!("design.anchors[{index}]"), name)?;
        if anchors.contains(&anchor) {
            return Err(fail.at(
                &format!("design.anchors[{index}]"),
                format!("expected each anchor once, \"{name}\" appears twice"),
            ));
        }
        anchors.push(anchor);
    }
    Ok(anchored_pair_indices(&anchors, conditions.len()))
}

/// `pairs = "anchored"` on condition indices: every anchor with every other anchor, then every
/// other of the `count` conditions with each anchor.
pub fn anchored_pair_indices(anchors: &[usize], count: usize) -> Vec<(usize, usize)> {
    let mut pairs = Vec::new();
    for (position, &first) in anchors.iter().enumerate() {
        for &second in &anchors[position + 1..] {
            pairs.push((first, second));
        }
    }
    for &anchor in anchors {
        for other in (0..count).filter(|other| !anchors.contains(other)) {
            pairs.push((anchor, other));
        }
    }
    pairs
}

/// `pairs = "list"`: the pairs listed, each once.
fn listed_pairs(fail: Fail, list: &[Vec<String>], conditions: &[Condition]) -> Result<Vec<(usize, usize)>, StudyError> {
    if list.is_empty() {
        return Err(fail.at("design.list", "expected a list of condition pairs for pairs = \"list\""));
    }
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for (index, pair) in list.iter().enumerate() {
        let key = format!("design.list[{index}]");
        if pair.len() != 2 {
            return Err(fail.at(&key, "expected a pair of two condition names"));
        }
        let first = condition_index(fail, conditions, &key, &pair[0])?;
        let second = condition_index(fail, conditions, &key, &pair[1])?;
        if first == second {
            return Err(fail.at(&key, "expected two different conditions"));
        }
        if pairs.iter().any(|&(a, b)| (a, b) == (first, second) || (a, b) == (second, first)) {
            return Err(fail.at(&key, "expected each pair once"));
        }
        pairs.push((first, second));
    }
    Ok(pairs)
}

impl Study {
    /// Refuses an image file of the study (its scene configurations' and catch trials') that is
    /// not inside `folder` once `..` and symbolic links are followed.
    pub fn check_images_inside(&self, folder: &Path) -> Result<(), StudyError> {
        let fail = Fail(&self.file);
        for (index, scene) in self.scenes.iter().enumerate() {
            if let StimulusSource::Images(paths) = &scene.source {
                for (condition, path) in self.conditions.iter().zip(paths) {
                    check_inside(fail, &format!("scenes[{index}].images.{}", condition.name), path, folder)?;
                }
            }
        }
        for (index, catch) in self.catch.iter().enumerate() {
            check_inside(fail, &format!("catch[{index}].better"), &catch.better, folder)?;
            check_inside(fail, &format!("catch[{index}].worse"), &catch.worse, folder)?;
        }
        if let Some(rating) = &self.rating {
            rating.check_images_inside(fail, folder)?;
        }
        Ok(())
    }
}

/// Catch trials: unique names, repetitions, and their two image files.
fn check_catch(fail: Fail, base: &Path, raw: &[CatchFile]) -> Result<Vec<CatchTrial>, StudyError> {
    let mut catch: Vec<CatchTrial> = Vec::new();
    for (index, catch_file) in raw.iter().enumerate() {
        let key = format!("catch[{index}]");
        if !is_condition_name(&catch_file.name) || catch.iter().any(|other| other.name == catch_file.name) {
            return Err(fail.at(
                &format!("{key}.name"),
                format!("expected a unique name of A-Z, a-z, 0-9 and + - _ ., found \"{}\"", catch_file.name),
            ));
        }
        if catch_file.repetitions == 0 || catch_file.repetitions > 100 {
            return Err(
                fail.at(&format!("{key}.repetitions"), format!("expected 1 to 100, found {}", catch_file.repetitions))
            );
        }
        catch.push(CatchTrial {
            name: catch_file.name.clone(),
            better: check_image(fail, &format!("{key}.better"), base, &catch_file.better)?,
            worse: check_image(fail, &format!("{key}.worse"), base, &catch_file.worse)?,
            repetitions: catch_file.repetitions,
        });
    }
    Ok(catch)
}

/// The completion page: a fixed code's characters, an http(s) redirect.
fn check_completion(fail: Fail, completion: &Completion) -> Result<(), StudyError> {
    if let Some(code) = &completion.code
        && (code.is_empty()
            || code.len() > 64
            || !code.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'))
    {
        return Err(fail.at(
            "completion.code",
            format!("expected 1 to 64 characters of A-Z, a-z, 0-9, - and _, found \"{code}\""),
        ));
    }
    if let Some(redirect) = &completion.redirect
        && !(redirect.starts_with("https://") || redirect.starts_with("http://"))
    {
        return Err(
            fail.at("completion.redirect", format!("expected an http:// or https:// URL, found \"{redirect}\""))
        );
    }
    Ok(())
}

/// The participation keys: response-time floor, external ids, screen requirements.
fn check_participation(fail: Fail, raw: &StudyFile) -> Result<Participation, StudyError> {
    let min_response_ms = check_min_response_ms(fail, raw.min_response_ms)?;
    if !(0..=10_000).contains(&raw.answer_lock_ms) {
        return Err(fail.at("answer_lock_ms", format!("expected 0 to 10000 ms, found {}", raw.answer_lock_ms)));
    }
    if let Some([width, height]) = raw.min_viewport
        && (width == 0 || height == 0 || width > 10_000 || height > 10_000)
    {
        return Err(fail.at(
            "min_viewport",
            format!("expected [width, height] in CSS pixels from 1 to 10000, found [{width}, {height}]"),
        ));
    }
    if raw.unique_external_id && raw.url_params.as_ref().is_some_and(Vec::is_empty) {
        return Err(fail.at(
            "unique_external_id",
            "expected `url_params` to name the external id (e.g. \"PROLIFIC_PID\"), found none",
        ));
    }
    if raw.allow_tie
        && let Some(index) = raw.conditions.iter().position(|condition| condition.name == "tie")
    {
        return Err(fail.at(
            &format!("conditions[{index}].name"),
            "expected a name other than \"tie\": with `allow_tie` the export's `chosen` says \"tie\" for \"not sure\"",
        ));
    }
    if raw.allow_tie && raw.design.reference.is_some() {
        return Err(fail.at(
            "allow_tie",
            "expected a paired comparison of conditions: a detection design (`design.reference`) asks which image is the real one, and has no \"not sure\"",
        ));
    }
    if raw.abandon_after_minutes == 0 {
        return Err(fail.at("abandon_after_minutes", "expected at least 1 minute, found 0"));
    }
    let devices = match &raw.devices {
        Some(devices) if devices.is_empty() => {
            return Err(fail.at("devices", "expected at least one of \"desktop\", \"tablet\", \"phone\""));
        }
        Some(devices) => devices.clone(),
        None => Vec::new(),
    };
    Ok(Participation {
        min_response_ms,
        answer_lock_ms: raw.answer_lock_ms as u32,
        allow_tie: raw.allow_tie,
        unique_external_id: raw.unique_external_id,
        min_viewport: raw.min_viewport,
        devices,
        orientation: raw.orientation,
        display: raw.display,
        abandon_after_minutes: raw.abandon_after_minutes,
    })
}
