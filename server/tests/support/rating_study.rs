//! The ACR rating study the tests build from the demo study (its texts, demographics,
//! conditions and images rated on P.910's 5-point scale, with a catch trial of the demo's broken
//! image expecting "Bad"), with the keys they vary. Shared by the server's rating tests and the
//! binary's end-to-end test (included there by `#[path]`).

/// An ACR rating study over the demo study's body: `AcrStudy { slug: "x", ..AcrStudy::default() }`.
#[derive(Debug, Clone)]
pub struct AcrStudy<'a> {
    pub slug: &'a str,
    pub title: &'a str,
    pub question: &'a str,
    /// Top-level lines after the question (e.g. `min_response_ms = 0`).
    pub top_level: &'a str,
    pub seed: u64,
    pub completion_code: &'a str,
}

impl Default for AcrStudy<'_> {
    fn default() -> Self {
        AcrStudy {
            slug: "rating-demo",
            title: "Ratings",
            question: "How good is this image?",
            top_level: "",
            seed: 1,
            completion_code: "R-1",
        }
    }
}

impl AcrStudy<'_> {
    /// The study file, its body (`[texts]` up to `[design]`) taken from the demo study's `demo`.
    pub fn toml(&self, demo: &str) -> String {
        let AcrStudy { slug, title, question, top_level, seed, completion_code } = self;
        let body = &demo[demo.find("[texts]").unwrap()..demo.find("[design]").unwrap()];
        format!(
            r#"slug = "{slug}"
title = "{title}"
kind = "rating"
question = "{question}"
{top_level}
{body}
[rating]
method = "acr"
seed = {seed}

[[rating.catch]]
name = "broken"
image = "shadows-demo/catch-bad.png"
expected = 1

[completion]
code = "{completion_code}"
"#
        )
    }
}
