//! The mock autopilot's async shell: one task owns a UDP socket (bound from a `udpin:HOST:PORT`
//! URL, port 0 allowed), decodes MAVLink 2 frames, feeds the [`MissionServer`], answers the last
//! peer heard, sends a HEARTBEAT at 1 Hz, and injects seeded transport faults: loss per
//! direction (`up` is ground to vehicle), duplication, reordering and delay. With a
//! [`FlightConfig`] it also flies: a [`SimVehicle`] beside the server answers commands, flies the
//! stored mission in simulated time (`speedup` x wall time) and streams its telemetry (and its
//! heartbeat, and as ArduPilot its fence status from the server's fence check) through the same
//! faulty outbox. Without one it still answers a request for its
//! home (MAV_CMD_REQUEST_MESSAGE of HOME_POSITION), as every autopilot with a position does.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::{MavHeader, MavlinkReader, MessageData, SigningConfig, SigningData};
use tokio::net::UdpSocket;
use tokio::sync::watch;
use tokio::time::Instant;

use super::server::{MissionServer, ProtocolFaults, ServerConfig, ServerStats};
use super::storage::Home;
use super::vehicle::{FlightConfig, SimVehicle, Snapshot};
use crate::link::mav::{
    MavCmd, MavMessage, MavMissionResult, MavModeFlag, MavResult, MavState, MavType,
    COMMAND_ACK_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, MISSION_ITEM_INT_DATA,
};
use crate::link::Flavour;
use crate::physics::Vehicle;
use crate::rng::Rng;

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
    /// The simulated flight; None: a mission server with a 1 Hz heartbeat and nothing else
    /// (quiet enough for hundreds of mocks in one test).
    pub flight: Option<FlightConfig>,
    /// Simulated seconds per wall second (flight time, telemetry rates, time_boot_ms).
    pub speedup: f64,
    /// Arm and start each newly stored mission as a ground station would.
    pub autostart: bool,
    /// The vehicle's own home (the ArduPilot flavour answers it for item 0).
    pub home: Home,
    /// How long the ArduPilot flavour refuses uploads with MAV_MISSION_NO_SPACE after start
    /// (ArduCopter SITL: about 10 s; 2 s by default so tests see it without waiting long).
    pub boot: Duration,
}

/// Default speed-up: the 8-waypoint sample (about 170 s of flight) flies in under 10 s.
pub const DEFAULT_SPEEDUP: f64 = 20.0;

impl Default for MockConfig {
    fn default() -> Self {
        MockConfig {
            flavour: Flavour::Px4,
            faults: Faults::default(),
            seed: 1,
            system_id: 1,
            component_id: 1,
            signing_key: None,
            flight: None,
            speedup: DEFAULT_SPEEDUP,
            autostart: false,
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
    #[error("mock configuration: {field} {value}: {reason}")]
    Config {
        field: &'static str,
        value: String,
        reason: &'static str,
    },
    #[error("simulated vehicle: {0}")]
    Vehicle(String),
}

#[derive(Debug, Default)]
struct Shared {
    revision: u64,
    mission: Vec<MISSION_ITEM_INT_DATA>,
    fence: Vec<MISSION_ITEM_INT_DATA>,
    rally: Vec<MISSION_ITEM_INT_DATA>,
    stats: ServerStats,
    vehicle: Option<Snapshot>,
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

    /// The stored fence items, as received.
    pub fn fence(&self) -> Vec<MISSION_ITEM_INT_DATA> {
        self.shared
            .lock()
            .map(|s| s.fence.clone())
            .unwrap_or_default()
    }

    /// The stored rally point items, as received.
    pub fn rally(&self) -> Vec<MISSION_ITEM_INT_DATA> {
        self.shared
            .lock()
            .map(|s| s.rally.clone())
            .unwrap_or_default()
    }

    /// What the mission server has done.
    pub fn stats(&self) -> ServerStats {
        self.shared.lock().map(|s| s.stats).unwrap_or_default()
    }

    /// The simulated vehicle's state (None without a flight).
    pub fn vehicle(&self) -> Option<Snapshot> {
        self.shared.lock().ok().and_then(|s| s.vehicle)
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
    /// Binds `listen` and starts the mock on the current tokio runtime; a flight flies the
    /// built-in S1000 (the shipped models/s1000 vehicle).
    pub async fn spawn(listen: &str, config: MockConfig) -> Result<MockHandle, SimError> {
        let vehicle =
            crate::physics::builtin::vehicle().map_err(|e| SimError::Vehicle(e.to_string()))?;
        Self::spawn_with_vehicle(listen, config, vehicle).await
    }

    /// As [`MockAutopilot::spawn`], flying `vehicle`'s physics.
    pub async fn spawn_with_vehicle(
        listen: &str,
        config: MockConfig,
        vehicle: Vehicle,
    ) -> Result<MockHandle, SimError> {
        if !(config.speedup.is_finite() && config.speedup > 0.0 && config.speedup <= 1000.0) {
            return Err(SimError::Config {
                field: "speedup",
                value: config.speedup.to_string(),
                reason: "must be a number above 0 and at most 1000",
            });
        }
        // The vehicle is built once before the mock answers: one it cannot fly (it cannot
        // hover) is refused here with its reason, not left to an autopilot that never speaks.
        sim_vehicle(&config, &vehicle)?;
        let socket = UdpSocket::bind(listen_addr(listen)?).await?;
        let local_addr = socket.local_addr()?;
        let shared = Arc::new(Mutex::new(Shared::default()));
        let (tx, rx) = watch::channel(false);
        let task = tokio::spawn(run(Arc::new(socket), config, vehicle, shared.clone(), rx));
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

/// A mock without a flight answers a request for its home: the ack, then HOME_POSITION at
/// `config.home` (a flying mock answers it from its flight's home).
fn home_answer(config: &MockConfig, from: (u8, u8), message: &MavMessage) -> Vec<MavMessage> {
    let MavMessage::COMMAND_LONG(c) = message else {
        return Vec::new();
    };
    if c.command != MavCmd::MAV_CMD_REQUEST_MESSAGE
        || c.target_system != config.system_id
        || c.param1 != HOME_POSITION_DATA::ID as f32
    {
        return Vec::new();
    }
    let home = config.home;
    vec![
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: c.command,
            result: MavResult::MAV_RESULT_ACCEPTED,
            target_system: from.0,
            target_component: from.1,
            ..Default::default()
        }),
        MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: home.lat_e7,
            longitude: home.lon_e7,
            altitude: (f64::from(home.alt_m) * 1000.0).round() as i32,
            q: [1.0, 0.0, 0.0, 0.0],
            ..Default::default()
        }),
    ]
}

/// The simulated vehicle `config` flies (None when it only serves the mission protocol).
fn sim_vehicle<'v>(
    config: &MockConfig,
    vehicle: &'v Vehicle,
) -> Result<Option<SimVehicle<'v>>, SimError> {
    config
        .flight
        .map(|flight| {
            SimVehicle::new(
                config.flavour,
                vehicle,
                flight,
                (config.system_id, config.component_id),
            )
            .map_err(|e| SimError::Vehicle(format!("the mock cannot fly it: {e}")))
        })
        .transpose()
}

