//! One module per `emplan` subcommand: argument structs (clap) and the code that runs them.

pub mod battery_sim;
pub mod calibrate;
pub mod calibrate_logs;
pub mod convert;
pub mod download;
pub mod energy;
pub mod flights;
pub mod fly;
pub mod flying;
pub mod generate;
pub mod ledger;
pub mod mock_autopilot;
pub mod pack;
pub mod packs;
pub mod plan;
pub mod plot;
pub mod progress;
pub mod record;
pub mod replay;
pub mod report;
pub mod serve;
pub mod sorties;
pub mod study;
pub mod table;
pub mod tsp;
pub mod upload;

/// Where `fly`, `record` and `serve` make flight directories unless `--log-dir` says (and so
/// where the ledger is by default).
pub const DEFAULT_LOG_DIR: &str = "flights";

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
pub fn setting_error(e: emplan::planner::study::StudyError) -> anyhow::Error {
    match e {
        emplan::planner::study::StudyError::Setting {
            setting,
            value,
            problem,
        } => {
            let option = match setting {
                "waypoints" => "--waypoints",
                "xy_m" => "--xy",
                "z_m" => "--z",
                "missions" => "--missions",
                "blocks" => "--blocks",
                "block_spacing_m" => "--block-spacing",
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
    /// Vehicle directory holding vehicle.toml and its energy tables (default: $EMPLAN_VEHICLE,
    /// else the S1000 built into emplan)
    #[arg(long, value_name = "DIR")]
    pub vehicle: Option<std::path::PathBuf>,
    /// Flight profile pricing the legs: ptf, hvb, px4 or ardupilot (default: the vehicle's, px4
    /// for the shipped S1000; `fly` on a connected autopilot: its own, px4 on PX4 and ardupilot
    /// on ArduPilot)
    #[arg(long)]
    pub profile: Option<emplan::physics::Profile>,
}

/// The variable naming a vehicle directory when `--vehicle` is not given.
pub const VEHICLE_VARIABLE: &str = "EMPLAN_VEHICLE";

impl VehicleArgs {
    /// Where the vehicle comes from, and what chose it (for errors): `--vehicle`, else
    /// `$EMPLAN_VEHICLE`, else the built-in S1000.
    pub fn source(&self) -> (emplan::physics::VehicleSource, String) {
        use emplan::physics::VehicleSource;
        if let Some(dir) = &self.vehicle {
            return (
                VehicleSource::Dir(dir.clone()),
                format!("--vehicle {}", dir.display()),
            );
        }
        match std::env::var_os(VEHICLE_VARIABLE).filter(|v| !v.is_empty()) {
            Some(dir) => {
                let dir = std::path::PathBuf::from(dir);
                let chosen = format!("{VEHICLE_VARIABLE}={}", dir.display());
                (VehicleSource::Dir(dir), chosen)
            }
            None => (VehicleSource::BuiltIn, "the built-in vehicle".into()),
        }
    }

    /// The files of the chosen vehicle directory (vehicle.toml and every profile's table),
    /// inputs an output file must never replace; none for the built-in vehicle.
    pub fn files(&self) -> Vec<std::path::PathBuf> {
        match self.source().0 {
            emplan::physics::VehicleSource::Dir(dir) => vehicle_files(&dir),
            emplan::physics::VehicleSource::BuiltIn => Vec::new(),
        }
    }

    /// The vehicle's parameters; an error names what chose the vehicle.
    pub fn vehicle(&self) -> anyhow::Result<emplan::physics::Vehicle> {
        let (source, chosen) = self.source();
        source
            .vehicle()
            .map_err(|e| vehicle_error(e.into(), &chosen))
    }

    /// The vehicle with the table of the chosen profile; an error names what chose the vehicle.
    pub fn model(&self) -> anyhow::Result<emplan::physics::VehicleModel> {
        let (source, chosen) = self.source();
        emplan::physics::VehicleModel::open(&source, self.profile)
            .map_err(|e| vehicle_error(e.into(), &chosen))
    }
}

/// A vehicle directory's files: vehicle.toml and every profile's table.
pub fn vehicle_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let tables = emplan::physics::Profile::ALL
        .iter()
        .map(|&p| emplan::physics::EnergyTable::path(dir, p));
    std::iter::once(dir.join("vehicle.toml"))
        .chain(tables)
        .collect()
}

pub fn vehicle_error(error: anyhow::Error, chosen: &str) -> anyhow::Error {
    error.context(format!("the vehicle chosen by {chosen}"))
}

/// Options of every command that orders waypoints.
#[derive(Debug, Clone, clap::Args)]
pub struct SolverArgs {
    /// Tour solver: auto (Held-Karp up to 12 waypoints, branch-and-cut up to 500 nodes, the
    /// heuristic beyond), held-karp, branch-cut or heuristic
    #[arg(long, default_value = "auto")]
    pub solver: emplan::tour::solver::Solver,
    /// Wall-clock budget of the command's solves together (s); a solve cut short reports its
    /// best tour and a proven lower bound
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
    pub fn options(&self) -> anyhow::Result<emplan::tour::solver::Options> {
        if !(self.time_limit.is_finite() && self.time_limit >= 0.0) {
            anyhow::bail!(
                "--time-limit {}: expected a non-negative number of seconds",
                self.time_limit
            );
        }
        Ok(emplan::tour::solver::Options {
            solver: self.solver,
            time_limit: std::time::Duration::from_secs_f64(self.time_limit.min(1e9)),
            seed: self.seed,
            kicks: self.kicks,
        })
    }
}

/// Which visiting order to fly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OrderArg {
    /// The minimum-energy order
    Energy,
    /// The minimum-distance order, in its cheaper direction
    Distance,
    /// The order the mission file lists
    Listed,
}

impl From<OrderArg> for emplan::planner::FlownOrder {
    fn from(order: OrderArg) -> Self {
        match order {
            OrderArg::Energy => emplan::planner::FlownOrder::Energy,
            OrderArg::Distance => emplan::planner::FlownOrder::Distance,
            OrderArg::Listed => emplan::planner::FlownOrder::Listed,
        }
    }
}

/// Where a flight is planned from (`--origin`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OriginArg {
    /// The mission's origin; the vehicle's home must be within 20 m of it
    Mission,
    /// The vehicle's home, learned over the link: the mission re-planned from where it stands
    Vehicle,
}

