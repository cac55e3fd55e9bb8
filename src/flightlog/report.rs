//! Reports: per leg predicted vs measured energy, the settles, hovers, take-off and landing,
//! totals and flags, for one flight ([`FlightReport`]) or for repeated flights of the same legs
//! ([`combine`]: mean, sample standard deviation, min, max and count per leg, matched by (from,
//! to), as the paper averaged repeated operations). Energies are joules here; the JSON views
//! ([`ReportJson`], [`CombinedJson`]) are in kJ, the shape of docs/json.md:
//! `{"flight", "legs": [{"from", "to", "predicted_kj", "measured_kj", "error_pct", "duration_s",
//! "flags"}], "hovers": [..], "total": {"predicted_kj", "measured_kj"}}` plus take-off, landing,
//! settles, times, coverage and the spans of a replayed .tlog skipped as corrupt (`log_gaps`).
//! Which waypoints a flight visited ([`visits`]) is decided here, once: a report names the ones
//! left (`waypoints_left`) and `flightlog::resume` flies them. When the energy guard sent the
//! vehicle home, the way home and its landing are one part (`return_home`), priced as the guard
//! priced it when it decided.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::energy::{Flag, Measurement};
use super::flight_plan::{FlightPlan, PlannedPoint, ORIGIN_NAME};
use super::photos::{PhotoReport, PlacedPhoto, PointPhotos};
use super::segment::{Segment, SegmentKind, Segmenter};
use super::tlog::TlogGap;
use super::watch::{GuardReport, NoteKind};

/// A leg that begins further than this from the point it was planned to leave is flagged
/// `far_start` (m): five times the acceptance radius PX4 and ArduPilot default to (2 m). PX4 SITL's
/// legs begin 0.1-2 m off their point (docs/px4-sitl.md); a vehicle that took off away from the
/// mission's origin begins its first leg as far off as it stood.
pub const FAR_START_M: f64 = 10.0;

/// What a report measured from: the ground station's `.tlog` (live or replayed), or the flight
/// controller's own log (`ulog`, `dataflash`), with its battery sample rate and where it tore.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogSource {
    /// `tlog`, `ulog` or `dataflash`.
    pub format: String,
    /// Battery readings per second over the flight (None: fewer than two).
    pub battery_hz: Option<f64>,
    /// Where the log tore (a power cut mid-flight): the parts after it are missing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tear: Option<TearJson>,
    /// The records of an onboard log refused as corrupt (only when there were any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<SkippedJson>,
}

/// The records of an onboard log refused as corrupt: how many, and the first of them (its byte
/// offset, its message and why). Each is also one of the report's `log_gaps`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedJson {
    pub count: usize,
    pub offset: u64,
    pub record: String,
    pub reason: String,
}

/// Where a log tore: its byte offset, the log time of the last reading before it, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TearJson {
    pub offset: u64,
    pub after_s: Option<f64>,
    pub reason: String,
}

impl LogSource {
    /// A log of `format` whose battery readings came at `times` (seconds, in order).
    pub fn of(format: &str, times: &[f64]) -> LogSource {
        let battery_hz = match (times.first(), times.last()) {
            (Some(first), Some(last)) if times.len() > 1 && last > first => {
                Some((times.len() - 1) as f64 / (last - first))
            }
            _ => None,
        };
        LogSource {
            format: format.to_string(),
            battery_hz,
            tear: None,
            skipped: None,
        }
    }
}

/// One part of a flight, predicted and measured.
#[derive(Debug, Clone, PartialEq)]
pub struct PartReport {
    /// Where it starts (legs: the point left) and where it is (legs: the point reached).
    pub from: String,
    pub to: String,
    pub predicted_j: Option<f64>,
    pub measured_j: Option<f64>,
    /// The autopilot's charge counter x mean voltage.
    pub consumed_j: Option<f64>,
    pub duration_s: f64,
    pub predicted_duration_s: Option<f64>,
    pub start_s: f64,
    pub end_s: f64,
    pub coverage: f64,
    pub flags: Vec<Flag>,
    /// A leg's vehicle when it began: 3D distance from the point left and 3D speed.
    pub start_offset_m: Option<f64>,
    pub start_speed_m_s: Option<f64>,
    /// The via points a leg round a fence zone passed through (0: a straight leg, or not a
    /// leg): it is measured as one, from its departure to its arrival, against its chain's
    /// price.
    pub via_points: usize,
}

impl PartReport {
    /// (measured - predicted) / predicted in percent, for a complete part with both.
    pub fn error_pct(&self) -> Option<f64> {
        if self.flags.contains(&Flag::Incomplete) {
            return None;
        }
        match (self.predicted_j, self.measured_j) {
            (Some(p), Some(m)) if p > 0.0 => Some((m - p) / p * 100.0),
            _ => None,
        }
    }
}

/// Predicted vs measured energy of a whole flight.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightReport {
    pub flight: String,
    pub takeoff: Option<PartReport>,
    pub legs: Vec<PartReport>,
    pub settles: Vec<PartReport>,
    pub hovers: Vec<PartReport>,
    pub landing: Option<PartReport>,
    /// The way home after the energy guard sent the vehicle there, and its landing, in place of
    /// the plan's landing: priced as the guard priced it when it decided (its `return` note).
    pub return_home: Option<PartReport>,
    /// Where that way home went ("home", "rally point 1": the guard's `return` note's
    /// destination, as the autopilot's rule chose it when the guard priced it).
    pub return_to: Option<String>,
    /// The fence breaches the autopilot told (FENCE_STATUS), with where and when.
    pub breaches: Vec<super::breach::Breach>,
    /// The waypoints of the plan this flight did not visit (in the plan's order): what `fly
    /// --resume` flies ([`visits`]). Not empty: the mission is incomplete.
    pub waypoints_left: Vec<String>,
    /// Sum of the predicted parts, when the plan carries a prediction.
    pub predicted_j: Option<f64>,
    /// Arming to disarming.
    pub measured_j: Option<f64>,
    pub duration_s: f64,
    /// Whether the flight ended with a landing (not cut off).
    pub complete: bool,
    /// Every flag of every part.
    pub flags: Vec<Flag>,
    /// Spans of the replayed .tlog that were not records, skipped (none live).
    pub log_gaps: Vec<TlogGap>,
    /// What the energy guard saw and decided, when the flight was guarded.
    pub guard: Option<GuardReport>,
    /// The log measured (None: a report written before it was said).
    pub source: Option<LogSource>,
    /// The rest of the flight priced again in the wind the vehicle estimated in flight.
    pub repriced: Vec<RepricedNote>,
    /// The photos the autopilot reported, per point of the plan and apart
    /// (`flightlog::photos`).
    pub photos: PhotoReport,
    /// The plan's blocks (surveys, scans) as flown: each measured from the arrival at its
    /// entry to the arrival at its exit, and its photos.
    pub blocks: Vec<BlockReport>,
}

