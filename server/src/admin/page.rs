//! The admin's HTML pages: the study list and one study's page (progress, analysis, participants).

use super::participants::{ParticipantLine, participants};
use super::stats::{Metrics, StudyStats, all_slugs, analysis_json, stats};
use crate::AppState;
use crate::auth::authorize_admin_via as authorize;
use crate::error::{AppError, AppResult};
use crate::export::Include;
use askama::Template;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use mrstudy_analysis::analysis::Scale;

pub(super) async fn page_authorize(state: &AppState, headers: &HeaderMap) -> Result<(), Box<Response>> {
    authorize(state, headers).await.map(|_| ()).map_err(|error| {
        Box::new({
            let status = error.status();
            crate::pages::message_page(
                status,
                if status == StatusCode::UNAUTHORIZED { "Admin token needed" } else { "Wrong admin token" },
                "Open the admin link that mrstudy serve printed; it carries the admin token.",
            )
        })
    })
}

#[derive(Template)]
#[template(path = "admin.html")]
pub(super) struct AdminPage {
    studies: Vec<StudyStats>,
    /// Lab task studies being served: (slug, title, frame-rate line, interactive).
    lab: Vec<(String, String, String, bool)>,
    /// Studies whose stimuli are still being rendered (or could not be).
    preparing: Vec<PreparingRow>,
    /// Task studies whose lab is still starting: (slug, title).
    lab_starting: Vec<(String, String)>,
    /// Seconds after which the page reloads itself: while something is being prepared.
    refresh: Option<u64>,
    /// Refusals counted per status and route template ([`crate::logs`]).
    refusals: Vec<crate::logs::Refusal>,
    /// The render queue of on-demand threshold levels in one line, when a study has them.
    render_queue: Option<String>,
}

/// One study being prepared, as the admin page shows it ([`crate::preparing`]).
pub struct PreparingRow {
    pub slug: String,
    pub title: String,
    /// Done, in per cent (0 to 100).
    pub percent: u32,
    /// Counts and the estimate of the time left, or why it failed.
    pub summary: String,
    pub failed: bool,
}

impl AdminPage {
    fn new(state: &AppState, studies: Vec<StudyStats>) -> AdminPage {
        let now = std::time::Instant::now();
        let preparing: Vec<PreparingRow> = state
            .preparation()
            .studies()
            .iter()
            .map(|study| PreparingRow {
                slug: study.slug.clone(),
                title: study.title.clone(),
                percent: (study.fraction() * 100.0).floor() as u32,
                summary: study.summary(now),
                failed: matches!(study.stage, crate::preparing::Stage::Failed(_)),
            })
            .collect();
        let lab_starting = state.preparation().lab();
        let busy = preparing.iter().any(|row| !row.failed) || !lab_starting.is_empty();
        AdminPage {
            studies,
            lab: crate::lab::results::overview(state),
            preparing,
            lab_starting,
            refresh: busy.then_some(10),
            refusals: state.refusals().kinds(),
            render_queue: state.render_queue().summary_line(),
        }
    }
}

pub(super) async fn admin_page(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if let Err(page) = page_authorize(&state, &headers).await {
        return *page;
    }
    let result: AppResult<Vec<StudyStats>> = async {
        let mut all = Vec::new();
        for slug in all_slugs(&state).await? {
            all.push(stats(&state, &slug).await?);
        }
        Ok(all)
    }
    .await;
    match result {
        Ok(studies) => crate::pages::render(&AdminPage::new(&state, studies)),
        Err(error) => error.into_response(),
    }
}

/// One bar of the dropout funnel.
pub struct FunnelBar {
    pub trial: usize,
    pub reached: i64,
    pub stopped: i64,
    pub x: f64,
    pub width: f64,
    pub height: f64,
    pub y: f64,
    /// Whether the trial number is written under the bar.
    pub label: bool,
}

