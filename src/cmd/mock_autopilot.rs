//! `emplan mock-autopilot`: run the built-in mock autopilot until Ctrl-C. It flies: arm and
//! MAV_CMD_MISSION_START (or `--autostart`) fly the stored mission in simulated time.

use std::process::ExitCode;

use anyhow::anyhow;
use emplan::link::Flavour;
use emplan::sim::{
    Faults, FlightConfig, Gap, Home, MockAutopilot, MockConfig, TelemetryFaults, DEFAULT_SPEEDUP,
};

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FlavourArg {
    /// PX4: atomic uploads, requests every 250 ms, gives up after 5 s, _INT frames on read-back
    Px4,
    /// ArduPilot: item 0 is its home, unused parameters stored as 0, NO_SPACE while booting
    Ardupilot,
    /// MAVSDK's MissionRawServer: keeps items as received, gives up after 5 tries
    Generic,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to listen: udpin:HOST:PORT
    #[arg(long, default_value = "udpin:127.0.0.1:14550")]
    listen: String,
    #[arg(long, value_enum, default_value = "px4")]
    flavour: FlavourArg,
    /// Probability a datagram from the ground is lost
    #[arg(long, default_value_t = 0.0)]
    loss_up: f64,
    /// Probability a datagram to the ground is lost
    #[arg(long, default_value_t = 0.0)]
    loss_down: f64,
    /// Probability a datagram to the ground is duplicated
    #[arg(long, default_value_t = 0.0)]
    duplicate: f64,
    /// Probability a datagram to the ground is held back behind the next one
    #[arg(long, default_value_t = 0.0)]
    reorder: f64,
    /// Delay added to every datagram to the ground (ms)
    #[arg(long, default_value_t = 0)]
    delay_ms: u64,
    /// NACK the upload when this item arrives
    #[arg(long)]
    nack_item: Option<u16>,
    /// The MAV_MISSION_RESULT of that NACK (name or number; default MAV_MISSION_ERROR)
    #[arg(long)]
    nack: Option<String>,
    /// Never send the final ACCEPTED ack
    #[arg(long)]
    drop_final_ack: bool,
    /// Reboot (lose the transfer) when this item arrives
    #[arg(long)]
    reboot_at_item: Option<u16>,
    /// Answer read-backs of this item with its latitude 1 degE7 off (a vehicle holding
    /// something else than was sent: emplan must not report the upload verified)
    #[arg(long, value_name = "SEQ")]
    corrupt_readback: Option<u16>,
    /// Seconds after start during which the ArduPilot flavour refuses uploads with
    /// MAV_MISSION_NO_SPACE, as ArduPilot does while its storage boots
    #[arg(long, default_value_t = 2.0)]
    boot_s: f64,
    /// Altitude of the vehicle's own home above mean sea level (m), what the ArduPilot flavour
    /// answers for item 0 (ArduCopter SITL reports 16.1 m for a 16 m home)
    #[arg(long, default_value_t = 16.1)]
    home_alt_m: f32,
    /// MAVLink 2 signing key file (32 raw bytes or 64 hex characters): sign everything sent,
    /// drop frames not signed with this key
    #[arg(long)]
    signing_key: Option<std::path::PathBuf>,
    /// Seed of the fault generator
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulated seconds per wall second: flight, telemetry rates and time_boot_ms all run this
    /// much faster (the 8-waypoint sample, about 170 s of flight, takes under 10 s at 20)
    #[arg(long, default_value_t = DEFAULT_SPEEDUP)]
    speedup: f64,
    /// Arm and start each newly uploaded mission by itself (as a ground station would: PX4
    /// MISSION_START; ArduPilot GUIDED, arm, MISSION_START)
    #[arg(long)]
    autostart: bool,
    /// Vehicle directory whose physics the flight uses (default: the built-in S1000)
    #[arg(long)]
    vehicle: Option<std::path::PathBuf>,
    /// Flight profile the legs are flown with (default: the vehicle's, as planning uses)
    #[arg(long)]
    profile: Option<emplan::physics::Profile>,
    /// Where the vehicle stands at boot: LAT,LON,ALT_AMSL_M (default: the sample missions'
    /// field, 38.5362,-121.7875,16)
    #[arg(long, value_parser = parse_home)]
    home: Option<emplan::mission::Geodetic>,
    /// A steady wind the vehicle flies in (its physics in moving air) and reports, SPEED@FROM_DEG
    /// (6@270: 6 m/s from the west): the PX4 flavour as WIND_COV, the ArduPilot flavour as WIND.
    /// Default still air and no wind message
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    wind: Option<emplan::physics::Wind>,
    /// The wind changes in flight, T_S=SPEED@FROM_DEG: T_S seconds after the first arming the
    /// vehicle flies in (and reports) SPEED@FROM_DEG
    #[arg(long, value_name = "T_S=SPEED@FROM_DEG")]
    wind_change: Option<emplan::sim::WindChange>,
    /// Telemetry fault: no telemetry at all from START_S for LEN_S simulated seconds
    #[arg(long, value_name = "START_S:LEN_S", value_parser = parse_gap)]
    telemetry_gap: Option<Gap>,
    /// Telemetry fault: from S simulated seconds on the battery reports its current as unknown (-1)
    #[arg(long, value_name = "S")]
    battery_unknown_current_after: Option<f64>,
    /// Telemetry fault: PX4 SITL's simulated battery (current -100 cA, consumed charge negative)
    #[arg(long)]
    px4_fake_current: bool,
    /// Time constant of the battery current filter in s (default 0: none, as PX4 main and
    /// ArduPilot; 0.5 reproduces PX4 up to v1.14)
    #[arg(long, default_value_t = 0.0)]
    current_filter_s: f64,
}

