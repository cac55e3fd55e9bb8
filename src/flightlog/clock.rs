//! The vehicle-time clock: energy is integrated over the vehicle's time, not the ground's, because
//! simulators run faster than real time (PX4 and ArduPilot SITL at 10x, the mock at its speed-up)
//! and wall time would give a tenth of the energy.
//!
//! Messages that carry `time_boot_ms` (GLOBAL_POSITION_INT, LOCAL_POSITION_NED, ATTITUDE,
//! SYSTEM_TIME, ...) give the vehicle time exactly; they are the clock's anchors. Messages without
//! it (BATTERY_STATUS, SYS_STATUS, HEARTBEAT, MISSION_CURRENT, ...) are stamped by extrapolating
//! from the latest anchor at the measured rate (vehicle seconds per wall second, estimated over
//! the last `window_s` of wall time, clamped, 1 until anchors span `min_span_s`), but never
//! further past the latest anchor than `hold_factor` times the usual spacing of the anchors: a
//! message that arrives late (a radio's or a simulator's burst, a hiccup of the ground station)
//! was still sent before the next anchor, so wall time must not carry it beyond (at 20x a 15 ms
//! delay would otherwise move it 0.3 s of flight); when the anchors have stopped, extrapolation
//! runs on. Stamps never go
//! backwards: a reboot that resets `time_boot_ms` starts a new epoch, offset so the flight's time
//! continues; a timed message slightly older than the last stamp is held at it. With no timed
//! messages at all the clock is the wall clock. The output is a pure function of the inputs, so a
//! replay of the .tlog reproduces every stamp.

use std::collections::VecDeque;

/// Tuning of the clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockConfig {
    /// Wall time over which the rate is estimated.
    pub window_s: f64,
    /// Least wall-time span of the anchors before the rate is estimated (1 until then): two
    /// messages of one datagram would otherwise give any rate.
    pub min_span_s: f64,
    pub min_rate: f64,
    pub max_rate: f64,
    /// A `time_boot_ms` this much below the last one is a reboot (a new epoch), not reordering.
    pub reboot_jump_s: f64,
    /// An untimed message is stamped at most this many anchor spacings past the latest anchor.
    pub hold_factor: f64,
}

impl Default for ClockConfig {
    fn default() -> Self {
        ClockConfig {
            window_s: 2.0,
            min_span_s: 0.25,
            min_rate: 0.05,
            max_rate: 1000.0,
            reboot_jump_s: 2.0,
            hold_factor: 1.5,
        }
    }
}

/// Stamps readings with vehicle seconds since the flight's first message.
#[derive(Debug, Clone)]
pub struct VehicleClock {
    cfg: ClockConfig,
    first_wall_us: Option<u64>,
    last_wall_us: u64,
    /// Latest anchor (wall us, flight s); the wall clock's start before any timed message.
    reference: (u64, f64),
    /// Timed messages of the last `window_s` of wall time.
    anchors: VecDeque<(u64, f64)>,
    rate: f64,
    /// Flight time minus boot time in the current epoch.
    offset_s: Option<f64>,
    last_boot_ms: Option<u32>,
    last_t_s: f64,
    epochs: u32,
    /// Smoothed vehicle time between distinct anchors.
    spacing_s: Option<f64>,
}

impl Default for VehicleClock {
    fn default() -> Self {
        VehicleClock::new(ClockConfig::default())
    }
}

impl VehicleClock {
    pub fn new(cfg: ClockConfig) -> VehicleClock {
        VehicleClock {
            cfg,
            first_wall_us: None,
            last_wall_us: 0,
            reference: (0, 0.0),
            anchors: VecDeque::new(),
            rate: 1.0,
            offset_s: None,
            last_boot_ms: None,
            last_t_s: 0.0,
            epochs: 0,
            spacing_s: None,
        }
    }

    /// The current estimate of vehicle seconds per wall second.
    pub fn rate(&self) -> f64 {
        self.rate
    }

    /// Reboots seen (new epochs of `time_boot_ms`).
    pub fn reboots(&self) -> u32 {
        self.epochs
    }

    /// The latest stamp given.
    pub fn now_s(&self) -> f64 {
        self.last_t_s
    }

    fn extrapolate(&self, wall_us: u64) -> f64 {
        let (wall0, t0) = self.reference;
        t0 + self.rate * wall_us.saturating_sub(wall0) as f64 * 1e-6
    }