/// One block of the plan (`flight_plan::PlannedBlock`) as flown: its inner legs, and the
/// settles and hovers between them, predicted and measured as one part, from the arrival at
/// its entry (4 m) to the arrival at its exit, and the photos the autopilot reported taken in
/// that time (its distance trigger's, along its lines).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockReport {
    pub name: String,
    pub kind: String,
    pub reversed: bool,
    /// Its entry and exit points, as flown.
    pub from: String,
    pub to: String,
    /// How many legs it has (its lines and the turns between them).
    pub legs: usize,
    pub predicted_j: Option<f64>,
    /// None until the flight has arrived at its exit.
    pub measured_j: Option<f64>,
    pub duration_s: Option<f64>,
    pub predicted_duration_s: Option<f64>,
    /// About one per trigger distance of its lines flown with the camera trigger on.
    pub photos_expected: u32,
    pub photos_taken: u32,
}

impl BlockReport {
    /// The measurement's error against the prediction (%).
    pub fn error_pct(&self) -> Option<f64> {
        match (self.predicted_j, self.measured_j) {
            (Some(p), Some(m)) if p > 0.0 => Some((m - p) / p * 100.0),
            _ => None,
        }
    }

    /// One line for the user.
    pub fn line(&self) -> String {
        let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.3} kJ", j / 1e3));
        let error = self
            .error_pct()
            .map_or(String::new(), |e| format!(" ({e:+.1}%)"));
        format!(
            "{} {}{}: {} -> {}, {} legs: predicted {}, measured {}{error}; {} photos taken along its lines (about {} expected)",
            self.kind,
            self.name,
            if self.reversed { " (reversed)" } else { "" },
            self.from,
            self.to,
            self.legs,
            kj(self.predicted_j),
            kj(self.measured_j),
            self.photos_taken,
            self.photos_expected
        )
    }
}

/// Each block of the plan as `segments` flew it, with the photos of `photos` taken along it.
fn blocks(
    segmenter: &Segmenter,
    segments: &[Segment],
    photos: &[super::photos::TakenPhoto],
) -> Vec<BlockReport> {
    let plan = segmenter.plan();
    let arrival = |k: usize| {
        segments.iter().find_map(|s| match s.kind {
            SegmentKind::Leg(i) if i == k && s.complete => Some(s.end_s),
            _ => None,
        })
    };
    plan.blocks
        .iter()
        .map(|b| {
            let name = |k: usize| {
                plan.points
                    .get(k)
                    .map_or_else(String::new, |p| p.name.clone())
            };
            // The legs inside it, and the stops between them (at its entry up to the point
            // before its exit).
            let predicted = b
                .legs()
                .map(|k| plan.predicted_leg(k))
                .chain((b.first_point..b.last_point).map(|k| plan.predicted_leg(k)))
                .collect::<Option<Vec<_>>>();
            let n_legs = b.legs().count();
            let (predicted_j, predicted_duration_s) = match predicted {
                Some(legs) => {
                    let (inner, stops) = legs.split_at(n_legs);
                    let mut j: f64 = inner.iter().map(|l| l.energy_j).sum();
                    let mut t: f64 = inner.iter().map(|l| l.duration_s).sum();
                    for (k, l) in (b.first_point..b.last_point).zip(stops) {
                        let hold_s = plan.points.get(k).map_or(0.0, |p| p.hold_s);
                        let power = plan.predicted_hover_power_w(k).unwrap_or(0.0);
                        j += l.settle_energy_j + power * hold_s;
                        t += l.settle_duration_s + hold_s;
                    }
                    (Some(j), Some(t))
                }
                None => (None, None),
            };
            let span = arrival(b.first_point).zip(arrival(b.last_point));
            let measured = span.map(|(t0, t1)| segmenter.series().measure(t0, t1));
            let photos_taken = span.map_or(0, |(t0, t1)| {
                (photos.iter())
                    .filter(|p| p.captured && p.t_s >= t0 && p.t_s <= t1)
                    .count()
            });
            BlockReport {
                name: b.name.clone(),
                kind: b.kind.clone(),
                reversed: b.reversed,
                from: name(b.first_point),
                to: name(b.last_point),
                legs: n_legs,
                predicted_j,
                measured_j: measured.as_ref().and_then(|m| m.energy_j),
                duration_s: measured.map(|m| m.duration_s),
                predicted_duration_s,
                photos_expected: b.photos_expected(),
                photos_taken: u32::try_from(photos_taken).unwrap_or(u32::MAX),
            }
        })
        .collect()
}

/// The rest of a flight priced again in a wind heard in flight (`fly --wind live`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RepricedNote {
    /// Flight-log time (s).
    pub t_s: f64,
    pub wind: crate::mission::wind::Wind,
    /// The point whose leg was the first priced again.
    pub from: String,
    /// The stages from there on (legs, settles, hovers, the landing), priced before and after.
    pub rest_before_kj: f64,
    pub rest_after_kj: f64,
}

/// A repricing in a sentence, for the user.
pub fn repriced_line(r: &RepricedNote) -> String {
    format!(
        "wind now {:.1} m/s from {:.0} deg (the vehicle's estimate): the rest of the flight from {} priced again, {:.1} kJ -> {:.1} kJ",
        r.wind.speed_m_s, r.wind.from_deg, r.from, r.rest_before_kj, r.rest_after_kj
    )
}

impl RepricedNote {
    /// The note of repricing `r` of `plan`.
    pub fn of(plan: &super::flight_plan::FlightPlan, r: &super::flight_plan::Repricing) -> Self {
        RepricedNote {
            t_s: r.t_s,
            wind: r.wind,
            from: plan
                .points
                .get(r.from_point)
                .map_or_else(String::new, |p| p.name.clone()),
            rest_before_kj: r.rest_before_j / 1e3,
            rest_after_kj: r.rest_after_j / 1e3,
        }
    }
}