/// One factor estimate row of the live analysis.
pub struct EstimateRow {
    pub name: String,
    pub estimate: String,
    pub se: String,
    pub p: String,
}

/// One condition row of the live analysis.
pub struct WorthRow {
    pub condition: String,
    pub worth: String,
    pub log_worth: String,
    /// pwcmp's JOD (`--scale jod`), "–" where it has none.
    pub jod: String,
    pub wins: String,
    pub comparisons: String,
}

#[derive(Template)]
#[template(path = "admin_study.html")]
pub(super) struct AdminStudyPage {
    stats: StudyStats,
    /// An active design: how many judgments its posterior has absorbed, and why it fell back to
    /// the fixed design if it did.
    active_note: Option<String>,
    active_warning: Option<String>,
    /// Every visitor: participants who started and visitors screened out (`stopped`).
    visitors_bar: FunnelBar,
    funnel: Vec<FunnelBar>,
    funnel_width: f64,
    funnel_top: i64,
    analysis_error: Option<String>,
    judgments: String,
    agreement_u: Option<String>,
    worth: Vec<WorthRow>,
    estimates: Vec<EstimateRow>,
    warnings: Vec<String>,
    participants: Vec<ParticipantLine>,
    /// A preference analysis exists (not only detection trials).
    has_preference: bool,
    /// Detection trials ("real or rendered?"): one row per condition.
    detection: Vec<DetectionRow>,
    detection_note: Option<String>,
    /// The image metrics against the preference, best predictor first.
    metric_rows: Vec<MetricRow>,
    metrics_note: Option<String>,
    /// pwcmp's outlier analysis beside the JOD: the participants with dist_L > 1.5.
    jod_note: Option<String>,
    /// A rating study: what the MOS are of, the MOS per condition, the screening per participant.
    ratings_note: Option<String>,
    mos_rows: Vec<MosRow>,
    rating_screening: Vec<RatingScreenRow>,
}

/// One condition's mean opinion score (a rating study).
pub struct MosRow {
    pub condition: String,
    pub ratings: String,
    pub mos: String,
    pub ci: String,
}

/// One participant of a rating study: P.910's screening and MLE_CO's bias and inconsistency.
pub struct RatingScreenRow {
    pub participant: String,
    pub verdict: String,
    pub golden: String,
    pub outlier_votes: String,
    pub bias: String,
    pub inconsistency: String,
}

/// The rating analysis (`ratings` of the Analysis JSON) as the page's rows.
fn fill_ratings(page: &mut AdminStudyPage, ratings: &serde_json::Value) {
    let scores = if ratings["scores"] == "dv" {
        "differential viewer scores against the hidden reference (DMOS, ACR-HR)"
    } else {
        "ratings"
    };
    page.ratings_note = Some(format!(
        "{} {} on the {} scale ({}); mean opinion score per condition over its scene configurations, with its 95 % t-interval; P.910's screening (golden questions, straight-lining) leaves a screened participant out, and votes with |z| ≥ 3.29 within their stimulus.",
        format_number(&ratings["ratings"], 0),
        scores,
        ratings["scale"].as_str().unwrap_or_default(),
        ratings["method"].as_str().unwrap_or_default()
    ));
    let plus_minus = |value: &serde_json::Value, se: &serde_json::Value| match value.as_f64() {
        Some(_) => format!("{} ± {}", format_number(value, 2), format_number(se, 2)),
        None => "–".to_string(),
    };
    for condition in ratings["conditions"].as_array().into_iter().flatten() {
        page.mos_rows.push(MosRow {
            condition: condition["condition"].as_str().unwrap_or_default().to_string(),
            ratings: format_number(&condition["ratings"], 0),
            mos: format_number(&condition["mos"], 2),
            ci: match condition["mos_ci"].as_array() {
                Some(ci) if ci.len() == 2 => format!("[{}, {}]", format_number(&ci[0], 2), format_number(&ci[1], 2)),
                _ => condition["note"].as_str().unwrap_or("–").to_string(),
            },
        });
    }
    for participant in ratings["participants"].as_array().into_iter().flatten() {
        let reason = participant["reason"].as_str();
        page.rating_screening.push(RatingScreenRow {
            participant: participant["participant"].as_str().unwrap_or_default().to_string(),
            verdict: match (participant["screened"].as_bool() == Some(true), reason) {
                (true, Some(reason)) => format!("screened: {reason}"),
                (false, Some(reason)) => format!("kept (screening off; would be screened: {reason})"),
                _ => "kept".to_string(),
            },
            golden: format!(
                "{} of {}",
                format_number(&participant["golden_failed"], 0),
                format_number(&participant["golden_answered"], 0)
            ),
            outlier_votes: format_number(&participant["outlier_votes"], 0),
            bias: plus_minus(&participant["bias"], &participant["bias_se"]),
            inconsistency: plus_minus(&participant["inconsistency"], &participant["inconsistency_se"]),
        });
    }
    page.warnings.extend(
        ratings["warnings"].as_array().into_iter().flatten().filter_map(|warning| warning.as_str().map(str::to_string)),
    );
}

