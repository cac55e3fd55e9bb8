//! The parts a flight is cut into (take-off, legs, settles, hovers, landing) and where a leg
//! began: what the segmenter finds and the energy guard and the report read.

use serde::Serialize;

/// What a segment is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", content = "index", rename_all = "snake_case")]
pub enum SegmentKind {
    Takeoff,
    /// The leg ending at points[k].
    Leg(usize),
    Settle(usize),
    Hover(usize),
    Landing,
}

/// A stretch of the flight in vehicle time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Segment {
    pub kind: SegmentKind,
    pub start_s: f64,
    pub end_s: f64,
    /// False when the flight (or the log) ended inside it.
    pub complete: bool,
    /// A leg the autopilot ended before the arrival radius (its acceptance radius is larger).
    pub missed_radius: bool,
    /// A leg's vehicle when it began, if positions were known.
    pub start_state: Option<StartState>,
}

/// Where and how fast the vehicle was when a leg began: a leg begun off its point or still
/// moving (PX4's first leg starts out of the take-off's climb; its SIH vehicle leaves a 5 s hold
/// up to 1.5 m past the point, along the way it came) is not the hover-to-hover operation the
/// model prices.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StartState {
    /// 3D distance from the point left (as the autopilot set it).
    pub offset_m: f64,
    /// 3D speed.
    pub speed_m_s: f64,
}

impl Segment {
    pub fn duration_s(&self) -> f64 {
        self.end_s - self.start_s
    }
}