    /// The vehicle time of a message that arrived at `wall_us` (unix microseconds) carrying
    /// `boot_ms` (its `time_boot_ms`) if it has one.
    pub fn stamp(&mut self, wall_us: u64, boot_ms: Option<u32>) -> f64 {
        if self.first_wall_us.is_none() {
            self.first_wall_us = Some(wall_us);
            self.reference = (wall_us, 0.0);
            self.last_wall_us = wall_us;
        }
        // The wall clock may step back (NTP); never extrapolate backwards.
        let wall_us = wall_us.max(self.last_wall_us);
        self.last_wall_us = wall_us;
        let t_s = match boot_ms {
            None => {
                let t = self.extrapolate(wall_us);
                // Held back only while the anchors are merely late; when they have stopped
                // (no anchor for four spacings of wall time, at least a quarter second) the
                // untimed messages run on at the measured rate.
                let waited_s = wall_us.saturating_sub(self.reference.0) as f64 * 1e-6;
                match self.spacing_s {
                    Some(spacing) if waited_s <= (4.0 * spacing / self.rate).max(0.25) => {
                        t.min(self.reference.1 + self.cfg.hold_factor * spacing)
                    }
                    _ => t,
                }
            }
            Some(boot_ms) => self.anchor(wall_us, boot_ms),
        };
        let t_s = if t_s.is_finite() {
            t_s.max(self.last_t_s)
        } else {
            self.last_t_s
        };
        self.last_t_s = t_s;
        t_s
    }

    fn anchor(&mut self, wall_us: u64, boot_ms: u32) -> f64 {
        let boot_s = f64::from(boot_ms) * 1e-3;
        let rebooted = self
            .last_boot_ms
            .is_some_and(|last| f64::from(last) * 1e-3 - boot_s > self.cfg.reboot_jump_s);
        if self.offset_s.is_none() || rebooted {
            // Continue the timeline from where extrapolation has it.
            self.offset_s = Some(self.extrapolate(wall_us) - boot_s);
            if rebooted {
                self.epochs += 1;
                self.anchors.clear();
            }
        }
        let t_s = boot_s + self.offset_s.unwrap_or(0.0);
        if let Some(&(_, last_t)) = self.anchors.back() {
            let delta = t_s - last_t;
            // Two streams sent in one step give a zero spacing: only distinct times count.
            if delta > 1e-3 && !rebooted {
                self.spacing_s = Some(match self.spacing_s {
                    Some(s) => s + 0.1 * (delta - s),
                    None => delta,
                });
            }
        }
        if self.last_boot_ms.is_none_or(|last| boot_ms >= last) || rebooted {
            self.last_boot_ms = Some(boot_ms);
        }
        self.reference = (wall_us, t_s);
        self.anchors.push_back((wall_us, t_s));
        let window_us = (self.cfg.window_s * 1e6) as u64;
        while self.anchors.len() > 2
            && self
                .anchors
                .front()
                .is_some_and(|&(w, _)| wall_us.saturating_sub(w) > window_us)
        {
            self.anchors.pop_front();
        }
        if let (Some(&(w0, t0)), Some(&(w1, t1))) = (self.anchors.front(), self.anchors.back()) {
            let span_s = w1.saturating_sub(w0) as f64 * 1e-6;
            if span_s >= self.cfg.min_span_s {
                let rate = (t1 - t0) / span_s;
                if rate.is_finite() {
                    self.rate = rate.clamp(self.cfg.min_rate, self.cfg.max_rate);
                }
            }
        }
        t_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const START_US: u64 = 1_700_000_000_000_000;

    /// A vehicle at `speedup` sending a timed message every 100 ms of its time and an untimed one
    /// half-way between: returns (timed stamps, untimed stamps, true vehicle times of the untimed).
    fn run(clock: &mut VehicleClock, speedup: f64, boot0_ms: u32, seconds: f64) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let steps = (seconds / 0.1) as u32;
        for k in 0..steps {
            let vehicle_s = f64::from(k) * 0.1;
            let wall = START_US + (vehicle_s / speedup * 1e6) as u64;
            let t = clock.stamp(wall, Some(boot0_ms + k * 100));
            out.push((vehicle_s, t));
            let mid_s = vehicle_s + 0.05;
            let wall_mid = START_US + (mid_s / speedup * 1e6) as u64;
            let t_mid = clock.stamp(wall_mid, None);
            out.push((mid_s, t_mid));
        }
        out
    }

