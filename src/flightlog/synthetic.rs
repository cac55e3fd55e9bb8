//! A scripted flight with known answers, for tests, benches and demonstrations: the vehicle arms,
//! climbs to the origin, flies each leg in a straight line at constant speed until the arrival
//! radius and then brakes uniformly to a stop on the point, hovers its hold time, and lands, with
//! a constant electrical power per part (take-off, leg, settle, hover, landing). Telemetry comes
//! as PX4 sends it: positions and battery at `rate_hz` (battery half a period later, without
//! boot time), HEARTBEAT, MISSION_CURRENT and EXTENDED_SYS_STATE at 1 Hz and on change, and
//! MISSION_ITEM_REACHED when an item is left, repeated once a second, never for the last point
//! (a leg's via points are flown through at its speed, each reported reached as it is passed),
//! and each photo a point's `photos` asks for as the vehicle leaves it (CAMERA_TRIGGER, then
//! CAMERA_IMAGE_CAPTURED where it is, 20 ms later, as PX4 sends them).
//! Each part's true span and energy (power x duration) is known exactly.
//!
//! This is not the physics model's flight (that is `sim`'s); it exists so segmentation and
//! integration can be checked against an analytic answer.

use super::flight_plan::{FlightPlan, PlannedPoint, Predicted, PredictedLeg, ORIGIN_NAME};
use super::segment::SegmentKind;
use super::telemetry::{
    Battery, BatterySource, FlightMode, LandedState, MissionState, Photo, PhotoMessage,
    PhotoPosition, Position, Reading, Stamped,
};
use crate::mission::{Enu, Geodetic};

/// A small plan to fly: three waypoints around a 60 m square at 20 m above home (origin at 20 m),
/// then the origin; PX4 numbering (take-off 0, waypoints 1-3, origin 4, land 5), holds of 3 s,
/// and a prediction of round numbers.
pub fn square_plan() -> FlightPlan {
    let point = |seq: u16, name: &str, x: f64, y: f64, z: f64, hold_s: f64| PlannedPoint {
        seq,
        name: name.into(),
        enu: Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        },
        hold_s,
        photos: 0,
        via: Vec::new(),
    };
    let leg = PredictedLeg {
        energy_j: 25_000.0,
        duration_s: 11.0,
        settle_energy_j: 3_000.0,
        settle_duration_s: 1.6,
    };
    FlightPlan {
        mission: "square".into(),
        home: Geodetic {
            lat_deg: 38.5362,
            lon_deg: -121.7875,
            alt_m: 16.0,
        },
        origin_height_m: 20.0,
        points: vec![
            point(1, "A", 60.0, 0.0, 0.0, 3.0),
            point(2, "B", 60.0, 60.0, 10.0, 3.0),
            point(3, "C", 0.0, 60.0, -5.0, 3.0),
            point(4, ORIGIN_NAME, 0.0, 0.0, 0.0, 0.0),
        ],
        takeoff_seq: Some(0),
        land_seq: Some(5),
        predicted: Some(Predicted {
            takeoff_j: 40_000.0,
            landing_j: 35_000.0,
            legs: vec![leg; 4],
            hover_power_w: 1_900.0,
        }),
        resumes: None,
        guard: None,
        wind: None,
        repricings: Vec::new(),
        priced_by: None,
        blocks: Vec::new(),
        pack: None,
    }
}

/// The shape of the scripted flight.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticConfig {
    pub speed_m_s: f64,
    pub climb_m_s: f64,
    pub land_m_s: f64,
    /// Braking distance at the end of a leg (the arrival radius).
    pub brake_m: f64,
    /// Idle time before arming.
    pub arm_s: f64,
    /// Armed on the ground before the climb.
    pub spool_s: f64,
    /// Hover at the origin after the climb, before the first leg.
    pub takeoff_hover_s: f64,
    /// On the ground after touch-down before the disarm.
    pub disarm_after_s: f64,
    /// Telemetry after the disarm.
    pub tail_s: f64,
    pub rate_hz: f64,
    pub idle_power_w: f64,
    pub takeoff_power_w: f64,
    pub leg_power_w: f64,
    pub settle_power_w: f64,
    pub hover_power_w: f64,
    pub landing_power_w: f64,
    /// Pack voltage at the start and its linear sag.
    pub voltage_v: f64,
    pub sag_v_per_s: f64,
    /// Vehicle seconds per wall second.
    pub speedup: f64,
    pub start_wall_us: u64,
    pub boot_ms: u32,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        SyntheticConfig {
            speed_m_s: 5.0,
            climb_m_s: 2.0,
            land_m_s: 1.0,
            brake_m: 4.0,
            arm_s: 1.0,
            spool_s: 1.0,
            takeoff_hover_s: 2.0,
            disarm_after_s: 2.0,
            tail_s: 2.0,
            rate_hz: 10.0,
            idle_power_w: 15.0,
            takeoff_power_w: 2600.0,
            leg_power_w: 2300.0,
            settle_power_w: 2100.0,
            hover_power_w: 1900.0,
            landing_power_w: 1500.0,
            voltage_v: 25.0,
            sag_v_per_s: 0.002,
            speedup: 1.0,
            start_wall_us: 1_750_000_000_000_000,
            boot_ms: 120_000,
        }
    }
}

