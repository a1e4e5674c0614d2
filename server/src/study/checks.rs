//! The checks both kinds of study file share: the refusal maker (`Fail`), the name rules
//! (slug, identifier, condition name), non-empty texts, the reference to a scene for the
//! renderer, image files and the response-time floor; a study kind's own table (`kind_table`).

use std::path::{Path, PathBuf};

use super::StudyError;

/// Makes the refusals of one study file: `fail.at(key, expected)` names the file, the key (a
/// dotted path such as `design.pairs`) and what was expected there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fail<'a>(pub &'a Path);

impl Fail<'_> {
    pub(crate) fn at(self, key: &str, expected: impl Into<String>) -> StudyError {
        StudyError { file: self.0.to_path_buf(), key: key.to_string(), expected: expected.into() }
    }
}

/// A study kind's own table (`[threshold]`, `[rating]`): refuses the tables of a
/// paired-comparison file the kind makes itself (`made`: each key and why), then takes `[kind]`
/// out of `table` and reads it as `T`; `hint` is what the missing table should hold.
pub(crate) fn kind_table<T: serde::de::DeserializeOwned>(
    table: &mut toml::Table,
    fail: Fail,
    kind: &str,
    made: &[(&str, &str)],
    hint: &str,
) -> Result<T, StudyError> {
    for (key, why) in made {
        if table.contains_key(*key) {
            return Err(fail.at(key, format!("expected no `{key}` in a {kind} study: {why}")));
        }
    }
    let raw = table.remove(kind).ok_or_else(|| fail.at(kind, format!("expected a [{kind}] table ({hint})")))?;
    raw.try_into().map_err(|error: toml::de::Error| fail.at(kind, super::one_line(&error.to_string())))
}

/// A study slug: lower-case letters, digits and `-`, not first, at most 64 characters.
pub(crate) fn is_slug(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
        && !name.starts_with('-')
}

/// Refuses `name` at `key` unless it is a slug.
pub(crate) fn check_slug(fail: Fail, key: &str, name: &str) -> Result<(), StudyError> {
    if is_slug(name) {
        Ok(())
    } else {
        Err(fail.at(key, format!("expected 1 to 64 characters of a-z, 0-9 and '-', found \"{name}\"")))
    }
}

/// A factor or demographic field name: a lower-case identifier of at most 64 characters.
pub(crate) fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_lowercase())
        && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        && name.len() <= 64
}

/// A condition (also scene configuration and catch trial) name. The first character is no `+`,
/// `-` or `.`, so that the name is never neutralised as a spreadsheet formula in the trials CSV
/// (`export::text_cell`).
pub(crate) fn is_condition_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || "+-_.".contains(c))
}

/// Refuses `name` at `<key>.name` unless it is a condition name ([`is_condition_name`]) not
/// among the `earlier` names of its list.
pub(crate) fn check_name<'a>(
    fail: Fail,
    key: &str,
    name: &str,
    mut earlier: impl Iterator<Item = &'a str>,
) -> Result<(), StudyError> {
    if !is_condition_name(name) {
        return Err(fail.at(
            &format!("{key}.name"),
            format!(
                "expected 1 to 64 characters of A-Z, a-z, 0-9 and + - _ ., starting with a letter, digit or _, found \"{name}\""
            ),
        ));
    }
    if earlier.any(|other| other == name) {
        return Err(fail.at(&format!("{key}.name"), format!("expected a unique name, \"{name}\" appears twice")));
    }
    Ok(())
}

/// Refuses the first `(key, text)` whose text is blank.
pub(crate) fn check_texts(fail: Fail, texts: &[(&str, &str)]) -> Result<(), StudyError> {
    match texts.iter().find(|(_, text)| text.trim().is_empty()) {
        Some((key, _)) => Err(fail.at(key, "expected a non-empty text")),
        None => Ok(()),
    }
}

