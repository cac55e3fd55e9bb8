//! The path from the link to the flight log, the same live and in replay: the autopilot
//! filter, decoding, the vehicle clock.

use mavlink::MavHeader;

use super::decode::TelemetryDecoder;
use super::frame::parse_frame;
use crate::flightlog::clock::VehicleClock;
use crate::flightlog::telemetry::Stamped;
use crate::link::mav::MavMessage;

/// The path from the link to the flight log, the same live and in replay: source filter,
/// decode, vehicle clock.
#[derive(Debug, Clone, Default)]
pub struct Telemetry {
    decoder: TelemetryDecoder,
    clock: VehicleClock,
    undecodable: u64,
}

impl Telemetry {
    pub fn new() -> Telemetry {
        Telemetry::default()
    }

    /// With a known autopilot and clock settings.
    pub fn with(decoder: TelemetryDecoder, clock: VehicleClock) -> Telemetry {
        Telemetry {
            decoder,
            clock,
            undecodable: 0,
        }
    }

    pub fn clock(&self) -> &VehicleClock {
        &self.clock
    }

    pub fn autopilot(&self) -> Option<(u32, u8)> {
        self.decoder.autopilot()
    }

    /// Frames that were not a known MAVLink message (bad CRC, unknown id or enum value).
    pub fn undecodable(&self) -> u64 {
        self.undecodable
    }

    /// One message that arrived at `wall_us` (unix microseconds).
    pub fn message(
        &mut self,
        wall_us: u64,
        header: &MavHeader,
        message: &MavMessage,
    ) -> Option<Stamped> {
        let decoded = self.decoder.decode(header, message);
        if decoded.time_boot_ms.is_none() && decoded.reading.is_none() {
            return None;
        }
        let t_s = self.clock.stamp(wall_us, decoded.time_boot_ms);
        decoded.reading.map(|reading| Stamped {
            t_s,
            wall_us,
            reading,
        })
    }

    /// One raw frame; frames that do not parse are counted and give nothing.
    pub fn frame(&mut self, wall_us: u64, frame: &[u8]) -> Option<Stamped> {
        match parse_frame(frame) {
            Ok((header, message)) => self.message(wall_us, &header, &message),
            Err(_) => {
                self.undecodable += 1;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::Reading;
    use crate::link::mav::{self, MavMessage};

    const NONE10: [u16; 10] = [u16::MAX; 10];
    use crate::link::testing::autopilot_header as vehicle;

    #[test]
    fn the_pipeline_stamps_battery_readings_with_vehicle_time_between_positions() {
        let mut telemetry = Telemetry::new();
        let start = 1_700_000_000_000_000u64;
        let mut cells = NONE10;
        cells[0] = 22_000;
        let battery = MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
            voltages: cells,
            current_battery: 4000,
            ..Default::default()
        });
        let mut last = None;
        for k in 0..40u32 {
            // 10x speed-up: 100 ms of vehicle time every 10 ms of wall time.
            let wall = start + u64::from(k) * 10_000;
            let position = MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
                time_boot_ms: 60_000 + k * 100,
                lat: 385_362_000,
                lon: -1_217_875_000,
                ..Default::default()
            });
            telemetry.message(wall, &vehicle(), &position);
            last = telemetry.message(wall + 5_000, &vehicle(), &battery);
        }
        let last = last.expect("a stamped battery reading");
        assert!((last.t_s - 3.95).abs() < 0.01, "t {}", last.t_s);
        assert!(matches!(last.reading, Reading::Battery(_)));
    }
}
