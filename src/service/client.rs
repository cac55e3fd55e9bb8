//! The HTTP client of `emplan upload/fly --service URL`: plain HTTP/1.1 on the hyper that axum
//! already builds (no second HTTP stack to compile), one connection per request, JSON bodies,
//! and the server-sent event stream read as JSON objects.

use std::time::Duration;

use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper::{header, Method, Request};
use hyper_util::rt::TokioIo;
use tokio::net::TcpStream;

use super::Token;

/// Why a request to the service failed (not the service's own refusals: those are answers).
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("service URL {url:?}: {reason} (expected http://HOST:PORT)")]
    Url { url: String, reason: String },
    #[error("service at {url}: {reason}")]
    Connect { url: String, reason: String },
    #[error("service at {url}: {what}: {reason}")]
    Http {
        url: String,
        what: String,
        reason: String,
    },
}

/// Why the token a client was given cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TokenError {
    #[error("--token-file {file}: {reason}")]
    File { file: String, reason: String },
    #[error("EMPLAN_TOKEN: {0}")]
    Variable(String),
}

/// The token a client of the service sends: read from `file` when given, else the
/// `EMPLAN_TOKEN` environment variable, else `flights/token` (where `emplan serve` creates it
/// by default; none when that is absent or unreadable).
pub fn find_token(file: Option<&std::path::Path>) -> Result<Option<Token>, TokenError> {
    let in_file = |file: &std::path::Path, reason: String| TokenError::File {
        file: file.display().to_string(),
        reason,
    };
    match (file, std::env::var("EMPLAN_TOKEN")) {
        (Some(file), _) => {
            let text = std::fs::read_to_string(file).map_err(|e| in_file(file, e.to_string()))?;
            Token::new(&text)
                .map(Some)
                .map_err(|e| in_file(file, e.to_string()))
        }
        (None, Ok(text)) => Token::new(&text)
            .map(Some)
            .map_err(|e| TokenError::Variable(e.to_string())),
        (None, Err(_)) => Ok(std::fs::read_to_string("flights/token")
            .ok()
            .and_then(|t| Token::new(&t).ok())),
    }
}

/// A client of one service.
#[derive(Debug, Clone)]
pub struct Client {
    url: String,
    /// host:port
    authority: String,
    /// The path prefix before `/api/` (empty, or `/prefix`).
    prefix: String,
    token: Option<Token>,
}

/// An answer: the HTTP status and its JSON body (Null when it had none).
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    pub status: u16,
    pub body: serde_json::Value,
}

impl Answer {
    pub fn ok(&self) -> bool {
        (200..300).contains(&self.status)
    }

    /// The body read as the wire type `T` (`service::wire`): how clients read an answer.
    pub fn parse<T: serde::de::DeserializeOwned>(&self) -> Result<T, serde_json::Error> {
        T::deserialize(&self.body)
    }
}

impl Client {
    /// A client of the service at `url` (`http://HOST:PORT`), sending `token` with requests
    /// that change the vehicle.
    pub fn new(url: &str, token: Option<Token>) -> Result<Client, ClientError> {
        let bad = |reason: &str| ClientError::Url {
            url: url.to_string(),
            reason: reason.to_string(),
        };
        let rest = url
            .strip_prefix("http://")
            .ok_or_else(|| bad("only http:// is served"))?;
        let (authority, path) = match rest.find('/') {
            Some(i) => (&rest[..i], rest[i..].trim_end_matches('/')),
            None => (rest, ""),
        };
        if authority.is_empty() || !authority.contains(':') {
            return Err(bad("no host:port"));
        }
        let prefix = path.strip_suffix("/api").unwrap_or(path).to_string();
        Ok(Client {
            url: url.trim_end_matches('/').to_string(),
            authority: authority.to_string(),
            prefix,
            token,
        })
    }

    pub fn url(&self) -> &str {
        &self.url
    }

    async fn send(
        &self,
        method: Method,
        path: &str,
        body: Option<&serde_json::Value>,
    ) -> Result<hyper::Response<hyper::body::Incoming>, ClientError> {
        let connect = |reason: String| ClientError::Connect {
            url: self.url.clone(),
            reason,
        };
        let http = |what: &str, reason: String| ClientError::Http {
            url: self.url.clone(),
            what: what.to_string(),
            reason,
        };
        let stream = TcpStream::connect(&self.authority)
            .await
            .map_err(|e| connect(format!("{e} (is `emplan serve` running?)")))?;
        let _ = stream.set_nodelay(true);
        let (mut sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(stream))
            .await
            .map_err(|e| connect(e.to_string()))?;
        tokio::spawn(async move {
            let _ = connection.await;
        });
        let bytes = match body {
            Some(b) => serde_json::to_vec(b).map_err(|e| http("request body", e.to_string()))?,
            None => Vec::new(),
        };
        let mut request = Request::builder()
            .method(method.clone())
            .uri(format!("{}{path}", self.prefix))
            .header(header::HOST, &self.authority)
            .header(header::ACCEPT, "application/json, text/event-stream");
        if body.is_some() {
            request = request.header(header::CONTENT_TYPE, "application/json");
        }
        if let Some(token) = &self.token {
            request = request.header(header::AUTHORIZATION, format!("Bearer {}", token.as_str()));
        }
        let request = request
            .body(Full::new(Bytes::from(bytes)))
            .map_err(|e| http(&format!("{method} {path}"), e.to_string()))?;
        sender
            .send_request(request)
            .await
            .map_err(|e| http(&format!("{method} {path}"), e.to_string()))
    }

