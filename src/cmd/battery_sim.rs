//! `emplan battery-sim`: a physical battery for PX4 SITL (started with `SIM_BAT_ENABLE=0`).
//! Listens to the vehicle's onboard MAVLink link (PX4 SITL instance 0 sends it to UDP 14540),
//! follows its motion and sends the vehicle model's BATTERY_STATUS back as a smart battery
//! (system 1, component 180); PX4 reports it as its battery on every link. The physics is
//! `emplan::sim::battery_sim`, its socket `emplan::sim::battery_link`; this parses and prints. Runs until Ctrl-C or SIGTERM.

use std::process::ExitCode;

use emplan::sim::battery_link::{serve, BatteryLink};
use emplan::sim::battery_sim::{BatterySim, BatterySimConfig};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// MAVLink connection to the vehicle's onboard link (PX4 SITL: udpin:127.0.0.1:14540)
    #[arg(long, default_value = "udpin:127.0.0.1:14540")]
    connect: String,
    /// Vehicle directory whose physics prices the motion (default: the built-in S1000)
    #[arg(long)]
    vehicle: Option<std::path::PathBuf>,
    /// BATTERY_STATUS messages per second of vehicle time
    #[arg(long, default_value_t = 20.0)]
    rate_hz: f64,
    /// LOCAL_POSITION_NED rate asked of the vehicle (Hz of vehicle time; the velocity is
    /// differentiated for the acceleration)
    #[arg(long, default_value_t = 50.0)]
    position_hz: f64,
    /// State of charge of the pack at start (0..1)
    #[arg(long, default_value_t = 1.0)]
    state_of_charge: f64,
    /// The vehicle's MAVLink system id (the battery is a component of it)
    #[arg(long, default_value_t = 1)]
    system: u8,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for (flag, value, lo, hi) in [
        ("rate-hz", args.rate_hz, 0.1, 1000.0),
        ("position-hz", args.position_hz, 1.0, 1000.0),
        ("state-of-charge", args.state_of_charge, 0.0, 1.0),
    ] {
        if !(value.is_finite() && (lo..=hi).contains(&value)) {
            anyhow::bail!("--{flag} {value}: expected {lo} to {hi}");
        }
    }
    let vehicle = match &args.vehicle {
        Some(dir) => emplan::physics::Vehicle::load(dir)?,
        None => emplan::physics::builtin::vehicle()?,
    };
    let cfg = BatterySimConfig {
        rate_hz: args.rate_hz,
        state_of_charge: args.state_of_charge,
        target_system: args.system,
        ..BatterySimConfig::default()
    };
    let mut sim = BatterySim::new(&vehicle, cfg)?;
    let link = BatteryLink {
        url: args.connect.clone(),
        system: args.system,
        position_hz: args.position_hz,
    };
    eprintln!(
        "battery-sim: {} for {} on {} ({} BATTERY_STATUS per vehicle second); Ctrl-C stops it",
        vehicle.name, args.system, args.connect, args.rate_hz
    );
    let served = super::runtime()?.block_on(async {
        let mut terminate = terminate_signal()?;
        let stop = async move {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = terminate.recv() => {}
            }
        };
        anyhow::Ok(serve(&mut sim, &link, cfg.target_component, stop).await?)
    })?;
    let now = served.now;
    eprintln!(
        "battery-sim: stopped at vehicle time {:.1} s: {:.1} kJ ({:.0} mAh) drawn, state of charge {:.1} %, {} BATTERY_STATUS sent, {} instants beyond the model",
        now.t_s,
        now.consumed_j / 1000.0,
        now.consumed_mah,
        now.state_of_charge * 100.0,
        served.sent,
        served.physics_errors
    );
    Ok(ExitCode::SUCCESS)
}

/// SIGTERM (how scripts stop it) on unix; never elsewhere.
#[cfg(unix)]
fn terminate_signal() -> anyhow::Result<tokio::signal::unix::Signal> {
    Ok(tokio::signal::unix::signal(
        tokio::signal::unix::SignalKind::terminate(),
    )?)
}

#[cfg(not(unix))]
fn terminate_signal() -> anyhow::Result<Never> {
    Ok(Never)
}

#[cfg(not(unix))]
struct Never;

#[cfg(not(unix))]
impl Never {
    async fn recv(&mut self) -> Option<()> {
        std::future::pending().await
    }
}
