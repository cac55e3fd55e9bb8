//! A steady horizontal wind, and what a leg sees of it: a field condition of a mission, kept
//! here below the physics (which prices in it), the tour (headings) and the flight log (a
//! plan's wind) alike.
//!
//! A wind is given as `SPEED@FROM_DEG` (`--wind 6@270`: 6 m/s from the west), the
//! meteorological convention: the direction it blows from, degrees clockwise from north. A leg
//! flown on a heading (its direction of travel over the ground, degrees clockwise from north)
//! sees it as [`LegWind`]: the air's velocity along the leg (positive with the travel, a
//! tailwind) and across it (positive to the right of the travel). The body and rotors work in
//! the air: their airspeed is the ground velocity minus the wind (`physics::body::demand_in_wind`). The
//! autopilots fly their trajectories over the ground, so a leg's motion is the same in wind as
//! in still air; what changes is the thrust, the attitude and the rotors' airflow along it
//! (docs/energy-model.md "Wind").

use serde::{Deserialize, Serialize};

/// The heading (degrees clockwise from north, in [0, 360)) of a move `dx_east_m`, `dy_north_m`;
/// 0 (north) for a vertical move.
pub fn heading_deg(dx_east_m: f64, dy_north_m: f64) -> f64 {
    if dx_east_m == 0.0 && dy_north_m == 0.0 {
        return 0.0;
    }
    dx_east_m.atan2(dy_north_m).to_degrees().rem_euclid(360.0)
}

/// A steady horizontal wind.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Wind {
    /// Speed (m/s, not negative).
    pub speed_m_s: f64,
    /// The direction it blows from, degrees clockwise from north ([0, 360)).
    pub from_deg: f64,
}

/// The wind as one leg sees it (m/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegWind {
    /// The air's velocity along the leg's direction of travel (positive: a tailwind).
    pub along_m_s: f64,
    /// The air's velocity across it (positive: to the right of the travel).
    pub cross_m_s: f64,
}

impl LegWind {
    /// No wind.
    pub const CALM: LegWind = LegWind {
        along_m_s: 0.0,
        cross_m_s: 0.0,
    };

    /// Whether there is no wind at all (both components exactly zero).
    pub fn is_calm(&self) -> bool {
        self.along_m_s == 0.0 && self.cross_m_s == 0.0
    }
}

/// The largest wind `Wind::new` takes (m/s): a multirotor of the S1000's class is not flown in
/// a storm; a typo (`60@270`) is refused rather than priced.
pub const MAX_WIND_M_S: f64 = 30.0;

/// Why a wind was refused; every value is echoed short (`shown`, `echoed`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WindError {
    #[error("wind speed {0} m/s: must be a number of m/s, 0 or more")]
    Speed(String),
    #[error("wind speed {0} m/s: more than {MAX_WIND_M_S} m/s is not a flying wind")]
    Storm(String),
    #[error("wind direction {0}: must be degrees")]
    Direction(String),
    #[error(
        "wind \"{0}\": expected SPEED@FROM_DEG (m/s and the direction it blows from, degrees \
         clockwise from north), e.g. 6@270"
    )]
    Usage(String),
    #[error(
        "wind direction {0} deg: must be from 0 to under 360 (degrees clockwise from north it \
         blows from)"
    )]
    OutOfCircle(String),
}

impl Wind {
    /// Still air.
    pub const CALM: Wind = Wind {
        speed_m_s: 0.0,
        from_deg: 0.0,
    };

    /// A wind of `speed_m_s` from `from_deg`; refuses a negative, non-finite or storm speed and
    /// a non-finite direction. The direction is taken modulo 360.
    pub fn new(speed_m_s: f64, from_deg: f64) -> Result<Wind, WindError> {
        if !speed_m_s.is_finite() || speed_m_s < 0.0 {
            return Err(WindError::Speed(shown(speed_m_s)));
        }
        if speed_m_s > MAX_WIND_M_S {
            return Err(WindError::Storm(shown(speed_m_s)));
        }
        if !from_deg.is_finite() {
            return Err(WindError::Direction(shown(from_deg)));
        }
        Ok(Wind {
            speed_m_s,
            from_deg: from_deg.rem_euclid(360.0),
        })
    }

    /// The wind whose air moves at `north_m_s`, `east_m_s` (PX4's WIND_COV `wind_x`, `wind_y`).
    pub fn from_velocity(north_m_s: f64, east_m_s: f64) -> Result<Wind, WindError> {
        let speed = north_m_s.hypot(east_m_s);
        // It blows from the opposite of where the air goes.
        let from = heading_deg(-east_m_s, -north_m_s);
        Wind::new(speed, if speed > 0.0 { from } else { 0.0 })
    }

    /// Whether there is no wind.
    pub fn is_calm(&self) -> bool {
        self.speed_m_s == 0.0
    }

    /// The air's velocity (east, north; m/s).
    pub fn velocity_en_m_s(&self) -> (f64, f64) {
        let (s, c) = self.from_deg.to_radians().sin_cos();
        (-self.speed_m_s * s, -self.speed_m_s * c)
    }

