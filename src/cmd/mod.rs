//! One module per `emplan` subcommand: argument structs (clap) and the code that runs them.

pub mod calibrate;
pub mod convert;
pub mod download;
pub mod energy;
pub mod generate;
pub mod mock_autopilot;
pub mod plan;
pub mod plot;
pub mod sorties;
pub mod study;
pub mod table;
pub mod tsp;
pub mod upload;

/// The tokio runtime of every command that talks to an autopilot: one thread, so the link's
/// receive task hands each message to the transfer without a cross-thread wake-up (measured:
/// the 500-item upload bench), timers and sockets enabled. Blocking work (the flight log's
/// file writes) runs on threads of its own.
pub fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?)
}

/// A study or generator setting refused by the library, in the words of the command line
/// (`--xy 60: ...`).
pub fn setting_error(e: emplan::plan::study::StudyError) -> anyhow::Error {
    match e {
        emplan::plan::study::StudyError::Setting {
            setting,
            value,
            problem,
        } => {
            let option = match setting {
                "waypoints" => "--waypoints",
                "xy_m" => "--xy",
                "z_m" => "--z",
                "missions" => "--missions",
                "lat_deg" => "--origin-lat",
                "lon_deg" => "--origin-lon",
                "home_alt_amsl_m" => "--home-alt-amsl",
                "hover_s" => "--hover-s",
                _ => "a setting",
            };
            anyhow::anyhow!("{option} {value}: {problem}")
        }
        other => other.into(),
    }
}

/// Options of every command that prices legs with a vehicle model.
#[derive(Debug, Clone, clap::Args)]
pub struct VehicleArgs {
    /// Vehicle directory holding vehicle.toml and its energy tables
    #[arg(long, default_value = "models/s1000")]
    pub vehicle: std::path::PathBuf,
    /// Flight profile pricing the legs: ptf, hvb or px4 (default: the vehicle's, px4 for the
    /// shipped S1000 since that is what an uploaded mission flies)
    #[arg(long)]
    pub profile: Option<emplan::physics::Profile>,
}

/// Options of every command that orders waypoints.
#[derive(Debug, Clone, clap::Args)]
pub struct SolverArgs {
    /// Tour solver: auto (Held-Karp up to 12 waypoints, branch-and-cut up to 500 nodes, the
    /// heuristic beyond), held-karp, branch-cut or heuristic
    #[arg(long, default_value = "auto")]
    pub solver: emplan::plan::solver::Solver,
    /// Wall-clock budget per tour solve (s); a solve cut short reports its best tour and a
    /// proven lower bound
    #[arg(long, default_value_t = 60.0)]
    pub time_limit: f64,
    /// Seed of the heuristic (same seed and kick budget: same tour)
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Kick budget of the heuristic (default: grows with the size)
    #[arg(long)]
    pub kicks: Option<u64>,
}

impl SolverArgs {
    /// The library's solver options.
    pub fn options(&self) -> anyhow::Result<emplan::plan::solver::Options> {
        if !(self.time_limit.is_finite() && self.time_limit >= 0.0) {
            anyhow::bail!(
                "--time-limit {}: expected a non-negative number of seconds",
                self.time_limit
            );
        }
        Ok(emplan::plan::solver::Options {
            solver: self.solver,
            time_limit: std::time::Duration::from_secs_f64(self.time_limit.min(1e9)),
            seed: self.seed,
            kicks: self.kicks,
        })
    }
}

/// Options of every command that talks to an autopilot.
#[derive(Debug, clap::Args)]
pub struct LinkArgs {
    /// MAVLink connection: udpin:HOST:PORT, udpout:HOST:PORT, tcpin:, tcpout:, serial:DEV:BAUD.
    /// Without it, emplan starts its built-in mock autopilot (PX4 flavour) on loopback and
    /// talks to that
    #[arg(long)]
    pub connect: Option<String>,
    /// Time allowed for the whole transfer, upload and read-back (s). Resends adapt to the
    /// measured round trip, so only a very slow or lossy radio needs more than the default
    /// (30 s plus two of the autopilot's re-request periods per item: 0.5 s for PX4, 2 s for
    /// ArduPilot)
    #[arg(long)]
    pub budget_s: Option<f64>,
    /// Seconds to wait for the autopilot (its port to open, then its heartbeat)
    #[arg(long, default_value_t = 10.0)]
    pub discover_s: f64,
    /// MAVLink 2 signing key file (32 raw bytes or 64 hex characters)
    #[arg(long)]
    pub signing_key: Option<std::path::PathBuf>,
}

/// An open link to the autopilot (and the built-in mock, when that is the autopilot).
pub struct Opened {
    pub link: emplan::link::connection::Link,
    pub target: emplan::link::connection::Autopilot,
    pub config: emplan::link::transfer::TransferConfig,
    /// Where the autopilot is, for messages.
    pub describe: String,
    /// Kept alive as long as the link; dropped (and stopped) with it.
    pub _mock: Option<emplan::sim::MockHandle>,
}

/// Seconds from the command line as a duration: finite, positive and at most a year.
fn seconds(flag: &str, value: f64) -> anyhow::Result<std::time::Duration> {
    if !(value.is_finite() && value > 0.0 && value <= 3.2e7) {
        anyhow::bail!("--{flag} {value}: expected a positive number of seconds");
    }
    Ok(std::time::Duration::from_secs_f64(value))
}

impl LinkArgs {
    /// Connects (starting the built-in mock when no `--connect` is given), discovers the
    /// autopilot and returns the link with the transfer settings.
    pub async fn open(&self) -> anyhow::Result<Opened> {
        let patience = seconds("discover-s", self.discover_s)?;
        let budget = self.budget_s.map(|b| seconds("budget-s", b)).transpose()?;
        let signing_key = match &self.signing_key {
            Some(path) => Some(emplan::link::read_signing_key(path)?),
            None => None,
        };
        let (url, describe, mock) = match &self.connect {
            Some(url) => (url.clone(), url.clone(), None),
            None => {
                let mock = emplan::sim::MockAutopilot::spawn(
                    "udpin:127.0.0.1:0",
                    emplan::sim::MockConfig {
                        signing_key,
                        ..Default::default()
                    },
                )
                .await?;
                let url = format!("udpout:{}", mock.local_addr());
                let describe = format!("the built-in mock autopilot ({url}; no --connect given)");
                (url, describe, Some(mock))
            }
        };
        let signing = signing_key.map(|key| mavlink::SigningConfig::new(key, 0, true, false));
        let link = emplan::link::connection::Link::connect_within(
            &url,
            Default::default(),
            signing,
            patience,
        )
        .await?;
        let target = link.discover(patience).await?;
        let config = emplan::link::transfer::TransferConfig {
            target_system: target.system_id,
            target_component: target.component_id,
            flavour: target.flavour,
            timing: Default::default(),
            budget,
        };
        Ok(Opened {
            link,
            target,
            config,
            describe,
            _mock: mock,
        })
    }
}
