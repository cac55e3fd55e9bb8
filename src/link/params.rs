//! Reading an autopilot's parameters by name, sans-IO: PARAM_REQUEST_READ (param_index -1, the
//! name in param_id) for each, a few at a time, each resent until its PARAM_VALUE arrives or its
//! retries run out. `start`, `handle`, `tick` take a fake or real clock and return the messages
//! to send.
//!
//! Values: MAV_PARAM_TYPE_REAL32 is the float. Integer parameters are decoded as the autopilot
//! encodes them: PX4 puts the integer's bytes in the float field (MAV_PROTOCOL_CAPABILITY_
//! PARAM_ENCODE_BYTEWISE, PX4 mavlink_parameters.cpp `send_param`), ArduPilot and others cast
//! the value to float (PARAM_ENCODE_C_CAST).

use std::time::Duration;

use super::mav::{self, MavMessage, MavParamType};
use super::Flavour;

/// Timing and addressing of the reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamConfig {
    pub target_system: u8,
    pub target_component: u8,
    pub flavour: Flavour,
    /// Wait this long for a PARAM_VALUE before asking again.
    pub timeout: Duration,
    /// Resends after the first request before a parameter counts as unanswered.
    pub retries: u32,
    /// Requests outstanding at once.
    pub window: usize,
}

impl Default for ParamConfig {
    fn default() -> Self {
        ParamConfig {
            target_system: 1,
            target_component: 1,
            flavour: Flavour::Px4,
            timeout: Duration::from_millis(500),
            retries: 4,
            window: 4,
        }
    }
}

/// Where one parameter's read stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    Waiting,
    /// Sent `attempts` times, the last resend due at `deadline`.
    Asked {
        attempts: u32,
        deadline: Duration,
    },
    Read(f64),
    Unanswered,
}

/// Reads parameters by name.
#[derive(Debug, Clone)]
pub struct ParamReads {
    cfg: ParamConfig,
    names: Vec<String>,
    slots: Vec<Slot>,
}

/// A parameter id as MAVLink carries it: at most 16 bytes, NUL-padded.
fn param_id(name: &str) -> mavlink::types::CharArray<16> {
    name.into()
}

impl ParamReads {
    /// Reads of `names` (PX4 or ArduPilot names, at most 16 characters each).
    pub fn new(cfg: ParamConfig, names: &[&str]) -> ParamReads {
        ParamReads {
            cfg,
            names: names.iter().map(|n| n.to_string()).collect(),
            slots: vec![Slot::Waiting; names.len()],
        }
    }

    /// Whether every parameter was read or given up on.
    pub fn finished(&self) -> bool {
        self.slots
            .iter()
            .all(|s| matches!(s, Slot::Read(_) | Slot::Unanswered))
    }

    /// Every name with its value (None: not answered).
    pub fn values(&self) -> Vec<(String, Option<f64>)> {
        self.names
            .iter()
            .zip(&self.slots)
            .map(|(n, s)| {
                (
                    n.clone(),
                    match s {
                        Slot::Read(v) => Some(*v),
                        _ => None,
                    },
                )
            })
            .collect()
    }

    fn request(&self, k: usize) -> MavMessage {
        MavMessage::PARAM_REQUEST_READ(mav::PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            param_id: param_id(&self.names[k]),
        })
    }

    /// Sends the first requests.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.tick(now)
    }

    /// Takes in a message from the autopilot; a PARAM_VALUE of a name asked for is its value.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        let MavMessage::PARAM_VALUE(p) = message else {
            return Vec::new();
        };
        let Ok(name) = p.param_id.to_str() else {
            return Vec::new();
        };
        if let Some(k) = self.names.iter().position(|n| n == name) {
            if !matches!(self.slots[k], Slot::Read(_)) {
                self.slots[k] = Slot::Read(decode(self.cfg.flavour, p.param_value, p.param_type));
            }
        }
        self.tick(now)
    }

    /// Resends what timed out, gives up after the retries, and keeps `window` requests out.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        let mut out = Vec::new();
        for k in 0..self.slots.len() {
            if let Slot::Asked { attempts, deadline } = self.slots[k] {
                if now >= deadline {
                    if attempts > self.cfg.retries {
                        self.slots[k] = Slot::Unanswered;
                    } else {
                        self.slots[k] = Slot::Asked {
                            attempts: attempts + 1,
                            deadline: now + self.cfg.timeout,
                        };
                        out.push(self.request(k));
                    }
                }
            }
        }
        let outstanding = self
            .slots
            .iter()
            .filter(|s| matches!(s, Slot::Asked { .. }))
            .count();
        let free = self.cfg.window.max(1).saturating_sub(outstanding);
        let waiting: Vec<usize> = (0..self.slots.len())
            .filter(|&k| self.slots[k] == Slot::Waiting)
            .take(free)
            .collect();
        for k in waiting {
            self.slots[k] = Slot::Asked {
                attempts: 1,
                deadline: now + self.cfg.timeout,
            };
            out.push(self.request(k));
        }
        out
    }
}

