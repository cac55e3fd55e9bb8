//! The link: one task owns the MAVLink connection (any rust-mavlink URL: `udpin:`, `udpout:`,
//! `tcpin:`, `tcpout:`, `serial:DEV:BAUD`), receives with timeouts and fans messages out to
//! subscribers; another sends the ground station's HEARTBEAT at 1 Hz (PX4's data-link-loss
//! failsafe watches it). The autopilot is discovered from its first HEARTBEAT. When the
//! transport fails (TCP closed, serial unplugged; UDP never fails) the error is logged and the
//! receive task reconnects every second until it succeeds or the link is dropped (each
//! reconnect is counted on `reconnects()`, so telemetry requests can be issued again);
//! `connect_within` waits for an autopilot whose port is not open yet.
//!
//! Taps (`tap()`) get every frame that crosses the link as raw bytes with its wall-clock time,
//! received and sent, through an unbounded channel: the flight log must never lose a frame to a
//! slow subscriber, which the broadcast channel of parsed messages may (it lags and drops).
//! Frames we send are logged as serialised by us (MAVLink 2, unsigned, our own sequence
//! number): the connection renumbers and signs them on the wire.

use std::sync::Arc;
use std::time::Duration;

use mavlink::{AsyncMavConnection, MAVLinkMessageRaw, MavHeader, Message};
use tokio::sync::{broadcast, mpsc, watch};

use super::mav::{MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA};
use super::{Flavour, LinkError};

/// Who we are on the link (MAVLink GCS convention: system 255, component 190 = mission planner).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    pub system_id: u8,
    pub component_id: u8,
}

impl Default for Identity {
    fn default() -> Self {
        Identity {
            system_id: 255,
            component_id: 190,
        }
    }
}

/// The autopilot found on the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Autopilot {
    pub system_id: u8,
    pub component_id: u8,
    pub flavour: Flavour,
}

/// One MAVLink frame as it crossed the link.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// When it was received or sent: microseconds since the Unix epoch (the .tlog timestamp).
    pub wall_us: u64,
    /// Sent by us (true) or received (false).
    pub outgoing: bool,
    /// The whole frame, header to checksum (and signature).
    pub bytes: Vec<u8>,
}

/// Microseconds since the Unix epoch, now.
pub fn wall_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

type Taps = Arc<std::sync::Mutex<Vec<mpsc::UnboundedSender<Frame>>>>;

/// Hands a frame to every tap, forgetting taps whose receiver is gone.
fn to_taps(taps: &Taps, frame: Frame) {
    if let Ok(mut taps) = taps.lock() {
        taps.retain(|tap| tap.send(frame.clone()).is_ok());
    }
}

/// The connection URLs the link opens (rust-mavlink's `ConnectionAddress::parse_address`; its
/// `file:` reads a recording and sends nowhere, so it is no way to a vehicle), for errors.
pub const URL_FORMS: &str = "udpin:HOST:PORT, udpout:HOST:PORT, udpbcast:HOST:PORT, \
                             tcpin:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD";

/// What a connection URL opens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transport {
    /// `udpin:`, `udpout:`, `udpbcast:` (the scheme) to HOST:PORT.
    Udp { scheme: String, address: String },
    /// `tcpin:`, `tcpout:` (the scheme) to HOST:PORT.
    Tcp { scheme: String, address: String },
    Serial {
        device: std::path::PathBuf,
        baud: u32,
    },
}

