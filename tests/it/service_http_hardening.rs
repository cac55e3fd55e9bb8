//! The service's HTTP side hardened for a network beyond loopback: connections that send their
//! headers slowly or sit idle are closed, requests naming another host are refused, plots and
//! downloads are bounded, files are sent whole, the bearer scheme is read in any case, and names
//! written to the log cannot carry control characters. The real service on 127.0.0.1:0, spoken to
//! over raw TCP where the test needs what a well-behaved client would not send.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use emplan::flightlog::recorder::TLOG_FILE;
use emplan::physics::VehicleModel;
use emplan::service::wire::Failure;
use emplan::service::{HttpConfig, ServiceConfig, ServiceError, Token, VehicleLink};
use emplan::sim::MockConfig;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// A generous bound on what should happen at once: reaching it fails the test.
const PATIENCE: Duration = Duration::from_secs(20);

struct Service {
    addr: SocketAddr,
    token: Token,
    log_dir: PathBuf,
    stop: tokio::sync::oneshot::Sender<()>,
    task: tokio::task::JoinHandle<Result<(), ServiceError>>,
    _work: tempfile::TempDir,
}

impl Service {
    async fn start(http: HttpConfig) -> Service {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let work = tempfile::tempdir().expect("temp dir");
        let missions = work.path().join("missions");
        let log_dir = work.path().join("flights");
        std::fs::create_dir_all(&missions).expect("missions dir");
        let token = Token::random().expect("token");
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bound");
        let addr = listener.local_addr().expect("addr");
        let cfg = ServiceConfig {
            vehicle: VehicleLink::Mock {
                config: Box::new(MockConfig::default()),
                vehicle: None,
            },
            missions_dir: missions,
            log_dir: log_dir.clone(),
            ledger: emplan::ledger::LedgerSpec::Sqlite(log_dir.join("ledger.sqlite")),
            token: token.clone(),
            model: Arc::new(
                VehicleModel::load(&root.join("models/s1000"), None).expect("the model"),
            ),
            solver: Default::default(),
            transfer_budget: None,
            resume_within: emplan::service::DEFAULT_RESUME_WITHIN,
            guard: Default::default(),
            watch: emplan::service::missions::WatchSettings {
                settle: std::time::Duration::from_millis(300),
                ..Default::default()
            },
            http,
        };
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(emplan::service::run(listener, cfg, async move {
            let _ = stopped.await;
        }));
        Service {
            addr,
            token,
            log_dir,
            stop,
            task,
            _work: work,
        }
    }

    async fn stop(self) {
        let _ = self.stop.send(());
        tokio::time::timeout(PATIENCE, self.task)
            .await
            .expect("the service stops")
            .expect("the service task")
            .expect("the service ran");
    }

    /// A flight directory `name` whose log is `bytes`.
    fn flight(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let dir = self.log_dir.join(name);
        std::fs::create_dir_all(&dir).expect("flight dir");
        std::fs::write(dir.join(TLOG_FILE), bytes).expect("log written");
        dir
    }
}

/// An answer read off the wire.
struct Answer {
    status: u16,
    head: String,
    body: Vec<u8>,
}

impl Answer {
    /// The body read as the service's failure document.
    fn failure(&self) -> Failure {
        serde_json::from_slice(&self.body).expect("a failure document")
    }
}

/// Sends one request (closing the connection after it) with `host` and `extra` header lines,
/// and reads the whole answer.
async fn request(addr: SocketAddr, method: &str, path: &str, host: &str, extra: &str) -> Answer {
    let mut stream = TcpStream::connect(addr).await.expect("connected");
    let text = format!(
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\n{extra}Content-Length: 0\r\nConnection: close\r\n\r\n"
    );
    stream.write_all(text.as_bytes()).await.expect("sent");
    let mut bytes = Vec::new();
    tokio::time::timeout(PATIENCE, stream.read_to_end(&mut bytes))
        .await
        .expect("answered")
        .expect("read");
    parse(&bytes)
}

fn parse(bytes: &[u8]) -> Answer {
    let split = bytes
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a head");
    let head = String::from_utf8_lossy(&bytes[..split]).into_owned();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("a status");
    Answer {
        status,
        head,
        body: bytes[split + 4..].to_vec(),
    }
}

