//! HTML pages (askama templates in `web/templates/`), static files (`web/static/`, embedded in
//! the binary) and stimuli (from the content-addressed store, cached as immutable).
//!
//! The participant page is one page whose stages (welcome and consent, demographics,
//! instructions, trials, completion) are shown by `web/static/survey.js` on top of the JSON API.

use askama::Template;
use axum::Router;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;

use crate::prepared::{PreparedStudy, stimulus_content_type};
use crate::study::{DemographicField, FieldType};
use crate::{AppError, AppState};

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/", get(index))
        .route("/studies/{slug}", get(study_page))
        .route("/static/{file}", get(static_file))
        // browsers ask for it whatever the page names: the same icon, never a 404
        .route("/favicon.ico", get(|| static_file(Path("favicon.svg".to_string()))))
        .route("/stimuli/{name}", get(stimulus))
}

/// Static files, embedded at build time: (name, content type, bytes).
const STATIC_FILES: &[(&str, &str, &str)] = &[
    ("survey.js", "text/javascript; charset=utf-8", include_str!("../../web/static/survey.js")),
    ("admin.js", "text/javascript; charset=utf-8", include_str!("../../web/static/admin.js")),
    ("lab.js", "text/javascript; charset=utf-8", include_str!("../../web/static/lab.js")),
    ("style.css", "text/css; charset=utf-8", include_str!("../../web/static/style.css")),
    ("favicon.svg", "image/svg+xml", include_str!("../../web/static/favicon.svg")),
];

pub(crate) fn render<T: Template>(template: &T) -> Response {
    match template.render() {
        Ok(html) => Html(html).into_response(),
        Err(error) => AppError::Internal(format!("template: {error}")).into_response(),
    }
}

#[derive(Template)]
#[template(path = "message.html")]
struct MessagePage<'a> {
    title: &'a str,
    message: &'a str,
    /// Seconds after which the page reloads itself, if it should.
    refresh: Option<u64>,
}

/// A plain page with a title and one sentence, with a status code.
pub(crate) fn message_page(status: StatusCode, title: &str, message: &str) -> Response {
    let mut response = render(&MessagePage { title, message, refresh: None });
    *response.status_mut() = status;
    response
}

/// The page of a study still being prepared: 503 with `Retry-After`, saying that it opens in a
/// few minutes, and reloading itself after that many seconds.
pub(crate) fn opens_soon_page(title: &str, retry_after_seconds: u64) -> Response {
    let message = format!("{} This page reloads itself.", crate::error::OPENS_SOON);
    let mut response = render(&MessagePage { title, message: &message, refresh: Some(retry_after_seconds) });
    *response.status_mut() = StatusCode::SERVICE_UNAVAILABLE;
    response.headers_mut().insert(header::RETRY_AFTER, retry_after_seconds.into());
    response
}

pub(crate) async fn not_found(uri: axum::http::Uri) -> Response {
    if uri.path().starts_with("/api/") {
        AppError::NotFound(format!("There is no API call {}.", uri.path())).into_response()
    } else {
        message_page(StatusCode::NOT_FOUND, "Page not found", "There is no page at this address.")
    }
}

pub struct StudyLink {
    pub slug: String,
    pub title: String,
    pub trials: usize,
}

#[derive(Template)]
#[template(path = "index.html")]
struct IndexPage {
    studies: Vec<StudyLink>,
}

async fn index(State(state): State<AppState>) -> Response {
    let mut studies = Vec::new();
    for prepared in state.studies() {
        match state.storage().is_open(&prepared.study.slug).await {
            Ok(true) => studies.push(StudyLink {
                slug: prepared.study.slug.clone(),
                title: prepared.study.title.clone(),
                trials: prepared.study.trial_count(),
            }),
            Ok(false) => {}
            Err(error) => return AppError::from(error).into_response(),
        }
    }
    render(&IndexPage { studies })
}

