//! The write token of a console that is not on loopback: printed at start, required in the
//! [`TOKEN_HEADER`] header (or `Authorization: Bearer TOKEN`) of every request that changes
//! something. Reads stay open: they change nothing on the cell.

use std::io::Read;

use axum::extract::{Request, State};
use axum::http::{HeaderMap, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::api::ApiError;
use super::AppState;

pub const TOKEN_HEADER: &str = "x-drivetwin-token";

/// 128 random bits from the kernel, as hex.
pub fn new_token() -> std::io::Result<String> {
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut bytes)?;
    Ok(crate::value_text::hex(&bytes).to_ascii_lowercase())
}

fn presented(headers: &HeaderMap) -> Option<&str> {
    if let Some(v) = headers.get(TOKEN_HEADER) {
        return v.to_str().ok();
    }
    headers
        .get(axum::http::header::AUTHORIZATION)?
        .to_str()
        .ok()?
        .strip_prefix("Bearer ")
}

/// Equal without an early exit, so the time taken does not tell how much of a guess was right.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

pub async fn require_token_for_writes(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Response {
    let reads = matches!(
        *request.method(),
        Method::GET | Method::HEAD | Method::OPTIONS
    );
    if let (Some(token), false) = (&state.token, reads) {
        let ok = presented(request.headers()).is_some_and(|p| same(p, token));
        if !ok {
            return ApiError::new(
                StatusCode::UNAUTHORIZED,
                format!("this console is not on loopback: a write needs the token printed at start, in the {TOKEN_HEADER} header"),
            )
            .into_response();
        }
    }
    next.run(request).await
}
