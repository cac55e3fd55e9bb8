//! Where the vehicle is before a flight, as a sans-IO machine (`start(now)`, `handle(now,
//! message)`, `tick(now)` return the messages to send): its home (HOME_POSITION), else its
//! position (GLOBAL_POSITION_INT), so that a plan priced from a mission's origin is not flown
//! from somewhere else.
//!
//! HOME_POSITION is asked for with MAV_CMD_REQUEST_MESSAGE (message id 242), which PX4
//! (`MavlinkReceiver`, the stream's `request_message`) and ArduPilot (`GCS_MAVLINK::
//! handle_command_request_message`) both answer; PX4 also streams it every 2 s. Neither has a
//! home before its first position fix (ArduPilot's `send_home_position` sends nothing until
//! `home_is_set`), so the request is resent every retry period (an ACCEPTED ack is no
//! promise), and only UNSUPPORTED stops it. A vehicle that never tells its home (a generic
//! MAVLink autopilot) is taken at its position once it has been asked for its home for
//! `position_after`: standing on the ground before a flight, it is where its home would be.
//! ArduPilot sends GLOBAL_POSITION_INT before a fix with latitude and longitude 0: a
//! position at (0, 0) is no position.

use std::time::Duration;

use mavlink::MessageData;

use super::connection::Autopilot;
use super::mav::{MavCmd, MavMessage, MavResult, HOME_POSITION_DATA};
use crate::mission::Geodetic;

/// Timing of [`Locate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocateConfig {
    /// Ask for HOME_POSITION again when it has not come within this.
    pub retry: Duration,
    /// Take the vehicle's position instead once its home has been asked for this long.
    pub position_after: Duration,
    /// Give up when neither has come within this.
    pub budget: Duration,
}

impl Default for LocateConfig {
    fn default() -> Self {
        LocateConfig {
            retry: Duration::from_secs(1),
            // PX4 streams HOME_POSITION every 2 s and both autopilots answer the request within
            // a round trip: 5 s is two of PX4's periods and several requests over a lossy radio.
            position_after: Duration::from_secs(5),
            // A GNSS receiver's cold start takes about half a minute to its first fix (u-blox M8
            // datasheet: cold start 26 s), and the autopilots set home at their first fix: a
            // vehicle just switched on is waited for, one with no fix after that is refused.
            budget: Duration::from_secs(30),
        }
    }
}

/// Where the vehicle's home was learned from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HomeSource {
    /// The autopilot's HOME_POSITION.
    HomePosition,
    /// Its position (GLOBAL_POSITION_INT): it never sent its home.
    Position,
}

/// The vehicle's home, and where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// Latitude, longitude and altitude above mean sea level.
    pub home: Geodetic,
    pub source: HomeSource,
}

/// Why the vehicle's home is not known.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LocateError {
    #[error(
        "the vehicle sent neither its home (HOME_POSITION, asked {requests} times, last answer: {}) nor a position (GLOBAL_POSITION_INT) within {budget_s:.0} s: has it a position fix?",
        .answer.map(|r| format!("{r:?}")).unwrap_or_else(|| "none".into())
    )]
    Timeout {
        budget_s: f64,
        requests: u32,
        answer: Option<MavResult>,
    },
}

/// Learns where `target` is.
#[derive(Debug, Clone)]
pub struct Locate {
    target: Autopilot,
    cfg: LocateConfig,
    started: Duration,
    next_send: Duration,
    requests: u32,
    answer: Option<MavResult>,
    position: Option<Geodetic>,
    result: Option<Result<Located, LocateError>>,
}

/// A latitude and longitude in degE7 and an altitude in mm as a position, None for (0, 0) (no
/// fix) or out of range.
fn geodetic(lat_e7: i32, lon_e7: i32, alt_mm: i32) -> Option<Geodetic> {
    let (lat_deg, lon_deg) = (f64::from(lat_e7) * 1e-7, f64::from(lon_e7) * 1e-7);
    let known = (lat_e7, lon_e7) != (0, 0) && lat_deg.abs() <= 90.0 && lon_deg.abs() <= 180.0;
    known.then_some(Geodetic {
        lat_deg,
        lon_deg,
        alt_m: f64::from(alt_mm) * 1e-3,
    })
}