async fn run(
    socket: Arc<UdpSocket>,
    config: MockConfig,
    vehicle: Vehicle,
    shared: Arc<Mutex<Shared>>,
    mut shutdown: watch::Receiver<bool>,
) -> Result<(), SimError> {
    let mut flight = sim_vehicle(&config, &vehicle)?;
    let mut autostarted = 0;
    let mut fence_due_s = 0.0;
    // The rally points the vehicle returns to, handed over whenever a stored list changes.
    let mut rally_revision = None;
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
    let mut rng_up = Rng::new(config.seed ^ 0x005e_ed0f_u64);
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
        rng: Rng::new(config.seed),
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
    // A flying mock steps finely, so that a speed-up spreads its telemetry over wall time as a
    // vehicle would instead of delivering 0.4 s of flight in one burst every 20 ms (a ground
    // station stamps BATTERY_STATUS, which has no time field, by when it arrives).
    let period = if config.flight.is_some() {
        Duration::from_millis(2)
    } else {
        Duration::from_millis(20)
    };
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
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
                    if flight.is_none() {
                        replies.extend(home_answer(&config, from, &message));
                    }
                    if let Some(vehicle) = flight.as_mut().filter(|_| !MissionServer::answers_version_request(&message)) {
                        // Up to date with the clock and the stored mission before it answers.
                        replies.extend(vehicle.step(now.as_secs_f64() * config.speedup));
                        vehicle.set_mission(server.mission(), server.current());
                        replies.extend(vehicle.handle(from, &message));
                    }
                }
                replies
            }
            _ = tick.tick() => {
                let mut out = server.tick(start.elapsed());
                if let Some(vehicle) = flight.as_mut() {
                    vehicle.set_mission(server.mission(), server.current());
                    if rally_revision != Some(server.revision()) {
                        rally_revision = Some(server.revision());
                        vehicle.set_rally_points(&server.rally_points());
                    }
                    let stored = server.stats.uploads_accepted;
                    if config.autostart && stored > autostarted && !server.mission().is_empty() && !vehicle.armed() {
                        autostarted = stored;
                        vehicle.autostart();
                    }
                    out.extend(vehicle.step(start.elapsed().as_secs_f64() * config.speedup));
                    // ArduPilot's extended status stream: FENCE_STATUS at 2 Hz.
                    let snapshot = vehicle.snapshot();
                    if snapshot.time_s >= fence_due_s {
                        fence_due_s = snapshot.time_s + 0.5;
                        let at = [snapshot.position[0], snapshot.position[1]];
                        if let Some(home) = config.flight.map(|f| f.home) {
                            out.extend(server.fence_status((snapshot.time_s * 1e3) as u32, home, at));
                        }
                    }
                }
                out
            }
            _ = beat.tick(), if flight.is_none() => vec![heartbeat.clone()],
        };
        // The mission is copied out only when it changed: not once per message.
        if let Ok(mut s) = shared.lock() {
            if s.revision != server.revision() {
                s.revision = server.revision();
                s.mission = server.mission().to_vec();
                s.fence = server.fence().to_vec();
                s.rally = server.rally().to_vec();
            }
            s.stats = server.stats;
            s.vehicle = flight.as_ref().map(SimVehicle::snapshot);
        }
        if let Some(peer) = peer {
            for message in &replies {
                out.send(peer, message).await?;
            }
        }
    }
}