/// Reads until the peer closes the connection (true) or `PATIENCE` runs out (false).
async fn closed_by_peer(stream: &mut TcpStream) -> bool {
    let mut sink = [0u8; 4096];
    let read_to_end = async {
        loop {
            match stream.read(&mut sink).await {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
        }
    };
    tokio::time::timeout(PATIENCE, read_to_end).await.is_ok()
}

fn short_timeouts() -> HttpConfig {
    HttpConfig {
        header_timeout: Duration::from_millis(300),
        ..HttpConfig::default()
    }
}

#[tokio::test]
async fn a_connection_that_never_finishes_its_headers_is_closed_after_the_header_timeout() {
    let service = Service::start(short_timeouts()).await;
    let mut stream = TcpStream::connect(service.addr).await.expect("connected");
    // The head's last empty line never comes.
    let partial = format!("GET /api/link HTTP/1.1\r\nHost: {}\r\n", service.addr);
    stream.write_all(partial.as_bytes()).await.expect("sent");
    assert!(
        closed_by_peer(&mut stream).await,
        "the connection is still open"
    );
    // A connection that sends nothing at all is closed too.
    let mut silent = TcpStream::connect(service.addr).await.expect("connected");
    assert!(closed_by_peer(&mut silent).await, "the silent one is open");
    service.stop().await;
}

#[tokio::test]
async fn a_kept_alive_connection_left_idle_is_closed_after_the_header_timeout() {
    let service = Service::start(short_timeouts()).await;
    let mut stream = TcpStream::connect(service.addr).await.expect("connected");
    let text = format!("GET /api/link HTTP/1.1\r\nHost: {}\r\n\r\n", service.addr);
    stream.write_all(text.as_bytes()).await.expect("sent");
    // The whole answer (its length from the head), the connection kept alive after it.
    let mut bytes = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        let n = tokio::time::timeout(PATIENCE, stream.read(&mut chunk))
            .await
            .expect("answered")
            .expect("read");
        assert_ne!(n, 0, "closed before the answer was whole");
        bytes.extend_from_slice(&chunk[..n]);
        if let Some(split) = bytes.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&bytes[..split]).to_ascii_lowercase();
            let length: usize = head
                .lines()
                .find_map(|l| l.strip_prefix("content-length:"))
                .and_then(|v| v.trim().parse().ok())
                .expect("a content length");
            if bytes.len() >= split + 4 + length {
                break;
            }
        }
    }
    assert_eq!(parse(&bytes).status, 200);
    assert!(
        closed_by_peer(&mut stream).await,
        "the idle connection is open"
    );
    service.stop().await;
}

#[tokio::test]
async fn a_request_naming_another_host_is_refused_and_this_machines_names_served() {
    let service = Service::start(HttpConfig {
        allowed_hosts: vec!["field-laptop.local".into()],
        ..HttpConfig::default()
    })
    .await;
    let port = service.addr.port();
    for path in ["/api/link", "/api/missions", "/", "/api/flights"] {
        // What a page of evil.example sees once it has rebound its name to 127.0.0.1.
        let refused = request(
            service.addr,
            "GET",
            path,
            &format!("evil.example:{port}"),
            "",
        )
        .await;
        assert_eq!(refused.status, 421, "{path}: {}", refused.head);
        let doc = refused.failure();
        assert!(!doc.ok, "{doc:?}");
        assert!(doc.error.contains("evil.example"), "{doc:?}");
    }
    for host in [
        service.addr.to_string(),
        format!("localhost:{port}"),
        format!("field-laptop.local:{port}"),
    ] {
        let served = request(service.addr, "GET", "/api/link", &host, "").await;
        assert_eq!(served.status, 200, "{host}: {}", served.head);
    }
    service.stop().await;
}

#[tokio::test]
async fn the_bearer_scheme_is_accepted_in_any_case() {
    let service = Service::start(HttpConfig::default()).await;
    let host = service.addr.to_string();
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let header = format!("Authorization: {scheme} {}\r\n", service.token.as_str());
        // Past the token check, the mission is not found.
        let answer = request(
            service.addr,
            "POST",
            "/api/missions/none.toml/upload",
            &host,
            &header,
        )
        .await;
        assert_eq!(answer.status, 404, "{scheme}: {}", answer.head);
    }
    let wrong = request(
        service.addr,
        "POST",
        "/api/missions/none.toml/upload",
        &host,
        "Authorization: bearer wrong\r\n",
    )
    .await;
    assert_eq!(wrong.status, 401);
    service.stop().await;
}

/// Bytes that tell where each was meant to be.
fn numbered_bytes(len: usize) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15).to_be_bytes()[0])
        .collect()
}