fn part(
    segmenter: &Segmenter,
    segment: &Segment,
    names: (String, String),
    predicted: Option<(f64, Option<f64>)>,
) -> PartReport {
    let via_points = match segment.kind {
        SegmentKind::Leg(k) => segmenter.plan().points.get(k).map_or(0, |p| p.via.len()),
        _ => 0,
    };
    let m: Measurement = segmenter.measure(segment);
    let mut flags = m.flags;
    if !segment.complete {
        flags.push(Flag::Incomplete);
    }
    if segment.missed_radius {
        flags.push(Flag::MissedRadius);
    }
    if segment
        .start_state
        .is_some_and(|s| s.offset_m > FAR_START_M)
    {
        flags.push(Flag::FarStart);
    }
    flags.sort();
    flags.dedup();
    PartReport {
        from: names.0,
        to: names.1,
        predicted_j: predicted.map(|p| p.0),
        measured_j: m.energy_j,
        consumed_j: m.consumed_j,
        duration_s: m.duration_s,
        predicted_duration_s: predicted.and_then(|p| p.1),
        start_s: segment.start_s,
        end_s: segment.end_s,
        coverage: m.coverage,
        flags,
        start_offset_m: segment.start_state.map(|s| s.offset_m),
        start_speed_m_s: segment.start_state.map(|s| s.speed_m_s),
        via_points,
    }
}

impl FlightReport {
    /// The report of a flight segmented so far (a flight in progress gives its parts so far,
    /// the last one `incomplete`).
    pub fn build(flight: &str, segmenter: &Segmenter) -> FlightReport {
        let plan = segmenter.plan();
        let predicted = plan.predicted.as_ref();
        let repriced = plan
            .repricings
            .iter()
            .map(|r| RepricedNote::of(plan, r))
            .collect();
        let point_name = |k: usize| {
            plan.points
                .get(k)
                .map_or_else(String::new, |p| p.name.clone())
        };
        let mut report = FlightReport {
            flight: flight.to_string(),
            takeoff: None,
            legs: Vec::new(),
            settles: Vec::new(),
            hovers: Vec::new(),
            landing: None,
            return_home: None,
            return_to: None,
            breaches: Vec::new(),
            waypoints_left: Vec::new(),
            predicted_j: None,
            measured_j: None,
            duration_s: 0.0,
            complete: false,
            flags: Vec::new(),
            log_gaps: Vec::new(),
            guard: segmenter.watch().map(|w| w.report()),
            source: Some(LogSource::of(
                "tlog",
                &(segmenter.series().samples().iter())
                    .filter(|s| s.primary)
                    .map(|s| s.t_s)
                    .collect::<Vec<_>>(),
            )),
            repriced,
            photos: PhotoReport::default(),
            blocks: Vec::new(),
        };
        let segments = segmenter.segments();
        report.photos = super::photos::assign(plan, &segments, segmenter.photos().photos());
        report.blocks = blocks(segmenter, &segments, segmenter.photos().photos());
        report.breaches = segmenter.breaches().to_vec();
        // The guard's decision to go home and its price of the way home from there.
        let sent_home = (report.guard.iter())
            .flat_map(|g| &g.notes)
            .find(|n| n.kind == NoteKind::Return);
        let sent_home_kj = sent_home.map(|n| n.home_kj);
        report.return_to = sent_home.map(|n| n.return_to.clone().unwrap_or_else(|| "home".into()));
        let mut last_point = ORIGIN_NAME.to_string();
        for segment in segments {
            match segment.kind {
                SegmentKind::Takeoff => {
                    let p = predicted.map(|p| (p.takeoff_j, None));
                    report.takeoff = Some(part(
                        segmenter,
                        &segment,
                        ("ground".into(), ORIGIN_NAME.into()),
                        p,
                    ));
                }
                SegmentKind::Leg(k) => {
                    let p = plan
                        .predicted_leg(k)
                        .map(|l| (l.energy_j, Some(l.duration_s)));
                    report
                        .legs
                        .push(part(segmenter, &segment, plan.leg_names(k), p));
                }
                SegmentKind::Settle(k) => {
                    let p = plan
                        .predicted_leg(k)
                        .map(|l| (l.settle_energy_j, Some(l.settle_duration_s)));
                    let name = point_name(k);
                    report
                        .settles
                        .push(part(segmenter, &segment, (name.clone(), name), p));
                }
                SegmentKind::Hover(k) => {
                    let hold_s = plan.points.get(k).map_or(0.0, |p| p.hold_s);
                    let p = plan
                        .predicted_hover_power_w(k)
                        .map(|w| (w * hold_s, Some(hold_s)));
                    let name = point_name(k);
                    report
                        .hovers
                        .push(part(segmenter, &segment, (name.clone(), name), p));
                }
                SegmentKind::Landing => match sent_home_kj {
                    Some(home_kj) => {
                        let p = home_kj.map(|kj| (kj * 1e3, None));
                        let names = (last_point.clone(), "ground".into());
                        report.return_home = Some(part(segmenter, &segment, names, p));
                    }
                    None => {
                        let p = plan.predicted_landing_j().map(|j| (j, None));
                        report.landing = Some(part(
                            segmenter,
                            &segment,
                            (ORIGIN_NAME.into(), "ground".into()),
                            p,
                        ));
                    }
                },
            }
            last_point = match segment.kind {
                SegmentKind::Settle(k) | SegmentKind::Hover(k) => point_name(k),
                SegmentKind::Leg(k) if segment.complete => point_name(k),
                _ => last_point,
            };
        }
        report.predicted_j = plan.predicted_total_j();
        if let Some((start, end)) = segmenter.flight_span() {
            let whole = segmenter.series().measure(start, end);
            report.measured_j = whole.energy_j;
            report.duration_s = whole.duration_s;
        }
        report.complete = segmenter.is_finished()
            && (report.landing.as_ref())
                .or(report.return_home.as_ref())
                .is_some_and(|l| !l.flags.contains(&Flag::Incomplete));
        report.waypoints_left = visits(plan, &report)
            .into_iter()
            .filter(|v| v.visit != Visit::Visited)
            .map(|v| v.name)
            .collect();
        let mut flags: Vec<Flag> = report
            .parts()
            .flat_map(|p| p.flags.iter().copied())
            .collect();
        if !report.complete {
            flags.push(Flag::Incomplete);
        }
        flags.sort();
        flags.dedup();
        report.flags = flags;
        report
    }