/// A PARAM_VALUE's value as a number (see the module doc for the encodings).
pub fn decode(flavour: Flavour, value: f32, kind: MavParamType) -> f64 {
    use MavParamType::*;
    let bytewise = flavour == Flavour::Px4;
    let bits = value.to_bits();
    match kind {
        MAV_PARAM_TYPE_REAL32 | MAV_PARAM_TYPE_REAL64 => f64::from(value),
        _ if !bytewise => f64::from(value),
        MAV_PARAM_TYPE_UINT8 => f64::from(bits as u8),
        MAV_PARAM_TYPE_INT8 => f64::from(bits as u8 as i8),
        MAV_PARAM_TYPE_UINT16 => f64::from(bits as u16),
        MAV_PARAM_TYPE_INT16 => f64::from(bits as u16 as i16),
        MAV_PARAM_TYPE_UINT32 => f64::from(bits),
        MAV_PARAM_TYPE_INT32 => f64::from(bits as i32),
        MAV_PARAM_TYPE_UINT64 | MAV_PARAM_TYPE_INT64 => f64::from(bits as i32),
    }
}

/// The parameter that sets the height an autopilot's return (RTL) flies home at: it climbs to
/// it first when lower, then flies home and lands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnAltitude {
    pub name: &'static str,
    /// Metres per unit of the parameter.
    pub metres_per_unit: f64,
    /// The autopilot's default, for when it does not answer (m).
    pub default_m: f64,
}

impl ReturnAltitude {
    /// PX4: RTL_RETURN_ALT, metres, default 60 (rtl_params.c); ArduCopter: RTL_ALT,
    /// centimetres, default 1500 (0: home at the current height).
    pub fn of(flavour: Flavour) -> ReturnAltitude {
        match flavour {
            Flavour::ArduPilot => ReturnAltitude {
                name: "RTL_ALT",
                metres_per_unit: 0.01,
                default_m: 15.0,
            },
            Flavour::Px4 | Flavour::Generic => ReturnAltitude {
                name: "RTL_RETURN_ALT",
                metres_per_unit: 1.0,
                default_m: 60.0,
            },
        }
    }
}

