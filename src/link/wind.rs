//! The vehicle's own wind estimate before a flight (`fly --wind live`), as a sans-IO machine
//! (`start(now)`, `handle(now, message)`, `tick(now)`; it sends nothing): PX4's WIND_COV (231,
//! from its `vehicle_wind` topic: `wind_x` north, `wind_y` east, the air's velocity, m/s) or
//! ArduPilot's WIND (168: `direction` it blows from, degrees, and `speed`). Neither is sent
//! unless the autopilot's estimator runs one (PX4: EKF2 drag fusion, ArduPilot: EK3 drag), so
//! a vehicle that says nothing within the budget has no estimate ([`ListenWind::finished`]
//! answers None). A message with a NaN or out-of-range field is not an estimate.

use std::time::Duration;

use super::mav::MavMessage;
use crate::physics::Wind;

/// Waits for `target`'s wind estimate.
#[derive(Debug, Clone)]
pub struct ListenWind {
    budget: Duration,
    started: Duration,
    heard: Option<Wind>,
    expired: bool,
}

impl ListenWind {
    /// Listens for at most `budget` (the driver hands it only the target's messages).
    pub fn new(budget: Duration) -> ListenWind {
        ListenWind {
            budget,
            started: Duration::ZERO,
            heard: None,
            expired: false,
        }
    }

    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.started = now;
        Vec::new()
    }

    pub fn handle(&mut self, _now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.heard.is_none() {
            self.heard = wind_of(message);
        }
        Vec::new()
    }

    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if now.saturating_sub(self.started) >= self.budget {
            self.expired = true;
        }
        Vec::new()
    }

    /// Whether it is done: an estimate heard, or the budget spent.
    pub fn done(&self) -> bool {
        self.heard.is_some() || self.expired
    }

    /// The estimate heard (None: none within the budget).
    pub fn finished(&self) -> Option<Wind> {
        self.heard
    }
}

/// The wind a WIND_COV or WIND message carries, if it is a usable estimate.
pub fn wind_of(message: &MavMessage) -> Option<Wind> {
    match message {
        MavMessage::WIND_COV(w) => {
            Wind::from_velocity(f64::from(w.wind_x), f64::from(w.wind_y)).ok()
        }
        MavMessage::WIND(w) => Wind::new(f64::from(w.speed), f64::from(w.direction)).ok(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::{WIND_COV_DATA, WIND_DATA};

    #[test]
    fn a_wind_estimate_is_read_from_either_autopilots_message() {
        // PX4: the air moving east at 6 m/s is a wind from the west.
        let px4 = MavMessage::WIND_COV(WIND_COV_DATA {
            wind_x: 0.0,
            wind_y: 6.0,
            ..Default::default()
        });
        let w = wind_of(&px4).unwrap();
        assert!((w.speed_m_s - 6.0).abs() < 1e-6 && (w.from_deg - 270.0).abs() < 1e-4);
        let ardupilot = MavMessage::WIND(WIND_DATA {
            direction: 270.0,
            speed: 6.0,
            speed_z: 0.0,
        });
        assert_eq!(wind_of(&ardupilot).unwrap(), Wind::new(6.0, 270.0).unwrap());
        let unknown = MavMessage::WIND_COV(WIND_COV_DATA {
            wind_x: f32::NAN,
            wind_y: f32::NAN,
            ..Default::default()
        });
        assert_eq!(wind_of(&unknown), None);
    }

    #[test]
    fn listening_ends_with_the_first_estimate_or_the_budget() {
        let mut m = ListenWind::new(Duration::from_secs(5));
        m.start(Duration::ZERO);
        m.tick(Duration::from_secs(4));
        assert!(!m.done());
        m.tick(Duration::from_secs(5));
        assert!(m.done() && m.finished().is_none());
        let mut m = ListenWind::new(Duration::from_secs(5));
        m.start(Duration::ZERO);
        m.handle(
            Duration::from_secs(1),
            &MavMessage::WIND(WIND_DATA {
                direction: 90.0,
                speed: 4.0,
                speed_z: 0.0,
            }),
        );
        assert_eq!(m.finished(), Some(Wind::new(4.0, 90.0).unwrap()));
    }
}
