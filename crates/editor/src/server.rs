//! The local web server of `assetfield edit`: the page (HTML, CSS and JS compiled into the
//! binary) and the HTTP API that drives an [`EditSession`].
//!
//! Every `/api` call must carry the session's token (query `token=` or header
//! `X-Assetfield-Token`), else 403: another page open in the same browser can send requests
//! to 127.0.0.1 but cannot know the token. Request bodies are read up to
//! [`MAX_BODY_BYTES`]; a longer one, a body that is not UTF-8 and an edit that does not parse
//! or resolve answer 400 and change nothing. The session runs on blocking threads behind a
//! mutex (changes and renders are served one at a time); `GET /api/layout` answers the
//! layout as the last finished change left it without waiting for the session, so a slow
//! request never blocks reading the layout. A panic in one request (a bug) answers 500 and
//! the server goes on with the session as the panic left it.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;

use crate::error::EditorError;
use crate::session::{EditSession, ViewRequest};

/// Largest request body the server reads, bytes (an edit list is a few hundred).
pub const MAX_BODY_BYTES: usize = 256 * 1024;

const INDEX_HTML: &str = include_str!("page/index.html");
const EDITOR_JS: &str = include_str!("page/editor.js");
const EDITOR_CSS: &str = include_str!("page/editor.css");

/// What the handlers share.
#[derive(Clone)]
pub struct AppState {
    session: Arc<Mutex<EditSession>>,
    /// `GET /api/layout`'s answer (JSON) as of the last finished change.
    layout: Arc<Mutex<Bytes>>,
    token: Arc<str>,
    /// The `Host` headers requests may carry (`None`: any): for a server on loopback, its
    /// own address by number or as `localhost`, so that a page whose domain was rebound to
    /// 127.0.0.1 is refused before the token is even looked at.
    hosts: Option<Arc<[String]>>,
}

impl std::fmt::Debug for AppState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AppState").finish_non_exhaustive()
    }
}

impl AppState {
    /// A state serving `session`, guarded by `token`.
    pub fn new(session: EditSession, token: String) -> Self {
        let layout = Arc::new(Mutex::new(layout_bytes(&session)));
        AppState {
            session: Arc::new(Mutex::new(session)),
            layout,
            token: token.into(),
            hosts: None,
        }
    }

    /// Accept only the `Host` headers a browser sends to `addr` when it is a loopback
    /// address (any otherwise: a server on the network is reached by names it cannot know).
    pub fn serving(mut self, addr: SocketAddr) -> Self {
        if addr.ip().is_loopback() {
            let port = addr.port();
            let ip = match addr.ip() {
                std::net::IpAddr::V6(v6) => format!("[{v6}]"),
                v4 => v4.to_string(),
            };
            self.hosts = Some(vec![format!("{ip}:{port}"), format!("localhost:{port}")].into());
        }
        self
    }
}

async fn check_host(State(s): State<AppState>, req: Request, next: Next) -> Response {
    if let Some(hosts) = &s.hosts {
        let host = req.headers().get(header::HOST).and_then(|v| v.to_str().ok());
        if !host.is_some_and(|h| hosts.iter().any(|a| a.eq_ignore_ascii_case(h))) {
            return (
                StatusCode::FORBIDDEN,
                "unexpected Host header: open the URL `assetfield edit` printed\n",
            )
                .into_response();
        }
    }
    next.run(req).await
}

/// A fresh random token: 128 bits from the operating system's generator, as hex.
pub fn random_token() -> String {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    let from_os = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut bytes));
    if from_os.is_err() {
        // no /dev/urandom: std's per-process random hash keys, mixed with the time
        use std::hash::{BuildHasher, Hasher};
        for chunk in bytes.chunks_mut(8) {
            let mut h = std::collections::hash_map::RandomState::new().build_hasher();
            h.write_u128(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos()),
            );
            chunk.copy_from_slice(&h.finish().to_le_bytes()[..chunk.len()]);
        }
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The router: the page and the API.
pub fn router(state: AppState) -> Router {
    let api = Router::new()
        .route("/layout", get(get_layout))
        .route("/edits", post(post_edits))
        .route("/undo", post(post_undo))
        .route("/redo", post(post_redo))
        .route("/render", get(get_render))
        .route("/bev", get(get_bev))
        .route("/save", post(post_save))
        .route("/recolour", post(post_recolour))
        .route("/thumbnail", get(get_thumbnail))
        .layer(middleware::from_fn_with_state(state.clone(), require_token));
    Router::new()
        .route("/", get(|| async { html(INDEX_HTML) }))
        .route("/editor.js", get(|| async { asset(EDITOR_JS, "text/javascript; charset=utf-8") }))
        .route("/editor.css", get(|| async { asset(EDITOR_CSS, "text/css; charset=utf-8") }))
        .nest("/api", api)
        .layer(middleware::from_fn_with_state(state.clone(), check_host))
        .with_state(state)
}

