//! The flight modes both flavours know, and each one's HEARTBEAT custom_mode numbers (PX4's
//! main and sub modes, ArduCopter's mode numbers).

use crate::link::Flavour;

/// Flight modes both flavours know (mapped to each one's custom_mode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// PX4 AUTO.LOITER (Hold), ArduCopter LOITER.
    Hold,
    /// PX4 AUTO.MISSION, ArduCopter AUTO.
    Mission,
    /// PX4 AUTO.TAKEOFF.
    Takeoff,
    /// PX4 AUTO.LAND, ArduCopter LAND.
    Land,
    /// PX4 AUTO.RTL, ArduCopter RTL.
    Rtl,
    /// ArduCopter GUIDED (PX4 OFFBOARD).
    Guided,
    /// PX4 POSCTL, ArduCopter POSHOLD.
    Position,
    /// PX4 ALTCTL, ArduCopter ALT_HOLD.
    Altitude,
    /// PX4 STABILIZED, ArduCopter STABILIZE.
    Stabilized,
    /// PX4 MANUAL.
    Manual,
}

// PX4 custom mode (px4_custom_mode.h): main mode in byte 2, sub mode in byte 3.
const PX4_MANUAL: u32 = 1;
const PX4_ALTCTL: u32 = 2;
const PX4_POSCTL: u32 = 3;
const PX4_AUTO: u32 = 4;
const PX4_OFFBOARD: u32 = 6;
const PX4_STABILIZED: u32 = 7;
const PX4_AUTO_TAKEOFF: u32 = 2;
const PX4_AUTO_LOITER: u32 = 3;
const PX4_AUTO_MISSION: u32 = 4;
const PX4_AUTO_RTL: u32 = 5;
const PX4_AUTO_LAND: u32 = 6;

impl Mode {
    /// The HEARTBEAT custom_mode of this mode.
    pub fn custom_mode(self, flavour: Flavour) -> u32 {
        match flavour {
            Flavour::Px4 | Flavour::Generic => {
                let (main, sub) = match self {
                    Mode::Hold => (PX4_AUTO, PX4_AUTO_LOITER),
                    Mode::Mission => (PX4_AUTO, PX4_AUTO_MISSION),
                    Mode::Takeoff => (PX4_AUTO, PX4_AUTO_TAKEOFF),
                    Mode::Land => (PX4_AUTO, PX4_AUTO_LAND),
                    Mode::Rtl => (PX4_AUTO, PX4_AUTO_RTL),
                    Mode::Guided => (PX4_OFFBOARD, 0),
                    Mode::Position => (PX4_POSCTL, 0),
                    Mode::Altitude => (PX4_ALTCTL, 0),
                    Mode::Stabilized => (PX4_STABILIZED, 0),
                    Mode::Manual => (PX4_MANUAL, 0),
                };
                (main << 16) | (sub << 24)
            }
            // ArduCopter mode numbers (mode.h `Mode::Number`).
            Flavour::ArduPilot => match self {
                Mode::Stabilized | Mode::Manual => 0,
                Mode::Altitude => 2,
                Mode::Mission => 3,
                Mode::Guided => 4,
                Mode::Hold => 5,
                Mode::Rtl => 6,
                Mode::Land => 9,
                Mode::Position => 16,
                Mode::Takeoff => 4,
            },
        }
    }

    /// The mode a custom_mode names, if the flavour knows it.
    pub fn from_custom(flavour: Flavour, custom_mode: u32) -> Option<Mode> {
        match flavour {
            Flavour::Px4 | Flavour::Generic => {
                let main = (custom_mode >> 16) & 0xff;
                let sub = (custom_mode >> 24) & 0xff;
                Some(match (main, sub) {
                    (PX4_AUTO, PX4_AUTO_LOITER) => Mode::Hold,
                    (PX4_AUTO, PX4_AUTO_MISSION) => Mode::Mission,
                    (PX4_AUTO, PX4_AUTO_TAKEOFF) => Mode::Takeoff,
                    (PX4_AUTO, PX4_AUTO_LAND) => Mode::Land,
                    (PX4_AUTO, PX4_AUTO_RTL) => Mode::Rtl,
                    (PX4_OFFBOARD, _) => Mode::Guided,
                    (PX4_POSCTL, _) => Mode::Position,
                    (PX4_ALTCTL, _) => Mode::Altitude,
                    (PX4_STABILIZED, _) => Mode::Stabilized,
                    (PX4_MANUAL, _) => Mode::Manual,
                    _ => return None,
                })
            }
            Flavour::ArduPilot => Some(match custom_mode {
                0 => Mode::Stabilized,
                2 => Mode::Altitude,
                3 => Mode::Mission,
                4 => Mode::Guided,
                5 => Mode::Hold,
                6 => Mode::Rtl,
                9 => Mode::Land,
                16 => Mode::Position,
                _ => return None,
            }),
        }
    }
}
