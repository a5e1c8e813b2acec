//! The editor's API: open a DDF, check a document as it is edited (the XML, the
//! diagnostics of the validator of `tutti check` at their fields, the layout and topics of
//! `tutti show`), parse XML typed by hand, save atomically.

use std::path::Path;
use std::sync::Arc;

use axum::extract::State;
use axum::http::StatusCode;
use axum::Json;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use tutti_core::ddf::write::{write, Document, Written};
use tutti_core::ddf::{self, DdfError, Model};
use tutti_core::mapping::Profile;

use crate::error::ApiError;
use crate::files;
use crate::request::{ApiJson, ApiQuery};
use crate::AppState;

/// One diagnostic as the page shows it.
#[derive(Debug, Serialize)]
pub struct DiagJson {
    pub line: u32,
    pub col: u32,
    pub message: String,
    /// The field it is about (see [`Written::fields`]), when the XML was written from a
    /// document.
    pub field: Option<String>,
}

/// What the page gets back for a document or a text: everything it shows beside the forms.
#[derive(Debug, Serialize)]
pub struct Checked {
    pub xml: String,
    pub valid: bool,
    pub diagnostics: Vec<DiagJson>,
    /// `tutti show --json` of the document, when valid.
    pub show: Option<Value>,
    /// The document, when the text was valid (for XML typed by hand or a file opened).
    pub document: Option<Document>,
}

fn show_json(model: &Model, path: &str) -> Option<Value> {
    let view = tutti_core::show::show(model, Path::new(path), Profile::Ros2, "cyclone");
    serde_json::to_value(view).ok()
}

fn diagnostics(err: &DdfError, written: Option<&Written>) -> Vec<DiagJson> {
    match err {
        DdfError::Io { cause: source, .. } => {
            vec![DiagJson { line: 1, col: 1, message: source.to_string(), field: None }]
        }
        DdfError::Invalid { diagnostics, .. } => diagnostics
            .iter()
            .map(|d| DiagJson {
                line: d.pos.line,
                col: d.pos.col,
                message: d.message.clone(),
                field: written.and_then(|w| w.field_of(d)).map(str::to_string),
            })
            .collect(),
    }
}

/// Checks a document: writes it, validates the XML.
pub fn check_document(doc: &Document, path: &str) -> Checked {
    let written = write(doc);
    match ddf::parse_str(&written.xml, path) {
        Ok(model) => Checked {
            show: show_json(&model, path),
            xml: written.xml,
            valid: true,
            diagnostics: Vec::new(),
            document: None,
        },
        Err(e) => Checked {
            diagnostics: diagnostics(&e, Some(&written)),
            xml: written.xml,
            valid: false,
            show: None,
            document: None,
        },
    }
}

/// Checks a text (a file, or XML typed by hand): its document when it is valid.
pub fn check_text(bytes: &[u8], path: &str) -> Checked {
    let xml = String::from_utf8_lossy(bytes).into_owned();
    match ddf::parse_bytes(bytes, path) {
        Ok(model) => Checked {
            show: show_json(&model, path),
            document: Some(Document::from(&model)),
            xml,
            valid: true,
            diagnostics: Vec::new(),
        },
        Err(e) => Checked { diagnostics: diagnostics(&e, None), xml, valid: false, show: None, document: None },
    }
}

#[derive(Debug, Deserialize)]
pub struct PathQuery {
    pub path: String,
}

/// `GET /api/open?path=P`: the file's text, version, and its document when valid.
pub async fn open(State(st): State<Arc<AppState>>, ApiQuery(q): ApiQuery<PathQuery>) -> Result<Json<Value>, ApiError> {
    let real = st.root.existing(&q.path)?;
    let bytes = files::read_limited(&real, ddf::MAX_FILE_BYTES)?;
    let rel = st.root.relative(&real);
    let checked = check_text(&bytes, &rel);
    Ok(Json(json!({ "path": rel, "version": files::version(&bytes), "checked": checked })))
}

#[derive(Debug, Deserialize)]
pub struct CheckBody {
    pub document: Document,
    #[serde(default)]
    pub path: Option<String>,
}

