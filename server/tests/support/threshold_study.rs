//! The threshold study (`kind = "threshold"`: how many VPLs, on two survey scene
//! configurations, with a catch trial) the tests use, with the keys they vary. Shared by the
//! server's threshold tests and the binary's end-to-end test (included there by `#[path]`).
// Each includer uses a different part of it.
#![allow(dead_code)]

use std::path::Path;

/// A threshold study for tests: `ThresholdStudy { slug: "x", ..ThresholdStudy::default() }`.
#[derive(Debug, Clone)]
pub struct ThresholdStudy<'a> {
    pub slug: &'a str,
    /// The `[texts]` table.
    pub texts: &'a str,
    pub size: [u32; 2],
    pub trials: u32,
    /// Lines added at the end of the `[threshold]` table (e.g. `render = "on-demand"`).
    pub render: &'a str,
    /// Tables after it (e.g. `[completion]`).
    pub after: &'a str,
}

impl Default for ThresholdStudy<'_> {
    fn default() -> Self {
        ThresholdStudy {
            slug: "vpls-tiny",
            texts: "[texts]\nwelcome = \"w\"\nconsent = \"c\"\ninstructions = \"i\"\n",
            size: [32, 24],
            trials: 10,
            render: "",
            after: "",
        }
    }
}

impl ThresholdStudy<'_> {
    /// Writes the study file as `file_name` into `dir`, with its catch images under `img/` (the
    /// demo study's from `repo_studies`).
    pub fn write(&self, dir: &Path, file_name: &str, repo_studies: &Path) {
        std::fs::create_dir_all(dir.join("img")).unwrap();
        for (name, from) in [("good.png", "catch-good.png"), ("broken.png", "catch-bad.png")] {
            std::fs::copy(repo_studies.join("shadows-demo").join(from), dir.join("img").join(name)).unwrap();
        }
        std::fs::write(dir.join(file_name), self.toml()).unwrap();
    }

    pub fn toml(&self) -> String {
        let ThresholdStudy { slug, texts, size: [width, height], trials, render, after } = self;
        format!(
            r#"slug = "{slug}"
title = "How many VPLs?"
kind = "threshold"
question = "In which image was nothing added afterwards?"
{texts}
[[scenes]]
name = "one"
render = "survey-1"
[[scenes]]
name = "two"
render = "survey-2"
[render]
size = [{width}, {height}]
spp = 1
[[catch]]
name = "obvious"
better = "img/good.png"
worse = "img/broken.png"
[threshold]
knob = "vpls"
levels = [1, 4, 16, 64]
intensity = "inverse-knob"
scale = "log10"
function = "weibull"
threshold = [-2.0, -1.5, -1.0, -0.5, 0.0]
slope = [2.0, 3.5]
lapse = [0.0, 0.02]
guess = 0.5
trials = {trials}
{render}
{after}"#
        )
    }
}
