//! Criterion bench of the telemetry path, in messages per second: a minute of a PX4-like stream
//! (ATTITUDE 50 Hz, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, BATTERY_STATUS and SYS_STATUS
//! 10 Hz, MISSION_CURRENT and EXTENDED_SYS_STATE 2 Hz, HEARTBEAT 1 Hz: 93 messages per second)
//! pre-serialised as MAVLink 2 frames, then
//! - `decode`: parse + decode + vehicle clock (what a replay does per frame);
//! - `record`: the same plus the recorder writing flight.tlog and samples.csv into a fresh flight
//!   directory under target/, flushing and fsyncing on the frames' wall times as it does live
//!   (a minute of stream: 60 fsyncs of each file, here within a fraction of a second: the disk's
//!   fsync time dominates);
//! - `record_unsynced`: the recorder with its periodic fsync off (flushes every 0.5 s of stream,
//!   one fsync at close): the CPU and write cost per message.
//!
//! Target: at least 20 000 messages/s on one core. Run with `cargo bench --bench telemetry`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use emplan::flightlog::recorder::{Recorder, RecorderConfig};
use emplan::flightlog::synthetic::square_plan;
use emplan::flightlog::telemetry::{
    Battery, BatterySource, FlightMode, LandedState, MissionState, Position, Reading,
};
use emplan::link::mav::{self, MavMessage};
use emplan::link::telemetry::{encode, frame_bytes, Telemetry};
use emplan::link::Flavour;
use mavlink::MavHeader;

const START_US: u64 = 1_750_000_000_000_000;

/// (wall us, frame) of `seconds` of stream.
fn stream(seconds: u32) -> Vec<(u64, Vec<u8>)> {
    let plan = square_plan();
    let origin = plan.origin();
    let header = |sequence: u8| MavHeader {
        system_id: 1,
        component_id: 1,
        sequence,
    };
    let mut out: Vec<(u64, MavMessage)> = Vec::new();
    // 50 Hz ticks; slower streams on multiples.
    for tick in 0..seconds * 50 {
        let t = f64::from(tick) * 0.02;
        let wall = START_US + u64::from(tick) * 20_000;
        let boot = 60_000 + tick * 20;
        out.push((
            wall,
            MavMessage::ATTITUDE(mav::ATTITUDE_DATA {
                time_boot_ms: boot,
                roll: 0.01,
                pitch: -0.05,
                yaw: 1.2,
                ..Default::default()
            }),
        ));
        if tick % 5 == 0 {
            let p = emplan::mission::Enu {
                x_east_m: 5.0 * t,
                y_north_m: 0.0,
                z_up_m: 0.0,
            };
            let g = origin.to_geodetic(p);
            out.push((
                wall + 1_000,
                encode(
                    &Reading::Position(Position {
                        time_boot_ms: boot,
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        alt_amsl_m: g.alt_m,
                        relative_alt_m: g.alt_m - plan.home.alt_m,
                        vn_m_s: 0.0,
                        ve_m_s: 5.0,
                        vd_m_s: 0.0,
                    }),
                    Flavour::Px4,
                ),
            ));
            out.push((
                wall + 2_000,
                MavMessage::LOCAL_POSITION_NED(mav::LOCAL_POSITION_NED_DATA {
                    time_boot_ms: boot,
                    x: 0.0,
                    y: 5.0 * t as f32,
                    z: -20.0,
                    vx: 0.0,
                    vy: 5.0,
                    vz: 0.0,
                }),
            ));
            let battery = |source| Battery {
                source,
                voltage_v: Some(23.9 - 0.001 * t),
                current_a: Some(95.0),
                consumed_mah: Some((t * 26.4).round()),
                energy_consumed_j: None,
                remaining_pct: Some(80.0),
                fake_current: false,
            };
            out.push((
                wall + 3_000,
                encode(
                    &Reading::Battery(battery(BatterySource::BatteryStatus {
                        id: 0,
                        component: 1,
                    })),
                    Flavour::Px4,
                ),
            ));
            out.push((
                wall + 4_000,
                encode(
                    &Reading::Battery(battery(BatterySource::SysStatus)),
                    Flavour::Px4,
                ),
            ));
        }
        if tick % 25 == 0 {
            out.push((
                wall + 5_000,
                encode(
                    &Reading::MissionCurrent {
                        seq: 2,
                        total: Some(6),
                        state: MissionState::Active,
                    },
                    Flavour::Px4,
                ),
            ));
            out.push((
                wall + 6_000,
                encode(&Reading::Landed(LandedState::InAir), Flavour::Px4),
            ));
        }
        if tick % 50 == 0 {
            out.push((
                wall + 7_000,
                encode(
                    &Reading::Heartbeat {
                        armed: true,
                        mode: FlightMode::Mission,
                    },
                    Flavour::Px4,
                ),
            ));
        }
    }
    out.into_iter()
        .enumerate()
        .map(|(k, (wall, m))| (wall, frame_bytes(&header(k as u8), &m)))
        .collect()
}

fn bench_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-telemetry");
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn telemetry(c: &mut Criterion) {
    let frames = stream(60);
    let mut group = c.benchmark_group("telemetry");
    group.throughput(Throughput::Elements(frames.len() as u64));
    group.sample_size(20);
    group.bench_function("decode", |b| {
        b.iter(|| {
            let mut t = Telemetry::new();
            let mut readings = 0usize;
            for (wall, frame) in &frames {
                readings += usize::from(t.frame(*wall, frame).is_some());
            }
            assert_eq!(t.undecodable(), 0);
            readings
        })
    });
    let dir = bench_dir();
    for (name, cfg) in [
        ("record", RecorderConfig::default()),
        (
            "record_unsynced",
            RecorderConfig {
                sync_every_us: u64::MAX,
                ..RecorderConfig::default()
            },
        ),
    ] {
        group.bench_function(name, |b| {
            b.iter_batched(
                || Recorder::create_with(&dir, "bench", START_US, cfg).expect("recorder"),
                |mut recorder| {
                    let mut t = Telemetry::new();
                    for (wall, frame) in &frames {
                        let stamped = t.frame(*wall, frame);
                        recorder
                            .record(*wall, frame, stamped.as_ref())
                            .expect("recorded");
                    }
                    let dir = recorder.close().expect("closed");
                    let _ = std::fs::remove_dir_all(dir);
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, telemetry);
criterion_main!(benches);