    /// The wind as a leg flown on `heading_deg` sees it; calm exactly when the wind is.
    pub fn on_heading(&self, heading_deg: f64) -> LegWind {
        if self.is_calm() {
            return LegWind::CALM;
        }
        let (east, north) = self.velocity_en_m_s();
        let (s, c) = heading_deg.to_radians().sin_cos();
        LegWind {
            along_m_s: east * s + north * c,
            cross_m_s: east * c - north * s,
        }
    }
}

impl std::fmt::Display for Wind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}@{}", self.speed_m_s, self.from_deg)
    }
}

impl std::str::FromStr for Wind {
    type Err = WindError;

    /// `SPEED@FROM_DEG`, e.g. `6@270`: 6 m/s from the west. The direction is given as it is
    /// meant, from 0 to under 360: anything else is refused, not wrapped (`8@400` is more
    /// likely a typo of 8@40 or 8@300 than a wind from 40 deg).
    fn from_str(s: &str) -> Result<Wind, WindError> {
        let usage = || WindError::Usage(echoed(s));
        let (speed, from) = s.trim().split_once('@').ok_or_else(usage)?;
        let speed: f64 = speed.trim().parse().map_err(|_| usage())?;
        let from_deg: f64 = from.trim().parse().map_err(|_| usage())?;
        if from_deg.is_finite() && !(0.0..360.0).contains(&from_deg) {
            return Err(WindError::OutOfCircle(echoed(from)));
        }
        Wind::new(speed, from_deg)
    }
}

/// A number for a message: as Rust writes it when that is short, else in scientific notation
/// (a speed of 1e308 is not echoed as 309 digits).
fn shown(value: f64) -> String {
    let plain = value.to_string();
    if plain.len() <= 16 {
        plain
    } else {
        format!("{value:.3e}")
    }
}

/// Text the user typed, for a message: trimmed, and cut after 32 characters.
fn echoed(text: &str) -> String {
    const MAX_CHARS: usize = 32;
    let text = text.trim();
    if text.chars().count() <= MAX_CHARS {
        text.to_string()
    } else {
        format!("{}...", text.chars().take(MAX_CHARS).collect::<String>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wind_is_read_as_speed_at_the_direction_it_blows_from() {
        let w: Wind = "6@270".parse().unwrap();
        assert_eq!((w.speed_m_s, w.from_deg), (6.0, 270.0));
        assert_eq!("5 @ 359.5".parse::<Wind>().unwrap().from_deg, 359.5);
        for bad in [
            "6", "6@", "@270", "x@270", "-1@0", "40@0", "6@nan", "5@-90", "8@400", "8@360",
        ] {
            assert!(bad.parse::<Wind>().is_err(), "{bad}");
        }
        let refusal = |text: &str| text.parse::<Wind>().unwrap_err().to_string();
        assert!(refusal("6@").contains("SPEED@FROM_DEG"));
        let wrapped = refusal("8@400");
        assert!(
            wrapped.contains("400") && wrapped.contains("under 360"),
            "{wrapped}"
        );
        let huge = refusal("1e308@0");
        assert!(huge.contains("1.000e308") && huge.len() < 100, "{huge}");
        let long = format!("{}@0", "9".repeat(400));
        assert!(refusal(&long).len() < 100);
        let typo = format!("{}@0", "x".repeat(400));
        assert!(refusal(&typo).len() < 200);
    }

    #[test]
    fn a_leg_sees_a_wind_from_ahead_as_a_headwind_and_from_its_left_as_blowing_right() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        // From the north, flying north: a headwind.
        let w = Wind::new(6.0, 0.0).unwrap().on_heading(0.0);
        assert!(close(w.along_m_s, -6.0) && close(w.cross_m_s, 0.0));
        // From the south, flying north: a tailwind.
        let w = Wind::new(6.0, 180.0).unwrap().on_heading(0.0);
        assert!(close(w.along_m_s, 6.0) && close(w.cross_m_s, 0.0));
        // From the west (the air moves east), flying north: it blows to the right.
        let w = Wind::new(6.0, 270.0).unwrap().on_heading(0.0);
        assert!(close(w.along_m_s, 0.0) && close(w.cross_m_s, 6.0));
        // From the west, flying east: a tailwind.
        let w = Wind::new(6.0, 270.0).unwrap().on_heading(90.0);
        assert!(close(w.along_m_s, 6.0) && close(w.cross_m_s, 0.0));
        assert!(Wind::CALM.on_heading(123.0).is_calm());
    }

    #[test]
    fn a_wind_velocity_reads_back_as_the_direction_it_comes_from() {
        let w = Wind::new(5.0, 300.0).unwrap();
        let (east, north) = w.velocity_en_m_s();
        let back = Wind::from_velocity(north, east).unwrap();
        assert!((back.speed_m_s - 5.0).abs() < 1e-12);
        assert!((back.from_deg - 300.0).abs() < 1e-9);
        assert_eq!(heading_deg(1.0, 0.0), 90.0);
        assert_eq!(heading_deg(0.0, -1.0), 180.0);
        assert_eq!(heading_deg(-1.0, 0.0), 270.0);
        assert_eq!(heading_deg(0.0, 0.0), 0.0);
    }
}