/// What to fly of a mission, and the checks before it goes to the vehicle (`upload`, `fly`).
#[derive(Debug, clap::Args)]
pub struct FlightArgs {
    /// Plan from the mission's origin (default; refused when the vehicle's home is farther
    /// than 20 m from it, or when the vehicle does not say where it is unless `mission` is
    /// given explicitly) or from the vehicle's home (the mission's waypoints re-planned from
    /// where the vehicle stands, the battery checked again)
    #[arg(long, value_enum, value_name = "mission|vehicle")]
    pub origin: Option<OriginArg>,
    #[arg(long, value_enum, default_value = "energy")]
    pub order: OrderArg,
    /// Fly only sortie K (1-based) of the split `emplan plan --sorties` prints: the mission
    /// flown on one battery of several, in its own minimum-energy order
    #[arg(long, value_name = "K", conflicts_with = "order")]
    pub sortie: Option<usize>,
    #[command(flatten)]
    pub model: VehicleArgs,
    /// Go ahead even when the model says the battery cannot fly the mission with its reserve
    #[arg(long)]
    pub allow_infeasible: bool,
    /// Waypoint acceptance radius sent as param2 (m)
    #[arg(long, default_value_t = 2.0)]
    pub acceptance_radius_m: f32,
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Price the flight in a steady wind, SPEED@FROM_DEG: m/s and the direction it blows from,
    /// degrees clockwise from north (6@270: 6 m/s from the west); the order, the battery check,
    /// the guard and the report's predictions are in it. Default still air
    /// `fly` only: `live` reads the vehicle's own wind estimate after connecting (PX4's
    /// WIND_COV, ArduPilot's WIND) and plans in it (still air, with a warning, when it sends
    /// none within 10 s)
    #[arg(long, value_name = "SPEED@FROM_DEG|live", allow_hyphen_values = true)]
    pub wind: Option<WindArg>,
    #[command(flatten)]
    pub pack: pack::PackArgs,
    /// The pack named and what the ledger taught of it, read before planning
    /// ([`FlightArgs::learn`]): the vehicle is planned on it.
    #[arg(skip)]
    pub on_pack: Option<pack::Pack>,
    /// plan.json's pack and the guard's start, from `on_pack`.
    #[arg(skip)]
    pack_used: Option<emplan::flightlog::flight_plan::PackUse>,
    #[arg(skip)]
    guard_start: Option<emplan::flightlog::guard::GuardStart>,
    /// The ledger learned from (`--ledger`, else the log directory's).
    #[arg(skip)]
    ledger: Option<emplan::ledger::LedgerSpec>,
}