/// The transport of a connection URL, checked for its form before anything is opened: a known
/// scheme, HOST:PORT with a port number, a serial device with its baud rate (split as
/// rust-mavlink splits it, at the first colon after the scheme). Whether the serial device is
/// there is not checked (see [`check_url`]): a service waits for one plugged in later.
pub fn parse_url(url: &str) -> Result<Transport, LinkError> {
    let refused = |reason: String| LinkError::Url {
        url: url.to_string(),
        reason,
    };
    let (scheme, rest) = url
        .split_once(':')
        .ok_or_else(|| refused("no scheme".into()))?;
    let host_port = || -> Result<String, LinkError> {
        let (host, port) = rest
            .rsplit_once(':')
            .ok_or_else(|| refused(format!("no port in {rest:?}")))?;
        if host.is_empty() {
            return Err(refused(format!("no host in {rest:?}")));
        }
        port.parse::<u16>()
            .map_err(|_| refused(format!("port {port:?} is not a number from 0 to 65535")))?;
        Ok(rest.to_string())
    };
    match scheme {
        "udpin" | "udpout" | "udpbcast" => Ok(Transport::Udp {
            scheme: scheme.to_string(),
            address: host_port()?,
        }),
        "tcpin" | "tcpout" => Ok(Transport::Tcp {
            scheme: scheme.to_string(),
            address: host_port()?,
        }),
        "serial" => {
            let (device, baud) = rest
                .split_once(':')
                .ok_or_else(|| refused("no baud rate".into()))?;
            if device.is_empty() {
                return Err(refused("no serial device".into()));
            }
            let baud =
                baud.parse::<u32>().ok().filter(|b| *b > 0).ok_or_else(|| {
                    refused(format!("baud rate {baud:?} is not a positive number"))
                })?;
            Ok(Transport::Serial {
                device: device.into(),
                baud,
            })
        }
        other => Err(refused(format!("unknown scheme {other:?}"))),
    }
}

/// [`parse_url`], and a serial device must exist: for a command that connects once, now.
pub fn check_url(url: &str) -> Result<Transport, LinkError> {
    let transport = parse_url(url)?;
    if let Transport::Serial { device, .. } = &transport {
        if !device.exists() {
            return Err(LinkError::Url {
                url: url.to_string(),
                reason: format!("no serial device {}", device.display()),
            });
        }
    }
    Ok(transport)
}

type Connection = mavlink::AsyncConnection<MavMessage>;
/// The current connection, replaced when the receive task reconnects.
type Shared = Arc<std::sync::RwLock<Arc<Connection>>>;

fn current(conn: &Shared) -> Option<Arc<Connection>> {
    conn.read().ok().map(|c| c.clone())
}

async fn open(url: &str, signing: Option<mavlink::SigningConfig>) -> Result<Connection, LinkError> {
    let mut conn = mavlink::connect_async::<MavMessage>(url)
        .await
        .map_err(|e| LinkError::Connect {
            url: url.to_string(),
            reason: e.to_string(),
        })?;
    conn.set_allow_recv_any_version(true);
    conn.setup_signing(signing);
    Ok(conn)
}

/// A running link. Dropping it stops its tasks.
pub struct Link {
    url: String,
    conn: Shared,
    header: MavHeader,
    incoming: broadcast::Sender<(MavHeader, MavMessage)>,
    taps: Taps,
    /// Our own sequence numbers for the frames we log as sent.
    sent: std::sync::atomic::AtomicU8,
    reconnects: watch::Receiver<u64>,
    shutdown: watch::Sender<bool>,
}

impl Drop for Link {
    fn drop(&mut self) {
        let _ = self.shutdown.send(true);
    }
}

impl Link {
    /// Connects to `url`, optionally with MAVLink 2 signing, and starts the receive and
    /// heartbeat tasks.
    pub async fn connect(
        url: &str,
        identity: Identity,
        signing: Option<mavlink::SigningConfig>,
    ) -> Result<Link, LinkError> {
        let conn: Shared = Arc::new(std::sync::RwLock::new(Arc::new(
            open(url, signing.clone()).await?,
        )));
        let (incoming, _) = broadcast::channel(4096);
        let (shutdown, _) = watch::channel(false);
        let header = MavHeader {
            system_id: u32::from(identity.system_id),
            component_id: identity.component_id,
            sequence: 0,
        };
        let taps: Taps = Arc::default();
        let (reconnected, reconnects) = watch::channel(0);
        tokio::spawn(receive(
            Receiver {
                url: url.to_string(),
                signing,
                conn: conn.clone(),
                incoming: incoming.clone(),
                taps: taps.clone(),
                reconnected,
            },
            shutdown.subscribe(),
        ));
        tokio::spawn(heartbeat(conn.clone(), header, shutdown.subscribe()));
        Ok(Link {
            url: url.to_string(),
            conn,
            header,
            incoming,
            taps,
            sent: std::sync::atomic::AtomicU8::new(0),
            reconnects,
            shutdown,
        })
    }

