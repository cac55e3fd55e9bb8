//! A session with one vehicle: [`open`] starts the built-in mock autopilot or connects to the
//! URL given, waits for the autopilot within the discovery time and keeps what every exchange
//! with it needs (the link, the autopilot found, the transfer settings: [`transfer_config`],
//! the one place they are built). [`Session::load`] puts a flight on the vehicle (the home
//! check, the autopilot's parameter check, the verified upload); [`Session::fly`] flies it:
//! that load, the start, the recorder's report ([`super::fly`]). `emplan upload` and `emplan
//! fly` are this; the service's vehicle actor, which keeps its link all day, opens it with
//! [`connect_until_open`] and loads flights with the same [`super::load`].

use std::time::Duration;

use super::fly::{fly, Flown, FlyError, FlyOptions, Load, Loaded};
use super::params::ParamCheck;
use super::recorder::{spawn_recorder, FlightEvent, RecorderConfig, RecorderHandle};
use crate::link::connection::{Autopilot, Identity, Link};
use crate::link::mav::MISSION_ITEM_INT_DATA;
use crate::link::transfer::TransferConfig;
use crate::link::LinkError;
use crate::physics::Vehicle;
use crate::sim::{MockAutopilot, MockConfig, MockHandle, SimError};

/// The vehicle a session talks to.
#[derive(Debug, Clone)]
pub enum Target {
    /// A MAVLink connection URL (`udpin:`, `udpout:`, `tcpin:`, `tcpout:`, `serial:DEV:BAUD`).
    Connect {
        url: String,
        signing_key: Option<[u8; 32]>,
    },
    /// The built-in mock autopilot on loopback, configured by `config` (`config.flight` makes
    /// it fly; its signing key is the link's), flying `vehicle`'s physics (None: the built-in
    /// S1000).
    Mock {
        config: Box<MockConfig>,
        vehicle: Option<Box<Vehicle>>,
    },
}

/// How a session is opened.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkOptions {
    /// Time allowed for the transport to open, then again for the autopilot's heartbeat.
    pub discover: Duration,
    /// Time allowed for one transfer (None: the default for its item count).
    pub transfer_budget: Option<Duration>,
}

impl Default for LinkOptions {
    fn default() -> Self {
        LinkOptions {
            discover: Duration::from_secs(10),
            transfer_budget: None,
        }
    }
}

/// Why a session did not open.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The link did not open, or no autopilot answered in time.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The built-in mock autopilot did not start (its configuration, its socket).
    #[error(transparent)]
    Mock(#[from] SimError),
}

/// An open link to an autopilot (and the built-in mock, when that is the autopilot).
pub struct Session {
    pub link: Link,
    pub target: Autopilot,
    pub transfer: TransferConfig,
    /// Where the autopilot is, for messages.
    pub describe: String,
    /// Kept alive as long as the link; dropped (and stopped) with it.
    mock: Option<MockHandle>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("target", &self.target)
            .field("describe", &self.describe)
            .finish()
    }
}

/// Starts the built-in mock or connects, and waits for the autopilot's heartbeat.
pub async fn open(target: Target, options: &LinkOptions) -> Result<Session, OpenError> {
    let (url, describe, signing_key, mock) = match target {
        Target::Connect { url, signing_key } => (url.clone(), url, signing_key, None),
        Target::Mock { config, vehicle } => {
            let signing_key = config.signing_key;
            let mock = match vehicle {
                Some(vehicle) => {
                    MockAutopilot::spawn_with_vehicle("udpin:127.0.0.1:0", *config, *vehicle)
                        .await?
                }
                None => MockAutopilot::spawn("udpin:127.0.0.1:0", *config).await?,
            };
            let url = format!("udpout:{}", mock.local_addr());
            let describe = format!("the built-in mock autopilot ({url}; no --connect given)");
            (url, describe, signing_key, Some(mock))
        }
    };
    let signing = signing_key.map(crate::link::signing_config);
    let link = Link::connect_within(&url, Identity::default(), signing, options.discover).await?;
    let target = link.discover(options.discover).await?;
    let transfer = transfer_config(&target, options.transfer_budget);
    Ok(Session {
        link,
        target,
        transfer,
        describe,
        mock,
    })
}

/// The settings of every transfer with `target`: its ids and flavour, the default timing, and
/// `budget` for the whole transfer (None: the default for its item count).
pub fn transfer_config(target: &Autopilot, budget: Option<Duration>) -> TransferConfig {
    TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        flavour: target.flavour,
        timing: Default::default(),
        budget,
    }
}

/// How long one attempt of [`connect_until_open`] may take, and the pause after a failed one.
const CONNECT_ATTEMPT: Duration = Duration::from_secs(2);
const CONNECT_PAUSE: Duration = Duration::from_secs(1);

