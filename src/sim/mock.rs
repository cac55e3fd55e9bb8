//! The mock autopilot's async shell: one task owns a UDP socket (bound from a `udpin:HOST:PORT`
//! URL, port 0 allowed), decodes MAVLink 2 frames, feeds the [`MissionServer`], answers the last
//! peer heard, sends a HEARTBEAT at 1 Hz, and injects seeded transport faults: loss per
//! direction (`up` is ground to vehicle), duplication, reordering and delay. A later flight
//! simulation plugs in beside the server: the stored mission is shared through the handle.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::{MavHeader, MavlinkReader, SigningConfig, SigningData};
use tokio::net::UdpSocket;
use tokio::sync::watch;
use tokio::time::Instant;

use super::server::{MissionServer, ProtocolFaults, ServerConfig, ServerStats};
use super::storage::Home;
use crate::link::mav::{
    MavMessage, MavMissionResult, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
    MISSION_ITEM_INT_DATA,
};
use crate::link::Flavour;

/// Transport and protocol faults to inject.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Faults {
    /// Probability a datagram from the ground is lost.
    pub loss_up: f64,
    /// Probability a datagram to the ground is lost.
    pub loss_down: f64,
    /// Probability a datagram to the ground is sent twice.
    pub duplicate: f64,
    /// Probability a datagram to the ground is held back and sent after the next one.
    pub reorder: f64,
    /// Delay added to every datagram to the ground.
    pub delay_ms: u64,
    pub nack_item: Option<u16>,
    pub nack_result: Option<MavMissionResult>,
    pub drop_final_ack: bool,
    pub reboot_at_item: Option<u16>,
    /// Answer read-backs of this item with its latitude 1 degE7 off.
    pub corrupt_readback: Option<u16>,
}

/// How the mock behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MockConfig {
    pub flavour: Flavour,
    pub faults: Faults,
    /// Seed of the fault generator: the same seed replays the same faults.
    pub seed: u64,
    pub system_id: u8,
    pub component_id: u8,
    /// MAVLink 2 signing key: when set, every frame sent is signed and frames that are unsigned
    /// or signed with another key are dropped.
    pub signing_key: Option<[u8; 32]>,
    /// The vehicle's own home (the ArduPilot flavour answers it for item 0).
    pub home: Home,
    /// How long the ArduPilot flavour refuses uploads with MAV_MISSION_NO_SPACE after start
    /// (ArduCopter SITL: about 10 s; 2 s by default so tests see it without waiting long).
    pub boot: Duration,
}

impl Default for MockConfig {
    fn default() -> Self {
        MockConfig {
            flavour: Flavour::Px4,
            faults: Faults::default(),
            seed: 1,
            system_id: 1,
            component_id: 1,
            signing_key: None,
            home: Home::default(),
            boot: Duration::from_secs(2),
        }
    }
}

/// Errors starting or running the mock.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("listen address {url:?}: {reason} (expected udpin:HOST:PORT)")]
    Listen { url: String, reason: String },
    #[error("socket: {0}")]
    Io(#[from] std::io::Error),
}

/// SplitMix64: a small seeded generator, so fault sequences reproduce.
#[derive(Debug, Clone)]
struct Rng(u64);

impl Rng {
    fn chance(&mut self, p: f64) -> bool {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        let u = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
        u < p
    }
}

#[derive(Debug, Default)]
struct Shared {
    revision: u64,
    mission: Vec<MISSION_ITEM_INT_DATA>,
    stats: ServerStats,
}

/// A running mock autopilot.
#[derive(Debug)]
pub struct MockHandle {
    local_addr: SocketAddr,
    shared: Arc<Mutex<Shared>>,
    shutdown: watch::Sender<bool>,
    task: tokio::task::JoinHandle<Result<(), SimError>>,
}

impl MockHandle {
    /// The address the mock listens on (connect with `udpout:` to it).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The stored mission.
    pub fn mission(&self) -> Vec<MISSION_ITEM_INT_DATA> {
        self.shared
            .lock()
            .map(|s| s.mission.clone())
            .unwrap_or_default()
    }

    /// What the mission server has done.
    pub fn stats(&self) -> ServerStats {
        self.shared.lock().map(|s| s.stats).unwrap_or_default()
    }

    /// Stops the mock and waits for its task.
    pub async fn shutdown(self) -> Result<(), SimError> {
        let _ = self.shutdown.send(true);
        self.task.await.unwrap_or(Ok(()))
    }

    /// Resolves when the mock's task ends by itself (a socket error, which it returns).
    pub async fn stopped(&mut self) -> Result<(), SimError> {
        (&mut self.task).await.unwrap_or(Ok(()))
    }
}

/// The mock autopilot.
pub struct MockAutopilot;

/// Parses `udpin:HOST:PORT` (also accepts a bare `HOST:PORT`).
fn listen_addr(url: &str) -> Result<SocketAddr, SimError> {
    let rest = url.strip_prefix("udpin:").unwrap_or(url);
    rest.parse()
        .map_err(|e: std::net::AddrParseError| SimError::Listen {
            url: url.to_string(),
            reason: e.to_string(),
        })
}

