//! The mission protocol's vehicle side as a sans-IO state machine, as strict as PX4
//! (DESIGN.md "The mock autopilot must be as strict as PX4"): it requests items with
//! MISSION_REQUEST_INT, re-requests a missing item every 250 ms and abandons a transfer after 5 s
//! without progress; an upload is atomic (a failed or abandoned upload leaves the previous
//! mission in place); the final MISSION_ACK is sent once; unsupported commands, frames and
//! mission types are NACKed as PX4 does. The ArduPilot flavour keeps seq 0 as home and writes
//! items as they arrive (not atomic).

use std::time::Duration;

use crate::link::mav::{
    MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MISSION_ACK_DATA,
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
};

/// Which firmware the mock imitates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flavour {
    Px4,
    ArduPilot,
}

/// Re-request period for a missing item (PX4).
pub const REREQUEST: Duration = Duration::from_millis(250);
/// A transfer without progress for this long is abandoned (PX4).
pub const ABANDON: Duration = Duration::from_secs(5);
/// Most items stored (PX4's dataman holds thousands; a bound keeps hostile counts out).
pub const MAX_ITEMS: u16 = 2000;

/// Injected protocol faults (transport faults live in the async shell).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProtocolFaults {
    /// NACK the upload when this item arrives.
    pub nack_item: Option<u16>,
    /// The result that NACK carries.
    pub nack_result: Option<MavMissionResult>,
    /// Never send the final ACCEPTED ack.
    pub drop_final_ack: bool,
    /// Lose the transfer state (a reboot) when this item arrives; the stored mission survives.
    pub reboot_at_item: Option<u16>,
}

#[derive(Debug, Clone)]
struct Receiving {
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    last_request: Duration,
    last_progress: Duration,
}

/// What the server has done (for tests and reports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServerStats {
    pub uploads_accepted: u32,
    pub uploads_rejected: u32,
    pub uploads_abandoned: u32,
    pub rerequests: u32,
    pub reboots: u32,
}

/// The vehicle side of the mission protocol.
#[derive(Debug, Clone)]
pub struct MissionServer {
    flavour: Flavour,
    faults: ProtocolFaults,
    mission: Vec<MISSION_ITEM_INT_DATA>,
    receiving: Option<Receiving>,
    /// (system, component) of the ground station being answered.
    gcs: (u8, u8),
    /// The current item (MISSION_SET_CURRENT), where a flight would resume.
    current: u16,
    pub stats: ServerStats,
}

fn supported(flavour: Flavour, item: &MISSION_ITEM_INT_DATA) -> Result<(), MavMissionResult> {
    use MavCmd::*;
    use MavFrame::*;
    let navigation = matches!(
        item.command,
        MAV_CMD_NAV_WAYPOINT
            | MAV_CMD_NAV_TAKEOFF
            | MAV_CMD_NAV_LAND
            | MAV_CMD_NAV_LOITER_TIME
            | MAV_CMD_NAV_LOITER_UNLIM
    );
    let command = matches!(
        item.command,
        MAV_CMD_NAV_RETURN_TO_LAUNCH
            | MAV_CMD_DO_CHANGE_SPEED
            | MAV_CMD_NAV_DELAY
            | MAV_CMD_DO_JUMP
    );
    if !navigation && !command {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED);
    }
    #[allow(deprecated)]
    let frame_ok = match item.frame {
        MAV_FRAME_GLOBAL
        | MAV_FRAME_GLOBAL_RELATIVE_ALT
        | MAV_FRAME_GLOBAL_INT
        | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => true,
        MAV_FRAME_MISSION => command,
        _ => false,
    };
    let ardupilot_home = flavour == Flavour::ArduPilot && item.seq == 0;
    if !(frame_ok || ardupilot_home) {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME);
    }
    if navigation
        && (item.x == 0 && item.y == 0)
        && item.command != MAV_CMD_NAV_LAND
        && item.command != MAV_CMD_NAV_TAKEOFF
    {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X);
    }
    if !item.z.is_finite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    }
    Ok(())
}

