//! The inverse of `decode`, for tests and simulations: a flight-log reading as the MAVLink
//! message an autopilot of a flavour would send.

use crate::flightlog::telemetry::{
    BatterySource, BreachType, FlightMode, LandedState, MissionState, Photo, PhotoMessage, Reading,
};
use crate::link::mav::{
    self, MavAutopilot, MavLandedState, MavMessage, MavModeFlag, MavSeverity, MavType,
    MissionState as MavMissionState,
};
use crate::link::Flavour;

fn px4_custom_mode(mode: &FlightMode) -> u32 {
    let (main, sub) = match mode {
        FlightMode::Mission => (4, 4),
        FlightMode::Takeoff => (4, 2),
        FlightMode::Hold => (4, 3),
        FlightMode::Rtl => (4, 5),
        FlightMode::Land => (4, 6),
        FlightMode::Manual => (3, 0),
        FlightMode::Guided => (6, 0),
        FlightMode::Other(_) => (4, 1),
    };
    (main << 16) | (sub << 24)
}

fn arducopter_custom_mode(mode: &FlightMode) -> u32 {
    match mode {
        FlightMode::Mission => 3,
        FlightMode::Guided | FlightMode::Takeoff => 4,
        FlightMode::Hold => 5,
        FlightMode::Rtl => 6,
        FlightMode::Land => 9,
        FlightMode::Manual | FlightMode::Other(_) => 0,
    }
}

/// The message an autopilot of `flavour` sends for `reading`: the inverse of [`decode`], with
/// PX4's battery encoding (pack in `voltages[0]`, split above 65534 mV). For tests, benches and
/// simulated vehicles.
pub fn encode(reading: &Reading, flavour: Flavour) -> MavMessage {
    let centi = |a: Option<f64>| a.map_or(-1, |a| (a * 100.0).round() as i16);
    match reading {
        Reading::Battery(b) => {
            let current = if b.fake_current {
                -100
            } else {
                centi(b.current_a)
            };
            let remaining = b.remaining_pct.map_or(-1, |r| r.round() as i8);
            match b.source {
                BatterySource::BatteryStatus { id, .. } => {
                    let mut voltages = [u16::MAX; 10];
                    if let Some(v) = b.voltage_v {
                        let mut mv = (v * 1000.0).round().max(0.0) as u32;
                        for cell in voltages.iter_mut() {
                            let part = mv.min(65534);
                            *cell = part as u16;
                            mv -= part;
                            if mv == 0 {
                                break;
                            }
                        }
                    }
                    MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
                        current_consumed: b.consumed_mah.map_or(-1, |c| c.round() as i32),
                        energy_consumed: b
                            .energy_consumed_j
                            .map_or(-1, |e| (e / 100.0).round() as i32),
                        temperature: i16::MAX,
                        voltages,
                        current_battery: current,
                        id,
                        battery_remaining: remaining,
                        ..Default::default()
                    })
                }
                BatterySource::SysStatus => MavMessage::SYS_STATUS(mav::SYS_STATUS_DATA {
                    voltage_battery: b
                        .voltage_v
                        .map_or(u16::MAX, |v| (v * 1000.0).round() as u16),
                    current_battery: current,
                    battery_remaining: remaining,
                    ..Default::default()
                }),
            }
        }
        Reading::Position(p) => MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: p.time_boot_ms,
            lat: (p.lat_deg * 1e7).round() as i32,
            lon: (p.lon_deg * 1e7).round() as i32,
            alt: (p.alt_amsl_m * 1000.0).round() as i32,
            relative_alt: (p.relative_alt_m * 1000.0).round() as i32,
            vx: (p.vn_m_s * 100.0).round() as i16,
            vy: (p.ve_m_s * 100.0).round() as i16,
            vz: (p.vd_m_s * 100.0).round() as i16,
            hdg: u16::MAX,
        }),
        Reading::MissionCurrent { seq, total, state } => {
            MavMessage::MISSION_CURRENT(mav::MISSION_CURRENT_DATA {
                seq: *seq,
                total: total.unwrap_or(u16::MAX),
                mission_state: match state {
                    MissionState::Unknown => MavMissionState::MISSION_STATE_UNKNOWN,
                    MissionState::NoMission => MavMissionState::MISSION_STATE_NO_MISSION,
                    MissionState::NotStarted => MavMissionState::MISSION_STATE_NOT_STARTED,
                    MissionState::Active => MavMissionState::MISSION_STATE_ACTIVE,
                    MissionState::Paused => MavMissionState::MISSION_STATE_PAUSED,
                    MissionState::Complete => MavMissionState::MISSION_STATE_COMPLETE,
                },
                ..Default::default()
            })
        }
        Reading::ItemReached { seq } => {
            MavMessage::MISSION_ITEM_REACHED(mav::MISSION_ITEM_REACHED_DATA { seq: *seq })
        }
        Reading::Heartbeat { armed, mode } => {
            let (autopilot, custom_mode) = match flavour {
                Flavour::ArduPilot => (
                    MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                    arducopter_custom_mode(mode),
                ),
                Flavour::Px4 | Flavour::Generic => {
                    (MavAutopilot::MAV_AUTOPILOT_PX4, px4_custom_mode(mode))
                }
            };
            let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
            if *armed {
                base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
            }
            MavMessage::HEARTBEAT(mav::HEARTBEAT_DATA {
                custom_mode,
                mavtype: MavType::MAV_TYPE_OCTOROTOR,
                autopilot,
                base_mode,
                system_status: mav::MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            })
        }
        Reading::Landed(state) => MavMessage::EXTENDED_SYS_STATE(mav::EXTENDED_SYS_STATE_DATA {
            landed_state: match state {
                LandedState::Undefined => MavLandedState::MAV_LANDED_STATE_UNDEFINED,
                LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
                LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
            },
            ..Default::default()
        }),
        Reading::Home {
            lat_deg,
            lon_deg,
            alt_amsl_m,
            set_boot_s,
        } => MavMessage::HOME_POSITION(mav::HOME_POSITION_DATA {
            latitude: (lat_deg * 1e7).round() as i32,
            longitude: (lon_deg * 1e7).round() as i32,
            altitude: (alt_amsl_m * 1000.0).round() as i32,
            q: [1.0, 0.0, 0.0, 0.0],
            time_usec: set_boot_s.map_or(0, |s| (s * 1e6).round() as u64),
            ..Default::default()
        }),
        Reading::Wind(wind) => match flavour {
            Flavour::ArduPilot => MavMessage::WIND(mav::WIND_DATA {
                direction: wind.from_deg as f32,
                speed: wind.speed_m_s as f32,
                ..Default::default()
            }),
            Flavour::Px4 | Flavour::Generic => {
                let (east, north) = wind.velocity_en_m_s();
                MavMessage::WIND_COV(mav::WIND_COV_DATA {
                    wind_x: north as f32,
                    wind_y: east as f32,
                    ..Default::default()
                })
            }
        },
        Reading::Photo(photo) => photo_message(photo),
        Reading::Fence(f) => MavMessage::FENCE_STATUS(mav::FENCE_STATUS_DATA {
            breach_status: u8::from(f.breached),
            breach_count: f.breach_count,
            breach_type: match f.breach_type {
                BreachType::None => mav::FenceBreach::FENCE_BREACH_NONE,
                BreachType::MinAltitude => mav::FenceBreach::FENCE_BREACH_MINALT,
                BreachType::MaxAltitude => mav::FenceBreach::FENCE_BREACH_MAXALT,
                BreachType::Boundary => mav::FenceBreach::FENCE_BREACH_BOUNDARY,
            },
            breach_time: f.last_breach_boot_s.map_or(0, |s| {
                (s * 1e3).round().clamp(0.0, f64::from(u32::MAX)) as u32
            }),
            ..Default::default()
        }),
        Reading::StatusText { severity, text } => {
            let mut bytes = [0u8; 50];
            for (slot, b) in bytes.iter_mut().zip(text.bytes()) {
                *slot = b;
            }
            MavMessage::STATUSTEXT(mav::STATUSTEXT_DATA {
                severity: severity_from(*severity),
                text: bytes.into(),
                ..Default::default()
            })
        }
    }
}