    /// Connects as `connect` does, trying again every 200 ms for up to `patience` while the
    /// transport refuses (an autopilot started a moment ago has not opened its TCP port yet).
    /// A URL of no known form ([`parse_url`]) is refused at once.
    pub async fn connect_within(
        url: &str,
        identity: Identity,
        signing: Option<mavlink::SigningConfig>,
        patience: Duration,
    ) -> Result<Link, LinkError> {
        parse_url(url)?;
        let deadline = tokio::time::Instant::now() + patience;
        loop {
            match Link::connect(url, identity, signing.clone()).await {
                Ok(link) => return Ok(link),
                Err(e) if tokio::time::Instant::now() >= deadline => return Err(e),
                Err(e) => {
                    tracing::debug!("{e}; trying again");
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
            }
        }
    }

    /// A receiver of every message that arrives from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<(MavHeader, MavMessage)> {
        self.incoming.subscribe()
    }

    /// Every frame that crosses the link from now on, received and sent, never dropped (the
    /// channel is unbounded: drain it).
    pub fn tap(&self) -> mpsc::UnboundedReceiver<Frame> {
        let (tx, rx) = mpsc::unbounded_channel();
        if let Ok(mut taps) = self.taps.lock() {
            taps.push(tx);
        }
        rx
    }

    /// How many times the transport has been reopened; changes on each reconnect.
    pub fn reconnects(&self) -> watch::Receiver<u64> {
        self.reconnects.clone()
    }

    /// The connection URL.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Sends one message.
    pub async fn send(&self, message: &MavMessage) -> Result<(), LinkError> {
        let conn = current(&self.conn).ok_or_else(|| LinkError::Closed(self.url.clone()))?;
        let tapped = self.taps.lock().map(|t| !t.is_empty()).unwrap_or(false);
        if tapped {
            let header = MavHeader {
                sequence: self.sent.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
                ..self.header
            };
            let mut raw = mavlink::MAVLinkV2MessageRaw::new();
            raw.serialize_message(header, message);
            to_taps(
                &self.taps,
                Frame {
                    wall_us: wall_us(),
                    outgoing: true,
                    bytes: raw.raw_bytes().to_vec(),
                },
            );
        }
        conn.send(&self.header, message)
            .await
            .map(|_| ())
            .map_err(|e| LinkError::Send {
                what: format!("{message:?}").chars().take(40).collect(),
                reason: e.to_string(),
            })
    }

    /// Waits for the first autopilot HEARTBEAT (MAV_AUTOPILOT_INVALID ones are other ground
    /// stations or peripherals).
    pub async fn discover(&self, timeout: Duration) -> Result<Autopilot, LinkError> {
        let mut rx = self.subscribe();
        let found = tokio::time::timeout(timeout, async {
            loop {
                match rx.recv().await {
                    Ok((h, MavMessage::HEARTBEAT(hb)))
                        if hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID =>
                    {
                        return Ok(Autopilot {
                            system_id: u8::try_from(h.system_id).unwrap_or(u8::MAX),
                            component_id: h.component_id,
                            flavour: Flavour::from_autopilot(hb.autopilot),
                        });
                    }
                    Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => {}
                    Err(broadcast::error::RecvError::Closed) => {
                        return Err(LinkError::Closed(self.url.clone()))
                    }
                }
            }
        })
        .await;
        found.unwrap_or(Err(LinkError::NoAutopilot {
            url: self.url.clone(),
            seconds: timeout.as_secs_f64(),
        }))
    }
}

fn gcs_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

async fn heartbeat(conn: Shared, header: MavHeader, mut shutdown: watch::Receiver<bool>) {
    let mut every = tokio::time::interval(Duration::from_secs(1));
    loop {
        tokio::select! {
            _ = shutdown.changed() => return,
            _ = every.tick() => {
                let Some(conn) = current(&conn) else { return };
                if let Err(e) = conn.send(&header, &gcs_heartbeat()).await {
                    tracing::warn!("heartbeat not sent: {e}");
                }
            }
        }
    }
}

/// What the receive task owns.
struct Receiver {
    url: String,
    signing: Option<mavlink::SigningConfig>,
    conn: Shared,
    incoming: broadcast::Sender<(MavHeader, MavMessage)>,
    taps: Taps,
    reconnected: watch::Sender<u64>,
}