    /// Every part in flight order by kind: take-off, legs, settles, hovers, landing (or the
    /// way home the guard sent the vehicle).
    pub fn parts(&self) -> impl Iterator<Item = &PartReport> {
        self.takeoff
            .iter()
            .chain(&self.legs)
            .chain(&self.settles)
            .chain(&self.hovers)
            .chain(self.landing.iter())
            .chain(self.return_home.iter())
    }

    /// Whether the mission was left unfinished: waypoints of the plan not visited.
    pub fn incomplete(&self) -> bool {
        !self.waypoints_left.is_empty()
    }

    /// The total's error against the plan's prediction (%): only for a flight that landed
    /// having flown the whole plan (a mission cut short flew less than the plan priced).
    pub fn total_error_pct(&self) -> Option<f64> {
        match (self.predicted_j, self.measured_j) {
            (Some(p), Some(m)) if p > 0.0 && self.complete && !self.incomplete() => {
                Some((m - p) / p * 100.0)
            }
            _ => None,
        }
    }

    /// Each point's settle and hover as one part, in flight order. Only their sum compares:
    /// the model ends a settle where the autopilot accepts the point (PX4 starts its hold
    /// there, while the vehicle still brakes) or after the profile's settle hover (ptf, hvb),
    /// the measurement where the vehicle stops inside the arrival radius, so the same flight
    /// splits its time at a point at different moments (sample 8 on the mock: settles +140%,
    /// hovers -45%, the sum right). A settle without its hover (the flight in progress or cut
    /// short) is a part alone, as is a hover without its settle (a log begun in flight).
    pub fn at_points(&self) -> Vec<PartReport> {
        let mut hovers: Vec<Option<&PartReport>> = self.hovers.iter().map(Some).collect();
        let mut parts: Vec<PartReport> = self
            .settles
            .iter()
            .map(|settle| {
                let hover = hovers.iter_mut().find(|h| {
                    h.is_some_and(|h| h.to == settle.to && (h.start_s - settle.end_s).abs() < 1e-6)
                });
                match hover.and_then(Option::take) {
                    Some(hover) => joined(settle, hover),
                    None => settle.clone(),
                }
            })
            .collect();
        parts.extend(hovers.into_iter().flatten().cloned());
        parts.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        parts
    }

    /// The JSON view (kJ).
    pub fn json(&self) -> ReportJson {
        ReportJson {
            flight: self.flight.clone(),
            legs: self.legs.iter().map(PartJson::from).collect(),
            hovers: self.hovers.iter().map(PartJson::from).collect(),
            settles: self.settles.iter().map(PartJson::from).collect(),
            at_points: self.at_points().iter().map(PartJson::from).collect(),
            takeoff: self.takeoff.as_ref().map(PartJson::from),
            landing: self.landing.as_ref().map(PartJson::from),
            return_home: self.return_home.as_ref().map(PartJson::from),
            return_to: self.return_home.as_ref().and(self.return_to.clone()),
            breaches: self.breaches.clone(),
            total: TotalJson {
                predicted_kj: self.predicted_j.map(kj),
                measured_kj: self.measured_j.map(kj),
                error_pct: self.total_error_pct(),
                duration_s: self.duration_s,
            },
            complete: self.complete,
            incomplete: self.incomplete(),
            waypoints_left: self.waypoints_left.clone(),
            flags: self.flags.clone(),
            log_gaps: self.log_gaps.clone(),
            guard: self.guard.clone(),
            source: self.source.clone(),
            repriced: self.repriced.clone(),
            photo_points: self.photos.points.clone(),
            photos_apart: self.photos.apart.clone(),
            blocks: self.blocks.iter().map(BlockJson::from).collect(),
        }
    }

    /// A report from its JSON view (what report.json holds).
    pub fn from_json(json: &ReportJson) -> FlightReport {
        let parts = |v: &[PartJson]| v.iter().map(PartJson::to_part).collect::<Vec<_>>();
        FlightReport {
            flight: json.flight.clone(),
            takeoff: json.takeoff.as_ref().map(PartJson::to_part),
            legs: parts(&json.legs),
            settles: parts(&json.settles),
            hovers: parts(&json.hovers),
            landing: json.landing.as_ref().map(PartJson::to_part),
            return_home: json.return_home.as_ref().map(PartJson::to_part),
            return_to: json.return_to.clone(),
            breaches: json.breaches.clone(),
            waypoints_left: json.waypoints_left.clone(),
            predicted_j: json.total.predicted_kj.map(j),
            measured_j: json.total.measured_kj.map(j),
            duration_s: json.total.duration_s,
            complete: json.complete,
            flags: json.flags.clone(),
            log_gaps: json.log_gaps.clone(),
            guard: json.guard.clone(),
            source: json.source.clone(),
            repriced: json.repriced.clone(),
            photos: PhotoReport {
                points: json.photo_points.clone(),
                apart: json.photos_apart.clone(),
            },
            blocks: json.blocks.iter().map(BlockJson::to_block).collect(),
        }
    }
}

/// What a flight did at one of its waypoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Visit {
    /// Arrived, and hovered its time.
    Visited,
    /// Arrived, but the hover was cut short: not counted as visited.
    CutShort,
    /// Arrived and hovered, but the autopilot reported fewer photos there than the mission takes:
    /// not counted as visited.
    PhotosMissing,
    NotReached,
}

/// One waypoint of a flight's plan and what the flight did there.
#[derive(Debug, Clone, PartialEq)]
pub struct PointVisit {
    pub name: String,
    pub visit: Visit,
    /// The leg that arrived there.
    pub leg: Option<PartReport>,
    /// Its settle and hover as one part (`FlightReport::at_points`).
    pub at_point: Option<PartReport>,
}

/// The waypoints of a plan (every point but the return to the origin), with their index.
pub fn plan_waypoints(plan: &FlightPlan) -> impl Iterator<Item = (usize, &PlannedPoint)> {
    plan.points.iter().enumerate().filter(|(_, p)| {
        let at_origin = p.enu.x_east_m.hypot(p.enu.y_north_m).hypot(p.enu.z_up_m) < 1e-6;
        !(p.name == ORIGIN_NAME && at_origin)
    })
}

