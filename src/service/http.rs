//! The HTTP side's defences for a service that may be reachable beyond this machine: the server
//! loop (hyper's HTTP/1 connections with a time limit on every request's head, which also closes
//! a kept-alive connection left idle), the `Host` check (a page of another site that rebinds its
//! name to this machine cannot read the API), and the gate that bounds the plots and file
//! downloads served at once (a flight plot replays the whole log in memory).

use std::future::Future;
use std::net::IpAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

use super::{escape_controls, Refusal};

/// Serves `app` on `listener` until `shutdown` resolves, then stops accepting, lets every request
/// in progress finish and returns when the last connection has closed.
///
/// Each connection has `header_timeout` to send a request's head, counted from its opening and
/// again from the end of each response: a client that sends its headers slowly, or never, or
/// keeps a connection open without asking anything, is cut off.
pub async fn serve(
    listener: TcpListener,
    app: axum::Router,
    header_timeout: Duration,
    shutdown: impl Future<Output = ()>,
) {
    let mut shutdown = std::pin::pin!(shutdown);
    let (stop_tx, stop_rx) = watch::channel(false);
    // Every connection task holds a receiver: the sender sees them all closed at the end.
    let (open_tx, open_rx) = watch::channel(());
    loop {
        let accepted = tokio::select! {
            _ = &mut shutdown => break,
            accepted = listener.accept() => accepted,
        };
        let stream = match accepted {
            Ok((stream, _peer)) => stream,
            Err(e) if is_connection_error(&e) => continue,
            Err(e) => {
                // Out of file descriptors, say: wait a little rather than spin.
                tracing::error!("accepting a connection: {e}");
                tokio::select! {
                    _ = &mut shutdown => break,
                    _ = tokio::time::sleep(Duration::from_secs(1)) => continue,
                }
            }
        };
        let service = TowerToHyperService::new(app.clone());
        let mut stop = stop_rx.clone();
        let open = open_rx.clone();
        tokio::spawn(async move {
            let mut builder = http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(header_timeout);
            let mut connection =
                std::pin::pin!(builder.serve_connection(TokioIo::new(stream), service));
            let served = tokio::select! {
                served = connection.as_mut() => served,
                _ = async { stop.wait_for(|stopping| *stopping).await.map(drop) } => {
                    connection.as_mut().graceful_shutdown();
                    connection.await
                }
            };
            if let Err(e) = served {
                tracing::debug!("connection closed: {e}");
            }
            drop(open);
        });
    }
    let _ = stop_tx.send(true);
    drop(open_rx);
    open_tx.closed().await;
}

/// Errors of one connection being accepted (the listener itself is fine).
fn is_connection_error(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::ConnectionRefused
            | std::io::ErrorKind::ConnectionAborted
            | std::io::ErrorKind::ConnectionReset
    )
}

/// Which `Host`s the service answers: any IP address, `localhost`, and the names the user
/// allowed (`serve --allow-host NAME`). A page that rebinds its own name to this machine's
/// address reaches the service with its name as the host, and is refused; an IP address cannot be
/// rebound, so every address of the machine is accepted whatever the service is bound to. Ports
/// are not compared: a rebinding page connects to the service's own port.
#[derive(Debug, Clone, Default)]
pub struct HostCheck {
    /// Lowercase, without a trailing dot.
    names: Arc<Vec<String>>,
}

impl HostCheck {
    /// A check accepting, besides IP addresses and `localhost`, the host names `allowed`.
    pub fn new(allowed: &[String]) -> HostCheck {
        HostCheck {
            names: Arc::new(allowed.iter().map(|n| normal_name(n)).collect()),
        }
    }

    /// Whether a request whose host (`Host` header or absolute URI's authority) is `host` is
    /// answered.
    pub fn accepts(&self, host: &str) -> bool {
        let Ok(authority) = host.parse::<axum::http::uri::Authority>() else {
            return false;
        };
        if authority.as_str().contains('@') {
            return false;
        }
        let name = authority.host();
        let bare = name
            .strip_prefix('[')
            .and_then(|n| n.strip_suffix(']'))
            .unwrap_or(name);
        if bare.parse::<IpAddr>().is_ok() {
            return true;
        }
        let name = normal_name(name);
        name == "localhost" || self.names.contains(&name)
    }
}