/// A photo as the message it names (see `decode` for the units).
fn photo_message(photo: &Photo) -> MavMessage {
    let e7 = |deg: f64| (deg * 1e7).round() as i32;
    let (lat, lon, alt_amsl_m, relative_alt_m) = photo.at.map_or((0, 0, 0.0, 0.0), |p| {
        (e7(p.lat_deg), e7(p.lon_deg), p.alt_amsl_m, p.relative_alt_m)
    });
    let usec = photo
        .camera_time_s
        .map_or(0, |t| (t * 1e6).round().max(0.0) as u64);
    match photo.message {
        PhotoMessage::CameraFeedback => MavMessage::CAMERA_FEEDBACK(mav::CAMERA_FEEDBACK_DATA {
            time_usec: usec,
            lat,
            lng: lon,
            alt_msl: alt_amsl_m as f32,
            alt_rel: relative_alt_m as f32,
            img_idx: photo.index.clamp(0, i64::from(u16::MAX)) as u16,
            flags: mav::CameraFeedbackFlags::CAMERA_FEEDBACK_PHOTO,
            completed_captures: photo.index.clamp(0, i64::from(u16::MAX)) as u16,
            ..Default::default()
        }),
        PhotoMessage::CameraTrigger => MavMessage::CAMERA_TRIGGER(mav::CAMERA_TRIGGER_DATA {
            time_usec: usec,
            seq: photo.index.clamp(0, i64::from(u32::MAX)) as u32,
        }),
        PhotoMessage::ImageCaptured => {
            MavMessage::CAMERA_IMAGE_CAPTURED(mav::CAMERA_IMAGE_CAPTURED_DATA {
                time_boot_ms: photo.camera_time_s.map_or(0, |t| {
                    (t * 1e3).round().clamp(0.0, f64::from(u32::MAX)) as u32
                }),
                lat,
                lon,
                alt: (alt_amsl_m * 1e3).round() as i32,
                relative_alt: (relative_alt_m * 1e3).round() as i32,
                q: [1.0, 0.0, 0.0, 0.0],
                image_index: photo.index.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                capture_result: if photo.captured {
                    mav::MavBool::MAV_BOOL_TRUE
                } else {
                    mav::MavBool::MAV_BOOL_FALSE
                },
                ..Default::default()
            })
        }
    }
}