/// The PARAM_VALUE an autopilot of `flavour` sends for `name` = `value` of `kind` (the mock's
/// answer; the inverse of [`decode`]).
pub fn encode(flavour: Flavour, name: &str, value: f64, kind: MavParamType) -> MavMessage {
    use MavParamType::*;
    let wire = match kind {
        MAV_PARAM_TYPE_REAL32 | MAV_PARAM_TYPE_REAL64 => value as f32,
        _ if flavour != Flavour::Px4 => value as f32,
        _ => f32::from_bits(value as i32 as u32),
    };
    MavMessage::PARAM_VALUE(mav::PARAM_VALUE_DATA {
        param_value: wire,
        param_count: 0,
        param_index: u16::MAX,
        param_id: param_id(name),
        param_type: kind,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn asked(out: &[MavMessage]) -> Vec<String> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::PARAM_REQUEST_READ(r) => {
                    assert_eq!(
                        (r.param_index, r.target_system, r.target_component),
                        (-1, 1, 1)
                    );
                    Some(r.param_id.to_str().unwrap().to_string())
                }
                _ => None,
            })
            .collect()
    }

    fn value(name: &str, v: f32) -> MavMessage {
        encode(
            Flavour::Px4,
            name,
            f64::from(v),
            MavParamType::MAV_PARAM_TYPE_REAL32,
        )
    }

    #[test]
    fn parameters_are_asked_for_a_window_at_a_time_and_read_from_their_answers() {
        let names = [
            "MPC_XY_CRUISE",
            "MPC_ACC_HOR",
            "MPC_JERK_AUTO",
            "NAV_ACC_RAD",
            "MPC_Z_V_AUTO_UP",
        ];
        let cfg = ParamConfig {
            window: 2,
            ..ParamConfig::default()
        };
        let mut reads = ParamReads::new(cfg, &names);
        assert_eq!(asked(&reads.start(ms(0))), ["MPC_XY_CRUISE", "MPC_ACC_HOR"]);
        // An answer frees a place in the window; answers of other names change nothing.
        assert_eq!(
            asked(&reads.handle(ms(10), &value("MPC_ACC_HOR", 3.0))),
            ["MPC_JERK_AUTO"]
        );
        assert!(asked(&reads.handle(ms(11), &value("SYS_AUTOSTART", 1.0))).is_empty());
        for (t, name, v) in [
            (20, "MPC_XY_CRUISE", 5.0),
            (30, "MPC_JERK_AUTO", 4.0),
            (40, "NAV_ACC_RAD", 2.0),
            (50, "MPC_Z_V_AUTO_UP", 3.0),
        ] {
            reads.handle(ms(t), &value(name, v));
        }
        assert!(reads.finished());
        assert_eq!(
            reads.values(),
            names
                .iter()
                .zip([5.0, 3.0, 4.0, 2.0, 3.0])
                .map(|(n, v)| (n.to_string(), Some(v)))
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_lost_request_is_asked_again_and_a_parameter_never_answered_is_given_up() {
        let mut reads =
            ParamReads::new(ParamConfig::default(), &["MPC_XY_CRUISE", "NO_SUCH_PARAM"]);
        assert_eq!(reads.start(ms(0)).len(), 2);
        assert!(reads.tick(ms(499)).is_empty());
        assert_eq!(
            asked(&reads.tick(ms(500))),
            ["MPC_XY_CRUISE", "NO_SUCH_PARAM"]
        );
        reads.handle(ms(600), &value("MPC_XY_CRUISE", 6.5));
        // Four resends after the first, 0.5 s apart; then the name is given up.
        let mut t = 1000;
        let mut resends = 0;
        while !reads.finished() {
            resends += asked(&reads.tick(ms(t))).len();
            t += 500;
            assert!(t < 10_000, "never gave up");
        }
        assert_eq!(resends, 3);
        assert_eq!(
            reads.values(),
            [
                ("MPC_XY_CRUISE".to_string(), Some(6.5)),
                ("NO_SUCH_PARAM".to_string(), None)
            ]
        );
        // A late answer after giving up is still taken.
        reads.handle(ms(t), &value("NO_SUCH_PARAM", 1.0));
        assert_eq!(reads.values()[1].1, Some(1.0));
    }

    #[test]
    fn integers_are_decoded_bytewise_from_px4_and_cast_from_others() {
        use MavParamType::*;
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            for (v, kind) in [
                (4.0, MAV_PARAM_TYPE_INT32),
                (-3.0, MAV_PARAM_TYPE_INT32),
                (2.5, MAV_PARAM_TYPE_REAL32),
                (200.0, MAV_PARAM_TYPE_UINT8),
            ] {
                let MavMessage::PARAM_VALUE(p) = encode(flavour, "X", v, kind) else {
                    panic!()
                };
                assert_eq!(
                    decode(flavour, p.param_value, p.param_type),
                    v,
                    "{flavour:?} {kind:?}"
                );
            }
        }
        // PX4's bytewise 4 is a tiny float, not 4.0.
        let MavMessage::PARAM_VALUE(p) =
            encode(Flavour::Px4, "MPC_YAW_MODE", 4.0, MAV_PARAM_TYPE_INT32)
        else {
            panic!()
        };
        assert!(p.param_value < 1e-30);
    }
}
