//! `emplan battery-sim`: a physical battery for PX4 SITL (started with `SIM_BAT_ENABLE=0`).
//! Listens to the vehicle's onboard MAVLink link (PX4 SITL instance 0 sends it to UDP 14540),
//! follows its motion and sends the vehicle model's BATTERY_STATUS back as a smart battery
//! (system 1, component 180); PX4 reports it as its battery on every link. The physics is
//! `emplan::sim::battery_sim`; this is the socket around it. Runs until Ctrl-C or SIGTERM.

use std::process::ExitCode;
use std::time::Duration;

use emplan::link::mav::{MavMessage, LOCAL_POSITION_NED_DATA};
use emplan::link::telemetry::{RequestOutcome, StreamConfig, StreamRequest, StreamRequests};
use emplan::sim::battery_sim::{BatterySim, BatterySimConfig, BATTERY_COMPONENT};
use mavlink::{AsyncMavConnection, MavHeader};

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
    super::runtime()?.block_on(async {
        let mut conn = mavlink::connect_async::<MavMessage>(&args.connect)
            .await
            .map_err(|e| anyhow::anyhow!("{}: {e}", args.connect))?;
        conn.set_allow_recv_any_version(true);
        let own = MavHeader {
            system_id: u32::from(args.system),
            component_id: BATTERY_COMPONENT,
            sequence: 0,
        };
        let mut streams = StreamRequests::new(
            StreamConfig {
                target_system: args.system,
                target_component: cfg.target_component,
                own_system: args.system,
                own_component: BATTERY_COMPONENT,
                ..StreamConfig::default()
            },
            vec![StreamRequest::of::<LOCAL_POSITION_NED_DATA>(args.position_hz)],
        );
        eprintln!(
            "battery-sim: {} for {} on {} ({} BATTERY_STATUS per vehicle second); Ctrl-C stops it",
            vehicle.name, args.system, args.connect, args.rate_hz
        );
        let t0 = tokio::time::Instant::now();
        // Streams are asked for once the vehicle is heard (a udpin socket has no peer before).
        let mut asked = false;
        let mut reported = false;
        let mut sent: u64 = 0;
        let mut tick = tokio::time::interval(Duration::from_millis(50));
        let mut status = tokio::time::interval(Duration::from_secs(5));
        let mut terminate = terminate_signal()?;
        let mut out: Vec<MavMessage> = Vec::new();
        loop {
            for message in out.drain(..) {
                conn.send(&own, &message).await?;
                if matches!(message, MavMessage::BATTERY_STATUS(_)) {
                    sent += 1;
                }
            }
            if asked && !reported && streams.finished() {
                reported = true;
                for (request, outcome) in streams.outcomes() {
                    if outcome != RequestOutcome::Accepted {
                        eprintln!("battery-sim: {} at {} Hz not accepted ({outcome:?}): following the vehicle's default rate", request.name, args.position_hz);
                    }
                }
            }
            tokio::select! {
                received = conn.recv() => match received {
                    Ok((header, message)) => {
                        let system = u8::try_from(header.system_id).unwrap_or(u8::MAX);
                        out = sim.handle(system, header.component_id, &message);
                        if system == args.system && header.component_id == cfg.target_component {
                            if !asked {
                                asked = true;
                                out.extend(streams.start(t0.elapsed()));
                            } else {
                                out.extend(streams.handle(t0.elapsed(), &message));
                            }
                        }
                    }
                    Err(mavlink::error::MessageReadError::Io(e)) => {
                        anyhow::bail!("{}: receive failed: {e}", args.connect)
                    }
                    // A message of another dialect or a damaged frame.
                    Err(_) => {}
                },
                _ = tick.tick() => {
                    if asked {
                        out = streams.tick(t0.elapsed());
                    }
                }
                _ = status.tick() => {
                    let now = sim.now();
                    tracing::info!(
                        "battery-sim: t {:.1} s {:?} {:.0} W {:.2} V {:.2} A, {:.1} kJ drawn, {} sent",
                        now.t_s, now.state, now.power_w, now.voltage_v, now.current_a,
                        now.consumed_j / 1000.0, sent
                    );
                }
                _ = tokio::signal::ctrl_c() => break,
                _ = terminate.recv() => break,
            }
        }
        let now = sim.now();
        eprintln!(
            "battery-sim: stopped at vehicle time {:.1} s: {:.1} kJ ({:.0} mAh) drawn, state of charge {:.1} %, {} BATTERY_STATUS sent, {} instants beyond the model",
            now.t_s,
            now.consumed_j / 1000.0,
            now.consumed_mah,
            now.state_of_charge * 100.0,
            sent,
            sim.physics_errors()
        );
        Ok(ExitCode::SUCCESS)
    })
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