/// A demographic field as the template shows it.
pub struct FieldView {
    pub name: String,
    pub label: String,
    pub is_choice: bool,
    pub is_integer: bool,
    pub options: Vec<String>,
    pub min: String,
    pub max: String,
    pub required: bool,
}

impl From<&DemographicField> for FieldView {
    fn from(field: &DemographicField) -> Self {
        FieldView {
            name: field.name.clone(),
            label: field.label.clone(),
            is_choice: field.field_type == FieldType::Choice,
            is_integer: field.field_type == FieldType::Integer,
            options: field.options.clone(),
            min: field.min.map(|min| min.to_string()).unwrap_or_default(),
            max: field.max.map(|max| max.to_string()).unwrap_or_default(),
            required: field.required,
        }
    }
}

fn paragraphs(text: &str) -> Vec<String> {
    text.split("\n\n")
        .map(|paragraph| paragraph.split_whitespace().collect::<Vec<_>>().join(" "))
        .filter(|paragraph| !paragraph.is_empty())
        .collect()
}

#[derive(Template)]
#[template(path = "study.html")]
struct StudyPage {
    slug: String,
    title: String,
    question: String,
    open: bool,
    trials: usize,
    welcome: Vec<String>,
    consent: Vec<String>,
    instructions: Vec<String>,
    thanks: Vec<String>,
    fields: Vec<FieldView>,
    /// `min_response_ms`: the page accepts no answer sooner after a pair is on screen.
    min_response_ms: u32,
    /// `answer_lock_ms`: after an answer the page takes no press that begins sooner.
    answer_lock_ms: u32,
    /// `allow_tie`: a third answer, "Not sure" (↓ or its button).
    allow_tie: bool,
    /// A rating study (`kind = "rating"`): one image (DCR: after its reference) and a 5-point
    /// scale instead of a pair.
    rating: bool,
    /// `native` or `fit` (how stimuli are scaled).
    display: &'static str,
    /// `landscape`, `portrait` or empty: checked again during the trials.
    orientation: &'static str,
    /// `min_viewport` as `W,H`, or empty.
    min_viewport: String,
}

impl StudyPage {
    fn new(prepared: &PreparedStudy, open: bool) -> StudyPage {
        let study = &prepared.study;
        StudyPage {
            slug: study.slug.clone(),
            title: study.title.clone(),
            question: study.question.clone(),
            open,
            trials: study.trial_count(),
            welcome: paragraphs(&study.texts.welcome),
            consent: paragraphs(&study.texts.consent),
            instructions: paragraphs(&study.texts.instructions),
            thanks: paragraphs(&study.texts.thanks),
            fields: study.demographics.iter().map(FieldView::from).collect(),
            min_response_ms: study.participation.min_response_ms,
            answer_lock_ms: study.participation.answer_lock_ms,
            allow_tie: study.participation.allow_tie,
            rating: study.rating.is_some(),
            display: match study.participation.display {
                crate::study::Display::Native => "native",
                crate::study::Display::Css => "css",
                crate::study::Display::Fit => "fit",
            },
            orientation: match study.participation.orientation {
                Some(crate::study::Orientation::Landscape) => "landscape",
                Some(crate::study::Orientation::Portrait) => "portrait",
                None => "",
            },
            min_viewport: study.participation.min_viewport.map(|[w, h]| format!("{w},{h}")).unwrap_or_default(),
        }
    }
}

async fn study_page(State(state): State<AppState>, Path(slug): Path<String>) -> Response {
    let Some(prepared) = state.study(&slug) else {
        if let Some(pending) = state.preparation().pending(&slug) {
            return opens_soon_page(&pending.title, state.preparation().retry_after(&slug));
        }
        return message_page(StatusCode::NOT_FOUND, "No such study", "There is no study at this address.");
    };
    match state.storage().is_open(&slug).await {
        Ok(open) => render(&StudyPage::new(prepared, open)),
        Err(error) => AppError::from(error).into_response(),
    }
}

