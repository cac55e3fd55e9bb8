//! Photos measured in flight: each photo the autopilot reported (`telemetry::Photo`: ArduPilot's
//! CAMERA_FEEDBACK, PX4's CAMERA_TRIGGER and CAMERA_IMAGE_CAPTURED) where it was taken in the
//! mission frame ([`PhotoLog`], fed by the segmenter as the readings arrive, so a replay sees
//! what the live flight saw), and each assigned to the point of the plan it was taken at
//! ([`assign`]).
//!
//! A photo action follows its waypoint in the mission: ArduPilot (`AP_Mission` starting the DO
//! commands after a navigation command once it completes) and PX4 (navigator `mission.cpp`) run
//! it when the waypoint is done, reached and its hold over, as the vehicle leaves for the next
//! point. So a photo belongs to the point whose arrival came last before it (between reaching
//! that point and reaching the next), when it was taken within [`NEAR_M`] of it; else to the
//! point nearest where it was taken, within the same distance; else to none, listed apart.
//!
//! PX4 reports one photo twice, CAMERA_TRIGGER (no position) and CAMERA_IMAGE_CAPTURED, under
//! the same index (both from the camera trigger's sequence): they are one photo. A photo whose
//! message gives no position is placed where the vehicle was when it arrived.

use serde::{Deserialize, Serialize};

use super::flight_plan::FlightPlan;
use super::part::{Segment, SegmentKind};
use super::telemetry::{Photo, PhotoMessage, Position};
use crate::mission::Enu;

/// How far from a point a photo may be taken and still be that point's (m, 3D): the distance
/// the report already allows between a point and where the leg leaving it begins
/// (`report::FAR_START_M`, five times the autopilots' 2 m default acceptance radius), since a
/// photo action runs at that very moment, as the vehicle leaves the point (PX4 accepts a
/// waypoint within its acceptance radius while still braking, and ArduCopter finishes a fast
/// waypoint half-way through its turn).
pub const NEAR_M: f64 = 10.0;

/// Where a photo's position came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LocatedBy {
    /// The photo's own message (CAMERA_FEEDBACK, CAMERA_IMAGE_CAPTURED).
    Message,
    /// The vehicle's latest position when the message arrived (CAMERA_TRIGGER alone).
    Vehicle,
}

/// One photo as the flight log saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TakenPhoto {
    /// Flight-log time of its first message.
    pub t_s: f64,
    /// The autopilot's image index.
    pub index: i64,
    /// The messages that reported it (`CAMERA_FEEDBACK`; PX4: `CAMERA_TRIGGER`,
    /// `CAMERA_IMAGE_CAPTURED`).
    pub messages: Vec<String>,
    /// Where it was taken: latitude, longitude, height above home, and in the mission frame
    /// (None: no message said and no position had arrived).
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    pub height_m: Option<f64>,
    #[serde(skip)]
    pub at: Option<Enu>,
    pub located_by: Option<LocatedBy>,
    /// False when the camera said it failed to capture it (CAMERA_IMAGE_CAPTURED): not counted.
    pub captured: bool,
}

/// The photos of a flight so far, in the order they were reported.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotoLog {
    photos: Vec<TakenPhoto>,
}

impl PhotoLog {
    pub fn new() -> PhotoLog {
        PhotoLog::default()
    }

    pub fn photos(&self) -> &[TakenPhoto] {
        &self.photos
    }

