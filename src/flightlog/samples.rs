//! Battery readings turned into power samples: which battery counts (the first BATTERY_STATUS
//! battery seen; SYS_STATUS only when no BATTERY_STATUS of it arrived lately), and the SYS_STATUS
//! voltage lent to a BATTERY_STATUS that carries none. The recorder writes every sample to
//! samples.csv; energy integration uses the primary ones.

use super::telemetry::{Battery, BatterySource};

/// One battery sample at a vehicle time: the reading, completed (see [`BatteryFeed`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerSample {
    pub t_s: f64,
    pub wall_us: u64,
    pub battery: Battery,
    /// Whether this sample is of the battery whose energy is measured.
    pub primary: bool,
}

impl PowerSample {
    /// Electrical power V*I, when both are known and the current is a measurement.
    pub fn power_w(&self) -> Option<f64> {
        match (self.battery.voltage_v, self.battery.current_a) {
            (Some(v), Some(i)) if !self.battery.fake_current => Some(v * i),
            _ => None,
        }
    }
}

/// Tuning of the battery choice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedConfig {
    /// SYS_STATUS becomes the source when no primary BATTERY_STATUS arrived for this long.
    pub fallback_after_s: f64,
    /// A SYS_STATUS voltage at most this old fills a BATTERY_STATUS without one.
    pub fill_within_s: f64,
}

impl Default for FeedConfig {
    fn default() -> Self {
        FeedConfig {
            fallback_after_s: 2.0,
            fill_within_s: 1.0,
        }
    }
}

/// Chooses and completes battery samples; the same rules live and in replay.
#[derive(Debug, Clone, Default)]
pub struct BatteryFeed {
    cfg: FeedConfig,
    primary: Option<BatterySource>,
    last_primary_t_s: Option<f64>,
    sys_voltage: Option<(f64, f64)>,
}

impl BatteryFeed {
    pub fn new(cfg: FeedConfig) -> BatteryFeed {
        BatteryFeed {
            cfg,
            ..BatteryFeed::default()
        }
    }

    /// The sample a battery reading at `t_s` makes, if it makes one: every BATTERY_STATUS does;
    /// a SYS_STATUS only while no primary BATTERY_STATUS arrives.
    pub fn push(&mut self, t_s: f64, wall_us: u64, battery: &Battery) -> Option<PowerSample> {
        let mut sample = PowerSample {
            t_s,
            wall_us,
            battery: *battery,
            primary: false,
        };
        match battery.source {
            BatterySource::BatteryStatus { .. } => {
                let primary = *self.primary.get_or_insert(battery.source);
                sample.primary = primary == battery.source;
                if sample.primary {
                    self.last_primary_t_s = Some(t_s);
                }
                if sample.battery.voltage_v.is_none() {
                    sample.battery.voltage_v = self
                        .sys_voltage
                        .filter(|&(t, _)| (t_s - t).abs() <= self.cfg.fill_within_s)
                        .map(|(_, v)| v);
                }
                Some(sample)
            }
            BatterySource::SysStatus => {
                if let Some(v) = battery.voltage_v {
                    self.sys_voltage = Some((t_s, v));
                }
                let quiet = self
                    .last_primary_t_s
                    .is_none_or(|t| t_s - t > self.cfg.fallback_after_s);
                sample.primary = quiet;
                quiet.then_some(sample)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn battery(source: BatterySource, voltage_v: Option<f64>) -> Battery {
        Battery {
            source,
            voltage_v,
            current_a: Some(10.0),
            consumed_mah: None,
            energy_consumed_j: None,
            remaining_pct: None,
            fake_current: false,
        }
    }

    const B0: BatterySource = BatterySource::BatteryStatus {
        id: 0,
        component: 1,
    };
    const B1: BatterySource = BatterySource::BatteryStatus {
        id: 1,
        component: 1,
    };

    #[test]
    fn sys_status_counts_only_while_no_battery_status_arrives() {
        let mut feed = BatteryFeed::default();
        let sys = battery(BatterySource::SysStatus, Some(22.0));
        assert!(feed.push(0.0, 0, &sys).is_some_and(|s| s.primary));
        assert!(feed
            .push(0.5, 0, &battery(B0, Some(22.1)))
            .is_some_and(|s| s.primary));
        assert!(feed.push(1.0, 0, &sys).is_none());
        assert!(feed.push(2.4, 0, &sys).is_none());
        // BATTERY_STATUS stopped more than 2 s ago: SYS_STATUS takes over.
        assert!(feed.push(2.6, 0, &sys).is_some_and(|s| s.primary));
    }

    #[test]
    fn the_first_battery_seen_is_the_primary_and_others_are_kept_but_not_primary() {
        let mut feed = BatteryFeed::default();
        assert!(feed
            .push(0.0, 0, &battery(B1, Some(22.0)))
            .is_some_and(|s| s.primary));
        assert!(feed
            .push(0.1, 0, &battery(B0, Some(22.0)))
            .is_some_and(|s| !s.primary));
        assert!(feed
            .push(0.2, 0, &battery(B1, Some(22.0)))
            .is_some_and(|s| s.primary));
    }

    #[test]
    fn a_battery_status_without_voltage_borrows_a_recent_sys_status_voltage() {
        let mut feed = BatteryFeed::default();
        feed.push(0.0, 0, &battery(BatterySource::SysStatus, Some(21.5)));
        let filled = feed.push(0.5, 0, &battery(B0, None)).expect("a sample");
        assert_eq!(filled.battery.voltage_v, Some(21.5));
        let stale = feed.push(1.6, 0, &battery(B0, None)).expect("a sample");
        assert_eq!(stale.battery.voltage_v, None);
    }

    #[test]
    fn a_fake_current_has_no_power() {
        let mut s = BatteryFeed::default()
            .push(0.0, 0, &battery(B0, Some(16.0)))
            .expect("a sample");
        assert_eq!(s.power_w(), Some(160.0));
        s.battery.fake_current = true;
        assert_eq!(s.power_w(), None);
    }
}