/// What `report`'s flight did at each waypoint of `plan` (the plan it was measured against), in
/// the plan's order. The report's legs and at-point parts come in flight order, so each is
/// matched to the next point of its name. The rule of `flightlog::resume`: a waypoint is
/// visited when the flight arrived and its hover ran its course with every photo taken.
pub fn visits(plan: &FlightPlan, report: &FlightReport) -> Vec<PointVisit> {
    let at_points = report.at_points();
    let legs = in_plan_order(plan, &report.legs);
    let arrivals = in_plan_order(plan, &at_points);
    plan_waypoints(plan)
        .map(|(k, point)| {
            let at_point = arrivals[k].cloned();
            let leg = legs[k].cloned();
            let photos_taken = (report.photos.points.iter())
                .find(|p| p.seq == point.seq && p.point == point.name)
                .map_or(0, |p| p.photos_taken);
            let visit = match &at_point {
                None => Visit::NotReached,
                Some(p) if p.flags.contains(&Flag::Incomplete) && point.hold_s > 0.0 => {
                    Visit::CutShort
                }
                Some(_) if photos_taken < point.photos => Visit::PhotosMissing,
                Some(_) => Visit::Visited,
            };
            PointVisit {
                name: point.name.clone(),
                visit,
                leg,
                at_point,
            }
        })
        .collect()
}

/// Parts ending at plan points (`to`), each placed at the next point of its name after the one
/// before it: one slot per point.
fn in_plan_order<'a>(plan: &FlightPlan, parts: &'a [PartReport]) -> Vec<Option<&'a PartReport>> {
    let mut slots = vec![None; plan.points.len()];
    let mut next = 0;
    for part in parts {
        if let Some(k) = (next..plan.points.len()).find(|&k| plan.points[k].name == part.to) {
            slots[k] = Some(part);
            next = k + 1;
        }
    }
    slots
}

/// Two consecutive parts as one: energies and times added (a sum only when both have it),
/// coverage weighted by duration, every flag of either.
pub fn joined(a: &PartReport, b: &PartReport) -> PartReport {
    let both = |x: Option<f64>, y: Option<f64>| x.zip(y).map(|(x, y)| x + y);
    let duration_s = a.duration_s + b.duration_s;
    let coverage = if duration_s > 0.0 {
        (a.coverage * a.duration_s + b.coverage * b.duration_s) / duration_s
    } else {
        a.coverage.min(b.coverage)
    };
    let mut flags: Vec<Flag> = a.flags.iter().chain(&b.flags).copied().collect();
    flags.sort();
    flags.dedup();
    PartReport {
        from: a.from.clone(),
        to: b.to.clone(),
        predicted_j: both(a.predicted_j, b.predicted_j),
        measured_j: both(a.measured_j, b.measured_j),
        consumed_j: both(a.consumed_j, b.consumed_j),
        duration_s,
        predicted_duration_s: both(a.predicted_duration_s, b.predicted_duration_s),
        start_s: a.start_s.min(b.start_s),
        end_s: a.end_s.max(b.end_s),
        coverage,
        flags,
        start_offset_m: a.start_offset_m,
        start_speed_m_s: a.start_speed_m_s,
        via_points: a.via_points.max(b.via_points),
    }
}

fn kj(j: f64) -> f64 {
    j / 1000.0
}

fn j(kj: f64) -> f64 {
    kj * 1000.0
}

/// One part in the report JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartJson {
    pub from: String,
    pub to: String,
    pub predicted_kj: Option<f64>,
    pub measured_kj: Option<f64>,
    pub error_pct: Option<f64>,
    pub duration_s: f64,
    pub predicted_duration_s: Option<f64>,
    pub consumed_kj: Option<f64>,
    pub start_s: f64,
    pub end_s: f64,
    pub coverage: f64,
    pub flags: Vec<Flag>,
    /// A leg's vehicle when it began (absent from reports written before they were kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_offset_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_speed_m_s: Option<f64>,
    /// A leg's via points round a fence zone (absent for a straight leg and from reports
    /// written before they were kept).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub via_points: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl From<&PartReport> for PartJson {
    fn from(p: &PartReport) -> PartJson {
        PartJson {
            from: p.from.clone(),
            to: p.to.clone(),
            predicted_kj: p.predicted_j.map(kj),
            measured_kj: p.measured_j.map(kj),
            error_pct: p.error_pct(),
            duration_s: p.duration_s,
            predicted_duration_s: p.predicted_duration_s,
            consumed_kj: p.consumed_j.map(kj),
            start_s: p.start_s,
            end_s: p.end_s,
            coverage: p.coverage,
            flags: p.flags.clone(),
            start_offset_m: p.start_offset_m,
            start_speed_m_s: p.start_speed_m_s,
            via_points: p.via_points,
        }
    }
}

impl PartJson {
    /// The part a JSON view shows (energies back in J).
    pub fn to_part(&self) -> PartReport {
        PartReport {
            from: self.from.clone(),
            to: self.to.clone(),
            predicted_j: self.predicted_kj.map(j),
            measured_j: self.measured_kj.map(j),
            consumed_j: self.consumed_kj.map(j),
            duration_s: self.duration_s,
            predicted_duration_s: self.predicted_duration_s,
            start_s: self.start_s,
            end_s: self.end_s,
            coverage: self.coverage,
            flags: self.flags.clone(),
            start_offset_m: self.start_offset_m,
            start_speed_m_s: self.start_speed_m_s,
            via_points: self.via_points,
        }
    }
}

/// Totals in the report JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TotalJson {
    pub predicted_kj: Option<f64>,
    pub measured_kj: Option<f64>,
    pub error_pct: Option<f64>,
    pub duration_s: f64,
}

