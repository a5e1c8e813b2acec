//! What a request may be, and the JSON answer when it is not: the body's size limit (413
//! before the body is read when its `Content-Length` is too large, 413 when a body without
//! one crosses the limit), and the extractors of the handlers ([`ApiJson`], [`ApiQuery`]),
//! whose rejections (a JSON syntax error, a wrong content type, a missing field, a bad query
//! string) answer the API's `{"error", "code"}` like every other failure, never axum's plain
//! text. See docs/studio.md, "Bad requests".

use std::time::Duration;

use axum::body::Body;
use axum::extract::rejection::{JsonRejection, QueryRejection};
use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::request::Parts;
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use futures::StreamExt as _;
use serde::de::DeserializeOwned;

use crate::error::ApiError;

/// The largest request body the studio takes, in bytes: 16 MiB. A DDF's document or XML is
/// kilobytes; anything this large is refused with 413 `too-large`.
pub const MAX_BODY_BYTES: usize = 16 << 20;

/// How long, at most, the rest of a refused body is read and thrown away before the
/// connection is closed, so that a client still sending it reads the 413 rather than a
/// reset (a "lingering close"); and how long a pause in it ends that early.
const LINGER_TOTAL: Duration = Duration::from_secs(10);
const LINGER_IDLE: Duration = Duration::from_secs(2);

fn too_large(limit: usize) -> Response {
    let mut resp = ApiError::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        "too-large",
        format!("the request body is larger than the studio's limit of {} MiB: refused", limit >> 20),
    )
    .into_response();
    // The connection cannot be used again: the body was not read to its end.
    resp.headers_mut().insert(header::CONNECTION, HeaderValue::from_static("close"));
    resp
}

/// Reads the rest of a refused body and throws it away, for at most [`LINGER_TOTAL`], on a
/// task of its own: the 413 is sent meanwhile, and the connection closes when this ends.
fn linger(mut rest: axum::body::BodyDataStream) {
    tokio::spawn(async move {
        let _ = tokio::time::timeout(LINGER_TOTAL, async {
            while let Ok(Some(Ok(_))) = tokio::time::timeout(LINGER_IDLE, rest.next()).await {}
        })
        .await;
    });
}

/// The middleware that holds every request body to [`MAX_BODY_BYTES`]: a declared
/// `Content-Length` above it is answered 413 at once (the body is not read, nor a
/// `100 Continue` sent); a body without one is read up to the limit and answered 413 when it
/// crosses it. A body within the limit is read whole before the handler runs.
pub async fn limit_body(req: Request, next: Next) -> Response {
    let limit = MAX_BODY_BYTES;
    let (parts, body) = req.into_parts();
    let declared = parts.headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok());
    if let Some(declared) = declared {
        match declared.trim().parse::<u64>() {
            Ok(n) if n > limit as u64 => {
                linger(body.into_data_stream());
                return too_large(limit);
            }
            Ok(_) => {}
            Err(_) => {
                return ApiError::bad_request(format!("Content-Length '{declared}' is not a number")).into_response()
            }
        }
    }
    let mut stream = body.into_data_stream();
    let mut bytes = Vec::new();
    while let Some(chunk) = stream.next().await {
        let chunk = match chunk {
            Ok(c) => c,
            Err(e) => return ApiError::bad_request(format!("the request body could not be read: {e}")).into_response(),
        };
        if bytes.len() + chunk.len() > limit {
            linger(stream);
            return too_large(limit);
        }
        bytes.extend_from_slice(&chunk);
    }
    next.run(Request::from_parts(parts, Body::from(bytes))).await
}

/// A JSON body (`Content-Type: application/json`) of type `T`; a body that is not one is
/// answered with the API's JSON error (400 `json-syntax`, 422 `json-data`, 415
/// `content-type`, 413 `too-large`).
#[derive(Debug)]
pub struct ApiJson<T>(pub T);

/// The query string as `T`; a query string that does not fit is answered 400 `query` in the
/// API's JSON.
#[derive(Debug)]
pub struct ApiQuery<T>(pub T);

impl From<JsonRejection> for ApiError {
    fn from(r: JsonRejection) -> Self {
        let code = match &r {
            JsonRejection::JsonSyntaxError(_) => "json-syntax",
            JsonRejection::JsonDataError(_) => "json-data",
            JsonRejection::MissingJsonContentType(_) => "content-type",
            _ if r.status() == StatusCode::PAYLOAD_TOO_LARGE => "too-large",
            _ => "body",
        };
        ApiError::new(r.status(), code, r.body_text())
    }
}

impl From<QueryRejection> for ApiError {
    fn from(r: QueryRejection) -> Self {
        ApiError::new(r.status(), "query", r.body_text())
    }
}

impl<T: DeserializeOwned, S: Send + Sync> FromRequest<S> for ApiJson<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        Ok(ApiJson(axum::Json::<T>::from_request(req, state).await?.0))
    }
}

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for ApiQuery<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Self::Rejection> {
        Ok(ApiQuery(axum::extract::Query::<T>::from_request_parts(parts, state).await?.0))
    }
}

/// The answer to a known path asked with another method (`GET /api/save`): 405 in the
/// API's JSON (axum keeps the `Allow` header).
pub async fn method_not_allowed() -> ApiError {
    ApiError::new(StatusCode::METHOD_NOT_ALLOWED, "method", "this API request does not take that method")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_json_rejection_keeps_its_status_and_gets_a_code() {
        use axum::extract::rejection::MissingJsonContentType;
        let e = ApiError::from(JsonRejection::from(MissingJsonContentType::default()));
        assert_eq!((e.status, e.code), (StatusCode::UNSUPPORTED_MEDIA_TYPE, "content-type"));
        assert!(e.message.contains("application/json"), "{}", e.message);
    }
}