    #[test]
    fn the_clock_measures_a_tenfold_speed_up_and_stamps_untimed_messages_in_vehicle_time() {
        let mut clock = VehicleClock::default();
        let stamps = run(&mut clock, 10.0, 5_000, 60.0);
        assert!((clock.rate() - 10.0).abs() < 0.05, "rate {}", clock.rate());
        // Once the anchors span `min_span_s` of wall time (2.5 s of vehicle time at 10x), every
        // stamp is the vehicle time (relative to the first message) to within a few milliseconds.
        for &(vehicle_s, t) in stamps.iter().skip(60) {
            assert!(
                (t - vehicle_s).abs() < 0.005,
                "vehicle {vehicle_s} stamped {t}"
            );
        }
    }

    #[test]
    fn stamps_never_go_backwards_even_for_a_timed_message_older_than_the_last_stamp() {
        let mut clock = VehicleClock::default();
        let a = clock.stamp(START_US, Some(10_000));
        let b = clock.stamp(START_US + 500_000, None);
        let c = clock.stamp(START_US + 510_000, Some(10_100));
        let d = clock.stamp(START_US + 520_000, Some(10_050));
        assert!(a <= b && b <= c && c <= d, "{a} {b} {c} {d}");
        assert!((b - 0.5).abs() < 1e-9, "extrapolated at rate 1: {b}");
    }

    #[test]
    fn a_reboot_starts_a_new_epoch_and_the_flight_time_continues() {
        let mut clock = VehicleClock::default();
        run(&mut clock, 1.0, 300_000, 10.0);
        let before = clock.now_s();
        // The autopilot reboots: 2 s of silence, then time_boot_ms starts again near zero.
        let wall = START_US + 12_000_000;
        let after = clock.stamp(wall, Some(150));
        assert_eq!(clock.reboots(), 1);
        assert!(
            (after - (before + 2.05)).abs() < 0.06,
            "before {before}, after {after}"
        );
        let later = clock.stamp(wall + 1_000_000, Some(1_150));
        assert!((later - after - 1.0).abs() < 1e-9, "{after} -> {later}");
    }

    #[test]
    fn without_timed_messages_the_clock_is_the_wall_clock() {
        let mut clock = VehicleClock::default();
        let stamps: Vec<f64> = (0..50)
            .map(|k| clock.stamp(START_US + k * 200_000, None))
            .collect();
        for (k, t) in stamps.iter().enumerate() {
            assert!((t - k as f64 * 0.2).abs() < 1e-9, "{k}: {t}");
        }
        assert_eq!(clock.rate(), 1.0);
    }

    #[test]
    fn timed_messages_that_stop_leave_untimed_ones_extrapolated_at_the_last_rate() {
        let mut clock = VehicleClock::default();
        run(&mut clock, 10.0, 0, 20.0);
        let last = clock.now_s();
        // Position stream lost: battery messages keep coming for 1 s of wall time.
        let wall_last = START_US + (19.95 / 10.0 * 1e6) as u64;
        let t = clock.stamp(wall_last + 1_000_000, None);
        assert!((t - (last + 10.0)).abs() < 0.1, "last {last}, then {t}");
    }

    #[test]
    fn an_untimed_message_arriving_late_is_not_carried_past_the_next_anchor() {
        let mut clock = VehicleClock::default();
        run(&mut clock, 20.0, 0, 20.0);
        let last = clock.now_s();
        // A 20 ms hiccup at 20x: by the wall clock 0.4 s of flight, but the message was sent
        // before the next anchor (0.1 s on): held at 1.5 spacings.
        let wall_last = START_US + (19.95 / 20.0 * 1e6) as u64;
        let t = clock.stamp(wall_last + 20_000, None);
        assert!(
            t - last <= 0.15 + 1e-9 && t >= last,
            "last {last}, then {t}"
        );
    }

    #[test]
    fn the_same_inputs_give_the_same_stamps() {
        let mut a = VehicleClock::default();
        let mut b = VehicleClock::default();
        assert_eq!(run(&mut a, 7.0, 42, 30.0), run(&mut b, 7.0, 42, 30.0));
    }

    #[test]
    fn two_anchors_in_one_datagram_do_not_set_an_absurd_rate() {
        let mut clock = VehicleClock::default();
        clock.stamp(START_US, Some(1_000));
        clock.stamp(START_US + 10, Some(1_100));
        assert_eq!(clock.rate(), 1.0);
    }
}
