//! What every study file shares, survey (`study`) and lab task (`task::study`) alike: the
//! refusal that names file, key and expectation ([`StudyError`]), the slug rule, TOML errors in
//! one line, and the file's SHA-256.

use std::fmt;
use std::path::PathBuf;

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

/// SHA-256 of `bytes`, hex-encoded.
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(bytes))
}

/// A study slug: lower-case letters, digits and `-`, not first, at most 64 characters.
pub(crate) fn is_slug(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
        && !name.starts_with('-')
}