/// Resolves a reference to a scene for the renderer: a built-in scene name stays as it is, a
/// scene file is joined to the study file's folder `base` and must exist.
pub(crate) fn resolve_scene(fail: Fail, key: &str, base: &Path, name: &str) -> Result<String, StudyError> {
    let name = name.trim();
    if mrstudy_renderer::builtin::names().any(|builtin| builtin == name) {
        return Ok(name.to_string());
    }
    if !name.is_empty() && base.join(name).is_file() {
        return Ok(base.join(name).display().to_string());
    }
    Err(fail.at(
        key,
        format!(
            "expected a built-in scene of the renderer ({}) or an existing scene file, found \"{name}\"",
            mrstudy_renderer::builtin::names().collect::<Vec<_>>().join(", ")
        ),
    ))
}

/// Image extensions a stimulus file may have, with their content types.
pub const IMAGE_TYPES: &[(&str, &str)] =
    &[("png", "image/png"), ("jpg", "image/jpeg"), ("jpeg", "image/jpeg"), ("webp", "image/webp")];

/// An image file of the study, relative to its folder `base`: a known extension, existing, a
/// regular file once every link is followed, and an image of the kind its extension says.
/// Where it may lie is checked by [`check_inside`] when `serve` loads a studies folder.
pub(crate) fn check_image(fail: Fail, key: &str, base: &Path, relative: &str) -> Result<PathBuf, StudyError> {
    let path = base.join(relative);
    let extension = path.extension().and_then(|ext| ext.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    if !IMAGE_TYPES.iter().any(|(ext, _)| *ext == extension) {
        return Err(fail.at(key, format!("expected a .png, .jpg, .jpeg or .webp image file, found \"{relative}\"")));
    }
    if !path.is_file() {
        return Err(fail.at(key, format!("expected an existing image file, but {} does not exist", path.display())));
    }
    if !std::fs::metadata(&path).is_ok_and(|meta| meta.file_type().is_file()) {
        return Err(fail.at(key, format!("expected a regular image file, but {} is not one", path.display())));
    }
    if !is_image(&path, &extension) {
        return Err(fail.at(key, format!("expected a .{extension} image, but {} does not read as one", path.display())));
    }
    Ok(path)
}

/// Refuses an image file `path` of the study unless it lies inside `folder` once every `..` and
/// symbolic link is followed: `serve` would hand it to anyone (a link to `/etc/passwd` was served
/// as `image/png`).
pub(crate) fn check_inside(fail: Fail, key: &str, path: &Path, folder: &Path) -> Result<(), StudyError> {
    match (folder.canonicalize(), path.canonicalize()) {
        (Ok(folder), Ok(resolved)) if resolved.starts_with(&folder) => Ok(()),
        _ => Err(fail.at(
            key,
            format!(
                "expected an image file inside the studies folder {}, but {} is not",
                folder.display(),
                path.display()
            ),
        )),
    }
}

/// Whether the file reads as an image of the kind `extension` says: its header decodes (PNG,
/// JPEG: the `image` crate reads the dimensions) or, for WebP (which the server does not decode),
/// its RIFF/WEBP signature.
fn is_image(path: &Path, extension: &str) -> bool {
    if extension == "webp" {
        let mut head = [0u8; 12];
        use std::io::Read;
        return std::fs::File::open(path).and_then(|mut file| file.read_exact(&mut head)).is_ok()
            && &head[0..4] == b"RIFF"
            && &head[8..12] == b"WEBP";
    }
    let expected = if extension == "png" { image::ImageFormat::Png } else { image::ImageFormat::Jpeg };
    let Ok(reader) = image::ImageReader::open(path).and_then(|reader| reader.with_guessed_format()) else {
        return false;
    };
    reader.format() == Some(expected) && reader.into_dimensions().is_ok_and(|(width, height)| width > 0 && height > 0)
}

/// The response-time floor `min_response_ms`: 0 to 60 000 ms.
pub(crate) fn check_min_response_ms(fail: Fail, value: i64) -> Result<u32, StudyError> {
    if (0..=60_000).contains(&value) {
        Ok(value as u32)
    } else {
        Err(fail.at("min_response_ms", format!("expected 0 to 60000 ms, found {value}")))
    }
}
