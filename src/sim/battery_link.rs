//! The socket around [`BatterySim`]: connects to the vehicle's onboard MAVLink link, asks it for
//! its motion, feeds every message to the machine and sends what it returns, as a component of
//! the vehicle (`BATTERY_COMPONENT`), until told to stop (`emplan battery-sim`).

use std::future::Future;
use std::time::Duration;

use mavlink::{AsyncMavConnection, MavHeader};

use super::battery_sim::{BatteryNow, BatterySim, BATTERY_COMPONENT};
use crate::link::mav::{MavMessage, LOCAL_POSITION_NED_DATA};
use crate::link::telemetry::{RequestOutcome, StreamConfig, StreamRequest, StreamRequests};

/// Why the battery stopped serving.
#[derive(Debug, thiserror::Error)]
pub enum BatteryLinkError {
    #[error("{url}: {source}")]
    Connect { url: String, source: std::io::Error },
    #[error("{url}: receive failed: {source}")]
    Receive { url: String, source: std::io::Error },
    #[error("{url}: send failed: {source}")]
    Send {
        url: String,
        source: mavlink::error::MessageWriteError,
    },
}

/// Where the battery is served and how.
#[derive(Debug, Clone)]
pub struct BatteryLink {
    /// MAVLink connection to the vehicle's onboard link.
    pub url: String,
    /// The vehicle's system id (the battery is a component of it).
    pub system: u8,
    /// LOCAL_POSITION_NED rate asked of the vehicle (Hz of vehicle time).
    pub position_hz: f64,
}

/// What the battery did, when it stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Served {
    pub now: BatteryNow,
    /// BATTERY_STATUS messages sent.
    pub sent: u64,
    /// Instants the vehicle model could not price.
    pub physics_errors: u64,
}

/// Serves `sim` on `link` until `stop` completes.
pub async fn serve(
    sim: &mut BatterySim<'_>,
    link: &BatteryLink,
    target_component: u8,
    stop: impl Future<Output = ()>,
) -> Result<Served, BatteryLinkError> {
    let url = link.url.clone();
    let mut conn = mavlink::connect_async::<MavMessage>(&url)
        .await
        .map_err(|source| BatteryLinkError::Connect {
            url: url.clone(),
            source,
        })?;
    conn.set_allow_recv_any_version(true);
    let own = MavHeader {
        system_id: u32::from(link.system),
        component_id: BATTERY_COMPONENT,
        sequence: 0,
    };
    let mut streams = StreamRequests::new(
        StreamConfig {
            target_system: link.system,
            target_component,
            own_system: link.system,
            own_component: BATTERY_COMPONENT,
            ..StreamConfig::default()
        },
        vec![StreamRequest::of::<LOCAL_POSITION_NED_DATA>(
            link.position_hz,
        )],
    );
    let t0 = tokio::time::Instant::now();
    // Streams are asked for once the vehicle is heard (a udpin socket has no peer before).
    let mut asked = false;
    let mut reported = false;
    let mut sent: u64 = 0;
    let mut tick = tokio::time::interval(Duration::from_millis(50));
    let mut status = tokio::time::interval(Duration::from_secs(5));
    let mut out: Vec<MavMessage> = Vec::new();
    tokio::pin!(stop);
    loop {
        for message in out.drain(..) {
            conn.send(&own, &message)
                .await
                .map_err(|source| BatteryLinkError::Send {
                    url: url.clone(),
                    source,
                })?;
            if matches!(message, MavMessage::BATTERY_STATUS(_)) {
                sent += 1;
            }
        }
        if asked && !reported && streams.finished() {
            reported = true;
            for (request, outcome) in streams.outcomes() {
                if outcome != RequestOutcome::Accepted {
                    tracing::warn!(
                        "battery-sim: {} at {} Hz not accepted ({outcome:?}): following the vehicle's default rate",
                        request.name,
                        link.position_hz
                    );
                }
            }
        }
        tokio::select! {
            received = conn.recv() => match received {
                Ok((header, message)) => {
                    let system = u8::try_from(header.system_id).unwrap_or(u8::MAX);
                    out = sim.handle(system, header.component_id, &message);
                    if system == link.system && header.component_id == target_component {
                        if !asked {
                            asked = true;
                            out.extend(streams.start(t0.elapsed()));
                        } else {
                            out.extend(streams.handle(t0.elapsed(), &message));
                        }
                    }
                }
                Err(mavlink::error::MessageReadError::Io(source)) => {
                    return Err(BatteryLinkError::Receive { url, source });
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
            () = &mut stop => break,
        }
    }
    Ok(Served {
        now: sim.now(),
        sent,
        physics_errors: sim.physics_errors(),
    })
}
