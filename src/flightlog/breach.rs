//! The geofence breaches a flight's FENCE_STATUS readings tell: a breach is a status that says
//! the vehicle is outside the fence when the one before did not, or with more breaches counted
//! than before (the autopilot counts them since boot). Each is kept with when (vehicle time,
//! and since take-off) and where (the autopilot's last position, and in the mission's frame),
//! so the report flags it and a replay of the log finds the same.

use serde::{Deserialize, Serialize};

use super::telemetry::{BreachType, FenceStatus, Position};

/// One fence breach.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Breach {
    /// Vehicle time of the status that told it (s, the flight log's clock).
    pub t_s: f64,
    /// Time since take-off (s); None when it came before the vehicle armed.
    pub since_takeoff_s: Option<f64>,
    #[serde(rename = "type")]
    pub breach_type: BreachType,
    /// Where the vehicle was, as the autopilot last said (degrees, m above home); None before
    /// any position.
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    pub height_m: Option<f64>,
    /// The same in the mission's frame (east, north, up from the origin; m), when known.
    pub east_m: Option<f64>,
    pub north_m: Option<f64>,
    pub up_m: Option<f64>,
}

impl Breach {
    /// "fence breach (boundary) 42.0 s after take-off at 47.3979800, 8.5461200, 20.0 m above
    /// home (east 30.0 m, north 12.0 m of the origin)": the report's line.
    pub fn line(&self) -> String {
        let when = match self.since_takeoff_s {
            Some(s) => format!("{s:.1} s after take-off"),
            None => format!("at {:.1} s, before take-off", self.t_s),
        };
        let mut line = format!("fence breach ({}) {when}", self.breach_type.name());
        if let (Some(lat), Some(lon)) = (self.lat_deg, self.lon_deg) {
            line.push_str(&format!(" at {lat:.7}, {lon:.7}"));
            if let Some(h) = self.height_m {
                line.push_str(&format!(", {h:.1} m above home"));
            }
        }
        if let (Some(e), Some(n)) = (self.east_m, self.north_m) {
            line.push_str(&format!(" (east {e:.1} m, north {n:.1} m of the origin)"));
        }
        line
    }
}

/// The breaches so far, from the statuses in the order they arrived.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Breaches {
    last: Option<FenceStatus>,
    list: Vec<Breach>,
}

impl Breaches {
    /// Takes in the status `status` read at `t_s`, the flight having taken off at `takeoff_s`,
    /// the vehicle last at `position` (and `at` in the mission's frame).
    pub fn push(
        &mut self,
        t_s: f64,
        status: &FenceStatus,
        takeoff_s: Option<f64>,
        position: Option<&Position>,
        at: Option<[f64; 3]>,
    ) {
        let new = status.breached
            && self
                .last
                .is_none_or(|l| !l.breached || status.breach_count > l.breach_count);
        self.last = Some(*status);
        if !new {
            return;
        }
        self.list.push(Breach {
            t_s,
            since_takeoff_s: takeoff_s.filter(|&s| s <= t_s).map(|s| t_s - s),
            breach_type: status.breach_type,
            lat_deg: position.map(|p| p.lat_deg),
            lon_deg: position.map(|p| p.lon_deg),
            height_m: position.map(|p| p.relative_alt_m),
            east_m: at.map(|a| a[0]),
            north_m: at.map(|a| a[1]),
            up_m: at.map(|a| a[2]),
        });
    }

    /// Every breach so far.
    pub fn list(&self) -> &[Breach] {
        &self.list
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(breached: bool, count: u16) -> FenceStatus {
        FenceStatus {
            breached,
            breach_count: count,
            breach_type: if count > 0 {
                BreachType::Boundary
            } else {
                BreachType::None
            },
            last_breach_boot_s: None,
        }
    }

    #[test]
    fn a_breach_counts_once_while_it_lasts_and_again_when_the_count_rises() {
        let mut b = Breaches::default();
        b.push(1.0, &status(false, 0), Some(0.5), None, None);
        b.push(
            2.0,
            &status(true, 1),
            Some(0.5),
            None,
            Some([1.0, 2.0, 3.0]),
        );
        b.push(2.5, &status(true, 1), Some(0.5), None, None);
        // Out again before the next status said it was back in: the count tells.
        b.push(3.0, &status(true, 2), Some(0.5), None, None);
        b.push(4.0, &status(false, 2), Some(0.5), None, None);
        b.push(5.0, &status(true, 3), None, None, None);
        let list = b.list();
        assert_eq!(list.len(), 3, "{list:?}");
        assert_eq!(list[0].since_takeoff_s, Some(1.5));
        assert_eq!(list[0].east_m, Some(1.0));
        assert_eq!(list[1].t_s, 3.0);
        assert_eq!(list[2].since_takeoff_s, None);
        assert!(list[0]
            .line()
            .starts_with("fence breach (boundary) 1.5 s after take-off"));
    }
}