fn parse_home(text: &str) -> Result<emplan::mission::Geodetic, String> {
    let parts: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e} (expected LAT,LON,ALT_AMSL_M)"))?;
    match parts[..] {
        [lat_deg, lon_deg, alt_m]
            if (-90.0..=90.0).contains(&lat_deg)
                && (-180.0..=180.0).contains(&lon_deg)
                && alt_m.is_finite() =>
        {
            Ok(emplan::mission::Geodetic {
                lat_deg,
                lon_deg,
                alt_m,
            })
        }
        _ => Err(format!(
            "{text:?}: expected LAT,LON,ALT_AMSL_M with -90 <= LAT <= 90, -180 <= LON <= 180"
        )),
    }
}

fn parse_gap(text: &str) -> Result<Gap, String> {
    let (start, len) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?}: expected START_S:LEN_S"))?;
    let number = |s: &str| {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x >= 0.0)
            .ok_or_else(|| format!("{text:?}: {s:?} is not a number of seconds >= 0"))
    };
    Ok(Gap {
        start_s: number(start)?,
        duration_s: number(len)?,
    })
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for (name, p) in [
        ("loss-up", args.loss_up),
        ("loss-down", args.loss_down),
        ("duplicate", args.duplicate),
        ("reorder", args.reorder),
    ] {
        if !(0.0..=1.0).contains(&p) {
            anyhow::bail!("--{name} {p}: a probability between 0 and 1 is required");
        }
    }
    if !(args.boot_s.is_finite() && (0.0..=3600.0).contains(&args.boot_s)) {
        anyhow::bail!("--boot-s {}: expected 0 to 3600 seconds", args.boot_s);
    }
    if !args.home_alt_m.is_finite() {
        anyhow::bail!(
            "--home-alt-m {}: expected a finite altitude",
            args.home_alt_m
        );
    }
    let nack_result =
        match &args.nack {
            Some(text) => Some(emplan::link::parse_mission_result(text).ok_or_else(|| {
                anyhow!("--nack {text:?}: not a MAV_MISSION_RESULT name or number")
            })?),
            None => None,
        };
    let config = MockConfig {
        flavour: match args.flavour {
            FlavourArg::Px4 => Flavour::Px4,
            FlavourArg::Ardupilot => Flavour::ArduPilot,
            FlavourArg::Generic => Flavour::Generic,
        },
        faults: Faults {
            loss_up: args.loss_up,
            loss_down: args.loss_down,
            duplicate: args.duplicate,
            reorder: args.reorder,
            delay_ms: args.delay_ms,
            nack_item: args.nack_item,
            nack_result,
            drop_final_ack: args.drop_final_ack,
            reboot_at_item: args.reboot_at_item,
            corrupt_readback: args.corrupt_readback,
        },
        home: match args.home {
            Some(home) => Home {
                lat_e7: emplan::link::items::deg_e7(home.lat_deg),
                lon_e7: emplan::link::items::deg_e7(home.lon_deg),
                alt_m: args.home_alt_m,
            },
            None => Home {
                alt_m: args.home_alt_m,
                ..Home::default()
            },
        },
        boot: std::time::Duration::from_secs_f64(args.boot_s),
        seed: args.seed,
        signing_key: match &args.signing_key {
            Some(path) => Some(emplan::link::read_signing_key(path)?),
            None => None,
        },
        flight: Some(FlightConfig {
            profile: args.profile,
            home: args.home.unwrap_or(FlightConfig::default().home),
            current_filter_s: Some(args.current_filter_s),
            faults: TelemetryFaults {
                gap: args.telemetry_gap,
                unknown_current_after_s: args.battery_unknown_current_after,
                px4_fake_current: args.px4_fake_current,
            },
            seed: args.seed,
            wind: args.wind,
            wind_change: args.wind_change,
            ..FlightConfig::default()
        }),
        speedup: args.speedup,
        autostart: args.autostart,
        ..MockConfig::default()
    };
    if !(args.current_filter_s.is_finite() && (0.0..=60.0).contains(&args.current_filter_s)) {
        anyhow::bail!(
            "--current-filter-s {}: seconds between 0 and 60 are required",
            args.current_filter_s
        );
    }
    let vehicle = match &args.vehicle {
        Some(dir) => Some(emplan::physics::Vehicle::load(dir)?),
        None => None,
    };
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let mut mock = match vehicle {
            Some(vehicle) => MockAutopilot::spawn_with_vehicle(&args.listen, config, vehicle).await?,
            None => MockAutopilot::spawn(&args.listen, config).await?,
        };
        eprintln!(
            "mock autopilot ({:?}, {}x simulated time) listening on udpin:{}; Ctrl-C stops it",
            config.flavour,
            config.speedup,
            mock.local_addr()
        );
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {
                let stats = mock.stats();
                mock.shutdown().await?;
                eprintln!("stopped: {} uploads accepted, {} rejected, {} abandoned", stats.uploads_accepted, stats.uploads_rejected, stats.uploads_abandoned);
            }
            result = mock.stopped() => result?,
        }
        Ok(ExitCode::SUCCESS)
    })
}