impl Locate {
    pub fn new(target: Autopilot, cfg: LocateConfig) -> Locate {
        Locate {
            target,
            cfg,
            started: Duration::ZERO,
            next_send: Duration::ZERO,
            requests: 0,
            answer: None,
            position: None,
            result: None,
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<Located, LocateError>> {
        self.result.as_ref()
    }

    fn unsupported(&self) -> bool {
        self.answer == Some(MavResult::MAV_RESULT_UNSUPPORTED)
    }

    fn request(&mut self, now: Duration) -> Vec<MavMessage> {
        self.requests += 1;
        self.next_send = now + self.cfg.retry;
        // The message id, 242.
        vec![super::request_message(&self.target, HOME_POSITION_DATA::ID)]
    }

    /// Asks for the home.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.started = now;
        self.request(now)
    }

    /// The position stands for the home once the home has been asked for long enough, or the
    /// autopilot cannot send it.
    fn settle_on_position(&mut self, now: Duration) {
        let waited = now.saturating_sub(self.started) >= self.cfg.position_after;
        if let Some(home) = self.position.filter(|_| waited || self.unsupported()) {
            self.result = Some(Ok(Located {
                home,
                source: HomeSource::Position,
            }));
        }
    }

    /// Reacts to a message from the target autopilot.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        match message {
            MavMessage::HOME_POSITION(h) => {
                if let Some(home) = geodetic(h.latitude, h.longitude, h.altitude) {
                    self.result = Some(Ok(Located {
                        home,
                        source: HomeSource::HomePosition,
                    }));
                }
            }
            MavMessage::GLOBAL_POSITION_INT(p) => {
                if let Some(position) = geodetic(p.lat, p.lon, p.alt) {
                    self.position = Some(position);
                    self.settle_on_position(now);
                }
            }
            MavMessage::COMMAND_ACK(ack) if ack.command == MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                self.answer = Some(ack.result);
                self.settle_on_position(now);
            }
            _ => {}
        }
        Vec::new()
    }

    /// Asks again; takes the position, or gives up, when their time has come.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        self.settle_on_position(now);
        if self.result.is_some() {
            return Vec::new();
        }
        if now.saturating_sub(self.started) >= self.cfg.budget {
            self.result = Some(Err(LocateError::Timeout {
                budget_s: self.cfg.budget.as_secs_f64(),
                requests: self.requests,
                answer: self.answer,
            }));
            return Vec::new();
        }
        if now >= self.next_send && !self.unsupported() {
            return self.request(now);
        }
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::{COMMAND_ACK_DATA, GLOBAL_POSITION_INT_DATA};
    use crate::link::testing::{autopilot, ms};
    use crate::link::Flavour;

    fn requests(out: &[MavMessage]) -> usize {
        out.iter()
            .filter(|m| {
                matches!(m, MavMessage::COMMAND_LONG(c)
                    if c.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
                        && c.param1 == 242.0
                        && c.target_system == 1)
            })
            .count()
    }

    fn home(lat_e7: i32, lon_e7: i32, alt_mm: i32) -> MavMessage {
        MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: lat_e7,
            longitude: lon_e7,
            altitude: alt_mm,
            ..Default::default()
        })
    }

    fn position(lat_e7: i32, lon_e7: i32) -> MavMessage {
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            lat: lat_e7,
            lon: lon_e7,
            alt: 16_000,
            ..Default::default()
        })
    }

    fn ack(result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            result,
            ..Default::default()
        })
    }

    fn locate() -> Locate {
        Locate::new(autopilot(Flavour::ArduPilot), LocateConfig::default())
    }

    #[test]
    fn the_home_is_asked_for_and_taken_from_home_position_in_si_units() {
        let mut m = locate();
        assert_eq!(requests(&m.start(ms(0))), 1);
        m.handle(ms(40), &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(m.finished(), None);
        m.handle(ms(50), &home(385_418_000, -1_218_132_000, 16_100));
        let located = m.finished().unwrap().clone().unwrap();
        assert_eq!(located.source, HomeSource::HomePosition);
        assert!((located.home.lat_deg - 38.5418).abs() < 1e-9);
        assert!((located.home.lon_deg + 121.8132).abs() < 1e-9);
        assert!((located.home.alt_m - 16.1).abs() < 1e-9);
        assert!(m.tick(ms(5000)).is_empty());
    }

    #[test]
    fn the_request_is_resent_every_retry_period_until_the_home_comes() {
        // ArduPilot accepts the request before it has a home, and sends nothing.
        let mut m = locate();
        let mut sent = requests(&m.start(ms(0)));
        m.handle(ms(30), &ack(MavResult::MAV_RESULT_ACCEPTED));
        for t in (50..=3000).step_by(50) {
            sent += requests(&m.tick(ms(t)));
        }
        assert_eq!(sent, 4);
        m.handle(ms(3010), &home(1, 2, 3));
        assert!(matches!(m.finished(), Some(Ok(_))));
    }

    #[test]
    fn a_position_at_zero_zero_is_no_fix_and_a_home_at_zero_zero_none_either() {
        let mut m = locate();
        m.start(ms(0));
        m.handle(ms(10), &home(0, 0, 0));
        m.handle(ms(6000), &position(0, 0));
        m.tick(ms(6050));
        assert_eq!(m.finished(), None);
    }

    #[test]
    fn a_position_stands_for_the_home_only_after_the_home_was_asked_for_long_enough() {
        let mut m = locate();
        m.start(ms(0));
        m.handle(ms(100), &position(385_362_000, -1_217_875_000));
        assert_eq!(m.finished(), None, "a home may still come");
        m.tick(ms(4950));
        assert_eq!(m.finished(), None);
        m.tick(ms(5000));
        let located = m.finished().unwrap().clone().unwrap();
        assert_eq!(located.source, HomeSource::Position);
        assert!((located.home.lat_deg - 38.5362).abs() < 1e-9);
    }

    #[test]
    fn an_autopilot_that_cannot_send_its_home_is_taken_at_its_position_at_once() {
        let mut m = locate();
        m.start(ms(0));
        m.handle(ms(20), &ack(MavResult::MAV_RESULT_UNSUPPORTED));
        assert!(m.tick(ms(1500)).is_empty(), "not asked again");
        m.handle(ms(1600), &position(385_362_000, -1_217_875_000));
        assert_eq!(
            m.finished().unwrap().as_ref().unwrap().source,
            HomeSource::Position
        );
    }

    #[test]
    fn neither_home_nor_position_within_the_budget_is_an_error_naming_what_was_asked() {
        let mut m = locate();
        m.start(ms(0));
        m.handle(ms(20), &ack(MavResult::MAV_RESULT_ACCEPTED));
        let mut t = 0;
        while m.finished().is_none() {
            t += 50;
            m.tick(ms(t));
        }
        assert_eq!(t, 30_000);
        let err = m.finished().unwrap().clone().unwrap_err();
        assert_eq!(
            err,
            LocateError::Timeout {
                budget_s: 30.0,
                requests: 30,
                answer: Some(MavResult::MAV_RESULT_ACCEPTED)
            }
        );
        let text = err.to_string();
        assert!(
            text.contains("HOME_POSITION") && text.contains("30 s"),
            "{text}"
        );
    }
}
