//! The retransmission timeout, adapted to the link as TCP does (RFC 6298): a smoothed
//! round-trip time and its mean deviation from request/answer pairs, RTO = SRTT + 4 RTTVAR,
//! bounded below (a fast link is fast without resending on every scheduling hiccup) and above
//! (a slow radio is not flooded, a dead one is noticed).

use std::time::Duration;

/// Bounds of the retransmission timeout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Before the first round trip is measured: RFC 6298 section 2.1's 1 s.
    pub initial_rto: Duration,
    /// Never resend sooner. 50 ms: well above a loopback or USB round trip plus an autopilot's
    /// scheduling (ArduPilot's 400 Hz loop, PX4's mavlink thread), so a clean link never sees a
    /// spurious resend; MAVSDK's server gives up on an item it has sent 5 times, so spurious
    /// resends are not free.
    pub min_rto: Duration,
    /// Never wait longer between resends: 1.5 s, the MAVLink mission protocol's own default
    /// timeout, well inside the autopilots' transfer timeouts (MAVSDK 2.5 s, PX4 5 s,
    /// ArduPilot 8 s), so a transfer is not lost to waiting; a link slower than that is resent
    /// to at 1.5 s.
    pub max_rto: Duration,
}

impl Default for Timing {
    fn default() -> Self {
        Timing {
            initial_rto: Duration::from_millis(1_000),
            min_rto: Duration::from_millis(50),
            max_rto: Duration::from_millis(1_500),
        }
    }
}

/// Clock granularity G of RFC 6298 (tokio's timers tick in milliseconds).
const GRANULARITY: Duration = Duration::from_millis(1);

/// The round-trip estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rto {
    timing: Timing,
    srtt: Option<Duration>,
    rttvar: Duration,
    samples: u32,
}

impl Rto {
    /// An estimator that has measured nothing yet.
    pub fn new(timing: Timing) -> Rto {
        Rto {
            timing,
            srtt: None,
            rttvar: Duration::ZERO,
            samples: 0,
        }
    }

    /// Takes one round trip of a message sent once (RFC 6298 section 2.2-2.3:
    /// RTTVAR <- 3/4 RTTVAR + 1/4 |SRTT - R|, SRTT <- 7/8 SRTT + 1/8 R).
    pub fn sample(&mut self, rtt: Duration) {
        self.samples += 1;
        match self.srtt {
            None => {
                self.srtt = Some(rtt);
                self.rttvar = rtt / 2;
            }
            Some(srtt) => {
                let deviation = srtt.abs_diff(rtt);
                self.rttvar = self.rttvar * 3 / 4 + deviation / 4;
                self.srtt = Some(srtt * 7 / 8 + rtt / 8);
            }
        }
    }

    /// The smoothed round-trip time, once measured.
    pub fn srtt(&self) -> Option<Duration> {
        self.srtt
    }

    /// How many round trips were measured.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The timeout of a first send: SRTT + max(G, 4 RTTVAR), within the bounds.
    pub fn base(&self) -> Duration {
        let raw = match self.srtt {
            Some(srtt) => srtt + GRANULARITY.max(self.rttvar * 4),
            None => self.timing.initial_rto,
        };
        raw.clamp(self.timing.min_rto, self.timing.max_rto)
    }

    /// The timeout after `attempt` consecutive timeouts of the same message: doubled per
    /// timeout as RFC 6298 section 5.5 does, but at most 4x (an autopilot re-requests on its own
    /// clock and abandons a transfer after a few seconds: backing off further only loses it),
    /// and never beyond the upper bound.
    pub fn timeout(&self, attempt: u32) -> Duration {
        (self.base() * (1u32 << attempt.min(2))).min(self.timing.max_rto)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(t: u64) -> Duration {
        Duration::from_millis(t)
    }

    #[test]
    fn the_timeout_starts_at_one_second_and_follows_the_measured_round_trip() {
        let mut rto = Rto::new(Timing::default());
        assert_eq!(rto.base(), ms(1000));
        rto.sample(ms(200));
        // SRTT 200, RTTVAR 100: 200 + 4 x 100.
        assert_eq!(rto.base(), ms(600));
        for _ in 0..50 {
            rto.sample(ms(200));
        }
        // A steady link: the variance decays and the timeout nears the round trip.
        assert!(
            rto.base() < ms(210) && rto.base() >= ms(200),
            "{:?}",
            rto.base()
        );
    }

    #[test]
    fn the_timeout_is_bounded_below_on_a_fast_link_and_above_on_a_slow_one() {
        let mut fast = Rto::new(Timing::default());
        for _ in 0..20 {
            fast.sample(Duration::from_micros(300));
        }
        assert_eq!(fast.base(), ms(50));
        let mut slow = Rto::new(Timing::default());
        slow.sample(ms(1200));
        assert_eq!(slow.base(), ms(1500));
    }

    #[test]
    fn repeated_timeouts_back_off_to_four_times_at_most() {
        let mut rto = Rto::new(Timing::default());
        rto.sample(ms(100));
        let base = rto.base();
        assert_eq!(rto.timeout(0), base);
        assert_eq!(rto.timeout(1), base * 2);
        assert_eq!(rto.timeout(2), base * 4);
        assert_eq!(rto.timeout(9), base * 4);
    }
}