    /// A photo reported at `t_s`. `frame_home_m` is the home altitude positions are measured
    /// from (as the segmenter measures them); `vehicle` the vehicle's latest position, for a
    /// photo whose message does not say where.
    pub fn push(
        &mut self,
        t_s: f64,
        photo: &Photo,
        plan: &FlightPlan,
        frame_home_m: Option<f64>,
        vehicle: Option<(Position, Enu)>,
    ) {
        let located = match (photo.at, vehicle) {
            (Some(at), _) => {
                let p = Position {
                    time_boot_ms: 0,
                    lat_deg: at.lat_deg,
                    lon_deg: at.lon_deg,
                    alt_amsl_m: at.alt_amsl_m,
                    relative_alt_m: at.relative_alt_m,
                    vn_m_s: 0.0,
                    ve_m_s: 0.0,
                    vd_m_s: 0.0,
                };
                Some((p, plan.to_local(&p, frame_home_m), LocatedBy::Message))
            }
            (None, Some((p, enu))) => Some((p, enu, LocatedBy::Vehicle)),
            (None, None) => None,
        };
        let height_m = |p: &Position| match frame_home_m {
            Some(home) => p.alt_amsl_m - home,
            None => p.relative_alt_m,
        };
        let name = photo.message.name().to_string();
        let px4 = |m: PhotoMessage| {
            matches!(m, PhotoMessage::CameraTrigger | PhotoMessage::ImageCaptured)
        };
        let same = (self.photos.iter_mut()).rev().find(|p| {
            p.index == photo.index
                && px4(photo.message)
                && !p.messages.contains(&name)
                && p.messages
                    .iter()
                    .all(|m| m != PhotoMessage::CameraFeedback.name())
        });
        if let Some(same) = same {
            // PX4's second message of the same photo: its position is the photo's own.
            same.messages.push(name);
            same.captured &= photo.captured;
            if let Some((p, enu, LocatedBy::Message)) = located {
                if same.located_by != Some(LocatedBy::Message) {
                    same.lat_deg = Some(p.lat_deg);
                    same.lon_deg = Some(p.lon_deg);
                    same.height_m = Some(height_m(&p));
                    same.at = Some(enu);
                    same.located_by = Some(LocatedBy::Message);
                }
            }
            return;
        }
        self.photos.push(TakenPhoto {
            t_s,
            index: photo.index,
            messages: vec![name],
            lat_deg: located.map(|(p, _, _)| p.lat_deg),
            lon_deg: located.map(|(p, _, _)| p.lon_deg),
            height_m: located.map(|(p, _, _)| height_m(&p)),
            at: located.map(|(_, enu, _)| enu),
            located_by: located.map(|(_, _, by)| by),
            captured: photo.captured,
        });
    }
}

/// A photo with the point it was assigned to and how far from it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlacedPhoto {
    #[serde(flatten)]
    pub photo: TakenPhoto,
    /// 3D distance from the point it was assigned to, or (apart) from the nearest point.
    pub distance_m: Option<f64>,
    /// Apart: the nearest point's name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nearest: Option<String>,
}

/// The photos expected and taken at one point of the plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointPhotos {
    /// The point's name and mission sequence number.
    pub point: String,
    pub seq: u16,
    /// The mission's photo actions at the point.
    pub photos_expected: u32,
    /// The photos captured there (a failed capture is listed, not counted).
    pub photos_taken: u32,
    pub photos: Vec<PlacedPhoto>,
    /// Why the point does not count as visited (fewer photos taken than expected).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub missing: Option<String>,
}

impl PointPhotos {
    /// Whether the autopilot reported every photo the mission takes at the point.
    pub fn complete(&self) -> bool {
        self.photos_taken >= self.photos_expected
    }
}

/// The photos of a flight: per point of the plan that expects or got any, and the ones taken
/// near no point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotoReport {
    pub points: Vec<PointPhotos>,
    pub apart: Vec<PlacedPhoto>,
}

fn distance(a: Enu, b: Enu) -> f64 {
    (a.x_east_m - b.x_east_m)
        .hypot(a.y_north_m - b.y_north_m)
        .hypot(a.z_up_m - b.z_up_m)
}

/// When the flight arrived at each point of `plan` (None: not yet, or not in the log): the end
/// of the leg to it, else the start of the settle or hover there.
fn arrivals(plan: &FlightPlan, segments: &[Segment]) -> Vec<Option<f64>> {
    (0..plan.points.len())
        .map(|k| {
            segments.iter().find_map(|s| match s.kind {
                SegmentKind::Leg(i) if i == k && s.complete => Some(s.end_s),
                SegmentKind::Settle(i) | SegmentKind::Hover(i) if i == k => Some(s.start_s),
                _ => None,
            })
        })
        .collect()
}