impl Receiver {
    /// Hands a received frame to the taps and, when it parses, its message to subscribers.
    fn deliver(&self, raw: &MAVLinkMessageRaw) {
        let bytes = match raw {
            MAVLinkMessageRaw::V1(frame) => frame.raw_bytes(),
            MAVLinkMessageRaw::V2(frame) => frame.raw_bytes(),
        };
        to_taps(
            &self.taps,
            Frame {
                wall_us: wall_us(),
                outgoing: false,
                bytes: bytes.to_vec(),
            },
        );
        match MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) {
            Ok(message) => {
                let header = MavHeader {
                    system_id: raw.system_id(),
                    component_id: raw.component_id(),
                    sequence: raw.sequence(),
                };
                let _ = self.incoming.send((header, message));
            }
            // A message of another dialect, or an enum value this one does not know: in the
            // log (tapped above), not for subscribers.
            Err(e) => tracing::debug!("frame {} not parsed: {e}", raw.message_id()),
        }
    }
}

async fn receive(rx: Receiver, mut shutdown: watch::Receiver<bool>) {
    loop {
        let Some(active) = current(&rx.conn) else {
            return;
        };
        tokio::select! {
            _ = shutdown.changed() => return,
            // No timeout around the receive: the shutdown branch ends the wait, and a TCP
            // read cancelled half-way through a frame would lose bytes.
            received = active.recv_raw() => match received {
                Ok(raw) => rx.deliver(&raw),
                Err(mavlink::error::MessageReadError::Io(e)) => {
                    // Never swallowed: reported, then the transport is reopened.
                    tracing::error!("link {}: receive failed: {e}; reconnecting", rx.url);
                    loop {
                        tokio::select! {
                            _ = shutdown.changed() => return,
                            _ = tokio::time::sleep(Duration::from_secs(1)) => {}
                        }
                        match open(&rx.url, rx.signing.clone()).await {
                            Ok(fresh) => {
                                if let Ok(mut slot) = rx.conn.write() {
                                    *slot = Arc::new(fresh);
                                }
                                rx.reconnected.send_modify(|n| *n += 1);
                                tracing::info!("link {}: reconnected", rx.url);
                                break;
                            }
                            Err(e) => tracing::warn!("{e}; retrying"),
                        }
                    }
                }
                Err(e) => tracing::debug!("unparsable frame skipped: {e}"),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_of_every_known_form_parse_and_others_are_refused_listing_the_forms() {
        for url in [
            "udpin:0.0.0.0:14550",
            "udpout:127.0.0.1:14540",
            "udpbcast:192.168.1.255:14550",
            "tcpin:0.0.0.0:5760",
            "tcpout:localhost:5760",
            "tcpout:[::1]:5760",
            "serial:/dev/ttyACM0:57600",
        ] {
            assert!(parse_url(url).is_ok(), "{url}");
        }
        assert_eq!(
            parse_url("serial:/dev/ttyUSB0:921600").expect("serial"),
            Transport::Serial {
                device: "/dev/ttyUSB0".into(),
                baud: 921_600
            }
        );
        for (url, reason) in [
            ("udp:127.0.0.1:1", "unknown scheme \"udp\""),
            ("http://x", "unknown scheme \"http\""),
            ("127.0.0.1", "no scheme"),
            ("udpin:127.0.0.1", "no port"),
            ("tcpout::5760", "no host"),
            ("udpout:127.0.0.1:99999", "port \"99999\""),
            ("serial:/dev/ttyACM0", "no baud rate"),
            ("serial:/dev/ttyACM0:fast", "baud rate \"fast\""),
            ("serial::57600", "no serial device"),
        ] {
            let err = parse_url(url).expect_err(url).to_string();
            assert!(
                err.contains(url) && err.contains(reason) && err.contains(URL_FORMS),
                "{url}: {err}"
            );
        }
        // A serial device is checked only by `check_url`: a service waits for one.
        assert!(parse_url("serial:/dev/does-not-exist:57600").is_ok());
        let err = check_url("serial:/dev/does-not-exist:57600").expect_err("absent");
        assert!(err
            .to_string()
            .contains("no serial device /dev/does-not-exist"));
    }
}
