//! The dashboard: one page at `/` with its script and style, embedded in the binary
//! (`include_str!`: no build step, nothing fetched from elsewhere, so it works at a field with
//! no internet). The page reads the API and follows `/api/events`; it holds no secret: the token
//! is typed by the user when an upload or a start asks for it and kept in the page's memory only.
//!
//! Every answer forbids anything but the service's own origin (`Content-Security-Policy`), so
//! the page cannot load or send to a third party even if a mission name carried markup.

use axum::http::header;
use axum::response::{IntoResponse, Response};

/// The page.
pub const PAGE: &str = include_str!("dashboard/index.html");
/// Its script.
pub const SCRIPT: &str = include_str!("dashboard/dashboard.js");
/// Its style.
pub const STYLE: &str = include_str!("dashboard/dashboard.css");

const POLICY: &str = "default-src 'self'; img-src 'self' data:; style-src 'self'; \
     script-src 'self'; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; \
     form-action 'none'";

fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CONTENT_SECURITY_POLICY, POLICY),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

pub async fn page() -> Response {
    asset("text/html; charset=utf-8", PAGE)
}

pub async fn script() -> Response {
    asset("text/javascript; charset=utf-8", SCRIPT)
}

pub async fn style() -> Response {
    asset("text/css; charset=utf-8", STYLE)
}