impl MissionServer {
    /// A server with an empty mission.
    pub fn new(flavour: Flavour, faults: ProtocolFaults) -> MissionServer {
        MissionServer {
            flavour,
            faults,
            mission: Vec::new(),
            receiving: None,
            gcs: (255, 190),
            current: 0,
            stats: ServerStats::default(),
        }
    }

    /// The current item (where a flight would resume).
    pub fn current(&self) -> u16 {
        self.current
    }

    /// The stored mission.
    pub fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.mission
    }

    fn ack(&self, result: MavMissionResult, mission_type: MavMissionType) -> MavMessage {
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mavtype: result,
            mission_type,
            opaque_id: 0,
        })
    }

    fn request(&self, seq: u16) -> MavMessage {
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
        })
    }

    fn reject(&mut self, result: MavMissionResult) -> Vec<MavMessage> {
        self.receiving = None;
        self.stats.uploads_rejected += 1;
        vec![self.ack(result, MavMissionType::MAV_MISSION_TYPE_MISSION)]
    }

    /// Reacts to a message from the ground station `(system, component)`.
    #[allow(deprecated)]
    pub fn handle(
        &mut self,
        now: Duration,
        from: (u8, u8),
        message: &MavMessage,
    ) -> Vec<MavMessage> {
        let mission = MavMissionType::MAV_MISSION_TYPE_MISSION;
        match message {
            MavMessage::MISSION_COUNT(c) => {
                self.gcs = from;
                if c.mission_type != mission {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, c.mission_type)
                    ];
                }
                if c.count > MAX_ITEMS {
                    return self.reject(MavMissionResult::MAV_MISSION_NO_SPACE);
                }
                if c.count == 0 {
                    self.mission.clear();
                    self.receiving = None;
                    self.stats.uploads_accepted += 1;
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, mission)];
                }
                if self.flavour == Flavour::ArduPilot {
                    self.mission.truncate(c.count as usize);
                }
                self.receiving = Some(Receiving {
                    count: c.count,
                    items: Vec::new(),
                    last_request: now,
                    last_progress: now,
                });
                vec![self.request(0)]
            }
            MavMessage::MISSION_ITEM_INT(item) => {
                let Some(rx) = self.receiving.as_mut() else {
                    return Vec::new();
                };
                if item.mission_type != mission || item.seq as usize != rx.items.len() {
                    return Vec::new(); // a duplicate or out of order: the timer re-requests
                }
                if self.faults.reboot_at_item == Some(item.seq) {
                    self.faults.reboot_at_item = None;
                    self.receiving = None;
                    self.stats.reboots += 1;
                    return Vec::new();
                }
                if self.faults.nack_item == Some(item.seq) {
                    let result = self
                        .faults
                        .nack_result
                        .unwrap_or(MavMissionResult::MAV_MISSION_ERROR);
                    return self.reject(result);
                }
                if let Err(result) = supported(self.flavour, item) {
                    return self.reject(result);
                }
                let count = rx.count;
                rx.items.push(item.clone());
                rx.last_progress = now;
                rx.last_request = now;
                if self.flavour == Flavour::ArduPilot {
                    // Not atomic: each item is written as it arrives.
                    let seq = item.seq as usize;
                    if seq < self.mission.len() {
                        self.mission[seq] = item.clone();
                    } else {
                        self.mission.push(item.clone());
                    }
                }
                let received = rx.items.len();
                if received == count as usize {
                    let items = self.receiving.take().map(|r| r.items).unwrap_or_default();
                    self.mission = items;
                    self.stats.uploads_accepted += 1;
                    if self.faults.drop_final_ack {
                        return Vec::new();
                    }
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, mission)];
                }
                vec![self.request(received as u16)]
            }
            MavMessage::MISSION_REQUEST_LIST(r) => {
                self.gcs = from;
                if r.mission_type != mission {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, r.mission_type)
                    ];
                }
                vec![MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                    count: self.mission.len() as u16,
                    target_system: from.0,
                    target_component: from.1,
                    mission_type: mission,
                    opaque_id: 0,
                })]
            }
            MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq, mission_type, ..
            })
            | MavMessage::MISSION_REQUEST(crate::link::mav::MISSION_REQUEST_DATA {
                seq,
                mission_type,
                ..
            }) => {
                self.gcs = from;
                if *mission_type != mission {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, *mission_type)];
                }
                match self.mission.get(*seq as usize) {
                    Some(item) => {
                        let mut item = item.clone();
                        item.target_system = from.0;
                        item.target_component = from.1;
                        vec![MavMessage::MISSION_ITEM_INT(item)]
                    }
                    None => vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, mission)],
                }
            }
            MavMessage::MISSION_SET_CURRENT(c) => {
                self.gcs = from;
                if (c.seq as usize) < self.mission.len() {
                    self.current = c.seq;
                    vec![MavMessage::MISSION_CURRENT(
                        crate::link::mav::MISSION_CURRENT_DATA {
                            seq: c.seq,
                            total: self.mission.len() as u16,
                            ..Default::default()
                        },
                    )]
                } else {
                    vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, mission)]
                }
            }
            MavMessage::MISSION_CLEAR_ALL(c) => {
                self.gcs = from;
                if c.mission_type == mission
                    || c.mission_type == MavMissionType::MAV_MISSION_TYPE_ALL
                {
                    self.mission.clear();
                    self.receiving = None;
                    vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, c.mission_type)]
                } else {
                    vec![self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, c.mission_type)]
                }
            }
            _ => Vec::new(),
        }
    }

    /// Re-requests a missing item every 250 ms; abandons after 5 s without progress.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        let Some(rx) = self.receiving.as_mut() else {
            return Vec::new();
        };
        if now.saturating_sub(rx.last_progress) >= ABANDON {
            self.receiving = None;
            self.stats.uploads_abandoned += 1;
            return Vec::new();
        }
        if now.saturating_sub(rx.last_request) >= REREQUEST {
            rx.last_request = now;
            let seq = rx.items.len() as u16;
            self.stats.rerequests += 1;
            return vec![self.request(seq)];
        }
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::MISSION_REQUEST_LIST_DATA;

    const GCS: (u8, u8) = (255, 190);

    fn ms(t: u64) -> Duration {
        Duration::from_millis(t)
    }

    fn items(n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
        (0..n)
            .map(|seq| MISSION_ITEM_INT_DATA {
                seq,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                x: 385_000_000,
                y: -1_217_000_000 - i32::from(seq),
                z: 30.0,
                autocontinue: 1,
                ..Default::default()
            })
            .collect()
    }

    fn count(n: u16) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            target_system: 1,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            opaque_id: 0,
        })
    }

    fn acks(out: &[MavMessage]) -> Vec<MavMissionResult> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_ACK(a) => Some(a.mavtype),
                _ => None,
            })
            .collect()
    }

    fn requested(out: &[MavMessage]) -> Option<u16> {
        out.iter().find_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
            _ => None,
        })
    }

    fn upload(server: &mut MissionServer, list: &[MISSION_ITEM_INT_DATA]) -> Vec<MavMessage> {
        let mut out = server.handle(ms(0), GCS, &count(list.len() as u16));
        for it in list {
            out.extend(server.handle(ms(1), GCS, &MavMessage::MISSION_ITEM_INT(it.clone())));
        }
        out
    }

    #[test]
    fn a_complete_upload_is_stored_and_acknowledged_once() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        let out = upload(&mut s, &items(3));
        assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(s.mission().len(), 3);
        // A repeated last item does not bring the ack back.
        assert!(s
            .handle(
                ms(2),
                GCS,
                &MavMessage::MISSION_ITEM_INT(items(3)[2].clone())
            )
            .is_empty());
    }

    #[test]
    fn the_server_re_requests_a_missing_item_every_250_ms() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        assert_eq!(requested(&s.handle(ms(0), GCS, &count(2))), Some(0));
        assert!(s.tick(ms(200)).is_empty());
        assert_eq!(requested(&s.tick(ms(250))), Some(0));
        assert_eq!(requested(&s.tick(ms(500))), Some(0));
        assert_eq!(s.stats.rerequests, 2);
    }

    #[test]
    fn an_abandoned_upload_after_five_seconds_keeps_the_previous_mission() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        upload(&mut s, &items(2));
        s.handle(ms(10), GCS, &count(3));
        s.handle(
            ms(20),
            GCS,
            &MavMessage::MISSION_ITEM_INT(items(3)[0].clone()),
        );
        s.tick(ms(5020));
        assert_eq!(s.stats.uploads_abandoned, 1);
        assert_eq!(s.mission(), &items(2)[..]);
        assert!(s.tick(ms(6000)).is_empty());
    }

    #[test]
    fn a_wrong_mission_type_is_refused_as_unsupported() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        let fence = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 2,
            mission_type: MavMissionType::MAV_MISSION_TYPE_FENCE,
            ..Default::default()
        });
        assert_eq!(
            acks(&s.handle(ms(0), GCS, &fence)),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]
        );
    }

    #[test]
    fn an_unsupported_frame_is_nacked_and_the_old_mission_stays() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        upload(&mut s, &items(1));
        let mut bad = items(2);
        bad[1].frame = MavFrame::MAV_FRAME_LOCAL_NED;
        let out = upload(&mut s, &bad);
        assert_eq!(
            acks(&out),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME]
        );
        assert_eq!(s.mission().len(), 1);
    }

    #[test]
    fn an_injected_nack_on_item_k_rejects_the_upload() {
        let faults = ProtocolFaults {
            nack_item: Some(1),
            nack_result: Some(MavMissionResult::MAV_MISSION_DENIED),
            ..Default::default()
        };
        let mut s = MissionServer::new(Flavour::Px4, faults);
        let out = upload(&mut s, &items(3));
        assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_DENIED]);
        assert!(s.mission().is_empty());
    }

    #[test]
    fn a_reboot_mid_upload_forgets_the_transfer_but_not_the_stored_mission() {
        let faults = ProtocolFaults {
            reboot_at_item: Some(1),
            ..Default::default()
        };
        let mut s = MissionServer::new(Flavour::Px4, faults);
        upload(&mut s, &items(3));
        assert_eq!(s.stats.reboots, 1);
        assert!(s.mission().is_empty() && s.tick(ms(300)).is_empty());
        upload(&mut s, &items(3));
        assert_eq!(s.mission().len(), 3);
    }

    #[test]
    fn ardupilot_keeps_home_at_seq_zero_and_writes_items_as_they_arrive() {
        let mut s = MissionServer::new(Flavour::ArduPilot, ProtocolFaults::default());
        let mut list = items(3);
        list[0].frame = MavFrame::MAV_FRAME_GLOBAL;
        upload(&mut s, &list);
        assert_eq!(s.mission()[0].frame, MavFrame::MAV_FRAME_GLOBAL);
        s.handle(ms(10), GCS, &count(3));
        s.handle(
            ms(11),
            GCS,
            &MavMessage::MISSION_ITEM_INT(items(3)[0].clone()),
        );
        // Abandoned after one item: not atomic, the first item was already replaced.
        s.tick(ms(6000));
        assert_eq!(
            s.mission()[0].frame,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
        );
    }

    #[test]
    fn a_download_is_answered_item_by_item_and_clear_all_empties_the_mission() {
        let mut s = MissionServer::new(Flavour::Px4, ProtocolFaults::default());
        upload(&mut s, &items(2));
        let list = MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            ..Default::default()
        });
        assert!(
            matches!(s.handle(ms(0), GCS, &list).as_slice(), [MavMessage::MISSION_COUNT(c)] if c.count == 2)
        );
        let req = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            ..Default::default()
        });
        assert!(
            matches!(s.handle(ms(0), GCS, &req).as_slice(), [MavMessage::MISSION_ITEM_INT(i)] if i.seq == 1)
        );
        let beyond = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: 5,
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            ..Default::default()
        });
        assert_eq!(
            acks(&s.handle(ms(0), GCS, &beyond)),
            vec![MavMissionResult::MAV_MISSION_INVALID_SEQUENCE]
        );
        let clear = MavMessage::MISSION_CLEAR_ALL(crate::link::mav::MISSION_CLEAR_ALL_DATA {
            mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            ..Default::default()
        });
        assert_eq!(
            acks(&s.handle(ms(0), GCS, &clear)),
            vec![MavMissionResult::MAV_MISSION_ACCEPTED]
        );
        assert!(s.mission().is_empty());
    }
}