/// Opens the link to `url` and keeps trying until it opens (a serial device plugged in later,
/// a TCP port opened later), telling `failed` of every failed attempt: the link of a process
/// that holds it all day (`emplan serve`), which waits for the autopilot's heartbeat itself.
/// Never returns an error; a caller that may stop selects on it.
pub async fn connect_until_open(
    url: &str,
    signing_key: Option<[u8; 32]>,
    mut failed: impl FnMut(&LinkError),
) -> Link {
    let signing = signing_key.map(crate::link::signing_config);
    loop {
        match Link::connect_within(url, Identity::default(), signing.clone(), CONNECT_ATTEMPT).await
        {
            Ok(link) => return link,
            Err(e) => {
                failed(&e);
                tokio::time::sleep(CONNECT_PAUSE).await;
            }
        }
    }
}

impl Session {
    /// The autopilot is emplan's built-in mock (it has no pilot: its missions are started by
    /// emplan).
    pub fn builtin(&self) -> bool {
        self.mock.is_some()
    }

    /// The items `load` sends to this autopilot (see [`super::fly::items`]).
    pub fn items(&self, load: &Load<'_>) -> Result<Vec<MISSION_ITEM_INT_DATA>, FlyError> {
        super::fly::items(self.target.flavour, load)
    }

    /// Puts `load` onto the vehicle (see [`super::load`]: the home check, the autopilot's
    /// parameter check, the verified upload), handing `recorder`, when there is one, what the
    /// next flight is measured against; `checked` sees the parameter check before anything is
    /// sent, `progress` the items sent (done, total).
    pub async fn load(
        &self,
        recorder: Option<&RecorderHandle>,
        load: &Load<'_>,
        checked: impl FnOnce(Option<&ParamCheck>),
        progress: impl FnMut(usize, usize),
    ) -> Result<Loaded, FlyError> {
        super::fly::load(
            &self.link,
            &self.target,
            self.transfer,
            recorder,
            load,
            checked,
            progress,
        )
        .await
    }

    /// The flight recorder on this session's link (one directory per flight under
    /// `config`'s log directory).
    pub fn recorder(&self, config: RecorderConfig) -> RecorderHandle {
        spawn_recorder(&self.link, config)
    }

    /// Flies `load` (see [`super::fly`]), recorded by `recorder` (from [`Session::recorder`]).
    pub async fn fly(
        &self,
        recorder: &RecorderHandle,
        load: &Load<'_>,
        options: &FlyOptions,
        checked: impl FnOnce(Option<&ParamCheck>),
        on_event: impl FnMut(&FlightEvent),
    ) -> Result<Flown, FlyError> {
        fly(
            &self.link,
            &self.target,
            self.transfer,
            recorder,
            load,
            options,
            checked,
            on_event,
        )
        .await
    }

    /// Stops the link and the built-in mock.
    pub async fn close(mut self) {
        let mock = self.mock.take();
        drop(self);
        if let Some(mock) = mock {
            let _ = mock.shutdown().await;
        }
    }
}

/// The built-in mock as `emplan fly` starts it for one mission: flying from the mission's home
/// with the plan's profile, `truth`'s physics and battery (the vehicle measured against), its
/// PX4 holding `params` (NAME, value) instead of `truth`'s `[px4]` values, datagrams lost with
/// probability `loss` each way.
#[derive(Debug, Clone)]
pub struct MockFlight {
    pub home: crate::mission::Geodetic,
    pub profile: crate::physics::Profile,
    pub truth: Vehicle,
    pub params: Vec<(String, f64)>,
    pub speedup: f64,
    pub seed: u64,
    pub loss: f64,
    pub signing_key: Option<[u8; 32]>,
    /// The wind it flies in and reports (None: still air, no wind estimate).
    pub wind: Option<crate::physics::Wind>,
    /// A change of that wind in flight.
    pub wind_change: Option<crate::sim::WindChange>,
    /// The serial number its smart battery gives (SMART_BATTERY_INFO); None: no smart battery.
    pub pack_serial: Option<u32>,
}

impl MockFlight {
    /// The session target that starts this mock.
    pub fn target(self) -> Target {
        let mut vehicle = self.truth;
        vehicle.px4 = vehicle.px4.with_autopilot_values(&self.params);
        let config = MockConfig {
            flight: Some(crate::sim::FlightConfig {
                profile: Some(self.profile),
                home: self.home,
                seed: self.seed,
                wind: self.wind,
                wind_change: self.wind_change,
                pack_serial: self.pack_serial,
                ..Default::default()
            }),
            speedup: self.speedup,
            seed: self.seed,
            faults: crate::sim::Faults {
                loss_up: self.loss,
                loss_down: self.loss,
                ..Default::default()
            },
            signing_key: self.signing_key,
            ..Default::default()
        };
        Target::Mock {
            config: Box::new(config),
            vehicle: Some(Box::new(vehicle)),
        }
    }
}