fn html(body: &'static str) -> Response {
    asset(body, "text/html; charset=utf-8")
}

fn asset(body: &'static str, kind: &'static str) -> Response {
    let mut r = body.into_response();
    r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(kind));
    r.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

/// Equal strings, in time that does not depend on where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn require_token(State(s): State<AppState>, req: Request, next: Next) -> Response {
    let from_header = req.headers().get("x-assetfield-token").and_then(|v| v.to_str().ok());
    let from_query = req
        .uri()
        .query()
        .and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")).map(str::to_string));
    let ok = from_header.is_some_and(|t| same(t, &s.token))
        || from_query.is_some_and(|t| same(&t, &s.token));
    if !ok {
        return (
            StatusCode::FORBIDDEN,
            "missing or wrong token (the URL printed by `assetfield edit` carries it)\n",
        )
            .into_response();
    }
    next.run(req).await
}

/// A JSON error body `{error, line, col}` with `status`.
fn error_response(status: StatusCode, e: &str, at: Option<(usize, usize)>) -> Response {
    let body = serde_json::json!({
        "error": e,
        "line": at.map(|a| a.0),
        "col": at.map(|a| a.1),
    });
    (status, axum::Json(body)).into_response()
}

fn editor_error(e: &EditorError) -> Response {
    let status = if e.is_bad_request() {
        StatusCode::BAD_REQUEST
    } else {
        StatusCode::INTERNAL_SERVER_ERROR
    };
    error_response(status, &e.to_string(), e.line_col())
}

/// Run `f` on the session on a blocking thread: its response, or its error as
/// [`editor_error`] answers it. A panic answers 500 and leaves the server usable (edits that
/// fail with an error change nothing; a panic is a bug).
async fn with_session(
    s: &AppState,
    f: impl FnOnce(&mut EditSession) -> Result<Response, EditorError> + Send + 'static,
) -> Response {
    let session = s.session.clone();
    tokio::task::spawn_blocking(move || {
        let mut guard: MutexGuard<'_, EditSession> =
            session.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        f(&mut guard).unwrap_or_else(|e| editor_error(&e))
    })
    .await
    .unwrap_or_else(|e| {
        tracing::error!("a request failed: {e}");
        error_response(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal error (see the server's log)",
            None,
        )
    })
}

/// [`with_session`] for a change: answers the layout after it (and keeps it for
/// `GET /api/layout`).
async fn change(
    s: &AppState,
    f: impl FnOnce(&mut EditSession) -> Result<(), EditorError> + Send + 'static,
) -> Response {
    let snapshot = s.layout.clone();
    with_session(s, move |s| {
        f(s)?;
        Ok(json_response(publish(&snapshot, s)))
    })
    .await
}

/// The session's layout serialised, kept as `GET /api/layout`'s answer, and returned.
fn publish(snapshot: &Mutex<Bytes>, s: &EditSession) -> Bytes {
    let json = layout_bytes(s);
    *snapshot.lock().unwrap_or_else(|p| p.into_inner()) = json.clone();
    json
}

/// The layout as `GET /api/layout` answers it, serialised.
fn layout_bytes(s: &EditSession) -> Bytes {
    // a LayoutView holds strings and numbers only: serialising it cannot fail
    Bytes::from(serde_json::to_vec(&s.view()).unwrap_or_default())
}

fn json_response(body: Bytes) -> Response {
    ([(header::CONTENT_TYPE, HeaderValue::from_static("application/json"))], body).into_response()
}

async fn get_layout(State(s): State<AppState>) -> Response {
    json_response(s.layout.lock().unwrap_or_else(|p| p.into_inner()).clone())
}

/// The body as UTF-8 text, at most [`MAX_BODY_BYTES`].
async fn body_text(body: Body) -> Result<String, Response> {
    let bytes: Bytes = axum::body::to_bytes(body, MAX_BODY_BYTES).await.map_err(|_| {
        error_response(
            StatusCode::BAD_REQUEST,
            &format!("request body over {MAX_BODY_BYTES} bytes"),
            None,
        )
    })?;
    String::from_utf8(bytes.to_vec()).map_err(|e| {
        error_response(StatusCode::BAD_REQUEST, &format!("request body is not UTF-8: {e}"), None)
    })
}

async fn post_edits(State(s): State<AppState>, req: Request) -> Response {
    match body_text(req.into_body()).await {
        Ok(text) => change(&s, move |s| s.apply(&text)).await,
        Err(r) => r,
    }
}

async fn post_undo(State(s): State<AppState>) -> Response {
    change(&s, |s| s.undo().map(drop)).await
}

async fn post_redo(State(s): State<AppState>) -> Response {
    change(&s, |s| s.redo().map(drop)).await
}

/// Query of `GET /api/render`.
#[derive(Debug, Deserialize)]
struct RenderQuery {
    width: Option<u32>,
    height: Option<u32>,
    azimuth: Option<f32>,
    elevation: Option<f32>,
    radius: Option<f32>,
}

/// PNG bytes with the layout version they show.
fn png(bytes: Vec<u8>, version: u64) -> Response {
    let mut headers = HeaderMap::new();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static("image/png"));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    if let Ok(v) = HeaderValue::from_str(&version.to_string()) {
        headers.insert("x-assetfield-version", v);
    }
    (headers, bytes).into_response()
}

