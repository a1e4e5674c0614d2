//! What the study kinds that make a paired-comparison table share (`kind = "rating"`,
//! `"threshold"`): reading the table they made as a survey, and refusing what their export
//! cannot hold. Apart from [`super::checks`], which the survey's own checks use.

use std::path::Path;

use super::StudyError;
use super::checks::Fail;

/// The table a study kind made (its own table rewritten as a paired-comparison file's), written
/// as TOML and read as a survey; a refusal's `design.` key is named under `kind`, the table the
/// researcher wrote.
pub(crate) fn parse_made(
    fail: Fail,
    table: &toml::Table,
    kind: &str,
    file: &Path,
    base: &Path,
    file_sha256: String,
) -> Result<super::Study, StudyError> {
    let text = toml::to_string(table).map_err(|error| fail.at("", super::one_line(&error.to_string())))?;
    super::survey::parse(&text, file, base, file_sha256).map_err(|mut error| {
        if let Some(key) = error.key.strip_prefix("design.") {
            error.key = format!("{kind}.{key}");
        }
        error
    })
}

/// A study kind's refusals of what its export cannot hold: more than 1000 trials per
/// participant (`key` the setting that makes them), a demographic field named like one of its
/// export's own `columns`.
pub(crate) fn check_export_fits(
    fail: Fail,
    study: &super::Study,
    key: &str,
    trials: usize,
    kind: &str,
    columns: &[&str],
) -> Result<(), StudyError> {
    if trials > 1000 {
        let expected = format!("expected at most 1000 trials per participant with the catch trials, found {trials}");
        return Err(fail.at(key, expected));
    }
    if let Some(field) = study.demographics.iter().find(|field| columns.contains(&field.name.as_str())) {
        return Err(fail.at(
            "demographics",
            format!(
                "expected no demographic field named like a column of the {kind} export ({}), found \"{}\"",
                columns.join(", "),
                field.name
            ),
        ));
    }
    Ok(())
}