/// The report JSON of one flight (report.json, `emplan report --json`, `fly --json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReportJson {
    pub flight: String,
    pub legs: Vec<PartJson>,
    pub hovers: Vec<PartJson>,
    pub settles: Vec<PartJson>,
    /// Each point's settle and hover as one part ([`FlightReport::at_points`]): the model
    /// and the measurement split a point's time at different moments, so only this compares.
    /// Absent from report.json files written before it.
    #[serde(default)]
    pub at_points: Vec<PartJson>,
    pub takeoff: Option<PartJson>,
    pub landing: Option<PartJson>,
    /// The way home the energy guard sent the vehicle, with its landing, in place of `landing`
    /// (`predicted_kj`: the guard's price of it, from the point named `from`); absent otherwise.
    #[serde(rename = "return", default, skip_serializing_if = "Option::is_none")]
    pub return_home: Option<PartJson>,
    /// Where `return` went ("home", "rally point 1"); only with `return`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub return_to: Option<String>,
    /// The fence breaches the autopilot told, with where and when; absent when none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub breaches: Vec<super::breach::Breach>,
    pub total: TotalJson,
    pub complete: bool,
    /// The mission was left unfinished: `waypoints_left` names the waypoints of the plan the
    /// flight did not visit (what `fly --resume` flies). Absent from reports written before.
    #[serde(default)]
    pub incomplete: bool,
    #[serde(default)]
    pub waypoints_left: Vec<String>,
    pub flags: Vec<Flag>,
    /// Spans of the .tlog skipped as not records: `{"offset", "bytes", "from_s", "to_s",
    /// "from_wall_us", "to_wall_us"}` (absent from reports written before they were kept).
    #[serde(default)]
    pub log_gaps: Vec<TlogGap>,
    /// What the energy guard saw and decided (absent when the flight was not guarded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guard: Option<GuardReport>,
    /// The log measured: `{"format": "tlog"|"ulog"|"dataflash", "battery_hz", "tear"?, "skipped"?}` (absent
    /// from reports written before it was said).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<LogSource>,
    /// The rest of the flight priced again in the wind the vehicle estimated in flight
    /// (`fly --wind live`; absent when it was not).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub repriced: Vec<RepricedNote>,
    /// Per point of the plan with photo actions or photos: the photos expected and taken there
    /// (`flightlog::photos`; absent when there are none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub photo_points: Vec<PointPhotos>,
    /// The photos taken near no point of the plan (absent when there are none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub photos_apart: Vec<PlacedPhoto>,
    /// The plan's blocks (surveys, scans) as flown ([`BlockReport`]; absent when the plan has
    /// none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<BlockJson>,
}

/// A block as flown in the report JSON (kJ).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockJson {
    pub name: String,
    pub kind: String,
    pub reversed: bool,
    pub from: String,
    pub to: String,
    pub legs: usize,
    pub predicted_kj: Option<f64>,
    pub measured_kj: Option<f64>,
    pub error_pct: Option<f64>,
    pub duration_s: Option<f64>,
    pub predicted_duration_s: Option<f64>,
    pub photos_expected: u32,
    pub photos_taken: u32,
}

impl From<&BlockReport> for BlockJson {
    fn from(b: &BlockReport) -> Self {
        BlockJson {
            name: b.name.clone(),
            kind: b.kind.clone(),
            reversed: b.reversed,
            from: b.from.clone(),
            to: b.to.clone(),
            legs: b.legs,
            predicted_kj: b.predicted_j.map(kj),
            measured_kj: b.measured_j.map(kj),
            error_pct: b.error_pct(),
            duration_s: b.duration_s,
            predicted_duration_s: b.predicted_duration_s,
            photos_expected: b.photos_expected,
            photos_taken: b.photos_taken,
        }
    }
}

impl BlockJson {
    pub fn to_block(&self) -> BlockReport {
        BlockReport {
            name: self.name.clone(),
            kind: self.kind.clone(),
            reversed: self.reversed,
            from: self.from.clone(),
            to: self.to.clone(),
            legs: self.legs,
            predicted_j: self.predicted_kj.map(j),
            measured_j: self.measured_kj.map(j),
            duration_s: self.duration_s,
            predicted_duration_s: self.predicted_duration_s,
            photos_expected: self.photos_expected,
            photos_taken: self.photos_taken,
        }
    }
}

/// One leg of a flight measured from two logs of it: the ground station's `.tlog` and the flight
/// controller's own log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LegSourcesJson {
    pub from: String,
    pub to: String,
    pub predicted_kj: Option<f64>,
    pub tlog_kj: Option<f64>,
    pub onboard_kj: Option<f64>,
    /// (onboard - tlog) / tlog in percent, when both measured it.
    pub difference_pct: Option<f64>,
    /// The leg's time in each log: the two segment the flight on their own.
    pub tlog_duration_s: Option<f64>,
    pub onboard_duration_s: Option<f64>,
}

/// `emplan report FLIGHT_DIR --onboard FILE --json`: both reports and their legs side by side.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourcesJson {
    pub tlog: ReportJson,
    pub onboard: ReportJson,
    pub legs: Vec<LegSourcesJson>,
}

/// The legs of two reports of one flight side by side, matched in flying order by their points
/// (a leg one log has and the other does not has only one side).
pub fn compare_sources(tlog: &FlightReport, onboard: &FlightReport) -> SourcesJson {
    let mut legs: Vec<LegSourcesJson> = Vec::new();
    let mut next = 0;
    let side = |p: &PartReport| (p.measured_j.map(kj), Some(p.duration_s));
    for a in &tlog.legs {
        let found = (next..onboard.legs.len())
            .find(|&k| onboard.legs[k].from == a.from && onboard.legs[k].to == a.to);
        let b = found.map(|k| &onboard.legs[k]);
        if let Some(k) = found {
            next = k + 1;
        }
        let (tlog_kj, tlog_duration_s) = side(a);
        let (onboard_kj, onboard_duration_s) = b.map_or((None, None), side);
        legs.push(LegSourcesJson {
            from: a.from.clone(),
            to: a.to.clone(),
            predicted_kj: a.predicted_j.map(kj),
            tlog_kj,
            onboard_kj,
            difference_pct: match (tlog_kj, onboard_kj) {
                (Some(t), Some(o)) if t > 0.0 => Some((o - t) / t * 100.0),
                _ => None,
            },
            tlog_duration_s,
            onboard_duration_s,
        });
    }
    SourcesJson {
        tlog: tlog.json(),
        onboard: onboard.json(),
        legs,
    }
}

/// Statistics of one quantity over repeated flights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    pub n: usize,
    pub mean: f64,
    /// Sample standard deviation (n - 1); 0 for a single value.
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