    async fn answer(
        &self,
        method: Method,
        path: &str,
        body: Option<&serde_json::Value>,
    ) -> Result<Answer, ClientError> {
        let response = self.send(method.clone(), path, body).await?;
        let status = response.status().as_u16();
        let what = format!("{method} {path}");
        let bytes = response
            .into_body()
            .collect()
            .await
            .map_err(|e| ClientError::Http {
                url: self.url.clone(),
                what: what.clone(),
                reason: e.to_string(),
            })?
            .to_bytes();
        let body = if bytes.is_empty() {
            serde_json::Value::Null
        } else {
            serde_json::from_slice(&bytes).map_err(|e| ClientError::Http {
                url: self.url.clone(),
                what,
                reason: format!("answer (HTTP {status}) is not JSON: {e}"),
            })?
        };
        Ok(Answer { status, body })
    }

    /// `GET path` (e.g. `/api/missions`).
    pub async fn get(&self, path: &str) -> Result<Answer, ClientError> {
        self.answer(Method::GET, path, None).await
    }

    /// `POST path` with a JSON body.
    pub async fn post(&self, path: &str, body: &serde_json::Value) -> Result<Answer, ClientError> {
        self.answer(Method::POST, path, Some(body)).await
    }

    /// Follows `GET /api/events`: once this returns, every event from now on arrives.
    pub async fn events(&self) -> Result<EventStream, ClientError> {
        let response = self.send(Method::GET, "/api/events", None).await?;
        if !response.status().is_success() {
            return Err(ClientError::Http {
                url: self.url.clone(),
                what: "GET /api/events".into(),
                reason: format!("HTTP {}", response.status()),
            });
        }
        Ok(EventStream {
            url: self.url.clone(),
            body: response.into_body(),
            buffer: Vec::new(),
        })
    }
}

/// The service's events, each a JSON object with a `type`.
pub struct EventStream {
    url: String,
    body: hyper::body::Incoming,
    buffer: Vec<u8>,
}

impl std::fmt::Debug for EventStream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EventStream({})", self.url)
    }
}

/// The JSON of one SSE block (its `data:` lines joined), None for a comment or keep-alive.
fn parse_block(block: &[u8]) -> Option<Result<serde_json::Value, serde_json::Error>> {
    let text = String::from_utf8_lossy(block);
    let data: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("data:"))
        .map(|d| d.strip_prefix(' ').unwrap_or(d))
        .collect();
    if data.is_empty() {
        return None;
    }
    Some(serde_json::from_str(&data.join("\n")))
}

/// Where the first block separator (a blank line) ends, if there is one.
fn block_end(buffer: &[u8]) -> Option<(usize, usize)> {
    let lf = buffer
        .windows(2)
        .position(|w| w == b"\n\n")
        .map(|i| (i, i + 2));
    let crlf = buffer
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map(|i| (i, i + 4));
    match (lf, crlf) {
        (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
        (a, b) => a.or(b),
    }
}

impl EventStream {
    /// The next event; None when the stream ends (the service stopped).
    pub async fn next(&mut self) -> Option<Result<serde_json::Value, ClientError>> {
        loop {
            if let Some((end, next)) = block_end(&self.buffer) {
                let block: Vec<u8> = self.buffer.drain(..next).take(end).collect();
                match parse_block(&block) {
                    None => continue,
                    Some(parsed) => {
                        return Some(parsed.map_err(|reason| ClientError::Http {
                            url: self.url.clone(),
                            what: "event".into(),
                            reason: reason.to_string(),
                        }))
                    }
                }
            }
            match self.body.frame().await {
                None => return None,
                Some(Err(e)) => {
                    return Some(Err(ClientError::Http {
                        url: self.url.clone(),
                        what: "event stream".into(),
                        reason: e.to_string(),
                    }))
                }
                Some(Ok(frame)) => {
                    if let Ok(data) = frame.into_data() {
                        self.buffer.extend_from_slice(&data);
                    }
                }
            }
        }
    }

    /// The next event within `timeout`; Err(None) when the time ran out.
    pub async fn next_within(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<Result<serde_json::Value, ClientError>>, tokio::time::error::Elapsed> {
        tokio::time::timeout(timeout, self.next()).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_urls_name_host_port_and_an_optional_prefix() {
        let c = Client::new("http://127.0.0.1:8080", None).expect("url");
        assert_eq!(
            (c.authority.as_str(), c.prefix.as_str()),
            ("127.0.0.1:8080", "")
        );
        let c = Client::new("http://localhost:1/api/", None).expect("url");
        assert_eq!(
            (c.authority.as_str(), c.prefix.as_str()),
            ("localhost:1", "")
        );
        let c = Client::new("http://h:2/emplan/", None).expect("url");
        assert_eq!(c.prefix, "/emplan");
        for bad in ["https://h:1", "127.0.0.1:8080", "http://", "http://host/x"] {
            assert!(Client::new(bad, None).is_err(), "{bad}");
        }
    }

    #[test]
    fn sse_blocks_give_their_data_as_json_and_skip_comments() {
        assert_eq!(
            parse_block(b"data: {\"type\":\"link\"}").and_then(Result::ok),
            Some(serde_json::json!({"type": "link"}))
        );
        assert_eq!(
            parse_block(b"event: x\ndata: {\"a\":\ndata: 1}").and_then(Result::ok),
            Some(serde_json::json!({"a": 1}))
        );
        assert!(parse_block(b": keep-alive").is_none());
        assert!(parse_block(b"data: not json").is_some_and(|r| r.is_err()));
        assert_eq!(block_end(b"data: 1\n\ndata: 2\n\n"), Some((7, 9)));
        assert_eq!(block_end(b"data: 1\r\n\r\n"), Some((7, 11)));
        assert_eq!(block_end(b"data: 1\n"), None);
    }
}