/// `--wind`: a steady wind given, or (`live`) the vehicle's own estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WindArg {
    Steady(emplan::physics::Wind),
    Live,
}

impl std::str::FromStr for WindArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.trim().eq_ignore_ascii_case("live") {
            return Ok(WindArg::Live);
        }
        s.parse()
            .map(WindArg::Steady)
            .map_err(|e| format!("{e}, or live"))
    }
}

/// How long `--wind live` waits for the vehicle's wind estimate (PX4 streams WIND_COV at
/// 0.5-1 Hz, ArduPilot WIND at its stream rate).
pub const LIVE_WIND_WAIT: std::time::Duration = std::time::Duration::from_secs(10);

/// A planner refusal in the words of the command line (`--sortie 3: ...`, how to override an
/// over-budget flight).
pub fn flight_error(e: emplan::planner::PlannerError) -> anyhow::Error {
    use emplan::planner::PlannerError;
    match e {
        PlannerError::NoSuchSortie { sortie, count } => anyhow::anyhow!(
            "--sortie {sortie}: the mission splits into {count} sorties (1 to {count})"
        ),
        refused @ PlannerError::OverBudget { .. } => anyhow::anyhow!(
            "{refused}: not uploaded (split it with `emplan plan --sorties` and upload one with --sortie K, or pass --allow-infeasible to override)"
        ),
        other => other.into(),
    }
}

impl FlightArgs {
    /// The vehicle with the chosen profile's table, in the `--wind` given (still air without).
    pub fn vehicle_model(&self) -> anyhow::Result<emplan::physics::VehicleModel> {
        let wind = match self.wind {
            Some(WindArg::Steady(w)) => w,
            // Planned once the vehicle has said its wind (`live_wind`).
            Some(WindArg::Live) | None => emplan::physics::Wind::CALM,
        };
        Ok(self.model.model()?.with_wind(wind))
    }

    /// Reads what the ledger knows of the pack named (`--pack`; `log_dir`'s ledger unless
    /// `--ledger`), before anything is planned.
    pub fn learn(&mut self, log_dir: &std::path::Path) -> anyhow::Result<()> {
        let vehicle = self.model.vehicle()?;
        self.on_pack = self.pack.learned(log_dir, &vehicle.name)?;
        self.ledger = Some(self.pack.spec(log_dir));
        self.pack_used = self.on_pack.as_ref().map(pack::Pack::used);
        self.guard_start = (self.on_pack.as_ref()).and_then(|p| p.learned.guard_start());
        Ok(())
    }

    /// Whether the wind is read from the vehicle (`--wind live`).
    pub fn live_wind(&self) -> bool {
        self.wind == Some(WindArg::Live)
    }