/// `POST /api/check {document, path?}`.
pub async fn check(ApiJson(body): ApiJson<CheckBody>) -> Json<Checked> {
    Json(check_document(&body.document, body.path.as_deref().unwrap_or("new.ddf")))
}

#[derive(Debug, Deserialize)]
pub struct ParseBody {
    pub xml: String,
    #[serde(default)]
    pub path: Option<String>,
}

/// `POST /api/parse {xml, path?}`: XML typed by hand.
pub async fn parse(ApiJson(body): ApiJson<ParseBody>) -> Json<Checked> {
    Json(check_text(body.xml.as_bytes(), body.path.as_deref().unwrap_or("new.ddf")))
}

#[derive(Debug, Deserialize)]
pub struct SaveBody {
    pub path: String,
    pub document: Document,
    /// The version the page opened (absent for a new file).
    #[serde(default)]
    pub version: Option<String>,
    /// Write even when the document is invalid ("save anyway").
    #[serde(default)]
    pub force: bool,
}

/// `POST /api/save {path, document, version?, force?}`: writes the product dialect
/// atomically; a new file answers 201, a file saved over 200. Refused: under
/// `--read-only`, outside the root, under a file (409 `not-a-folder`), when the file changed
/// on disk since `version` (or exists, for a new file: 409 `exists`, also when another save
/// created it an instant before), when the document is invalid and `force` is not set.
///
/// The studio's saves take turns (one lock), so that a version is checked and the file
/// written with no other save of the studio in between; a new file is created only if its
/// name is free at that instant ([`files::create_new`]), so another process cannot be
/// overwritten either.
pub async fn save(
    State(st): State<Arc<AppState>>,
    ApiJson(body): ApiJson<SaveBody>,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    if st.read_only {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "read-only",
            "the studio runs with --read-only: saving is off",
        ));
    }
    if !body.path.ends_with(".ddf") {
        return Err(ApiError::bad_request(format!("'{}': a DDF's name ends with .ddf", body.path)));
    }
    let _turn = st.save_turn.lock().await;
    let target = st.root.for_write(&body.path)?;
    let rel = st.root.relative(&target);
    let exists = |rel: &str| {
        ApiError::conflict("exists", format!("{rel} already exists: not saved. Open it, or save under another name."))
    };
    let on_disk = match std::fs::symlink_metadata(&target) {
        Ok(_) => Some(files::read_limited(&target, ddf::MAX_FILE_BYTES)?),
        Err(_) => None,
    };
    match (&on_disk, &body.version) {
        (Some(bytes), Some(v)) if &files::version(bytes) != v => {
            return Err(ApiError::conflict(
                "changed",
                format!("{rel} changed on disk since it was opened: not saved. Reload it (your edits are lost) or save under another name."),
            ));
        }
        (Some(_), None) => return Err(exists(&rel)),
        (None, Some(_)) => {
            return Err(ApiError::conflict(
                "changed",
                format!("{rel} was removed on disk since it was opened: not saved. Save it under a new name, or again as new."),
            ));
        }
        _ => {}
    }
    let checked = check_document(&body.document, &rel);
    if !checked.valid && !body.force {
        let n = checked.diagnostics.len();
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid",
            format!("{rel} not saved: the document has {n} problem(s). Fix them, or use \"save anyway\"."),
        )
        .with(json!(checked.diagnostics)));
    }
    let bytes = checked.xml.as_bytes();
    let (written, status) = match on_disk {
        None => (files::create_new(&target, bytes), StatusCode::CREATED),
        Some(_) => (files::write_atomic(&target, bytes), StatusCode::OK),
    };
    written.map_err(|e| match e.kind() {
        std::io::ErrorKind::AlreadyExists => exists(&rel),
        std::io::ErrorKind::PermissionDenied => {
            ApiError::new(StatusCode::FORBIDDEN, "permission", format!("{rel}: could not be written: {e}"))
        }
        _ => ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "io", format!("{rel}: could not be written: {e}")),
    })?;
    Ok((status, Json(json!({ "path": rel, "version": files::version(bytes), "valid": checked.valid }))))
}

/// `GET /api/files`: the DDFs under the root.
pub async fn list(State(st): State<Arc<AppState>>) -> Json<Value> {
    Json(json!({ "root": st.root.dir().display().to_string(), "files": st.root.list_ddfs(2000) }))
}