/// One message of the scripted flight.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticMessage {
    /// True vehicle time since the first message.
    pub t_s: f64,
    pub wall_us: u64,
    /// The autopilot's boot time, for messages that carry one.
    pub time_boot_ms: Option<u32>,
    pub reading: Reading,
}

/// A part of the flight as it truly was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruePart {
    pub kind: SegmentKind,
    pub start_s: f64,
    pub end_s: f64,
    pub power_w: f64,
}

impl TruePart {
    pub fn energy_j(&self) -> f64 {
        self.power_w * (self.end_s - self.start_s)
    }
}

/// A straight piece of the trajectory: from `a` at `t0` to `b` at `t1`, at constant speed or
/// braking uniformly to a stop at `b`.
#[derive(Debug, Clone, Copy)]
struct Piece {
    t0: f64,
    t1: f64,
    a: Enu,
    b: Enu,
    braking: bool,
}

fn lerp(a: Enu, b: Enu, s: f64) -> Enu {
    Enu {
        x_east_m: a.x_east_m + (b.x_east_m - a.x_east_m) * s,
        y_north_m: a.y_north_m + (b.y_north_m - a.y_north_m) * s,
        z_up_m: a.z_up_m + (b.z_up_m - a.z_up_m) * s,
    }
}

fn dist(a: Enu, b: Enu) -> f64 {
    ((a.x_east_m - b.x_east_m).powi(2)
        + (a.y_north_m - b.y_north_m).powi(2)
        + (a.z_up_m - b.z_up_m).powi(2))
    .sqrt()
}

impl Piece {
    fn new(t0: f64, t1: f64, a: Enu, b: Enu, braking: bool) -> Piece {
        Piece {
            t0,
            t1,
            a,
            b,
            braking,
        }
    }

    /// Position and velocity (east, north, up) at `t`.
    fn at(&self, t: f64) -> (Enu, [f64; 3]) {
        let duration = self.t1 - self.t0;
        let length = dist(self.a, self.b);
        if duration <= 0.0 || length <= 0.0 {
            return (self.b, [0.0; 3]);
        }
        let tau = (t - self.t0).clamp(0.0, duration);
        let (s, speed) = if self.braking {
            // Uniform braking from v0 = 2L/T to 0 over the piece.
            let v0 = 2.0 * length / duration;
            let decel = v0 / duration;
            (
                (v0 * tau - 0.5 * decel * tau * tau) / length,
                v0 - decel * tau,
            )
        } else {
            (tau / duration, length / duration)
        };
        let unit = [
            (self.b.x_east_m - self.a.x_east_m) / length,
            (self.b.y_north_m - self.a.y_north_m) / length,
            (self.b.z_up_m - self.a.z_up_m) / length,
        ];
        (
            lerp(self.a, self.b, s),
            [unit[0] * speed, unit[1] * speed, unit[2] * speed],
        )
    }
}

/// The scripted flight: its messages in time order and the truth.
#[derive(Debug, Clone)]
pub struct SyntheticFlight {
    pub messages: Vec<SyntheticMessage>,
    pub parts: Vec<TruePart>,
    pub arm_s: f64,
    pub disarm_s: f64,
}