/// One condition of the detection analysis.
pub struct DetectionRow {
    pub condition: String,
    pub trials: String,
    pub rate: String,
    pub ci: String,
    pub p: String,
    pub d_prime: String,
    pub verdict: String,
}

/// One metric × region set beside the preference.
pub struct MetricRow {
    pub rank: String,
    pub metric: String,
    pub region: String,
    pub spearman: String,
    pub kendall: String,
}

pub(crate) fn format_number(value: &serde_json::Value, digits: usize) -> String {
    match value.as_f64() {
        Some(number) if number != 0.0 && (number.abs() < 1e-3 || number.abs() >= 1e6) => format!("{number:.2e}"),
        Some(number) if number.fract() == 0.0 && digits == 0 => format!("{number:.0}"),
        Some(number) => format!("{number:.digits$}"),
        None => value.as_str().map(str::to_string).unwrap_or_default(),
    }
}

pub(super) async fn admin_study_page(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> Response {
    if let Err(page) = page_authorize(&state, &headers).await {
        return *page;
    }
    let stats = match stats(&state, &slug).await {
        Ok(stats) => stats,
        Err(AppError::NotFound(message)) => {
            return crate::pages::message_page(StatusCode::NOT_FOUND, "No such study", &message);
        }
        Err(error) => return error.into_response(),
    };
    // Bars share about 640 px, each 4 to 40 px wide; the first (grey) bar is every visitor,
    // those the screen requirements refused included, then one bar per number of trials answered.
    let visitors = stats.started + stats.screened_out;
    let bar_count = (stats.reached.len() + 1) as f64;
    let bar_width = (640.0 / bar_count).clamp(4.0, 40.0) - 2.0;
    let max_reached = visitors.max(1) as f64;
    let label_every = ((bar_count / 13.0).ceil() as usize).max(1);
    let visitors_height = 120.0 * visitors as f64 / max_reached;
    let visitors_bar = FunnelBar {
        trial: 0,
        reached: visitors,
        stopped: stats.screened_out,
        x: 50.0,
        width: bar_width,
        height: visitors_height,
        y: 140.0 - visitors_height,
        label: true,
    };
    let funnel = stats
        .reached
        .iter()
        .enumerate()
        .map(|(trial, &reached)| {
            let height = 120.0 * reached as f64 / max_reached;
            FunnelBar {
                trial,
                reached,
                stopped: stats.stopped_after.get(trial).copied().unwrap_or(0),
                x: 50.0 + (trial + 1) as f64 * (bar_width + 2.0),
                width: bar_width,
                height,
                y: 140.0 - height,
                label: trial % label_every == 0 || trial + 1 == stats.reached.len(),
            }
        })
        .collect();
    let funnel_width = 70.0 + bar_count * (bar_width + 2.0);
    let funnel_top = visitors;
    let mut page = AdminStudyPage {
        visitors_bar,
        funnel,
        funnel_width,
        funnel_top,
        analysis_error: None,
        judgments: String::new(),
        agreement_u: None,
        worth: Vec::new(),
        estimates: Vec::new(),
        warnings: Vec::new(),
        participants: Vec::new(),
        stats,
        active_note: None,
        active_warning: None,
        has_preference: false,
        detection: Vec::new(),
        detection_note: None,
        metric_rows: Vec::new(),
        metrics_note: None,
        jod_note: None,
        ratings_note: None,
        mos_rows: Vec::new(),
        rating_screening: Vec::new(),
    };
    let design = state.study(&slug).map(|prepared| prepared.study.design.clone());
    if let Some(active) = state.active(&slug)
        && let Some(design) = &design
        && let Some(active_design) = &design.active
    {
        let warmup = design.pairs.len() * design.repetitions as usize;
        let warmup = match warmup {
            0 => String::new(),
            trials => format!(", after a warm-up of {trials} fixed pair trials per participant"),
        };
        let active = active.lock().await;
        page.active_note = Some(format!(
            "Active design (target = \"{}\", prior = \"{}\"): each participant's trials are chosen {}, from every judgment so far ({} absorbed when a batch was last chosen){warmup}; it optimises {}; `mrstudy simulate --designs study,{}` measures what it trades against the fixed design.",
            active_design.target.describe().0,
            active_design.prior.name(),
            active_design.criterion(),
            active.judgments(),
            active_design.optimises(),
            active_design.simulate_design(),
        ));
        page.active_warning = active.failure.clone();
    }
    let analysis = analysis_json(&state, &slug, Include::default(), Metrics::Set, Scale::Jod).await;
    page.participants = match participants(&state, &slug, analysis.as_ref().ok()).await {
        Ok(entries) => entries.iter().map(ParticipantLine::from).collect(),
        Err(error) => return error.into_response(),
    };
    match analysis {
        Ok(analysis) => {
            page.has_preference = analysis.get("items").is_some();
            if let Some(ratings) = analysis.get("ratings") {
                fill_ratings(&mut page, ratings);
            }
            if let Some(detection) = analysis.get("detection") {
                page.detection_note = Some(format!(
                    "{} detection trials: how often the ground truth was taken for real (chance {}); exact binomial test at α = {}, power against a true rate of {}.",
                    format_number(&detection["judgments"], 0),
                    format_number(&detection["chance"], 2),
                    format_number(&detection["alpha"], 2),
                    format_number(&detection["alternative_rate"], 2)
                ));
                for rate in detection["conditions"].as_array().into_iter().flatten() {
                    let verdict = rate["verdict"].as_str().unwrap_or_default();
                    page.detection.push(DetectionRow {
                        condition: rate["condition"].as_str().unwrap_or_default().to_string(),
                        trials: format!(
                            "{} of {}",
                            format_number(&rate["correct"], 0),
                            format_number(&rate["trials"], 0)
                        ),
                        rate: format_number(&rate["rate"], 3),
                        ci: format!("[{}, {}]", format_number(&rate["ci"][0], 3), format_number(&rate["ci"][1], 3)),
                        p: format_number(&rate["p"], 3),
                        d_prime: format!(
                            "{} ± {}",
                            format_number(&rate["d_prime"], 2),
                            format_number(&rate["d_prime_se"], 2)
                        ),
                        verdict: if verdict == "inconclusive" {
                            format!("inconclusive (power {})", format_number(&rate["power"], 2))
                        } else {
                            verdict.to_string()
                        },
                    });
                }
                for warning in detection["warnings"].as_array().into_iter().flatten() {
                    page.warnings.extend(warning.as_str().map(str::to_string));
                }
            }
            if let Some(metrics) = analysis.get("metrics") {
                let best = &metrics["best"];
                page.metrics_note = Some(format!(
                    "{}. {}",
                    metrics["level_reason"].as_str().unwrap_or_default().trim_end_matches('.'),
                    match best.get("metric") {
                        Some(metric) => format!(
                            "Best predictor of preference: {} in the {} region.",
                            metric.as_str().unwrap_or_default(),
                            best["region"].as_str().unwrap_or_default()
                        ),
                        None => "No metric could be set beside the preference yet.".to_string(),
                    }
                ));
                let interval = |ci: &serde_json::Value| match ci.as_array() {
                    Some(ci) if ci.len() == 2 => {
                        format!(" [{}, {}]", format_number(&ci[0], 2), format_number(&ci[1], 2))
                    }
                    _ => String::new(),
                };
                // The ranked image metrics, then the timings (costs, not image errors: unranked).
                let timings = metrics["timings"].as_array().into_iter().flatten();
                for row in metrics["correlations"].as_array().into_iter().flatten().chain(timings) {
                    page.metric_rows.push(MetricRow {
                        rank: match row.get("rank") {
                            Some(rank) => format_number(rank, 0),
                            None => "timing, not ranked".to_string(),
                        },
                        metric: row["metric"].as_str().unwrap_or_default().to_string(),
                        region: row["region"].as_str().unwrap_or_default().to_string(),
                        spearman: format!(
                            "{}{}",
                            format_number(&row["spearman_rho"], 2),
                            interval(&row["spearman_ci"])
                        ),
                        kendall: format!("{}{}", format_number(&row["kendall_tau_b"], 2), interval(&row["kendall_ci"])),
                    });
                }
            }
            if let Some(section) = analysis.get("jod_scale") {
                let outliers: Vec<&str> =
                    section["outliers"].as_array().into_iter().flatten().filter_map(|p| p.as_str()).collect();
                page.jod_note = Some(match (section["observers"].as_array(), outliers.is_empty()) {
                    (None, _) => "pwcmp's outlier analysis needs three participants or more.".to_string(),
                    (Some(_), true) => "pwcmp's outlier analysis: no participant with dist_L > 1.5.".to_string(),
                    (Some(_), false) => {
                        format!("pwcmp's outlier analysis: dist_L > 1.5 (not dropped): {}.", outliers.join(", "))
                    }
                });
            }
            page.judgments = format_number(&analysis["judgments"], 0);
            page.agreement_u = analysis.get("agreement").map(|agreement| format_number(&agreement["u"], 3));
            for item in analysis["items"].as_array().into_iter().flatten() {
                page.worth.push(WorthRow {
                    condition: item["condition"].as_str().unwrap_or_default().to_string(),
                    worth: format_number(&item["worth"], 3),
                    log_worth: format_number(&item["log_worth"], 3),
                    jod: match item.get("jod") {
                        Some(jod) => format_number(jod, 2),
                        None => "–".to_string(),
                    },
                    wins: format_number(&item["wins"], 0),
                    comparisons: format_number(&item["comparisons"], 0),
                });
            }
            for covariate in analysis["covariates"].as_array().into_iter().flatten() {
                page.estimates.push(EstimateRow {
                    name: covariate["name"].as_str().unwrap_or_default().to_string(),
                    estimate: format_number(&covariate["estimate"], 3),
                    se: format_number(&covariate["se"], 3),
                    p: format_number(&covariate["p"], 3),
                });
            }
            page.warnings.extend(
                analysis["warnings"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .filter_map(|warning| warning.as_str().map(str::to_string)),
            );
        }
        Err(error) => page.analysis_error = Some(error.to_string()),
    }
    crate::pages::render(&page)
}

// ------------------------------------------------------------------------------------------
// Participants (issue 12): the list with status and flags, exclude/include, delete, preview.