impl MockAutopilot {
    /// Binds `listen` and starts the mock on the current tokio runtime.
    pub async fn spawn(listen: &str, config: MockConfig) -> Result<MockHandle, SimError> {
        let socket = UdpSocket::bind(listen_addr(listen)?).await?;
        let local_addr = socket.local_addr()?;
        let shared = Arc::new(Mutex::new(Shared::default()));
        let (tx, rx) = watch::channel(false);
        let task = tokio::spawn(run(Arc::new(socket), config, shared.clone(), rx));
        Ok(MockHandle {
            local_addr,
            shared,
            shutdown: tx,
            task,
        })
    }
}

struct Outbox {
    socket: Arc<UdpSocket>,
    signing: Option<Arc<SigningData>>,
    header: MavHeader,
    rng: Rng,
    faults: Faults,
    held: Option<Vec<u8>>,
}

impl Outbox {
    async fn send(&mut self, peer: SocketAddr, message: &MavMessage) -> Result<(), SimError> {
        let mut bytes = Vec::with_capacity(64);
        if mavlink::write_v2_msg_signed(&mut bytes, self.header, message, self.signing.as_deref())
            .is_err()
        {
            return Ok(());
        }
        self.header.sequence = self.header.sequence.wrapping_add(1);
        if self.rng.chance(self.faults.loss_down) {
            return Ok(());
        }
        let copies = if self.rng.chance(self.faults.duplicate) {
            2
        } else {
            1
        };
        let mut datagrams = Vec::new();
        if self.rng.chance(self.faults.reorder) && self.held.is_none() {
            self.held = Some(bytes);
        } else {
            for _ in 0..copies {
                datagrams.push(bytes.clone());
            }
            if let Some(held) = self.held.take() {
                datagrams.push(held);
            }
        }
        for datagram in datagrams {
            if self.faults.delay_ms > 0 {
                let socket = self.socket.clone();
                let delay = Duration::from_millis(self.faults.delay_ms);
                tokio::spawn(async move {
                    tokio::time::sleep(delay).await;
                    let _ = socket.send_to(&datagram, peer).await;
                });
            } else {
                self.socket.send_to(&datagram, peer).await?;
            }
        }
        Ok(())
    }
}

async fn run(
    socket: Arc<UdpSocket>,
    config: MockConfig,
    shared: Arc<Mutex<Shared>>,
    mut shutdown: watch::Receiver<bool>,
) -> Result<(), SimError> {
    let f = config.faults;
    let mut server = MissionServer::new(
        config.flavour,
        ServerConfig {
            faults: ProtocolFaults {
                nack_item: f.nack_item,
                nack_result: f.nack_result,
                drop_final_ack: f.drop_final_ack,
                reboot_at_item: f.reboot_at_item,
                corrupt_readback: f.corrupt_readback,
            },
            home: config.home,
            boot: config.boot,
        },
    );
    let mut rng_up = Rng(config.seed ^ 0x005e_ed0f_u64);
    let signing = config.signing_key.map(|key| {
        Arc::new(SigningData::from_config(SigningConfig::new(
            key, 0, true, false,
        )))
    });
    let mut out = Outbox {
        socket: socket.clone(),
        signing: signing.clone(),
        header: MavHeader {
            system_id: u32::from(config.system_id),
            component_id: config.component_id,
            sequence: 0,
        },
        rng: Rng(config.seed),
        faults: f,
        held: None,
    };
    let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_OCTOROTOR,
        autopilot: config.flavour.autopilot(),
        base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        system_status: MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    });
    let start = Instant::now();
    let mut peer: Option<SocketAddr> = None;
    let mut buf = vec![0u8; 4096];
    let mut tick = tokio::time::interval(Duration::from_millis(20));
    let mut beat = tokio::time::interval(Duration::from_secs(1));
    loop {
        let replies: Vec<MavMessage> = tokio::select! {
            _ = shutdown.changed() => return Ok(()),
            received = socket.recv_from(&mut buf) => {
                let (n, from) = received?;
                peer = Some(from);
                if rng_up.chance(f.loss_up) {
                    continue;
                }
                let now = start.elapsed();
                let mut reader = MavlinkReader::new(&buf[..n]);
                let mut replies = Vec::new();
                while let Ok((header, message)) = reader.read_any_message_signed::<MavMessage>(signing.as_deref()) {
                    let from = (u8::try_from(header.system_id).unwrap_or(u8::MAX), header.component_id);
                    replies.extend(server.handle(now, from, &message));
                }
                replies
            }
            _ = tick.tick() => server.tick(start.elapsed()),
            _ = beat.tick() => vec![heartbeat.clone()],
        };
        // The mission is copied out only when it changed: not once per message.
        if let Ok(mut s) = shared.lock() {
            if s.revision != server.revision() {
                s.revision = server.revision();
                s.mission = server.mission().to_vec();
            }
            s.stats = server.stats;
        }
        if let Some(peer) = peer {
            for message in &replies {
                out.send(peer, message).await?;
            }
        }
    }
}