async fn get_render(State(s): State<AppState>, Query(q): Query<RenderQuery>) -> Response {
    let v = ViewRequest {
        width: q.width.unwrap_or(256),
        height: q.height.unwrap_or(q.width.unwrap_or(256)),
        azimuth_deg: q.azimuth.unwrap_or(-60.0),
        elevation_deg: q.elevation.unwrap_or(35.0),
        radius: q.radius,
    };
    with_session(&s, move |s| {
        let rgb = s.render(&v)?;
        Ok(png(crate::png::encode_rgb_f32(v.width, v.height, rgb)?, s.version()))
    })
    .await
}

/// Query of `GET /api/bev`.
#[derive(Debug, Deserialize)]
struct BevQuery {
    footprints: Option<bool>,
}

async fn get_bev(State(s): State<AppState>, Query(q): Query<BevQuery>) -> Response {
    with_session(&s, move |s| Ok(png(s.bev_png(q.footprints.unwrap_or(true))?, s.version()))).await
}

/// Query of `GET /api/thumbnail`.
#[derive(Debug, Deserialize)]
struct ThumbnailQuery {
    category: String,
}

async fn get_thumbnail(State(s): State<AppState>, Query(q): Query<ThumbnailQuery>) -> Response {
    with_session(&s, move |s| Ok(png(s.thumbnail_png(&q.category)?, s.version()))).await
}

/// Query of `POST /api/recolour`.
#[derive(Debug, Deserialize)]
struct RecolourQuery {
    category: String,
    from: String,
}

async fn post_recolour(State(s): State<AppState>, Query(q): Query<RecolourQuery>) -> Response {
    change(&s, move |s| s.recolour(&q.category, &q.from)).await
}

async fn post_save(State(s): State<AppState>) -> Response {
    let snapshot = s.layout.clone();
    with_session(&s, move |s| {
        let path = s.save()?;
        // the layout's `unsaved` changed
        publish(&snapshot, s);
        let body = serde_json::json!({"saved": path.display().to_string(), "version": s.version()});
        Ok(axum::Json(body).into_response())
    })
    .await
}

/// Serve `state` on `listener` until `shutdown` completes.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    axum::serve(listener, router(state)).with_graceful_shutdown(shutdown).await
}

/// Bind `addr` (port 0 picks a free one), call `listening` with the page's URL (token
/// included), and serve until `stop` returns true (polled ten times a second).
pub fn run(
    session: EditSession,
    addr: SocketAddr,
    token: String,
    listening: impl FnOnce(&str),
    stop: impl Fn() -> bool + Send + 'static,
) -> std::io::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr).await?;
        let local = listener.local_addr()?;
        listening(&format!("http://{local}/?token={token}"));
        let shutdown = async move {
            while !stop() {
                tokio::time::sleep(std::time::Duration::from_millis(100)).await;
            }
        };
        serve(listener, AppState::new(session, token).serving(local), shutdown).await
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_fresh_hex_and_compared_whole() {
        let (a, b) = (random_token(), random_token());
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
        assert!(same(&a, &a.clone()));
        assert!(!same(&a, &b));
        assert!(!same(&a, &a[..31]));
        assert!(!same("", "x"));
    }
}
