//! The participant area of the HTTP API (docs/design.md): list open studies, join a study, get the
//! next trial, answer it.
//!
//! A participant is identified by a random 128-bit id and authorised by a random 256-bit bearer
//! token, of which only the SHA-256 is stored. A token opens only its own participant: any other
//! id answers 403, a missing token 401. Every body is validated before anything is written, and
//! a refused request changes nothing.
//!
//! The participant's types in each stage (joining, stored, listed, exported; survey and lab) are
//! in [`model`].

pub mod active;
pub mod model;
pub mod rating;
pub mod store;
pub mod threshold;

use axum::Router;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::auth::{bearer, constant_time_eq, sha256};
use crate::error::{AppError, AppResult, Json};
use crate::study::{Device, FieldType, Orientation, Participation, Study};
use crate::trial::{Answer, Choice, ResponseOutcome, ResponseRefused};
use crate::{AppState, random_hex};
use model::{NewParticipant, ParticipantRow};
use store::{JoinOutcome, NewResponse, ScreenOut, ScreenOutWrite, Shown};

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/api/studies", get(list_studies))
        .route("/api/studies/{slug}/participants", post(create_participant))
        .route("/api/studies/{slug}/screen", post(check_screen))
        .route("/api/participants/{id}/next", get(next_trial))
        .route("/api/participants/{id}/responses", post(create_response))
}

#[derive(Serialize)]
struct StudySummary {
    slug: String,
    title: String,
    kind: &'static str,
    trials: usize,
}