    /// With `--wind live`: `model` in the vehicle's own wind estimate, read over `session`
    /// (still air, with a warning, when it sends none); else `model` as it is.
    pub async fn in_live_wind(
        &self,
        session: &emplan::session::Session,
        model: emplan::physics::VehicleModel,
    ) -> anyhow::Result<emplan::physics::VehicleModel> {
        if !self.live_wind() {
            return Ok(model);
        }
        let heard =
            emplan::link::commands::listen_wind(&session.link, &session.target, LIVE_WIND_WAIT)
                .await?;
        match heard {
            Some(w) => {
                // Said even with --json (on stderr): the plan depends on it.
                eprintln!(
                    "wind from the vehicle: {:.1} m/s from {:.0} deg: planning in it",
                    w.speed_m_s, w.from_deg
                );
                Ok(model.with_wind(w))
            }
            None => {
                eprintln!(
                    "warning: --wind live: the vehicle sent no wind estimate (WIND_COV or WIND) within {} s (PX4 estimates wind only with EKF2 drag fusion, ArduPilot with EK3 drag): planning in still air",
                    LIVE_WIND_WAIT.as_secs()
                );
                Ok(model)
            }
        }
    }

    /// The library's choice of what to fly.
    pub fn choice(&self) -> emplan::planner::FlightChoice {
        emplan::planner::FlightChoice {
            order: self.order.into(),
            sortie: self.sortie,
            allow_infeasible: self.allow_infeasible,
        }
    }

    /// Plans what the command flies (see [`emplan::planner::FlightChoice`]).
    pub fn plan(
        &self,
        mission: &emplan::mission::Mission,
    ) -> anyhow::Result<(emplan::physics::VehicleModel, emplan::planner::Plan)> {
        let model = self.vehicle_model()?;
        let plan = self.plan_with(mission, &model)?;
        Ok((model, plan))
    }

    /// Plans `mission` with `model` (the vehicle chosen once, before a re-planning from the
    /// vehicle's home), its battery on the pack named ([`FlightArgs::learn`]).
    pub fn plan_with(
        &self,
        mission: &emplan::mission::Mission,
        model: &emplan::physics::VehicleModel,
    ) -> anyhow::Result<emplan::planner::Plan> {
        let (choice, solver) = (self.choice(), self.solver.options()?);
        // The battery check (and a split into sorties) on the pack named, as the ledger
        // learned it; everything else on the vehicle file's.
        let on_pack = self
            .on_pack
            .as_ref()
            .map(|p| emplan::physics::VehicleModel {
                vehicle: p.learned.on_pack(&model.vehicle),
                ..model.clone()
            });
        let model = on_pack.as_ref().unwrap_or(model);
        Ok(progress::solving(
            &format!("planning {}", mission.name),
            || choice.plan(mission, model, solver),
        )?)
    }

    /// The origin asked for (None: not asked, the mission's).
    pub fn plan_origin(&self) -> Option<emplan::session::PlanOrigin> {
        self.origin.map(|o| match o {
            OriginArg::Mission => emplan::session::PlanOrigin::Mission,
            OriginArg::Vehicle => emplan::session::PlanOrigin::Vehicle,
        })
    }

    /// Whether the flight is planned from the vehicle's home (`--origin vehicle`).
    pub fn plans_from_vehicle(&self) -> bool {
        self.origin == Some(OriginArg::Vehicle)
    }

    /// The flight chosen (`--sortie K` or the order), refused when the battery cannot fly it
    /// with its reserve unless `--allow-infeasible`.
    pub fn flight<'a>(
        &self,
        plan: &'a emplan::planner::Plan,
    ) -> anyhow::Result<emplan::planner::Flight<'a>> {
        self.choice().flight(plan).map_err(flight_error)
    }
}

/// Going through a running `emplan serve` instead of opening a link (`upload`, `fly`): two
/// processes must not fight over one radio.
#[derive(Debug, clap::Args)]
pub struct ServiceArgs {
    /// Go through the service at this URL (http://HOST:PORT, what `emplan serve` prints): the
    /// mission file must be in its missions folder; same output and exit codes
    #[arg(long, value_name = "URL", conflicts_with = "connect")]
    pub service: Option<String>,
    /// File holding the service's token (default: the EMPLAN_TOKEN environment variable, then
    /// flights/token, where `emplan serve` creates it by default)
    #[arg(long, value_name = "FILE", requires = "service")]
    pub token_file: Option<std::path::PathBuf>,
}

