//! End-to-end tests of the `mrstudy` binary, built as one test binary with one module per area
//! (`tests/e2e/*.rs`); each test gets its own temporary directory. (A crate root's `mod x;`
//! looks for `tests/x.rs`, hence the `#[path]`s.)

#[path = "e2e/admin.rs"]
mod admin;
#[path = "e2e/analyze.rs"]
mod analyze;
#[path = "e2e/browser.rs"]
mod browser;
#[path = "e2e/first_start.rs"]
mod first_start;
#[path = "e2e/gi_methods.rs"]
mod gi_methods;
#[path = "e2e/ground_truth.rs"]
mod ground_truth;
#[path = "e2e/lab.rs"]
mod lab;
#[path = "../server/tests/support/lab_study.rs"]
mod lab_study;
#[path = "e2e/logs.rs"]
mod logs;
#[path = "e2e/rating.rs"]
mod rating;
#[path = "../server/tests/support/rating_study.rs"]
mod rating_study;
#[path = "e2e/render.rs"]
mod render;
#[path = "e2e/render_gpu.rs"]
mod render_gpu;
#[path = "e2e/serve.rs"]
mod serve;
#[path = "e2e/serve_bench.rs"]
mod serve_bench;
#[path = "e2e/serve_durability.rs"]
mod serve_durability;
#[path = "e2e/serve_hardening.rs"]
mod serve_hardening;
#[path = "e2e/shard.rs"]
mod shard;
#[path = "e2e/simulate.rs"]
mod simulate;
#[path = "e2e/support.rs"]
mod support;
#[path = "e2e/survey_input.rs"]
mod survey_input;
#[path = "e2e/survey_intent.rs"]
mod survey_intent;
#[path = "e2e/survey_page.rs"]
mod survey_page;
#[path = "e2e/survey_polish.rs"]
mod survey_polish;
#[path = "e2e/survey_return.rs"]
mod survey_return;
#[path = "e2e/threshold.rs"]
mod threshold;
#[path = "../server/tests/support/threshold_study.rs"]
mod threshold_study;
