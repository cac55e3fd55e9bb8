//! The vehicle's wind estimate in flight, and when it has changed enough from the wind a flight
//! is priced in that the rest of the flight should be priced again (`fly --wind live`).
//!
//! The estimate is the mean of the air's velocity over the last [`WINDOW_S`] of WIND_COV or
//! WIND readings (PX4 sends WIND_COV at about 1 Hz, ArduPilot WIND at 2-4 Hz; a single
//! estimate jitters). It is due when it has at least [`MIN_READINGS`] readings spanning
//! [`MIN_SPAN_S`], has settled (every reading of the window within [`CHANGE_M_S`] of the mean,
//! so a change is priced once it is over, not on the way), differs from the priced wind by at
//! least [`CHANGE_M_S`] as a vector (a 1 m/s change moves a 40 m level leg's price by about 5%
//! into the wind, under 0.5% across or with it: `docs/energy-model.md`, "Wind") and [`MIN_APART_S`] has passed since the last look that
//! found it due, so a wind that drifts is not priced again at every reading.

use std::collections::VecDeque;

use crate::mission::wind::Wind;

/// Readings averaged (s of flight-log time).
pub const WINDOW_S: f64 = 6.0;
/// Readings and span the mean needs.
pub const MIN_READINGS: usize = 3;
pub const MIN_SPAN_S: f64 = 2.0;
/// The change (m/s, vector difference) that is worth pricing again.
pub const CHANGE_M_S: f64 = 1.0;
/// Time between two repricings at least (s).
pub const MIN_APART_S: f64 = 10.0;

/// The wind readings of the last [`WINDOW_S`].
#[derive(Debug, Clone, Default)]
pub struct WindTrack {
    /// (t, east, north) of the air's velocity.
    recent: VecDeque<(f64, f64, f64)>,
    last_due_s: Option<f64>,
}

impl WindTrack {
    pub fn new() -> WindTrack {
        WindTrack::default()
    }

    /// A reading of the vehicle's estimate at `t_s`.
    pub fn push(&mut self, t_s: f64, wind: Wind) {
        let (east, north) = wind.velocity_en_m_s();
        if !(east.is_finite() && north.is_finite()) {
            return;
        }
        self.recent.push_back((t_s, east, north));
        while self
            .recent
            .front()
            .is_some_and(|&(t, _, _)| t_s - t > WINDOW_S)
        {
            self.recent.pop_front();
        }
    }

    /// The mean estimate over the window, once it holds enough readings.
    pub fn estimate(&self) -> Option<Wind> {
        let (first, last) = (self.recent.front()?, self.recent.back()?);
        if self.recent.len() < MIN_READINGS || last.0 - first.0 < MIN_SPAN_S {
            return None;
        }
        let n = self.recent.len() as f64;
        let east = self.recent.iter().map(|r| r.1).sum::<f64>() / n;
        let north = self.recent.iter().map(|r| r.2).sum::<f64>() / n;
        Wind::from_velocity(north, east).ok()
    }

    /// Whether every reading of the window is within [`CHANGE_M_S`] of its mean.
    fn settled(&self, mean: Wind) -> bool {
        let (e, n) = mean.velocity_en_m_s();
        self.recent
            .iter()
            .all(|&(_, e1, n1)| (e1 - e).hypot(n1 - n) < CHANGE_M_S)
    }

    /// The estimate, when at `now_s` it differs from `priced` enough to price the rest again
    /// (and enough time has passed since the last time it was): marks it taken.
    pub fn take_due(&mut self, now_s: f64, priced: Wind) -> Option<Wind> {
        if self
            .last_due_s
            .is_some_and(|last| now_s - last < MIN_APART_S)
        {
            return None;
        }
        let estimate = self.estimate().filter(|e| self.settled(*e))?;
        let (e1, n1) = estimate.velocity_en_m_s();
        let (e0, n0) = priced.velocity_en_m_s();
        if (e1 - e0).hypot(n1 - n0) < CHANGE_M_S {
            return None;
        }
        self.last_due_s = Some(now_s);
        Some(estimate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wind(speed: f64, from: f64) -> Wind {
        Wind::new(speed, from).expect("a wind")
    }

    #[test]
    fn the_estimate_is_the_mean_velocity_of_the_window_once_it_spans_enough() {
        let mut track = WindTrack::new();
        track.push(0.0, wind(4.0, 270.0));
        track.push(1.0, wind(6.0, 270.0));
        assert_eq!(track.estimate(), None, "two readings are not enough");
        track.push(2.0, wind(8.0, 270.0));
        let w = track.estimate().expect("three readings over 2 s");
        assert!((w.speed_m_s - 6.0).abs() < 1e-9 && (w.from_deg - 270.0).abs() < 1e-9);
        // Opposite winds average to their velocities' mean, not their speeds'.
        let mut track = WindTrack::new();
        for (t, from) in [(0.0, 0.0), (1.0, 180.0), (2.0, 0.0), (3.0, 180.0)] {
            track.push(t, wind(5.0, from));
        }
        assert!(track.estimate().expect("an estimate").speed_m_s < 1e-9);
    }

    #[test]
    fn readings_older_than_the_window_drop_out() {
        let mut track = WindTrack::new();
        for t in 0..5 {
            track.push(f64::from(t), wind(2.0, 90.0));
        }
        for t in 20..24 {
            track.push(f64::from(t), wind(8.0, 90.0));
        }
        let w = track.estimate().expect("an estimate");
        assert!((w.speed_m_s - 8.0).abs() < 1e-9, "{w:?}");
    }

    #[test]
    fn a_step_in_the_wind_is_due_once_it_has_settled_not_on_the_way() {
        let mut track = WindTrack::new();
        let priced = wind(3.0, 270.0);
        for t in 0..10 {
            track.push(f64::from(t), priced);
            assert_eq!(track.take_due(f64::from(t), priced), None);
        }
        let mut due = None;
        for t in 10..30 {
            track.push(f64::from(t), wind(8.0, 270.0));
            if let Some(w) = track.take_due(f64::from(t), priced) {
                due = Some((t, w));
                break;
            }
        }
        let (t, w) = due.expect("due once settled");
        assert!(
            (w.speed_m_s - 8.0).abs() < 1e-9,
            "priced on the settled wind: {w:?}"
        );
        assert!(
            t as f64 > 10.0 + WINDOW_S - 1.5,
            "not before the window is all new: {t}"
        );
    }

    #[test]
    fn a_change_of_a_metre_per_second_is_due_once_then_not_again_for_a_while() {
        let mut track = WindTrack::new();
        for t in 0..4 {
            track.push(f64::from(t), wind(3.5, 270.0));
        }
        assert_eq!(track.take_due(3.0, wind(3.0, 270.0)), None, "0.5 m/s");
        // The same speed from 20 degrees round is a change of 2 x 3 x sin(10 deg) = 1.04 m/s.
        assert!(track.take_due(3.0, wind(3.5, 290.0)).is_some());
        assert_eq!(track.take_due(8.0, wind(3.5, 290.0)), None, "too soon");
        assert!(track.take_due(13.5, wind(3.5, 290.0)).is_some());
        let mut quiet = WindTrack::new();
        assert_eq!(quiet.take_due(0.0, Wind::CALM), None, "no readings");
    }
}