impl SyntheticFlight {
    /// Flies `plan` as `cfg` says.
    pub fn fly(plan: &FlightPlan, cfg: &SyntheticConfig) -> SyntheticFlight {
        let ground = Enu {
            z_up_m: -plan.origin_height_m,
            ..Enu::default()
        };
        let origin = Enu::default();
        let mut pieces: Vec<Piece> = Vec::new();
        let mut parts: Vec<TruePart> = Vec::new();
        // (time, reading) of the event messages.
        let mut events: Vec<(f64, Reading)> = Vec::new();
        let mut reached: Vec<(f64, u16)> = Vec::new();
        // (time, where) of each photo.
        let mut photos: Vec<(f64, Enu)> = Vec::new();
        let mut landed: Vec<(f64, LandedState)> = vec![(0.0, LandedState::OnGround)];
        let current = |seq: u16, state: MissionState| Reading::MissionCurrent {
            seq,
            total: None,
            state,
        };
        let first_seq = plan.takeoff_seq.unwrap_or(0);
        events.push((0.0, current(first_seq, MissionState::NotStarted)));

        let arm = cfg.arm_s;
        let lift = arm + cfg.spool_s;
        let climbed = lift + plan.origin_height_m / cfg.climb_m_s;
        let mut t = climbed + cfg.takeoff_hover_s;
        pieces.push(Piece::new(0.0, lift, ground, ground, false));
        pieces.push(Piece::new(lift, climbed, ground, origin, false));
        pieces.push(Piece::new(climbed, t, origin, origin, false));
        parts.push(TruePart {
            kind: SegmentKind::Takeoff,
            start_s: arm,
            end_s: t,
            power_w: cfg.takeoff_power_w,
        });
        landed.push((lift, LandedState::Takeoff));
        landed.push((climbed, LandedState::InAir));
        events.push((arm, current(first_seq, MissionState::Active)));

        let mut from = origin;
        let last = plan.points.len().saturating_sub(1);
        for (k, point) in plan.points.iter().enumerate() {
            let leg_start = t;
            let first = point.via.first().map_or(point.seq, |v| v.seq);
            events.push((t, current(first, MissionState::Active)));
            if k > 0 {
                if let Some(prev) = plan.points.get(k - 1) {
                    reached.push((t, prev.seq));
                }
            }
            // Through the leg's via points at the leg's speed, each reported reached as it is
            // passed and the next item made current.
            for (j, v) in point.via.iter().enumerate() {
                let passed = t + dist(from, v.enu) / cfg.speed_m_s;
                pieces.push(Piece::new(t, passed, from, v.enu, false));
                let next = point.via.get(j + 1).map_or(point.seq, |n| n.seq);
                events.push((passed, current(next, MissionState::Active)));
                reached.push((passed, v.seq));
                from = v.enu;
                t = passed;
            }
            let q = point.enu;
            let length = dist(from, q);
            let brake = length.min(cfg.brake_m);
            let brake_start = lerp(q, from, brake / length.max(f64::MIN_POSITIVE));
            let cruise_end = t + (length - brake) / cfg.speed_m_s;
            let stop = cruise_end + 2.0 * brake / cfg.speed_m_s;
            pieces.push(Piece::new(t, cruise_end, from, brake_start, false));
            pieces.push(Piece::new(cruise_end, stop, brake_start, q, true));
            let leave = stop + point.hold_s;
            pieces.push(Piece::new(stop, leave, q, q, false));
            parts.push(TruePart {
                kind: SegmentKind::Leg(k),
                start_s: leg_start,
                end_s: cruise_end,
                power_w: cfg.leg_power_w,
            });
            parts.push(TruePart {
                kind: SegmentKind::Settle(k),
                start_s: cruise_end,
                end_s: stop,
                power_w: cfg.settle_power_w,
            });
            parts.push(TruePart {
                kind: SegmentKind::Hover(k),
                start_s: stop,
                end_s: leave,
                power_w: cfg.hover_power_w,
            });
            photos.extend((0..point.photos).map(|_| (leave, q)));
            from = q;
            t = leave;
            if k == last {
                // PX4 never reports the last waypoint before landing reached.
                let land_seq = plan.land_seq.unwrap_or(point.seq.saturating_add(1));
                events.push((t, current(land_seq, MissionState::Active)));
            }
        }
        let touchdown = t + dist(from, ground) / cfg.land_m_s;
        pieces.push(Piece::new(t, touchdown, from, ground, false));
        let disarm = touchdown + cfg.disarm_after_s;
        let end = disarm + cfg.tail_s;
        pieces.push(Piece::new(touchdown, end, ground, ground, false));
        parts.push(TruePart {
            kind: SegmentKind::Landing,
            start_s: t,
            end_s: disarm,
            power_w: cfg.landing_power_w,
        });
        landed.push((t, LandedState::Landing));
        landed.push((touchdown, LandedState::OnGround));
        events.push((
            disarm,
            current(plan.land_seq.unwrap_or(0), MissionState::Complete),
        ));

        let power_at = |time: f64| -> f64 {
            parts
                .iter()
                .find(|p| p.start_s <= time && time < p.end_s)
                .map_or(cfg.idle_power_w, |p| p.power_w)
        };
        let position_at = |time: f64| -> (Enu, [f64; 3]) {
            pieces
                .iter()
                .find(|p| p.t0 <= time && time < p.t1)
                .or(pieces.last())
                .map_or((ground, [0.0; 3]), |p| p.at(time))
        };
        let armed_at = |time: f64| time >= arm && time < disarm;
        let landed_at = |time: f64| {
            landed
                .iter()
                .rev()
                .find(|(s, _)| *s <= time)
                .map_or(LandedState::OnGround, |x| x.1)
        };

        let mut out: Vec<(f64, Option<u32>, Reading)> = Vec::new();
        let period = 1.0 / cfg.rate_hz;
        let samples = (end * cfg.rate_hz).floor() as u64;
        let origin_frame = plan.origin();
        let mut consumed_mah = 0.0;
        for i in 0..=samples {
            let time = i as f64 * period;
            let (p, v) = position_at(time);
            let g = origin_frame.to_geodetic(p);
            let boot = cfg.boot_ms + (time * 1000.0).round() as u32;
            out.push((
                time,
                Some(boot),
                Reading::Position(Position {
                    time_boot_ms: boot,
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    alt_amsl_m: g.alt_m,
                    relative_alt_m: g.alt_m - plan.home.alt_m,
                    vn_m_s: v[1],
                    ve_m_s: v[0],
                    vd_m_s: -v[2],
                }),
            ));
            let tb = time + 0.5 * period;
            let voltage_v = cfg.voltage_v - cfg.sag_v_per_s * tb;
            let power_w = power_at(tb);
            consumed_mah += power_w / voltage_v * period / 3.6;
            out.push((
                tb,
                None,
                Reading::Battery(Battery {
                    source: BatterySource::BatteryStatus {
                        id: 0,
                        component: 1,
                    },
                    voltage_v: Some(voltage_v),
                    current_a: Some(power_w / voltage_v),
                    consumed_mah: Some(consumed_mah.round()),
                    energy_consumed_j: None,
                    remaining_pct: Some(90.0),
                    fake_current: false,
                }),
            ));
        }
        // 1 Hz: heartbeat, landed state, mission progress, the last item reached again.
        let mut second = 0.0;
        while second <= end {
            let tb = second + 0.01;
            out.push((
                tb,
                None,
                Reading::Heartbeat {
                    armed: armed_at(tb),
                    mode: FlightMode::Mission,
                },
            ));
            out.push((tb, None, Reading::Landed(landed_at(tb))));
            if let Some((_, r)) = events.iter().rev().find(|(s, _)| *s <= tb) {
                out.push((tb, None, r.clone()));
            }
            if let Some((_, seq)) = reached.iter().rev().find(|(s, _)| *s <= tb) {
                out.push((tb, None, Reading::ItemReached { seq: *seq }));
            }
            second += 1.0;
        }
        // On change.
        out.push((
            arm,
            None,
            Reading::Heartbeat {
                armed: true,
                mode: FlightMode::Mission,
            },
        ));
        out.push((
            disarm,
            None,
            Reading::Heartbeat {
                armed: false,
                mode: FlightMode::Mission,
            },
        ));
        out.extend(events.iter().map(|(s, r)| (*s, None, r.clone())));
        out.extend(
            reached
                .iter()
                .map(|(s, seq)| (*s, None, Reading::ItemReached { seq: *seq })),
        );
        out.extend(landed.iter().map(|(s, l)| (*s, None, Reading::Landed(*l))));
        for (index, (s, at)) in photos.iter().enumerate() {
            let g = origin_frame.to_geodetic(*at);
            let photo = |message, at, dt_s: f64| Photo {
                message,
                index: index as i64,
                at,
                camera_time_s: Some(f64::from(cfg.boot_ms) * 1e-3 + s + dt_s),
                captured: true,
            };
            let position = PhotoPosition {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_amsl_m: g.alt_m,
                relative_alt_m: g.alt_m - plan.home.alt_m,
            };
            out.push((
                *s,
                None,
                Reading::Photo(photo(PhotoMessage::CameraTrigger, None, 0.0)),
            ));
            out.push((
                s + 0.02,
                None,
                Reading::Photo(photo(PhotoMessage::ImageCaptured, Some(position), 0.02)),
            ));
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        let messages = out
            .into_iter()
            .map(|(t_s, time_boot_ms, reading)| SyntheticMessage {
                t_s,
                wall_us: cfg.start_wall_us + (t_s / cfg.speedup * 1e6).round() as u64,
                time_boot_ms,
                reading,
            })
            .collect();
        SyntheticFlight {
            messages,
            parts,
            arm_s: arm,
            disarm_s: disarm,
        }
    }

    /// The readings stamped with their true vehicle times (what a perfect clock gives).
    pub fn stamped(&self) -> Vec<Stamped> {
        self.messages
            .iter()
            .map(|m| Stamped {
                t_s: m.t_s,
                wall_us: m.wall_us,
                reading: m.reading.clone(),
            })
            .collect()
    }

    /// The true part of a kind.
    pub fn part(&self, kind: SegmentKind) -> Option<&TruePart> {
        self.parts.iter().find(|p| p.kind == kind)
    }

    /// The true energy from arming to disarming.
    pub fn total_j(&self) -> f64 {
        self.parts.iter().map(TruePart::energy_j).sum()
    }
}