impl Stats {
    /// Statistics of `values`; None when empty.
    pub fn of(values: &[f64]) -> Option<Stats> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        Some(Stats {
            n,
            mean,
            std: var.sqrt(),
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }
}

/// One part over repeated flights.
#[derive(Debug, Clone, PartialEq)]
pub struct CombinedPart {
    pub from: String,
    pub to: String,
    /// Flights in which the part appears.
    pub flights: usize,
    /// The prediction (the mean if flights predicted differently).
    pub predicted_j: Option<f64>,
    /// Over the flights where it was measured, complete.
    pub measured: Option<Stats>,
    pub duration: Option<Stats>,
    /// Every flag seen on it.
    pub flags: Vec<Flag>,
}

impl CombinedPart {
    pub fn error_pct(&self) -> Option<f64> {
        match (self.predicted_j, self.measured) {
            (Some(p), Some(m)) if p > 0.0 => Some((m.mean - p) / p * 100.0),
            _ => None,
        }
    }
}

/// Repeated flights combined.
#[derive(Debug, Clone, PartialEq)]
pub struct CombinedReport {
    pub flights: Vec<String>,
    pub legs: Vec<CombinedPart>,
    pub hovers: Vec<CombinedPart>,
    pub takeoff: Option<CombinedPart>,
    pub landing: Option<CombinedPart>,
    /// The whole mission (take-off to landing) over the complete flights: from `ground` to
    /// `ground`.
    pub mission: Option<CombinedPart>,
}

fn combine_parts<'a>(parts: impl IntoIterator<Item = &'a PartReport>) -> Vec<CombinedPart> {
    // Keyed by (from, to), in order of first appearance.
    let mut order: Vec<(String, String)> = Vec::new();
    let mut groups: BTreeMap<(String, String), Vec<&PartReport>> = BTreeMap::new();
    for p in parts {
        let key = (p.from.clone(), p.to.clone());
        if !groups.contains_key(&key) {
            order.push(key.clone());
        }
        groups.entry(key).or_default().push(p);
    }
    order
        .into_iter()
        .filter_map(|key| {
            let group = groups.get(&key)?;
            let usable: Vec<&&PartReport> = group
                .iter()
                .filter(|p| !p.flags.contains(&Flag::Incomplete))
                .collect();
            let measured: Vec<f64> = usable.iter().filter_map(|p| p.measured_j).collect();
            let durations: Vec<f64> = usable.iter().map(|p| p.duration_s).collect();
            let predictions: Vec<f64> = group.iter().filter_map(|p| p.predicted_j).collect();
            let mut flags: Vec<Flag> = group.iter().flat_map(|p| p.flags.iter().copied()).collect();
            flags.sort();
            flags.dedup();
            Some(CombinedPart {
                from: key.0,
                to: key.1,
                flights: group.len(),
                predicted_j: Stats::of(&predictions).map(|s| s.mean),
                measured: Stats::of(&measured),
                duration: Stats::of(&durations),
                flags,
            })
        })
        .collect()
}

/// Combines repeated flights of the same legs: per leg (matched by from and to) and per hover
/// the mean, spread, min and max of the complete measurements.
pub fn combine(reports: &[FlightReport]) -> CombinedReport {
    CombinedReport {
        flights: reports.iter().map(|r| r.flight.clone()).collect(),
        legs: combine_parts(reports.iter().flat_map(|r| &r.legs)),
        hovers: combine_parts(reports.iter().flat_map(|r| &r.hovers)),
        takeoff: combine_parts(reports.iter().filter_map(|r| r.takeoff.as_ref()))
            .into_iter()
            .next(),
        landing: combine_parts(reports.iter().filter_map(|r| r.landing.as_ref()))
            .into_iter()
            .next(),
        mission: combine_parts(&reports.iter().map(mission_part).collect::<Vec<_>>())
            .into_iter()
            .next(),
    }
}

/// A whole flight as one part (an incomplete flight flagged so, which combining leaves out).
fn mission_part(r: &FlightReport) -> PartReport {
    let mut flags = r.flags.clone();
    if !r.complete {
        flags.push(Flag::Incomplete);
    }
    PartReport {
        from: "ground".into(),
        to: "ground".into(),
        predicted_j: r.predicted_j,
        measured_j: r.measured_j,
        consumed_j: None,
        duration_s: r.duration_s,
        predicted_duration_s: None,
        start_s: 0.0,
        end_s: r.duration_s,
        coverage: 1.0,
        flags,
        start_offset_m: None,
        start_speed_m_s: None,
        via_points: 0,
    }
}

/// Statistics in kJ (or seconds) for the JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StatsJson {
    pub n: usize,
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

fn stats_json(s: Stats, scale: f64) -> StatsJson {
    StatsJson {
        n: s.n,
        mean: s.mean * scale,
        std: s.std * scale,
        min: s.min * scale,
        max: s.max * scale,
    }
}

/// One combined part in JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CombinedPartJson {
    pub from: String,
    pub to: String,
    pub flights: usize,
    pub predicted_kj: Option<f64>,
    /// Mean of the measurements.
    pub measured_kj: Option<f64>,
    pub error_pct: Option<f64>,
    pub measured_stats_kj: Option<StatsJson>,
    pub duration_stats_s: Option<StatsJson>,
    pub flags: Vec<Flag>,
}

impl From<&CombinedPart> for CombinedPartJson {
    fn from(p: &CombinedPart) -> CombinedPartJson {
        CombinedPartJson {
            from: p.from.clone(),
            to: p.to.clone(),
            flights: p.flights,
            predicted_kj: p.predicted_j.map(kj),
            measured_kj: p.measured.map(|s| kj(s.mean)),
            error_pct: p.error_pct(),
            measured_stats_kj: p.measured.map(|s| stats_json(s, 1e-3)),
            duration_stats_s: p.duration.map(|s| stats_json(s, 1.0)),
            flags: p.flags.clone(),
        }
    }
}

/// The combined report in JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CombinedJson {
    pub flights: Vec<String>,
    pub legs: Vec<CombinedPartJson>,
    pub hovers: Vec<CombinedPartJson>,
    pub takeoff: Option<CombinedPartJson>,
    pub landing: Option<CombinedPartJson>,
    /// The whole mission over the complete flights.
    #[serde(default)]
    pub mission: Option<CombinedPartJson>,
}