impl ServiceArgs {
    /// The client of the service, when one was given, with its token.
    pub fn client(&self) -> anyhow::Result<Option<emplan::service::Client>> {
        let Some(url) = &self.service else {
            return Ok(None);
        };
        let token = emplan::service::client::find_token(self.token_file.as_deref())?;
        Ok(Some(emplan::service::Client::new(url, token)?))
    }
}

impl FlightArgs {
    /// What goes onto the vehicle: `flight` of `plan` (of `mission`), planned with `vehicle`.
    pub fn load<'a>(
        &'a self,
        mission: &'a emplan::mission::Mission,
        plan: &'a emplan::planner::Plan,
        flight: &'a emplan::planner::Flight<'a>,
        vehicle: &'a emplan::physics::Vehicle,
    ) -> emplan::session::Load<'a> {
        emplan::session::Load {
            mission,
            plan,
            flight,
            acceptance_radius_m: self.acceptance_radius_m,
            vehicle,
            resumes: None,
            guard: emplan::flightlog::watch::Policy::Off,
            if_home_unknown: emplan::session::IfHomeUnknown::asked(self.plan_origin()),
            live_wind: None,
            pack: self.pack_used.as_ref(),
            guard_start: self.guard_start.as_ref(),
            ledger: self.ledger.as_ref(),
        }
    }

    /// The model and, from the mission's origin, the plan, made before connecting (a refusal
    /// needs no vehicle); with `--origin vehicle` the plan waits for the vehicle to say where
    /// its home is ([`FlightArgs::planned_at`]).
    pub fn plan_first(
        &self,
        mission: &emplan::mission::Mission,
    ) -> anyhow::Result<(emplan::physics::VehicleModel, Option<emplan::planner::Plan>)> {
        if self.plans_from_vehicle() || self.live_wind() {
            return Ok((self.vehicle_model()?, None));
        }
        let (model, plan) = self.plan(mission)?;
        self.flight(&plan)?;
        Ok((model, Some(plan)))
    }

    /// The mission and plan to fly: `planned`, planned from the mission's origin before
    /// connecting, or (`planned` None) planned now: with `--origin vehicle` re-planned by the
    /// session from the vehicle's home (said on stderr unless `quiet`); with `--wind live` alone
    /// from its own origin.
    pub async fn planned_at(
        &self,
        session: &emplan::session::Session,
        mission: emplan::mission::Mission,
        planned: Option<emplan::planner::Plan>,
        model: &emplan::physics::VehicleModel,
        quiet: bool,
    ) -> anyhow::Result<(emplan::mission::Mission, emplan::planner::Plan)> {
        match planned {
            Some(plan) => Ok((mission, plan)),
            None if self.plans_from_vehicle() => {
                let origin = mission.origin.home;
                let replanned = emplan::session::replan_from_vehicle(
                    &session.link,
                    &session.target,
                    &mission,
                    |rehomed, moved| {
                        if !quiet {
                            eprintln!(
                                "origin moved to the vehicle's home ({:.6}, {:.6}), {:.0} m from the mission's ({:.6}, {:.6})",
                                moved.home.lat_deg,
                                moved.home.lon_deg,
                                moved.offset.horizontal_m,
                                origin.lat_deg,
                                origin.lon_deg
                            );
                        }
                        std::future::ready(self.plan_with(rehomed, model))
                    },
                )
                .await
                .map_err(|e| match e {
                    emplan::session::ReplanError::Home(e) => {
                        anyhow::Error::new(emplan::session::FlyError::from(e))
                    }
                    emplan::session::ReplanError::Plan(e) => e,
                })?;
                self.flight(&replanned.plan)?;
                Ok((replanned.mission, replanned.plan))
            }
            None => {
                // `--wind live` alone: planned from the mission's origin, in the wind heard.
                let plan = self.plan_with(&mission, model)?;
                self.flight(&plan)?;
                Ok((mission, plan))
            }
        }
    }

    /// The upload request a service gets for these options.
    pub fn service_request(&self) -> anyhow::Result<emplan::service::wire::UploadRequest> {
        Ok(emplan::service::wire::UploadRequest {
            origin: self.plan_origin(),
            pack: self.pack.name()?,
            ..emplan::service::wire::UploadRequest::new(
                &self.choice(),
                self.acceptance_radius_m,
                self.model.profile,
                &self.solver.options()?,
            )
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

/// Seconds from the command line as a duration: finite, positive and at most a year.
pub fn seconds(flag: &str, value: f64) -> anyhow::Result<std::time::Duration> {
    if !(value.is_finite() && value > 0.0 && value <= 3.2e7) {
        anyhow::bail!("--{flag} {value}: expected a positive number of seconds");
    }
    Ok(std::time::Duration::from_secs_f64(value))
}

impl LinkArgs {
    /// Opens the session (see [`emplan::session::open`]): `--connect`, else the built-in mock
    /// (a default one, PX4 flavour).
    pub async fn open(&self) -> anyhow::Result<emplan::session::Session> {
        self.open_with(None).await
    }

    /// As [`LinkArgs::open`], the built-in mock (when no `--connect` is given) standing at
    /// `home` (a mission's origin: the mock is where the mission starts), its autopilot
    /// holding `vehicle`'s trajectory parameters (what the session's load checks).
    pub async fn open_at(
        &self,
        home: emplan::mission::Geodetic,
        vehicle: &emplan::physics::Vehicle,
    ) -> anyhow::Result<emplan::session::Session> {
        if self.connect.is_some() {
            return self.open().await;
        }
        let config = emplan::sim::MockConfig {
            home: emplan::sim::storage::Home {
                lat_e7: emplan::link::items::deg_e7(home.lat_deg),
                lon_e7: emplan::link::items::deg_e7(home.lon_deg),
                alt_m: home.alt_m as f32,
            },
            // Standing at its home, unarmed: its parameter server answers, as an autopilot's.
            flight: Some(emplan::sim::FlightConfig {
                home,
                ..Default::default()
            }),
            ..Default::default()
        };
        self.open_target(Some((config, vehicle.clone())), None)
            .await
    }

    /// As [`LinkArgs::open`], the built-in mock (when no `--connect` is given) started as
    /// `mock` says.
    pub async fn open_with(
        &self,
        mock: Option<emplan::session::MockFlight>,
    ) -> anyhow::Result<emplan::session::Session> {
        self.open_target(None, mock).await
    }

    /// Opens `--connect`, else the built-in mock: flying as `mock` says, else as `quiet` says
    /// with its vehicle (default: a quiet mock of the default configuration).
    async fn open_target(
        &self,
        quiet: Option<(emplan::sim::MockConfig, emplan::physics::Vehicle)>,
        mock: Option<emplan::session::MockFlight>,
    ) -> anyhow::Result<emplan::session::Session> {
        use emplan::session::{LinkOptions, Target};
        if let Some(url) = &self.connect {
            // Before any waiting: a URL of no known form, or a serial device that is not there.
            emplan::link::connection::check_url(url)
                .map_err(|e| anyhow::Error::new(e).context("--connect"))?;
        }
        let options = LinkOptions {
            discover: seconds("discover-s", self.discover_s)?,
            transfer_budget: self.budget_s.map(|b| seconds("budget-s", b)).transpose()?,
        };
        let signing_key = match &self.signing_key {
            Some(path) => Some(emplan::link::read_signing_key(path)?),
            None => None,
        };
        let target = match (&self.connect, mock) {
            (Some(url), _) => Target::Connect {
                url: url.clone(),
                signing_key,
            },
            (None, Some(mock)) => emplan::session::MockFlight {
                signing_key,
                ..mock
            }
            .target(),
            (None, None) => {
                let (config, vehicle) = match quiet {
                    Some((config, vehicle)) => (config, Some(Box::new(vehicle))),
                    None => (Default::default(), None),
                };
                Target::Mock {
                    config: Box::new(emplan::sim::MockConfig {
                        signing_key,
                        ..config
                    }),
                    vehicle,
                }
            }
        };
        Ok(emplan::session::open(target, &options).await?)
    }
}