async fn list_studies(State(state): State<AppState>) -> AppResult<Json<Vec<StudySummary>>> {
    let mut open = Vec::new();
    for prepared in state.studies() {
        if state.storage().is_open(&prepared.study.slug).await? {
            open.push(StudySummary {
                slug: prepared.study.slug.clone(),
                title: prepared.study.title.clone(),
                kind: prepared.study.kind.as_str(),
                trials: prepared.study.trial_count(),
            });
        }
    }
    Ok(Json(open))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JoinBody {
    demographics: Map<String, Value>,
    #[serde(default)]
    client: Map<String, Value>,
    #[serde(default)]
    url_params: Map<String, Value>,
    /// The token of an admin preview link: the participant is a pilot.
    #[serde(default)]
    preview: Option<String>,
    /// The id of this visitor's earlier screen-out, withdrawn now that the screen fits.
    #[serde(default)]
    screen_out: Option<String>,
    /// The token the page kept from an earlier join to this study link, if any: with
    /// `unique_external_id`, the proof that resumes the run of the same external id.
    #[serde(default)]
    token: Option<String>,
}

#[derive(Serialize)]
struct Joined {
    participant: String,
    token: String,
    trials: usize,
    /// True when the study keeps one run per external id, this id had joined before and the
    /// join carried that run's token: the earlier run continues (at its next unanswered trial),
    /// with the same token.
    resumed: bool,
}

/// Whether a preview token (if any) is one of the study's preview links: Ok(true) for a pilot,
/// 403 for a token that is not.
async fn pilot(state: &AppState, slug: &str, preview: Option<&str>) -> AppResult<bool> {
    let Some(token) = preview.map(str::trim).filter(|token| !token.is_empty()) else { return Ok(false) };
    if state.storage().is_preview(slug, &sha256(token.as_bytes())).await? {
        Ok(true)
    } else {
        Err(AppError::Forbidden(format!(
            "This preview link is not valid for the study \"{slug}\"; ask the researcher for a new one."
        )))
    }
}

/// The device a page reported in `client.device`, if any.
fn reported_device(client: &Map<String, Value>) -> Option<Device> {
    serde_json::from_value(client.get("device")?.clone()).ok()
}

/// The viewport a page reported in `client.viewport` (`[width, height]` in CSS pixels).
fn reported_viewport(client: &Map<String, Value>) -> Option<[f64; 2]> {
    let viewport = client.get("viewport")?.as_array()?;
    match viewport.as_slice() {
        [width, height] => Some([width.as_f64()?, height.as_f64()?]),
        _ => None,
    }
}

/// The kind of device the page reported, when the study does not admit it.
fn refused_device(participation: &Participation, client: &Map<String, Value>) -> Option<Device> {
    let device = reported_device(client)?;
    (!participation.devices.is_empty() && !participation.devices.contains(&device)).then_some(device)
}

/// Why a visitor's screen does not meet the study's requirements, as the one sentence shown
/// to them; None when it does (or when the client did not say: API clients without a page).
pub(crate) fn screen_refusal(participation: &Participation, client: &Map<String, Value>) -> Option<String> {
    if let Some(device) = refused_device(participation, client) {
        let allowed: Vec<&str> = participation.devices.iter().map(|device| device.described()).collect();
        let allowed = match allowed.as_slice() {
            [one] => one.to_string(),
            [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
            [] => unreachable!("devices is not empty"),
        };
        return Some(format!(
            "This study can only be done on {allowed}, not on {}: please open the link there.",
            device.described()
        ));
    }
    let viewport = reported_viewport(client);
    if let (Some([min_width, min_height]), Some([width, height])) = (participation.min_viewport, viewport)
        && (width < f64::from(min_width) || height < f64::from(min_height))
    {
        return Some(format!(
            "This study needs a browser window of at least {min_width} × {min_height} pixels and yours is {} × {}: please enlarge the window or use a larger screen.",
            width.round() as i64,
            height.round() as i64
        ));
    }
    if let (Some(orientation), Some([width, height])) = (participation.orientation, viewport) {
        let landscape = width >= height;
        match orientation {
            Orientation::Landscape if !landscape => {
                return Some(
                    "This study needs your screen in landscape orientation (wider than tall): please turn your device."
                        .into(),
                );
            }
            Orientation::Portrait if landscape => {
                return Some(
                    "This study needs your screen in portrait orientation (taller than wide): please turn your device."
                        .into(),
                );
            }
            _ => {}
        }
    }
    None
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ScreenBody {
    #[serde(default)]
    client: Map<String, Value>,
    #[serde(default)]
    url_params: Map<String, Value>,
    #[serde(default)]
    preview: Option<String>,
    /// This visitor's earlier screen-out, updated rather than counted again.
    #[serde(default)]
    screen_out: Option<String>,
}

#[derive(Serialize)]
struct ScreenAnswer {
    meets: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    screen_out: Option<String>,
    /// With a refusal: true when it is about the window (its size or orientation), which the
    /// visitor can change on this page; false when it is about the kind of device.
    #[serde(skip_serializing_if = "Option::is_none")]
    fixable: Option<bool>,
    /// A returning participant: the study keeps one run per external id and this one finished;
    /// the page shows the completion page instead of asking anything again.
    #[serde(skip_serializing_if = "Option::is_none")]
    completed: Option<Completed>,
}

/// What the completion page shows (as `…/next` answers once every trial is answered).
#[derive(Serialize)]
struct Completed {
    done: bool,
    completion_code: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    redirect: Option<String>,
}

/// The finished run of this external id, if the study keeps one run per external id.
async fn finished_run(
    state: &AppState,
    study: &Study,
    url_params: &Map<String, Value>,
) -> AppResult<Option<Completed>> {
    if !study.participation.unique_external_id {
        return Ok(None);
    }
    let Some(key) = external_key(study, url_params) else { return Ok(None) };
    let id: Option<String> = sqlx::query_scalar(
        "SELECT id FROM participants WHERE study = $1 AND external_key = $2 AND completed_at IS NOT NULL",
    )
    .bind(&study.slug)
    .bind(&key)
    .fetch_optional(&state.storage().read)
    .await?;
    let Some(id) = id else { return Ok(None) };
    Ok(state.storage().participant(&id).await?.map(|participant| Completed {
        done: true,
        redirect: redirect_url(study, &participant),
        completion_code: participant.completion_code,
    }))
}

/// Checks a visitor's screen against the study's requirements before anything is asked of
/// them: `200 {meets: true}`, or `201 {meets: false, reason, screen_out, fixable}` (`fixable`:
/// the refusal is about the window, not the kind of device) with the visitor
/// recorded as screened out (counted in the funnel; the same visitor checking again updates
/// that record, and joining later withdraws it). A visitor whose external id already finished
/// the study (`unique_external_id`) gets `200 {meets: true, completed: {done, completion_code,
/// redirect}}`, whatever the screen: a returning participant sees the completion page again.
async fn check_screen(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    Json(body): Json<ScreenBody>,
) -> AppResult<Response> {
    let prepared = state.served_study(&slug)?;
    let pilot = pilot(&state, &slug, body.preview.as_deref()).await?;
    let client = validate_client(body.client)?;
    let url_params = validate_url_params(&prepared.study, body.url_params)?;
    if !pilot && let Some(completed) = finished_run(&state, &prepared.study, &url_params).await? {
        let answer =
            ScreenAnswer { meets: true, reason: None, screen_out: None, fixable: None, completed: Some(completed) };
        return Ok(Json(answer).into_response());
    }
    let Some(reason) = screen_refusal(&prepared.study.participation, &client) else {
        let answer = ScreenAnswer { meets: true, reason: None, screen_out: None, fixable: None, completed: None };
        return Ok(Json(answer).into_response());
    };
    let id = match body.screen_out {
        Some(id) if id.len() == 32 && id.bytes().all(|b| b.is_ascii_hexdigit()) => id,
        _ => random_hex(16),
    };
    record_screen_out(&state, &slug, &id, &reason, &client, &url_params, pilot).await?;
    let fixable = refused_device(&prepared.study.participation, &client).is_none();
    Ok((
        StatusCode::CREATED,
        Json(ScreenAnswer {
            meets: false,
            reason: Some(reason),
            screen_out: Some(id),
            fixable: Some(fixable),
            completed: None,
        }),
    )
        .into_response())
}

async fn record_screen_out(
    state: &AppState,
    slug: &str,
    id: &str,
    reason: &str,
    client: &Map<String, Value>,
    url_params: &Map<String, Value>,
    pilot: bool,
) -> AppResult<()> {
    state
        .storage()
        .write(ScreenOutWrite {
            id: id.to_string(),
            screen_out: Some(ScreenOut {
                id: id.to_string(),
                study: slug.to_string(),
                reason: reason.to_string(),
                client: Value::Object(client.clone()).to_string(),
                url_params: Value::Object(url_params.clone()).to_string(),
                pilot,
            }),
        })
        .await?;
    Ok(())
}

/// A refused response, as the participant reads it.
impl From<ResponseRefused> for AppError {
    fn from(refused: ResponseRefused) -> Self {
        match refused {
            ResponseRefused::NeverServed { trial, next } => AppError::Conflict(format!(
                "Trial {trial} was never served to this participant, so it cannot be answered (the next trial is {next}; get it from …/next first)."
            )),
            ResponseRefused::AlreadyAnswered { trial, chosen } => AppError::Conflict(format!(
                "Trial {trial} was already answered with \"{chosen}\"; an answer cannot be changed."
            )),
            ResponseRefused::UnknownParticipant => AppError::NotFound("There is no such participant.".into()),
            ResponseRefused::NotYours => {
                AppError::Forbidden("This token does not give access to this participant.".into())
            }
            ResponseRefused::OutOfRange { trial, trials } => {
                AppError::Unprocessable(format!("`trial` must be between 1 and {trials}, found {trial}."))
            }
            ResponseRefused::NotYet { trial, next } => {
                AppError::Conflict(format!("Trial {trial} cannot be answered yet: the next trial is {next}."))
            }
        }
    }
}

async fn create_participant(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    Json(body): Json<JoinBody>,
) -> AppResult<Response> {
    let prepared = state.served_study(&slug)?;
    let pilot = pilot(&state, &slug, body.preview.as_deref()).await?;
    // A preview runs the study as a participant would, also before the study is opened.
    if !pilot && !state.storage().is_open(&slug).await? {
        return Err(AppError::Forbidden(format!("The study \"{slug}\" is closed and accepts no new participants.")));
    }
    let demographics = validate_demographics(&prepared.study, body.demographics)?;
    let client = validate_client(body.client)?;
    let url_params = validate_url_params(&prepared.study, body.url_params)?;
    if let Some(reason) = screen_refusal(&prepared.study.participation, &client) {
        let id = random_hex(16);
        record_screen_out(&state, &slug, &id, &reason, &client, &url_params, pilot).await?;
        return Err(AppError::Unprocessable(reason));
    }
    // One run per external id: the study's declared id parameter (its first URL parameter).
    let external_key = (prepared.study.participation.unique_external_id && !pilot)
        .then(|| external_key(&prepared.study, &url_params))
        .flatten();
    let resume_token = body.token.as_deref().map(str::trim).filter(|token| !token.is_empty());
    let withdraw_screen_out = body.screen_out.filter(|id| id.len() == 32 && id.bytes().all(|b| b.is_ascii_hexdigit()));
    let id = random_hex(16);
    let token = random_hex(32);
    let mut seed_bytes = [0u8; 8];
    getrandom::fill(&mut seed_bytes).expect("the operating system's random number generator works");
    let trials = prepared.study.trial_count();
    let token_sha256 = sha256(token.as_bytes()).to_vec();
    let outcome = state
        .storage()
        .write(NewParticipant {
            study: prepared,
            id: id.clone(),
            token_sha256: token_sha256.clone(),
            random_seed: u64::from_le_bytes(seed_bytes),
            demographics: Value::Object(demographics).to_string(),
            client: Value::Object(client).to_string(),
            url_params: Value::Object(url_params).to_string(),
            random_completion_code: random_hex(6).to_uppercase(),
            pilot,
            external_key,
            resume_token_sha256: resume_token.map(|token| sha256(token.as_bytes()).to_vec()),
            withdraw_screen_out,
        })
        .await?;
    let (status, id, token, token_sha256, trials, resumed) = match outcome {
        JoinOutcome::Created => (StatusCode::CREATED, id, token, token_sha256, trials as i64, false),
        JoinOutcome::Resumed { id, trials } => {
            let token = resume_token.expect("a run resumes only with its token").to_string();
            let token_sha256 = sha256(token.as_bytes()).to_vec();
            (StatusCode::OK, id, token, token_sha256, trials, true)
        }
        JoinOutcome::Taken => return Err(AppError::Conflict(TAKEN.into())),
    };
    state.cache_credentials(Credentials { id: id.clone(), study: slug.clone(), token_sha256, trials });
    Ok((status, Json(Joined { participant: id, token, trials: trials as usize, resumed })).into_response())
}

/// What a join with a known external id but without its run's token is told.
pub const TAKEN: &str = "This study was already started with this ID in another browser or window; please continue it there (the same browser and link), or contact the researcher.";

/// The key of one run per external id: the study's declared id parameter (its first URL
/// parameter, never another) with its value normalised ([`normalise_external_id`]); None when
/// the join does not carry it.
fn external_key(study: &Study, url_params: &Map<String, Value>) -> Option<String> {
    let name = study.url_params.first()?;
    let Some(Value::String(value)) = url_params.get(name) else { return None };
    let value = normalise_external_id(value);
    (!value.is_empty()).then(|| format!("{name}={value}"))
}

/// An external id as it is compared: Unicode NFKC (full-width and other compatibility forms
/// become their plain letters, a no-break space a space), without invisible format characters
/// (zero-width spaces and joiners, word joiner, byte-order mark, soft hyphen, direction marks)
/// or control characters anywhere, trimmed of white space, and in lower case: the ids of
/// crowdsourcing platforms (Prolific's 24 hexadecimal digits, MTurk's upper-case worker ids)
/// never differ by case alone, so `ABC` and `abc` are one person.
pub fn normalise_external_id(value: &str) -> String {
    use unicode_normalization::UnicodeNormalization;
    let invisible = |c: char| {
        c.is_control()
            || matches!(c, '\u{00AD}' | '\u{034F}' | '\u{061C}' | '\u{115F}' | '\u{1160}' | '\u{17B4}' | '\u{17B5}'
                | '\u{180B}'..='\u{180F}' | '\u{200B}'..='\u{200F}' | '\u{202A}'..='\u{202E}'
                | '\u{2060}'..='\u{206F}' | '\u{3164}' | '\u{FE00}'..='\u{FE0F}' | '\u{FEFF}' | '\u{FFA0}'
                | '\u{1D173}'..='\u{1D17A}' | '\u{E0000}'..='\u{E0FFF}')
    };
    let plain: String = value.nfkc().filter(|c| !invisible(*c)).collect();
    plain.trim().to_lowercase()
}

fn validate_demographics(study: &Study, mut given: Map<String, Value>) -> AppResult<Map<String, Value>> {
    let mut kept = Map::new();
    for field in &study.demographics {
        let value = given.remove(&field.name).unwrap_or(Value::Null);
        let value = match (&value, field.field_type) {
            (Value::Null, _) => {
                if field.required {
                    return Err(AppError::Unprocessable(format!(
                        "The demographic field `{}` ({}) is required.",
                        field.name, field.label
                    )));
                }
                Value::Null
            }
            (Value::String(text), FieldType::Choice) if field.options.contains(text) => value,
            (_, FieldType::Choice) => {
                return Err(AppError::Unprocessable(format!(
                    "The demographic field `{}` must be one of {}.",
                    field.name,
                    field.options.iter().map(|option| format!("\"{option}\"")).collect::<Vec<_>>().join(", ")
                )));
            }
            (Value::Number(number), FieldType::Integer)
                if number
                    .as_i64()
                    .is_some_and(|n| field.min.is_none_or(|min| n >= min) && field.max.is_none_or(|max| n <= max)) =>
            {
                value
            }
            (_, FieldType::Integer) => {
                return Err(AppError::Unprocessable(format!(
                    "The demographic field `{}` must be a whole number{}.",
                    field.name,
                    match (field.min, field.max) {
                        (Some(min), Some(max)) => format!(" from {min} to {max}"),
                        (Some(min), None) => format!(" of at least {min}"),
                        (None, Some(max)) => format!(" of at most {max}"),
                        (None, None) => String::new(),
                    }
                )));
            }
            (Value::String(text), FieldType::Text) if text.chars().count() <= 200 => {
                Value::String(text.trim().to_string())
            }
            (_, FieldType::Text) => {
                return Err(AppError::Unprocessable(format!(
                    "The demographic field `{}` must be a text of at most 200 characters.",
                    field.name
                )));
            }
        };
        kept.insert(field.name.clone(), value);
    }
    if let Some(unknown) = given.keys().next() {
        return Err(AppError::Unprocessable(format!(
            "The study asks no demographic field `{unknown}`; it asks {}.",
            study.demographics.iter().map(|field| format!("`{}`", field.name)).collect::<Vec<_>>().join(", ")
        )));
    }
    Ok(kept)
}

/// Client details: a flat JSON object of at most 20 short entries (viewport, devicePixelRatio,
/// userAgent, …).
fn validate_client(client: Map<String, Value>) -> AppResult<Map<String, Value>> {
    if client.len() > 20 {
        return Err(AppError::Unprocessable("`client` may have at most 20 entries.".into()));
    }
    for (key, value) in &client {
        let ok = key.len() <= 64
            && match value {
                Value::String(text) => text.len() <= 1024,
                Value::Number(_) | Value::Bool(_) | Value::Null => true,
                Value::Array(items) => items.len() <= 4 && items.iter().all(Value::is_number),
                Value::Object(_) => false,
            };
        if !ok {
            return Err(AppError::Unprocessable(format!(
                "`client.{}` must be a number, a boolean, a text of at most 1024 characters or a list of up to 4 numbers.",
                key.chars().take(64).collect::<String>()
            )));
        }
    }
    Ok(client)
}

/// Keeps the URL parameters the study names (crowdsourcing ids such as `PROLIFIC_PID`); others
/// are dropped, values must be short texts.
fn validate_url_params(study: &Study, params: Map<String, Value>) -> AppResult<Map<String, Value>> {
    let mut kept = Map::new();
    for (key, value) in params {
        if !study.url_params.contains(&key) {
            continue;
        }
        match value {
            Value::String(text) if text.len() <= 256 => {
                kept.insert(key, Value::String(text));
            }
            _ => {
                return Err(AppError::Unprocessable(format!(
                    "The URL parameter `{key}` must be a text of at most 256 characters."
                )));
            }
        }
    }
    Ok(kept)
}

/// What a response needs to know of its participant, kept in memory after the first lookup.
/// The token hash here only turns wrong tokens away early: the writer checks the token against
/// the database again when it stores the response, so a participant deleted through another
/// server is refused at once.
#[derive(Debug, Clone)]
pub(crate) struct Credentials {
    pub id: String,
    pub study: String,
    pub token_sha256: Vec<u8>,
    pub trials: i64,
}

/// The participant `id`, if the request carries its token; 401 without a token, 403 with a
/// token that is not this participant's (whether or not `id` exists).
async fn authorize(state: &AppState, headers: &HeaderMap, id: &str) -> AppResult<Credentials> {
    let token = bearer(headers)?;
    let token_sha256 = sha256(token.as_bytes());
    let cached =
        state.cached_credentials(id).filter(|credentials| constant_time_eq(&credentials.token_sha256, &token_sha256));
    let credentials = match cached {
        Some(credentials) => Some(credentials),
        // not known here, or known with another token: the database says
        None if id.len() == 32 => state.storage().participant(id).await?.map(|participant| {
            let credentials = Credentials {
                id: participant.id,
                study: participant.study,
                token_sha256: participant.token_sha256,
                trials: participant.trials,
            };
            state.cache_credentials(credentials.clone());
            credentials
        }),
        None => None,
    };
    match credentials {
        Some(credentials) if constant_time_eq(&credentials.token_sha256, &token_sha256) => Ok(credentials),
        _ => Err(forbidden(id)),
    }
}

fn forbidden(id: &str) -> AppError {
    AppError::Forbidden(format!(
        "This token does not give access to participant \"{}\".",
        id.chars().take(64).collect::<String>()
    ))
}

#[derive(Serialize)]
struct Image {
    url: String,
    alt: String,
}

#[derive(Serialize)]
#[serde(untagged)]
enum Next {
    Trial {
        trial: i64,
        total: i64,
        question: String,
        left: Image,
        right: Image,
        /// Stimulus URLs of the trial after this one, to preload.
        preload: Vec<String>,
    },
    /// A rating study's trial (`kind = "rating"`).
    Rating(rating::RatingTrial),
    Done {
        done: bool,
        completion_code: String,
        #[serde(skip_serializing_if = "Option::is_none")]
        redirect: Option<String>,
    },
}

pub(crate) fn stimulus_url(name: &str) -> String {
    format!("/stimuli/{name}")
}

async fn next_trial(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<Next>> {
    let token = bearer(&headers)?;
    let found = if id.len() == 32 { state.storage().participant_with_next(&id).await? } else { None };
    let (participant, trials) = match found {
        Some((participant, trials)) if constant_time_eq(&participant.token_sha256, &sha256(token.as_bytes())) => {
            (participant, trials)
        }
        _ => return Err(forbidden(&id)),
    };
    let prepared = state
        .study(&participant.study)
        .ok_or_else(|| AppError::Gone(format!("The study \"{}\" is no longer served.", participant.study)))?;
    if participant.answered >= participant.trials {
        return Ok(Json(Next::Done {
            done: true,
            redirect: redirect_url(&prepared.study, &participant),
            completion_code: participant.completion_code,
        }));
    }
    let number = participant.answered + 1;
    let mut trials = trials;
    if trials.first().is_none_or(|trial| trial.trial != number) && prepared.study.design.active.is_some() {
        // an active design: the next batch is chosen now, from every judgment so far
        active::extend(&state, prepared, &participant.id).await?;
        trials =
            state.storage().participant_with_next(&participant.id).await?.map(|(_, trials)| trials).unwrap_or_default();
    } else if trials.first().is_none_or(|trial| trial.trial != number) && prepared.study.threshold.is_some() {
        // a threshold study: the next level is chosen now, from the participant's own answers
        threshold::extend(&state, prepared, &participant.id).await?;
        trials =
            state.storage().participant_with_next(&participant.id).await?.map(|(_, trials)| trials).unwrap_or_default();
    }
    let mut trials = trials.into_iter();
    let trial = trials
        .next()
        .filter(|trial| trial.trial == number)
        .ok_or_else(|| AppError::Internal(format!("trial {number} of participant {} is missing", participant.id)))?;
    let following = trials.next();
    if !trial.shown {
        // durable before the trial is sent: after a crash (or on another server) its answer
        // must still find the trial served
        state.storage().write(Shown { participant: participant.id.clone(), trial: number }).await?;
    }
    if let Some(design) = &prepared.study.rating {
        let preload = following
            .iter()
            .flat_map(|following| [&following.left_stimulus, &following.right_stimulus])
            .filter(|name| !name.is_empty())
            .map(|name| stimulus_url(name))
            .collect();
        let (stimulus, reference) = (&trial.left_stimulus, &trial.right_stimulus);
        let shown = rating::trial(&prepared.study, design, (number, participant.trials), stimulus, reference, preload);
        return Ok(Json(Next::Rating(shown)));
    }
    Ok(Json(Next::Trial {
        trial: trial.trial,
        total: participant.trials,
        question: prepared.study.question.clone(),
        left: Image { url: stimulus_url(&trial.left_stimulus), alt: format!("Left image of trial {number}") },
        right: Image { url: stimulus_url(&trial.right_stimulus), alt: format!("Right image of trial {number}") },
        preload: following
            .map(|following| vec![stimulus_url(&following.left_stimulus), stimulus_url(&following.right_stimulus)])
            .unwrap_or_default(),
    }))
}

/// The completion redirect with `{code}` and kept URL parameters filled in (URL-encoded).
fn redirect_url(study: &Study, participant: &ParticipantRow) -> Option<String> {
    let template = study.completion.redirect.as_ref()?;
    let mut url = template.replace("{code}", &percent_encode(&participant.completion_code));
    if let Ok(Value::Object(params)) = serde_json::from_str::<Value>(&participant.url_params) {
        for (key, value) in params {
            if let Value::String(value) = value {
                url = url.replace(&format!("{{{key}}}"), &percent_encode(&value));
            }
        }
    }
    Some(url)
}

fn percent_encode(text: &str) -> String {
    let mut encoded = String::new();
    for byte in text.bytes() {
        if byte.is_ascii_alphanumeric() || b"-_.~".contains(&byte) {
            encoded.push(byte as char);
        } else {
            encoded.push_str(&format!("%{byte:02X}"));
        }
    }
    encoded
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ResponseBody {
    trial: i64,
    /// A paired comparison's answer.
    #[serde(default)]
    chosen: Option<Choice>,
    /// A rating study's answer, 1 to 5.
    #[serde(default)]
    rating: Option<i64>,
    rt_ms: f64,
    #[serde(default)]
    client: Map<String, Value>,
    /// The size one image of the pair was shown at, as the page measured it.
    #[serde(default)]
    display: Option<ShownSize>,
}

/// The size an image was shown at: `[width, height]` in CSS pixels and in device pixels.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShownSize {
    css: [f64; 2],
    device: [f64; 2],
}

/// `WxH` of a size in whole pixels (rounded), refused when it is not a plausible screen size.
fn size_text(key: &str, [width, height]: [f64; 2]) -> AppResult<String> {
    let plausible = |value: f64| value.is_finite() && (0.0..=100_000.0).contains(&value);
    if !(plausible(width) && plausible(height)) {
        return Err(AppError::Unprocessable(format!(
            "`display.{key}` must be [width, height] in pixels from 0 to 100000, found [{}, {}].",
            short_number(width),
            short_number(height)
        )));
    }
    Ok(format!("{}x{}", width.round() as u32, height.round() as u32))
}

#[derive(Serialize)]
struct Stored {
    trial: i64,
    #[serde(skip_serializing_if = "Option::is_none")]
    chosen: Option<Choice>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rating: Option<u8>,
}

/// Longest response time accepted: one hour.
pub const MAX_RT_MS: f64 = 3_600_000.0;

/// A number as a short text for an error sentence: `1e308`, not its 309 digits (Rust's `{}`
/// never writes an exponent).
pub fn short_number(value: f64) -> String {
    if value == 0.0 || (1e-3..1e9).contains(&value.abs()) { format!("{value}") } else { format!("{value:e}") }
}

async fn create_response(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    Json(body): Json<ResponseBody>,
) -> AppResult<Response> {
    let participant = authorize(&state, &headers, &id).await?;
    if !(body.rt_ms.is_finite() && (0.0..=MAX_RT_MS).contains(&body.rt_ms)) {
        return Err(AppError::Unprocessable(format!(
            "`rt_ms` must be a number of milliseconds from 0 to {MAX_RT_MS}, found {}.",
            short_number(body.rt_ms)
        )));
    }
    if body.trial < 1 || body.trial > participant.trials {
        return Err(AppError::Unprocessable(format!(
            "`trial` must be between 1 and {}, found {}.",
            participant.trials, body.trial
        )));
    }
    let client = validate_client(body.client)?;
    let (display_css, display_device) = match &body.display {
        Some(shown) => (Some(size_text("css", shown.css)?), Some(size_text("device", shown.device)?)),
        None => (None, None),
    };
    let (min_response_ms, allow_tie) = state.study(&participant.study).map_or((0, false), |prepared| {
        (prepared.study.participation.min_response_ms, prepared.study.participation.allow_tie)
    });
    let answer =
        rating::answer(state.study(&participant.study).map(|prepared| &prepared.study), body.chosen, body.rating)?;
    if body.chosen == Some(Choice::Tie) && !allow_tie {
        return Err(AppError::Unprocessable(
            "`chosen` must be \"left\" or \"right\": this study has no \"not sure\" answer (`allow_tie` is off)."
                .to_string(),
        ));
    }
    let outcome = state
        .storage()
        .write(NewResponse {
            token_sha256: participant.token_sha256,
            participant: participant.id,
            trial: body.trial,
            answer,
            rt_ms: body.rt_ms,
            client: Value::Object(client).to_string(),
            display_css,
            display_device,
            min_response_ms,
        })
        .await?
        .map_err(|refused| match refused {
            ResponseRefused::NotYours => forbidden(&id),
            refused => refused.into(),
        })?;
    let status = match outcome {
        ResponseOutcome::Created => StatusCode::CREATED,
        ResponseOutcome::Repeated => StatusCode::OK,
    };
    let (chosen, rating) = match answer {
        Answer::Choice(chosen) => (Some(chosen), None),
        Answer::Rating(rating) => (None, Some(rating)),
    };
    Ok((status, Json(Stored { trial: body.trial, chosen, rating })).into_response())
}