impl CombinedReport {
    pub fn json(&self) -> CombinedJson {
        CombinedJson {
            flights: self.flights.clone(),
            legs: self.legs.iter().map(CombinedPartJson::from).collect(),
            hovers: self.hovers.iter().map(CombinedPartJson::from).collect(),
            takeoff: self.takeoff.as_ref().map(CombinedPartJson::from),
            landing: self.landing.as_ref().map(CombinedPartJson::from),
            mission: self.mission.as_ref().map(CombinedPartJson::from),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leg(
        from: &str,
        to: &str,
        predicted: f64,
        measured: Option<f64>,
        flags: Vec<Flag>,
    ) -> PartReport {
        PartReport {
            from: from.into(),
            to: to.into(),
            predicted_j: Some(predicted),
            measured_j: measured,
            consumed_j: None,
            duration_s: 10.0,
            predicted_duration_s: Some(9.5),
            start_s: 0.0,
            end_s: 10.0,
            coverage: 1.0,
            flags,
            start_offset_m: None,
            start_speed_m_s: None,
            via_points: 0,
        }
    }

    fn report(name: &str, legs: Vec<PartReport>) -> FlightReport {
        FlightReport {
            flight: name.into(),
            takeoff: None,
            legs,
            settles: vec![],
            hovers: vec![],
            landing: None,
            return_home: None,
            return_to: None,
            breaches: Vec::new(),
            waypoints_left: vec![],
            predicted_j: Some(60_000.0),
            measured_j: Some(61_000.0),
            duration_s: 100.0,
            complete: true,
            flags: vec![],
            log_gaps: vec![],
            guard: None,
            source: None,
            repriced: vec![],
            photos: PhotoReport::default(),
            blocks: Vec::new(),
        }
    }

    #[test]
    fn a_leg_begun_far_from_its_point_is_flagged_far_start() {
        use crate::flightlog::segment::{SegmentConfig, Segmenter};
        use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
        let plan = square_plan();
        let flight = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
        let s = Segmenter::run(plan, SegmentConfig::default(), &flight.stamped()).expect("valid");
        let leg = *s
            .completed()
            .iter()
            .find(|x| x.kind == SegmentKind::Leg(0))
            .expect("leg 0");
        let names = || ("origin".to_string(), "A".to_string());
        let near = part(&s, &leg, names(), None);
        assert!(!near.flags.contains(&Flag::FarStart), "{near:?}");
        for (offset_m, far) in [(FAR_START_M - 0.5, false), (FAR_START_M + 0.5, true)] {
            let mut moved = leg;
            moved.start_state = Some(crate::flightlog::segment::StartState {
                offset_m,
                speed_m_s: 0.0,
            });
            let p = part(&s, &moved, names(), None);
            assert_eq!(p.flags.contains(&Flag::FarStart), far, "{offset_m}: {p:?}");
        }
    }

    #[test]
    fn repeated_legs_are_combined_by_their_ends_with_mean_spread_and_range() {
        let a = report(
            "f1",
            vec![
                leg("origin", "A", 20_000.0, Some(19_000.0), vec![]),
                leg("A", "B", 30_000.0, Some(33_000.0), vec![]),
            ],
        );
        let b = report(
            "f2",
            vec![
                leg("A", "B", 30_000.0, Some(31_000.0), vec![Flag::TelemetryGap]),
                leg("origin", "A", 20_000.0, Some(21_000.0), vec![]),
            ],
        );
        let c = report(
            "f3",
            vec![
                leg("origin", "A", 20_000.0, Some(23_000.0), vec![]),
                leg("A", "B", 30_000.0, Some(99_000.0), vec![Flag::Incomplete]),
                leg("B", "origin", 25_000.0, None, vec![Flag::Unmeasurable]),
            ],
        );
        let mut c = c;
        c.complete = false;
        c.measured_j = Some(40_000.0);
        let mut b = b;
        b.measured_j = Some(63_000.0);
        let combined = combine(&[a, b, c]);
        assert_eq!(combined.flights, ["f1", "f2", "f3"]);
        // The mission over the complete flights: 61 and 63 of 60 kJ predicted.
        let mission = combined.mission.as_ref().expect("the mission");
        assert_eq!(
            (mission.flights, mission.measured.map(|m| m.n)),
            (3, Some(2))
        );
        assert!((mission.error_pct().expect("both") - 100.0 / 30.0).abs() < 1e-9);
        let oa = &combined.legs[0];
        assert_eq!(
            (oa.from.as_str(), oa.to.as_str(), oa.flights),
            ("origin", "A", 3)
        );
        let m = oa.measured.expect("measured");
        // 19, 21, 23 kJ: mean 21, sample std 2.
        assert_eq!(
            (m.n, m.mean, m.min, m.max),
            (3, 21_000.0, 19_000.0, 23_000.0)
        );
        assert!((m.std - 2000.0).abs() < 1e-9);
        assert!((oa.error_pct().expect("both") - 5.0).abs() < 1e-9);
        // The incomplete A->B of f3 does not count; its flag is kept.
        let ab = &combined.legs[1];
        let m = ab.measured.expect("measured");
        assert_eq!((m.n, m.mean), (2, 32_000.0));
        assert!(ab.flags.contains(&Flag::Incomplete) && ab.flags.contains(&Flag::TelemetryGap));
        let bo = &combined.legs[2];
        assert_eq!((bo.flights, bo.measured), (1, None));
        let json = serde_json::to_value(combined.json()).expect("serialises");
        assert_eq!(json["legs"][0]["measured_kj"], serde_json::json!(21.0));
        assert_eq!(
            json["legs"][0]["measured_stats_kj"]["std"],
            serde_json::json!(2.0)
        );
    }

    #[test]
    fn the_json_view_is_in_kilojoules_with_null_for_unmeasurable_and_reads_back() {
        let r = report(
            "f1",
            vec![
                leg("origin", "A", 20_000.0, Some(22_000.0), vec![]),
                leg(
                    "A",
                    "origin",
                    25_000.0,
                    None,
                    vec![Flag::TelemetryGap, Flag::Unmeasurable],
                ),
            ],
        );
        let json = serde_json::to_value(r.json()).expect("serialises");
        assert_eq!(json["flight"], "f1");
        assert_eq!(json["legs"][0]["from"], "origin");
        assert_eq!(json["legs"][0]["predicted_kj"], serde_json::json!(20.0));
        assert_eq!(json["legs"][0]["measured_kj"], serde_json::json!(22.0));
        assert_eq!(json["legs"][0]["error_pct"], serde_json::json!(10.0));
        assert_eq!(json["legs"][0]["duration_s"], serde_json::json!(10.0));
        assert!(json["legs"][1]["measured_kj"].is_null());
        assert!(json["legs"][1]["error_pct"].is_null());
        assert_eq!(
            json["legs"][1]["flags"],
            serde_json::json!(["telemetry_gap", "unmeasurable"])
        );
        assert_eq!(json["total"]["predicted_kj"], serde_json::json!(60.0));
        assert!(json["hovers"].is_array());
        let back: ReportJson = serde_json::from_value(json).expect("parses");
        let again = FlightReport::from_json(&back);
        assert_eq!(again.legs[0].measured_j, Some(22_000.0));
        assert_eq!(
            again.legs[1].flags,
            vec![Flag::TelemetryGap, Flag::Unmeasurable]
        );
    }
}
