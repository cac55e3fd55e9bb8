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
#[cfg(test)]
use crate::mission::Geodetic;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::report::FlightReport;
    use crate::flightlog::segment::{SegmentConfig, Segmenter};
    use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
    use crate::flightlog::telemetry::{PhotoPosition, Reading, Stamped};

    /// The square with photos: one at A, two at B, one at C, none at the origin.
    fn plan() -> FlightPlan {
        let mut plan = square_plan();
        for (point, photos) in plan.points.iter_mut().zip([1, 2, 1, 0]) {
            point.photos = photos;
        }
        plan
    }

    fn report_of(plan: &FlightPlan, stamped: &[Stamped]) -> FlightReport {
        let s = Segmenter::run(plan.clone(), SegmentConfig::default(), stamped).expect("valid");
        FlightReport::build("f", &s)
    }

    fn flown(plan: &FlightPlan) -> Vec<Stamped> {
        SyntheticFlight::fly(plan, &SyntheticConfig::default()).stamped()
    }

    fn is_photo(m: &Stamped, index: i64) -> bool {
        matches!(&m.reading, Reading::Photo(p) if p.index == index)
    }

    #[test]
    fn each_photo_of_a_flight_is_assigned_to_the_waypoint_it_was_taken_at() {
        let plan = plan();
        let report = report_of(&plan, &flown(&plan));
        let photos = &report.photos;
        assert!(photos.apart.is_empty(), "{:?}", photos.apart);
        let counts: Vec<(&str, u32, u32)> = (photos.points.iter())
            .map(|p| (p.point.as_str(), p.photos_expected, p.photos_taken))
            .collect();
        assert_eq!(counts, [("A", 1, 1), ("B", 2, 2), ("C", 1, 1)]);
        for p in &photos.points {
            assert_eq!(p.missing, None);
            for x in &p.photos {
                // Taken on the point (the scripted vehicle stops on it): PX4's two messages are
                // one photo, placed where CAMERA_IMAGE_CAPTURED says.
                assert!(x.distance_m.expect("placed") < 0.01, "{x:?}");
                assert_eq!(
                    x.photo.messages,
                    ["CAMERA_TRIGGER", "CAMERA_IMAGE_CAPTURED"]
                );
                assert_eq!(x.photo.located_by, Some(LocatedBy::Message));
            }
        }
        let lines = lines(photos);
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert_eq!(
            lines[1],
            "photos at B: 2 taken of 2 expected (0.0 m, 0.0 m from it)"
        );
    }

    #[test]
    fn a_waypoint_with_a_photo_unreported_is_flagged_with_why() {
        let plan = plan();
        // The second photo at B (index 2) never reported.
        let stamped: Vec<Stamped> = (flown(&plan).into_iter())
            .filter(|m| !is_photo(m, 2))
            .collect();
        let report = report_of(&plan, &stamped);
        let b = &report.photos.points[1];
        assert_eq!((b.point.as_str(), b.photos_taken), ("B", 1));
        assert!(!b.complete());
        assert_eq!(
            b.missing.as_deref(),
            Some("1 of 2 photos reported taken: not visited")
        );
        assert!(report.photos.points[0].complete() && report.photos.points[2].complete());
        assert!(lines(&report.photos)[1].ends_with(": 1 of 2 photos reported taken: not visited"));
    }

    #[test]
    fn a_trigger_without_its_capture_is_placed_where_the_vehicle_was() {
        let plan = plan();
        let stamped: Vec<Stamped> = (flown(&plan).into_iter())
            .filter(|m| {
                !matches!(&m.reading, Reading::Photo(p) if p.message == PhotoMessage::ImageCaptured)
            })
            .collect();
        let report = report_of(&plan, &stamped);
        let taken: Vec<u32> = report
            .photos
            .points
            .iter()
            .map(|p| p.photos_taken)
            .collect();
        assert_eq!(taken, [1, 2, 1]);
        for x in report.photos.points.iter().flat_map(|p| &p.photos) {
            assert_eq!(x.photo.located_by, Some(LocatedBy::Vehicle));
            // The latest position, at most one 10 Hz sample before the photo, on the point.
            assert!(x.distance_m.expect("placed") < 0.5, "{x:?}");
        }
    }

    #[test]
    fn a_photo_near_no_point_is_listed_apart_with_the_nearest_and_a_failed_capture_is_not_counted()
    {
        let plan = plan();
        let mut stamped = flown(&plan);
        let far = plan.origin().to_geodetic(Enu {
            x_east_m: 30.0,
            y_north_m: 30.0,
            z_up_m: 0.0,
        });
        let t_s = stamped[stamped.len() / 2].t_s;
        let photo = |index: i64, at: Geodetic, captured: bool| Stamped {
            t_s,
            wall_us: 0,
            reading: Reading::Photo(Photo {
                message: PhotoMessage::CameraFeedback,
                index,
                at: Some(PhotoPosition {
                    lat_deg: at.lat_deg,
                    lon_deg: at.lon_deg,
                    alt_amsl_m: at.alt_m,
                    relative_alt_m: at.alt_m - plan.home.alt_m,
                }),
                camera_time_s: None,
                captured,
            }),
        };
        // A photo in the middle of the square, and a failed capture at C.
        stamped.push(photo(90, far, true));
        let c = plan.origin().to_geodetic(plan.points[2].enu);
        stamped.push(photo(91, c, false));
        stamped.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        let report = report_of(&plan, &stamped);
        assert_eq!(report.photos.apart.len(), 1);
        let apart = &report.photos.apart[0];
        assert_eq!(apart.photo.index, 90);
        // 30 m across, 30 m along: 42.4 m from every corner, nearest A (first of the ties
        // in the plan's order) and the origin.
        assert!(
            (apart.distance_m.expect("known") - 42.43).abs() < 0.1,
            "{apart:?}"
        );
        assert!(apart.nearest.is_some());
        let c = &report.photos.points[2];
        assert_eq!(
            (c.point.as_str(), c.photos.len(), c.photos_taken),
            ("C", 2, 1)
        );
        assert!(lines(&report.photos)
            .last()
            .expect("a line")
            .contains("taken near no point"));
    }

    #[test]
    fn the_photos_survive_the_report_json_as_a_replay_reads_it_back() {
        let plan = plan();
        let report = report_of(&plan, &flown(&plan));
        let text = serde_json::to_string(&report.json()).expect("serialises");
        let back: crate::flightlog::report::ReportJson =
            serde_json::from_str(&text).expect("parses");
        let again = FlightReport::from_json(&back).photos;
        // What a point's photos say, as the text and resume read them.
        type Said = (String, u32, u32, Vec<(i64, Vec<String>)>);
        let said = |r: &PhotoReport| -> Vec<Said> {
            (r.points.iter())
                .map(|p| {
                    let photos = (p.photos.iter())
                        .map(|x| (x.photo.index, x.photo.messages.clone()))
                        .collect();
                    (p.point.clone(), p.photos_expected, p.photos_taken, photos)
                })
                .collect()
        };
        assert_eq!(said(&again), said(&report.photos));
        assert_eq!(lines(&again), lines(&report.photos));
        // A report without photos has no photo keys at all (report.json files stay as they were).
        let plain = report_of(&square_plan(), &flown(&square_plan()));
        let text = serde_json::to_string(&plain.json()).expect("serialises");
        assert!(!text.contains("photo"), "{text}");
    }
}