#[tokio::test]
async fn a_large_flight_file_is_downloaded_whole() {
    let service = Service::start(HttpConfig::default()).await;
    let log = numbered_bytes(6 * 1024 * 1024 + 12_345);
    service.flight("2026-01-01T10-00-00", &log);
    let answer = request(
        service.addr,
        "GET",
        &format!("/api/flights/2026-01-01T10-00-00/files/{TLOG_FILE}"),
        &service.addr.to_string(),
        "",
    )
    .await;
    assert_eq!(answer.status, 200, "{}", answer.head);
    assert!(
        answer
            .head
            .to_ascii_lowercase()
            .contains(&format!("content-length: {}", log.len())),
        "{}",
        answer.head
    );
    assert_eq!(answer.body.len(), log.len());
    assert!(answer.body == log, "the file arrived changed");
    service.stop().await;
}

#[tokio::test]
async fn plots_and_downloads_beyond_the_bound_are_refused_until_one_finishes() {
    let service = Service::start(HttpConfig {
        heavy_requests: 1,
        heavy_wait: Duration::ZERO,
        ..HttpConfig::default()
    })
    .await;
    // Far more than the socket buffers hold: a download not read cannot finish.
    let log = numbered_bytes(48 * 1024 * 1024);
    service.flight("big", &log);
    let host = service.addr.to_string();
    let file = format!("/api/flights/big/files/{TLOG_FILE}");
    let mut held = TcpStream::connect(service.addr).await.expect("connected");
    held.write_all(format!("GET {file} HTTP/1.1\r\nHost: {host}\r\n\r\n").as_bytes())
        .await
        .expect("sent");
    let mut first = [0u8; 64];
    let n = tokio::time::timeout(PATIENCE, held.read(&mut first))
        .await
        .expect("answered")
        .expect("read");
    assert!(first[..n].starts_with(b"HTTP/1.1 200"), "{first:?}");
    // The one place is taken by the download not read: another download and a plot are refused.
    for path in [file.as_str(), "/api/flights/big/plot.svg"] {
        let refused = request(service.addr, "GET", path, &host, "").await;
        assert_eq!(refused.status, 503, "{path}: {}", refused.head);
        assert!(
            refused.head.to_ascii_lowercase().contains("retry-after:"),
            "{}",
            refused.head
        );
        assert!(refused.failure().error.contains("busy"), "{path}");
    }
    // Other requests are served meanwhile.
    assert_eq!(
        request(service.addr, "GET", "/api/flights", &host, "")
            .await
            .status,
        200
    );
    // Its client gone, the download ends and leaves its place.
    drop(held);
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let answer = request(service.addr, "GET", &file, &host, "").await;
        if answer.status == 200 {
            assert!(answer.body == log, "the file arrived changed");
            break;
        }
        assert_eq!(answer.status, 503, "{}", answer.head);
        assert!(
            tokio::time::Instant::now() < deadline,
            "the place was never left"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    service.stop().await;
}

/// The log lines written on this thread, as text.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Captured {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("log buffer").extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[tokio::test]
async fn a_mission_name_with_control_characters_is_logged_escaped() {
    // A current-thread runtime: the request's handler runs on this thread, under this logger.
    let captured = Captured::default();
    let writer = captured.clone();
    let logger = tracing_subscriber::fmt()
        .with_writer(move || writer.clone())
        .with_ansi(false)
        .with_max_level(tracing::Level::INFO)
        .finish();
    let _logging = tracing::subscriber::set_default(logger);
    let service = Service::start(HttpConfig::default()).await;
    let header = format!("Authorization: Bearer {}\r\n", service.token.as_str());
    // "x\nERROR forged line \x1b[31m" in the path.
    let answer = request(
        service.addr,
        "POST",
        "/api/missions/x%0AERROR%20forged%20line%20%1B%5B31m/upload",
        &service.addr.to_string(),
        &header,
    )
    .await;
    assert_eq!(answer.status, 404, "{}", answer.head);
    service.stop().await;
    let text = String::from_utf8_lossy(&captured.0.lock().expect("log buffer")).into_owned();
    let refused = text
        .lines()
        .find(|l| l.contains("refused"))
        .unwrap_or_else(|| panic!("no refusal logged in:\n{text}"));
    assert!(
        refused.contains(r"mission=x\nERROR forged line \u{1b}[31m"),
        "{refused}"
    );
    assert!(!text.contains('\u{1b}'), "{text:?}");
    assert!(
        !text.lines().any(|l| l.starts_with("ERROR forged")),
        "{text}"
    );
}
