//! The one error type at the HTTP edge, and the JSON extractor that reports its rejections
//! through it.
//!
//! 4xx errors tell the client what was wrong in one sentence; 5xx errors are logged to stderr
//! with their cause and shown as a plain sentence. Every error body is
//! `{"error": "one clear sentence"}`.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};

/// What a participant whose next level is still rendering is told ([`AppError::Rendering`]).
pub const RENDERING: &str = "The images of your next trial are being prepared; they follow in a moment.";

/// What a participant of a study still being prepared is told ([`AppError::OpensSoon`]).
pub const OPENS_SOON: &str = "This study opens in a few minutes.";

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AppError {
    #[error("{0}")]
    BadRequest(String),
    #[error("{0}")]
    Unprocessable(String),
    #[error("{0}")]
    Unauthorized(String),
    #[error("{0}")]
    Forbidden(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    Conflict(String),
    #[error("{0}")]
    Gone(String),
    #[error("{0}")]
    PayloadTooLarge(String),
    #[error("{0}")]
    UnsupportedMediaType(String),
    #[error("{0}")]
    TooManyRequests(String),
    #[error("{0}")]
    Unavailable(String),
    /// The study's stimuli are still being rendered ([`crate::preparing`]): 503 with
    /// `Retry-After`.
    #[error("{}", OPENS_SOON)]
    OpensSoon { retry_after_seconds: u64 },
    /// The participant's next level is still rendering, or the render queue is full
    /// (`crate::render_queue`): 503 with `Retry-After`.
    #[error("{}", RENDERING)]
    Rendering { retry_after_seconds: u64 },
    #[error("database error: {0}")]
    Database(#[from] sqlx::Error),
    #[error("internal error: {0}")]
    Internal(String),
}

impl AppError {
    pub fn status(&self) -> StatusCode {
        match self {
            AppError::BadRequest(_) => StatusCode::BAD_REQUEST,
            AppError::Unprocessable(_) => StatusCode::UNPROCESSABLE_ENTITY,
            AppError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            AppError::Forbidden(_) => StatusCode::FORBIDDEN,
            AppError::NotFound(_) => StatusCode::NOT_FOUND,
            AppError::Conflict(_) => StatusCode::CONFLICT,
            AppError::Gone(_) => StatusCode::GONE,
            AppError::PayloadTooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            AppError::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            AppError::TooManyRequests(_) => StatusCode::TOO_MANY_REQUESTS,
            AppError::Unavailable(_) | AppError::OpensSoon { .. } | AppError::Rendering { .. } => {
                StatusCode::SERVICE_UNAVAILABLE
            }
            AppError::Database(_) | AppError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        let status = self.status();
        let message = if status.is_server_error() && status != StatusCode::SERVICE_UNAVAILABLE {
            tracing::error!(error = %self, "a request failed");
            "The server could not complete the request; the error has been logged.".to_string()
        } else {
            self.to_string()
        };
        let mut response = (status, axum::Json(serde_json::json!({ "error": message }))).into_response();
        if status == StatusCode::UNAUTHORIZED {
            response
                .headers_mut()
                .insert(axum::http::header::WWW_AUTHENTICATE, axum::http::HeaderValue::from_static("Bearer"));
        }
        if let AppError::OpensSoon { retry_after_seconds } | AppError::Rendering { retry_after_seconds } = self {
            response.headers_mut().insert(axum::http::header::RETRY_AFTER, retry_after_seconds.into());
        }
        response
    }
}

/// A failure of the database is the server's (500); its cause is logged.
impl From<crate::storage::StorageError> for AppError {
    fn from(error: crate::storage::StorageError) -> Self {
        match error {
            crate::storage::StorageError::Database(error) => AppError::Database(error),
            other => AppError::Internal(other.to_string()),
        }
    }
}

/// The JSON body of a request, as `T`: strictly a JSON object (serde would also take an array
/// for a struct, `[1, "left", 500]`), sent as `Content-Type: application/json` (else 415),
/// at most [`crate::BODY_LIMIT_BYTES`] (else 413). A body that is not JSON is a 400; one that
/// is JSON but lacks or mistypes a field is a 422 naming the field, without the server's
/// internal type names.
pub struct Json<T>(pub T);

impl<T: serde::de::DeserializeOwned, S: Send + Sync> FromRequest<S> for Json<T> {
    type Rejection = AppError;

    async fn from_request(request: Request, state: &S) -> Result<Self, AppError> {
        if !json_content_type(request.headers()) {
            return Err(AppError::UnsupportedMediaType(NEEDS_JSON.into()));
        }
        let bytes = Bytes::from_request(request, state).await.map_err(|rejection| {
            if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
                AppError::PayloadTooLarge(body_too_large())
            } else {
                AppError::BadRequest("The request body could not be read.".into())
            }
        })?;
        let value: serde_json::Value = serde_json::from_slice(&bytes).map_err(|error| {
            AppError::BadRequest(format!(
                "The request body is not valid JSON ({}).",
                plain_serde_error(&error.to_string())
            ))
        })?;
        if !value.is_object() {
            return Err(AppError::Unprocessable("The request body must be a JSON object.".into()));
        }
        serde_path_to_error::deserialize(value).map(Json).map_err(|error| {
            let path = error.path().to_string();
            let message = plain_serde_error(&error.into_inner().to_string());
            AppError::Unprocessable(if path == "." {
                format!("The request body does not have the expected fields: {message}.")
            } else {
                format!("The request body does not have the expected fields: {path}: {message}.")
            })
        })
    }
}

/// The 415 sentence.
pub(crate) const NEEDS_JSON: &str = "The request needs the header Content-Type: application/json.";

/// The 413 sentence.
pub(crate) fn body_too_large() -> String {
    format!("The request body is larger than the limit of {} bytes.", crate::BODY_LIMIT_BYTES)
}

/// Whether the request says its body is JSON (`application/json`, parameters allowed).
fn json_content_type(headers: &axum::http::HeaderMap) -> bool {
    headers
        .get(axum::http::header::CONTENT_TYPE)
        .and_then(|value| value.to_str().ok())
        .and_then(|value| value.split(';').next())
        .is_some_and(|mime| mime.trim().eq_ignore_ascii_case("application/json"))
}

/// serde's message without the server's type names (`struct JoinBody`, `enum Chosen`) and
/// without the position suffix of a value that has no position.
pub(crate) fn plain_serde_error(message: &str) -> String {
    let mut words: Vec<String> = Vec::new();
    let mut rest = message.split(' ').peekable();
    while let Some(word) = rest.next() {
        match word {
            "struct" | "enum" | "map" if rest.peek().is_some_and(|next| next.starts_with(char::is_uppercase)) => {
                let name = rest.next().unwrap_or_default();
                let tail: String = name.chars().skip_while(|c| c.is_alphanumeric() || *c == '_').collect();
                words.push(if word == "enum" { "one of the allowed values".into() } else { "an object".into() });
                if !tail.is_empty() {
                    let last = words.pop().unwrap_or_default();
                    words.push(last + &tail);
                }
            }
            "tuple" if rest.peek() == Some(&"struct") => {
                rest.next();
                rest.next();
                words.push("a value".into());
            }
            _ => words.push(word.to_string()),
        }
    }
    words.join(" ").trim_end_matches('.').to_string()
}

impl<T: serde::Serialize> IntoResponse for Json<T> {
    fn into_response(self) -> Response {
        axum::Json(self.0).into_response()
    }
}

pub type AppResult<T> = Result<T, AppError>;