/// Assigns each photo of `photos` to the point of `plan` it was taken at (see the module doc),
/// with the flight's `segments` saying when it arrived where.
pub fn assign(plan: &FlightPlan, segments: &[Segment], photos: &[TakenPhoto]) -> PhotoReport {
    let arrived = arrivals(plan, segments);
    let mut placed: Vec<Vec<PlacedPhoto>> = vec![Vec::new(); plan.points.len()];
    let mut apart = Vec::new();
    for photo in photos {
        // The point arrived at last before the photo.
        let by_time = (0..plan.points.len())
            .filter(|&k| arrived[k].is_some_and(|a| a <= photo.t_s))
            .max_by(|&a, &b| {
                arrived[a]
                    .unwrap_or(0.0)
                    .total_cmp(&arrived[b].unwrap_or(0.0))
            });
        let nearest = photo.at.and_then(|at| {
            (plan.points.iter().enumerate())
                .map(|(k, p)| (k, distance(at, p.enu)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
        });
        let near = |k: usize| {
            photo
                .at
                .map(|at| distance(at, plan.points[k].enu))
                .filter(|d| *d <= NEAR_M)
        };
        let chosen = match by_time.and_then(|k| near(k).map(|d| (k, d))) {
            Some(hit) => Some(hit),
            None => nearest.filter(|(_, d)| *d <= NEAR_M),
        };
        match chosen {
            Some((k, d)) => placed[k].push(PlacedPhoto {
                photo: photo.clone(),
                distance_m: Some(d),
                nearest: None,
            }),
            None => apart.push(PlacedPhoto {
                photo: photo.clone(),
                distance_m: nearest.map(|(_, d)| d),
                nearest: nearest.map(|(k, _)| plan.points[k].name.clone()),
            }),
        }
    }
    let points = (plan.points.iter().zip(placed))
        .filter(|(p, photos)| p.photos > 0 || !photos.is_empty())
        .map(|(p, photos)| {
            let taken = photos.iter().filter(|x| x.photo.captured).count();
            let photos_taken = u32::try_from(taken).unwrap_or(u32::MAX);
            PointPhotos {
                point: p.name.clone(),
                seq: p.seq,
                photos_expected: p.photos,
                photos_taken,
                missing: (photos_taken < p.photos).then(|| {
                    format!(
                        "{photos_taken} of {} photos reported taken: not visited",
                        p.photos
                    )
                }),
                photos,
            }
        })
        .collect();
    PhotoReport { points, apart }
}

/// One line for the user per point with photos, and per photo taken near no point.
pub fn lines(report: &PhotoReport) -> Vec<String> {
    let mut out = Vec::new();
    for p in &report.points {
        let distances: Vec<String> = (p.photos.iter())
            .map(|x| match x.distance_m {
                Some(d) if x.photo.captured => format!("{d:.1} m"),
                Some(d) => format!("{d:.1} m, not captured"),
                None => "-".into(),
            })
            .collect();
        let from = if distances.is_empty() {
            String::new()
        } else {
            format!(" ({} from it)", distances.join(", "))
        };
        let missing = p
            .missing
            .as_ref()
            .map_or(String::new(), |m| format!(": {m}"));
        out.push(format!(
            "photos at {}: {} taken of {} expected{from}{missing}",
            p.point, p.photos_taken, p.photos_expected
        ));
    }
    for x in &report.apart {
        let near = match (&x.nearest, x.distance_m) {
            (Some(name), Some(d)) => format!("{d:.1} m from the nearest point, {name}"),
            _ => "where is unknown".into(),
        };
        out.push(format!(
            "photo {} at {:.1} s taken near no point ({near}; more than {NEAR_M} m)",
            x.photo.index, x.photo.t_s
        ));
    }
    out
}