async fn static_file(Path(file): Path<String>) -> Response {
    match STATIC_FILES.iter().find(|(name, _, _)| *name == file) {
        Some((_, content_type, body)) => {
            let mut response = (*body).into_response();
            response.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
            response.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
            response
        }
        None => message_page(StatusCode::NOT_FOUND, "Not found", "There is no such file."),
    }
}

async fn stimulus(State(state): State<AppState>, Path(name): Path<String>, headers: HeaderMap) -> Response {
    let Some(content_type) = stimulus_content_type(&name) else {
        return AppError::NotFound("There is no such stimulus.".into()).into_response();
    };
    let path = state.stimuli_dir().join(&name);
    let is_png = content_type == "image/png";
    let wants_webp = is_png
        && headers
            .get_all(header::ACCEPT)
            .iter()
            .filter_map(|value| value.to_str().ok())
            .any(|value| value.contains("image/webp"));
    let webp = if wants_webp { webp_beside(path.clone()).await } else { None };
    let (bytes, content_type) = match webp {
        Some(bytes) => (bytes, "image/webp"),
        None => match tokio::fs::read(&path).await {
            Ok(bytes) => (bytes, content_type),
            Err(_) => return AppError::NotFound("There is no such stimulus.".into()).into_response(),
        },
    };
    let mut response = bytes.into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("public, max-age=31536000, immutable"));
    if is_png {
        headers.insert(header::VARY, HeaderValue::from_static("Accept"));
    }
    response
}

/// The lossless WebP copy of the PNG stimulus at `png`: `<sha256>.webp` beside it, made on the
/// first request (off the async threads) and read from the store after that. `None` (the PNG is
/// served) when the PNG is not in the store, cannot be decoded or has more than 8 bits a channel.
async fn webp_beside(png: std::path::PathBuf) -> Option<Vec<u8>> {
    let webp = png.with_extension("webp");
    if let Ok(bytes) = tokio::fs::read(&webp).await {
        return Some(bytes);
    }
    tokio::task::spawn_blocking(move || {
        let bytes = lossless_webp(&std::fs::read(&png).ok()?)?;
        // written under a name of its own (per process and request) and renamed, so a concurrent
        // request never reads half a file
        static PARTIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = PARTIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let partial = webp.with_extension(format!("webp.{}-{n}.part", std::process::id()));
        if std::fs::write(&partial, &bytes).is_err() || std::fs::rename(&partial, &webp).is_err() {
            let _ = std::fs::remove_file(&partial);
        }
        Some(bytes)
    })
    .await
    .ok()
    .flatten()
}

/// `png` re-encoded as lossless WebP: the same pixels, fewer bytes. `None` for a PNG that WebP
/// cannot hold exactly (more than 8 bits a channel) or that does not decode.
pub fn lossless_webp(png: &[u8]) -> Option<Vec<u8>> {
    use image::DynamicImage::{ImageLuma8, ImageLumaA8, ImageRgb8, ImageRgba8};
    let image = match image::load_from_memory_with_format(png, image::ImageFormat::Png).ok()? {
        image @ (ImageRgb8(_) | ImageRgba8(_)) => image,
        image @ ImageLuma8(_) => ImageRgb8(image.to_rgb8()),
        image @ ImageLumaA8(_) => ImageRgba8(image.to_rgba8()),
        _ => return None,
    };
    let mut bytes = Vec::new();
    image.write_with_encoder(image::codecs::webp::WebPEncoder::new_lossless(&mut bytes)).ok()?;
    Some(bytes)
}

/// A file to download: `body` with its content type, saved as `file_name`.
pub(crate) fn download(content_type: &'static str, file_name: String, body: String) -> Response {
    let mut response = (StatusCode::OK, body).into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    if let Ok(value) = HeaderValue::from_str(&format!("attachment; filename=\"{file_name}\"")) {
        headers.insert(header::CONTENT_DISPOSITION, value);
    }
    response
}