fn normal_name(name: &str) -> String {
    name.trim().trim_end_matches('.').to_ascii_lowercase()
}

/// Middleware: refuses (421) a request for a host the service does not answer to, before any
/// route runs; a request without a host is refused (400) as HTTP/1.1 asks.
pub async fn check_host(State(hosts): State<HostCheck>, request: Request, next: Next) -> Response {
    let host = match request.uri().authority() {
        Some(authority) => Some(authority.as_str().to_string()),
        None => request
            .headers()
            .get(header::HOST)
            .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned()),
    };
    match host {
        Some(host) if hosts.accepts(&host) => next.run(request).await,
        Some(host) => {
            tracing::warn!(
                host = %escape_controls(&host),
                "a request for another host was refused"
            );
            Refusal::new(
                421,
                "request",
                &format!(
                    "host {:?} is not this service's: it answers IP addresses, localhost and the names given to serve --allow-host",
                    escape_controls(&host)
                ),
            )
            .into_response()
        }
        None => Refusal::new(400, "request", "a request needs a Host header").into_response(),
    }
}

/// Bounds the requests that cost memory or a file held open (plots, file downloads): at most
/// `limit` at once; one more waits up to `wait` for one to finish, and is refused (503) if none
/// does.
#[derive(Debug, Clone)]
pub struct Gate {
    permits: Arc<Semaphore>,
    limit: usize,
    wait: Duration,
}

impl Gate {
    pub fn new(limit: usize, wait: Duration) -> Gate {
        Gate {
            permits: Arc::new(Semaphore::new(limit)),
            limit,
            wait,
        }
    }

    /// A place among the `limit`, held until the permit drops (for a download, when its body
    /// has been sent).
    pub async fn enter(&self, what: &str) -> Result<OwnedSemaphorePermit, Refusal> {
        if let Ok(permit) = self.permits.clone().try_acquire_owned() {
            return Ok(permit);
        }
        if !self.wait.is_zero() {
            if let Ok(Ok(permit)) =
                tokio::time::timeout(self.wait, self.permits.clone().acquire_owned()).await
            {
                return Ok(permit);
            }
        }
        Err(Refusal::new(
            503,
            "service",
            &format!(
                "busy: {} plots or file downloads in progress already; {what} not served (try again)",
                self.limit
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ip_addresses_localhost_and_allowed_names_are_accepted_and_other_names_refused() {
        let hosts = HostCheck::new(&["Field-Laptop.local".to_string()]);
        for ok in [
            "127.0.0.1:8080",
            "127.0.0.1",
            "192.168.1.20:8080",
            "[::1]:8080",
            "[fe80::1]",
            "localhost:8080",
            "LOCALHOST",
            "localhost.:8080",
            "field-laptop.local:8080",
            "FIELD-LAPTOP.LOCAL.",
        ] {
            assert!(hosts.accepts(ok), "{ok}");
        }
        for refused in [
            "evil.example:8080",
            "evil.example",
            "localhost.evil.example",
            "127.0.0.1.nip.io:8080",
            "field-laptop.local.evil.example",
            "",
            "user@127.0.0.1",
            "a b",
        ] {
            assert!(!hosts.accepts(refused), "{refused}");
        }
        assert!(!HostCheck::default().accepts("field-laptop.local"));
    }

    #[tokio::test]
    async fn a_gate_of_two_refuses_a_third_until_one_finishes() {
        let gate = Gate::new(2, Duration::ZERO);
        let first = gate.enter("plot").await.expect("first");
        let _second = gate.enter("plot").await.expect("second");
        let refused = gate.enter("plot").await.expect_err("third refused");
        assert_eq!(refused.status, 503);
        assert!(refused.message().contains("busy"), "{}", refused.message());
        drop(first);
        drop(gate.enter("plot").await.expect("a place again"));
    }

    #[tokio::test]
    async fn a_waiting_request_gets_the_place_a_finished_one_leaves() {
        let gate = Gate::new(1, Duration::from_secs(60));
        let first = gate.enter("plot").await.expect("first");
        let waiting = tokio::spawn({
            let gate = gate.clone();
            async move { gate.enter("plot").await.map(drop) }
        });
        tokio::task::yield_now().await;
        drop(first);
        waiting
            .await
            .expect("task")
            .expect("served after the first");
    }
}