fn severity_from(n: u8) -> MavSeverity {
    use MavSeverity::*;
    [
        MAV_SEVERITY_EMERGENCY,
        MAV_SEVERITY_ALERT,
        MAV_SEVERITY_CRITICAL,
        MAV_SEVERITY_ERROR,
        MAV_SEVERITY_WARNING,
        MAV_SEVERITY_NOTICE,
        MAV_SEVERITY_INFO,
        MAV_SEVERITY_DEBUG,
    ]
    .get(usize::from(n))
    .copied()
    .unwrap_or(MAV_SEVERITY_INFO)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::{
        Battery, BatterySource, FlightMode, LandedState, MissionState, Reading,
    };

    use crate::link::telemetry::*;
    use crate::link::testing::autopilot_header as vehicle;
    use crate::link::Flavour;
    use mavlink::MavlinkVersion;

    #[test]
    fn encode_then_decode_gives_the_reading_back() {
        let readings = [
            Reading::Battery(Battery {
                source: BatterySource::BatteryStatus {
                    id: 0,
                    component: 1,
                },
                voltage_v: Some(71.234),
                current_a: Some(123.45),
                consumed_mah: Some(3210.0),
                energy_consumed_j: Some(45_600.0),
                remaining_pct: Some(64.0),
                fake_current: false,
            }),
            Reading::Battery(Battery {
                source: BatterySource::SysStatus,
                voltage_v: Some(22.8),
                current_a: None,
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            }),
            Reading::MissionCurrent {
                seq: 3,
                total: Some(12),
                state: MissionState::Active,
            },
            Reading::ItemReached { seq: 3 },
            Reading::Heartbeat {
                armed: true,
                mode: FlightMode::Land,
            },
            Reading::Landed(LandedState::Landing),
            Reading::StatusText {
                severity: 6,
                text: "Reached command #3".into(),
            },
            Reading::Fence(crate::flightlog::telemetry::FenceStatus {
                breached: true,
                breach_count: 2,
                breach_type: BreachType::Boundary,
                last_breach_boot_s: Some(81.25),
            }),
            Reading::Fence(crate::flightlog::telemetry::FenceStatus {
                breached: false,
                breach_count: 0,
                breach_type: BreachType::None,
                last_breach_boot_s: None,
            }),
        ];
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            for r in &readings {
                let frame = frame_bytes(&vehicle(), &encode(r, flavour));
                let (header, message) = parse_frame(&frame).expect("a frame");
                let back = decode(&header, &message).reading.expect("a reading");
                assert_eq!(&back, r, "{flavour:?}");
            }
        }
    }

    #[test]
    fn a_wind_estimate_goes_out_as_its_flavour_sends_it_and_comes_back() {
        let wind = crate::mission::wind::Wind::new(6.0, 250.0).expect("a wind");
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let message = encode(&Reading::Wind(wind), flavour);
            let as_sent = match flavour {
                Flavour::ArduPilot => matches!(message, MavMessage::WIND(_)),
                _ => matches!(message, MavMessage::WIND_COV(_)),
            };
            assert!(as_sent, "{flavour:?}: {message:?}");
            let frame = frame_bytes(&vehicle(), &message);
            let (header, message) = parse_frame(&frame).expect("a frame");
            let Some(Reading::Wind(back)) = decode(&header, &message).reading else {
                panic!("{flavour:?}: no wind read back");
            };
            assert!((back.speed_m_s - 6.0).abs() < 1e-4, "{back:?}");
            assert!((back.from_deg - 250.0).abs() < 1e-3, "{back:?}");
        }
    }

    #[test]
    fn mavlink_1_and_signed_mavlink_2_frames_parse_like_plain_ones() {
        let message = encode(&Reading::ItemReached { seq: 7 }, Flavour::Px4);
        let v1 = frame_bytes_versioned(&vehicle(), &message, MavlinkVersion::V1).expect("v1");
        assert_eq!(v1[0], 0xFE);
        let (_, back) = parse_frame(&v1).expect("v1 parses");
        assert_eq!(back, message);
        let signing = mavlink::SigningData::from_config(mavlink::SigningConfig::new(
            [7u8; 32], 0, true, false,
        ));
        let mut signed = Vec::new();
        mavlink::write_v2_msg_signed(&mut signed, vehicle(), &message, Some(&signing))
            .expect("signed");
        assert_eq!(signed[2] & 1, 1, "signed flag set");
        let (_, back) = parse_frame(&signed).expect("signed parses");
        assert_eq!(back, message);
        let mut broken = frame_bytes(&vehicle(), &message);
        let last = broken.len() - 1;
        broken[last] ^= 0xFF;
        assert!(parse_frame(&broken).is_err(), "a bad checksum is refused");
    }
}
