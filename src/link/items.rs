//! Mission items from a mission and a visiting order: optional NAV_TAKEOFF to the origin height,
//! optional DO_CHANGE_SPEED, the start's actions, one navigation item per waypoint
//! (NAV_WAYPOINT, or the spline or loiter the file gave; latitude/longitude as degE7, altitude
//! relative to home, param1 hover seconds, param2 acceptance radius) followed by its actions
//! and the commands that restore the file's settings for the next waypoint
//! (`mission::actions::restore`), translated for the autopilot ([`translate`]), and the ending: by
//! default a NAV_WAYPOINT back at the origin hover point, then NAV_LAND there (the return leg
//! and the landing the plan priced: PX4's RTL would first climb to RTL_RETURN_ALT, which is not
//! the planned leg); NAV_RETURN_TO_LAUNCH or a bare NAV_LAND on request. Frames PX4 accepts: GLOBAL_RELATIVE_ALT (3) for navigation items,
//! MISSION (2) for commands (PX4's mission item checks; docs/mavlink.md). ArduPilot
//! gets its home item at seq 0. A block an order flies last to first ([`reversed_runs`]) goes
//! up laid out as `mission::Mission::reversing` reverses it: its items contiguous, each line in
//! the file's settings on it, its camera trigger on at the end it enters and off at the end it
//! leaves; its flown-through waypoints keep the file's hold (a survey's: none).

use super::mav::{MavCmd, MavFrame, MavMissionType, MISSION_ITEM_INT_DATA};
use super::Flavour;
use crate::mission::actions::{id, Action, Command};
use crate::mission::{Enu, Geodetic, Mission, Origin, WaypointKind};

/// How a mission ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Fly the return leg to the origin hover point as a waypoint (hold 0), then land there:
    /// what the plan prices (the return leg, then the landing (0, -h)).
    ReturnAndLand,
    ReturnToLaunch,
    Land,
}

/// Options for building items.
#[derive(Debug, Clone, PartialEq)]
pub struct ItemOptions {
    pub flavour: Flavour,
    pub takeoff: bool,
    pub acceptance_radius_m: f32,
    /// Cruise speed to command with DO_CHANGE_SPEED before the first waypoint, if any.
    pub cruise_speed_m_s: Option<f32>,
    /// The vehicle's own horizontal speed, commanded where the file's order flies at it after
    /// another order changed it (None: DO_CHANGE_SPEED -2, "the vehicle's default").
    pub vehicle_speed_m_s: Option<f64>,
    pub ending: Ending,
}

impl Default for ItemOptions {
    fn default() -> Self {
        ItemOptions {
            flavour: Flavour::Px4,
            takeoff: true,
            acceptance_radius_m: 2.0,
            cruise_speed_m_s: None,
            vehicle_speed_m_s: None,
            ending: Ending::ReturnAndLand,
        }
    }
}

/// Degrees to MAVLink's degE7 integers (round to nearest).
pub fn deg_e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

/// One mission item (seq 0, autocontinue, mission type MISSION; numbered by the caller).
pub fn item(
    command: MavCmd,
    frame: MavFrame,
    params: [f32; 4],
    x: i32,
    y: i32,
    z: f32,
) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        x,
        y,
        z,
        seq: 0,
        command,
        target_system: 0,
        target_component: 0,
        frame,
        current: 0,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
    }
}

/// A mission item from the numbers a flight controller logs of it (ArduPilot's CMD records:
/// MAV_CMD, MAV_FRAME, the four parameters, degrees and metres as the frame gives them); None for
/// a command or frame this MAVLink dialect does not know.
pub fn item_from_numbers(
    seq: u16,
    command: u16,
    frame: u8,
    params: [f32; 4],
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
) -> Option<MISSION_ITEM_INT_DATA> {
    use num_traits::FromPrimitive;
    let e7 = |deg: f64| {
        let v = (deg * 1e7).round();
        (v.is_finite() && v.abs() <= f64::from(i32::MAX)).then_some(v as i32)
    };
    Some(MISSION_ITEM_INT_DATA {
        seq,
        ..item(
            MavCmd::from_u16(command)?,
            MavFrame::from_u8(frame)?,
            params,
            e7(lat_deg)?,
            e7(lon_deg)?,
            alt_m as f32,
        )
    })
}

/// Why a mission's items could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ItemsError {
    #[error("the order names waypoint {0}, which the mission does not have")]
    UnknownWaypoint(usize),
    #[error(
        "{place}: command {command} ({what}) is not taken by {autopilot} (it answers \
         MAV_MISSION_UNSUPPORTED): remove it from the mission or fly it with another autopilot"
    )]
    Unsupported {
        place: String,
        command: u16,
        what: String,
        autopilot: &'static str,
    },
    #[error("{place}: command {command} is not a MAVLink command this build knows")]
    UnknownCommand { place: String, command: u16 },
}

/// What an autopilot of `flavour` flies for a waypoint of `kind` with these actions: the
/// waypoint's MAV_CMD and yaw (param4, NaN: none), and the actions to send, with the notes of
/// what was translated. PX4 does not take CONDITION_YAW (115), DO_SET_SERVO (183), DO_SET_RELAY
/// (181) or NAV_SPLINE_WAYPOINT (82) (PX4 SITL answers MAV_MISSION_UNSUPPORTED:
/// shared/research/mission-items.md): an absolute yaw becomes the waypoint's own yaw, a spline
/// a straight waypoint; a servo, a relay or a relative yaw is refused.
pub fn translate(
    flavour: Flavour,
    place: &str,
    kind: WaypointKind,
    actions: &[Command],
) -> Result<(u16, f32, Vec<Command>, Vec<String>), ItemsError> {
    let mut command = kind.command();
    let mut yaw_deg = f32::NAN;
    let mut notes = Vec::new();
    let mut out = Vec::with_capacity(actions.len());
    let unsupported = |c: &Command| ItemsError::Unsupported {
        place: place.to_string(),
        command: c.command,
        what: c.describe(),
        autopilot: match flavour {
            Flavour::Px4 => "PX4",
            Flavour::ArduPilot => "ArduPilot",
            Flavour::Generic => "the autopilot",
        },
    };
    if flavour != Flavour::Px4 {
        if let Some(c) = actions
            .iter()
            .find(|c| !super::support::takes(flavour, c.command))
        {
            return Err(unsupported(c));
        }
        return Ok((command, yaw_deg, actions.to_vec(), notes));
    }
    if kind == WaypointKind::Spline {
        command = id::NAV_WAYPOINT;
        notes.push(format!(
            "{place}: spline waypoint sent to PX4 as a straight waypoint (PX4 has no splines)"
        ));
    }
    for c in actions {
        match (c.command, c.action()) {
            (
                id::CONDITION_YAW,
                Action::Yaw {
                    angle_deg,
                    relative: false,
                    ..
                },
            ) => {
                yaw_deg = angle_deg.rem_euclid(360.0) as f32;
                notes.push(format!(
                    "{place}: yaw to {angle_deg} deg sent to PX4 as the waypoint's own yaw \
                     (PX4 does not take CONDITION_YAW in a mission)"
                ));
            }
            (id::CONDITION_YAW, _) => return Err(unsupported(c)),
            _ if !super::support::takes(flavour, c.command) => return Err(unsupported(c)),
            _ => out.push(c.clone()),
        }
    }
    Ok((command, yaw_deg, out, notes))
}

/// A command as a mission item for `flavour`: a position in degE7 where it has one (frame as
/// the file gave it), else parameters 5 and 6 as integers in the frame the autopilot takes it
/// in ([`super::support::action_frame`]).
fn command_item(
    c: &Command,
    place: &str,
    flavour: Flavour,
) -> Result<MISSION_ITEM_INT_DATA, ItemsError> {
    use num_traits::FromPrimitive;
    let command = MavCmd::from_u16(c.command).ok_or_else(|| ItemsError::UnknownCommand {
        place: place.to_string(),
        command: c.command,
    })?;
    let mut p = c.params.map(|v| v as f32);
    if flavour == Flavour::ArduPilot {
        // ArduPilot refuses a NaN in parameters 1-4 of a command other than a waypoint,
        // take-off or landing (AP_Mission::sanity_check_params: MAV_MISSION_INVALID_PARAMn);
        // MAVLink's NaN there is "unused" or "the default", which 0 is for these commands
        // (QGroundControl writes NaN for IMAGE_START_CAPTURE's sequence number).
        for v in p.iter_mut().take(4) {
            if v.is_nan() {
                *v = 0.0;
            }
        }
    }
    let (frame, x, y) = if c.has_position() {
        let frame = MavFrame::from_u8(c.frame).unwrap_or(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
        (frame, deg_e7(c.params[4]), deg_e7(c.params[5]))
    } else {
        // x and y are parameters 5 and 6 as integers (MISSION_ITEM_INT).
        let int = |v: f64| {
            if v.is_finite() {
                v.round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
            } else {
                0
            }
        };
        let frame = super::support::action_frame(flavour, c.command, false);
        (frame, int(c.params[4]), int(c.params[5]))
    };
    let z = if p[6].is_nan() { 0.0 } else { p[6] };
    Ok(item(command, frame, [p[0], p[1], p[2], p[3]], x, y, z))
}

/// Where the navigation items of [`mission_items_noted`] are: what a flight is measured
/// against numbers its points by.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layout {
    pub takeoff_seq: Option<u16>,
    /// Each waypoint's item in the order flown, then the return to the origin (with the
    /// default ending).
    pub point_seqs: Vec<u16>,
    pub land_seq: u16,
    /// The items of each leg's via points ([`flight_items_noted`]), one list per leg in the
    /// order flown (the leg to `point_seqs[k]`; the return leg last), empty for a straight leg.
    pub via_seqs: Vec<Vec<u16>>,
}

/// The commands run between two navigation items with the horizontal speed first. ArduPilot
/// starts only the first of them before the next leg begins (AP_Mission::advance_current_nav_cmd
/// loads one command, the rest start one per update once the leg is under way), and a speed set
/// once a leg's S-curve is planned applies to it only in part: ArduCopter SITL flew 40 m "at
/// 4 m/s" in 8.6 s where 4 m/s takes 12, with the speed third after its waypoint. So the speed
/// the leg is flown at goes first; of several, the last is the one in force and the earlier are
/// left out (they would be overridden within milliseconds).
fn speed_first(commands: Vec<Command>) -> Vec<Command> {
    use crate::mission::actions::Setting;
    let is_speed = |c: &Command| c.action() == Action::Set(Setting::Speed);
    let Some(last) = commands.iter().rev().find(|c| is_speed(c)).cloned() else {
        return commands;
    };
    std::iter::once(last)
        .chain(commands.into_iter().filter(|c| !is_speed(c)))
        .collect()
}

/// The items that fly `mission` in `order` (indices into `mission.waypoints`), numbered from 0,
/// the notes of what was inserted or translated for the autopilot, and where its navigation
/// items are.
pub fn mission_items_noted(
    mission: &Mission,
    order: &[usize],
    opts: &ItemOptions,
) -> Result<(Vec<MISSION_ITEM_INT_DATA>, Vec<String>, Layout), ItemsError> {
    flight_items_noted(mission, order, &[], opts)
}

/// A via point of a leg as its item: a NAV_WAYPOINT with no hold (param1 0), accepted within
/// the load's radius, no yaw. Both autopilots fly through it: ArduCopter blends the corner
/// when a NAV_WAYPOINT follows (`physics::ardupilot_chain::is_fast`), PX4 takes it within its
/// acceptance radius and turns for the next item at once (mission_block.cpp
/// `is_mission_item_reached_or_completed`, no hold to wait out).
fn via_item(origin: &Origin, at: Enu, opts: &ItemOptions) -> MISSION_ITEM_INT_DATA {
    let g = origin.to_geodetic(at);
    item(
        MavCmd::MAV_CMD_NAV_WAYPOINT,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        [0.0, opts.acceptance_radius_m, 0.0, f32::NAN],
        deg_e7(g.lat_deg),
        deg_e7(g.lon_deg),
        (g.alt_m - origin.home.alt_m) as f32,
    )
}

/// [`mission_items_noted`] with each leg's via points (`via[k]`: the points the leg to the
/// `k`th waypoint of `order` passes through round a fence zone, in the mission's frame;
/// `via[order.len()]` the return leg's; missing lists are straight legs): each goes up as a
/// NAV_WAYPOINT without a hold ([`via_item`]) just before the leg's own end, after the
/// commands of the point the leg leaves and the commands that restore the file's settings for
/// the leg, so a waypoint's actions stay after it and the whole leg flies in the settings the
/// file gives it.
pub fn flight_items_noted(
    mission: &Mission,
    order: &[usize],
    via: &[Vec<Enu>],
    opts: &ItemOptions,
) -> Result<(Vec<MISSION_ITEM_INT_DATA>, Vec<String>, Layout), ItemsError> {
    if let Some(&k) = order.iter().find(|&&k| k >= mission.waypoints.len()) {
        return Err(ItemsError::UnknownWaypoint(k));
    }
    // A block flown last to first goes up as the reversed block (`Mission::reversing`): its
    // lines in the file's states on them, its trigger on at the end it enters and off at the
    // end it leaves; the order then flies it forward there.
    let runs = reversed_runs(mission, order);
    let oriented;
    let flown;
    let (mission, order) = if runs.is_empty() {
        (mission, order)
    } else {
        oriented = mission.reversing(&runs);
        flown = order
            .iter()
            .map(|&k| match runs.iter().find(|r| r.contains(&k)) {
                Some(r) => r.start + r.end - 1 - k,
                None => k,
            })
            .collect::<Vec<_>>();
        (&oriented, flown.as_slice())
    };
    let home = mission.origin.home;
    let (lat, lon) = (deg_e7(home.lat_deg), deg_e7(home.lon_deg));
    let relative = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    let mut items = Vec::new();
    let mut notes = Vec::new();
    if opts.flavour == Flavour::ArduPilot {
        // ArduPilot's seq 0 is home (AMSL), overwritten by the vehicle's own home.
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL,
            [0.0; 4],
            lat,
            lon,
            home.alt_m as f32,
        ));
    }
    let takeoff_seq = opts.takeoff.then_some(items.len() as u16);
    let mut point_seqs = Vec::with_capacity(order.len() + 1);
    let mut via_seqs: Vec<Vec<u16>> = Vec::with_capacity(order.len() + 1);
    let push_via = |items: &mut Vec<MISSION_ITEM_INT_DATA>, via_seqs: &mut Vec<Vec<u16>>| {
        let leg = via.get(via_seqs.len()).map_or(&[][..], Vec::as_slice);
        let mut seqs = Vec::with_capacity(leg.len());
        for &at in leg {
            seqs.push(items.len() as u16);
            items.push(via_item(&mission.origin, at, opts));
        }
        via_seqs.push(seqs);
    };
    if opts.takeoff {
        items.push(item(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            relative,
            [0.0, 0.0, 0.0, f32::NAN],
            lat,
            lon,
            mission.origin.height_above_home_m as f32,
        ));
    }
    if let Some(speed) = opts.cruise_speed_m_s {
        // param1 1 = ground speed, param2 speed, param3 -1 = no throttle change.
        items.push(item(
            MavCmd::MAV_CMD_DO_CHANGE_SPEED,
            MavFrame::MAV_FRAME_MISSION,
            [1.0, speed, -1.0, 0.0],
            0,
            0,
            0.0,
        ));
    }
    let restoring = mission.restoring(order, opts.vehicle_speed_m_s);
    let push_commands = |items: &mut Vec<MISSION_ITEM_INT_DATA>,
                         commands: &[Command],
                         place: &str|
     -> Result<(), ItemsError> {
        for c in commands {
            items.push(command_item(c, place, opts.flavour)?);
        }
        Ok(())
    };
    let (_, _, start, start_notes) = translate(
        opts.flavour,
        "the start",
        WaypointKind::Waypoint,
        &mission.start_actions,
    )?;
    notes.extend(start_notes);
    let restore = |i: usize, before: &str, notes: &mut Vec<String>| -> Vec<Command> {
        let inserted = restoring.get(i).cloned().unwrap_or_default();
        for (setting, c) in &inserted {
            notes.push(format!(
                "{before}: inserted {} to restore the file's {} ({})",
                c.command,
                setting.name(),
                c.describe()
            ));
        }
        inserted.into_iter().map(|(_, c)| c).collect()
    };
    let first = order.first().map_or("the way home".to_string(), |&k| {
        format!("before {}", mission.waypoints[k].name)
    });
    let inserted = restore(0, &first, &mut notes);
    let (_, _, inserted, _) = translate(opts.flavour, &first, WaypointKind::Waypoint, &inserted)?;
    push_commands(
        &mut items,
        &speed_first([start, inserted].concat()),
        "the start",
    )?;
    for (i, &k) in order.iter().enumerate() {
        let w = &mission.waypoints[k];
        let place = format!("waypoint {}", w.name);
        let (command, yaw_deg, actions, translated) =
            translate(opts.flavour, &place, w.kind, &w.actions)?;
        notes.extend(translated);
        let (wlat, wlon, alt) = mission
            .waypoint_relative(k)
            .ok_or(ItemsError::UnknownWaypoint(k))?;
        let hover = w.hover_s as f32;
        let params = match w.kind {
            WaypointKind::LoiterTime { params } if command == id::NAV_LOITER_TIME => {
                [hover, params[0] as f32, params[1] as f32, params[2] as f32]
            }
            _ => [hover, opts.acceptance_radius_m, 0.0, yaw_deg],
        };
        let nav = {
            use num_traits::FromPrimitive;
            MavCmd::from_u16(command).unwrap_or(MavCmd::MAV_CMD_NAV_WAYPOINT)
        };
        push_via(&mut items, &mut via_seqs);
        point_seqs.push(items.len() as u16);
        items.push(item(
            nav,
            relative,
            params,
            deg_e7(wlat),
            deg_e7(wlon),
            alt as f32,
        ));
        let next = order.get(i + 1).map_or("the way home".to_string(), |&n| {
            format!("after {}, before {}", w.name, mission.waypoints[n].name)
        });
        let inserted = restore(i + 1, &next, &mut notes);
        let (_, _, inserted, _) =
            translate(opts.flavour, &next, WaypointKind::Waypoint, &inserted)?;
        push_commands(
            &mut items,
            &speed_first([actions, inserted].concat()),
            &place,
        )?;
    }
    // The return leg's via points: before the return waypoint, or before the landing or the
    // RTL that ends the mission without one.
    push_via(&mut items, &mut via_seqs);
    if opts.ending == Ending::ReturnAndLand {
        point_seqs.push(items.len() as u16);
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            relative,
            [0.0, opts.acceptance_radius_m, 0.0, f32::NAN],
            lat,
            lon,
            mission.origin.height_above_home_m as f32,
        ));
    }
    let land_seq = items.len() as u16;
    items.push(match opts.ending {
        Ending::ReturnToLaunch => item(
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            MavFrame::MAV_FRAME_MISSION,
            [0.0; 4],
            0,
            0,
            0.0,
        ),
        Ending::Land | Ending::ReturnAndLand => item(
            MavCmd::MAV_CMD_NAV_LAND,
            relative,
            [0.0, 0.0, 0.0, f32::NAN],
            lat,
            lon,
            0.0,
        ),
    });
    for (seq, it) in items.iter_mut().enumerate() {
        it.seq = seq as u16;
    }
    let layout = Layout {
        takeoff_seq,
        point_seqs,
        land_seq,
        via_seqs,
    };
    Ok((items, notes, layout))
}

/// The runs of `order` that fly a block's waypoints last to first: two or more waypoints of
/// one block in a row, each the one before the last in the file, as ranges of file indices.
pub fn reversed_runs(mission: &Mission, order: &[usize]) -> Vec<std::ops::Range<usize>> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < order.len() {
        let Some(block) = mission
            .block_of(order[i])
            .and_then(|b| mission.blocks.get(b))
        else {
            i += 1;
            continue;
        };
        let mut j = i;
        while j + 1 < order.len() && order[j + 1] + 1 == order[j] && block.contains(order[j + 1]) {
            j += 1;
        }
        if j > i {
            runs.push(order[j]..order[i] + 1);
        }
        i = j + 1;
    }
    runs
}

/// The items that fly `mission` in `order` ([`mission_items_noted`] without its notes).
pub fn mission_items(
    mission: &Mission,
    order: &[usize],
    opts: &ItemOptions,
) -> Result<Vec<MISSION_ITEM_INT_DATA>, ItemsError> {
    mission_items_noted(mission, order, opts).map(|(items, _, _)| items)
}

/// An item as JSON: MISSION_ITEM_INT fields, frame and command as MAVLink numbers, x/y in
/// degE7, NaN params as null (what `upload --json` and `download` write).
pub fn item_json(item: &MISSION_ITEM_INT_DATA) -> serde_json::Value {
    serde_json::json!({
        "seq": item.seq,
        "frame": item.frame as u32,
        "command": item.command as u32,
        "current": item.current,
        "autocontinue": item.autocontinue,
        "param1": item.param1,
        "param2": item.param2,
        "param3": item.param3,
        "param4": item.param4,
        "x": item.x,
        "y": item.y,
        "z": item.z,
    })
}

/// Why mission items could not be read as a flight.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadItemsError {
    #[error("the mission has no NAV_TAKEOFF: emplan measures flights that take off from the origin (items {0})")]
    NoTakeoff(String),
    #[error("the mission visits no waypoint after its take-off")]
    NoWaypoints,
    #[error("item {seq}: {what}")]
    Item { seq: u16, what: String },
}

/// A mission as the autopilot holds it, read as a flight.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightItems {
    pub home: Geodetic,
    pub origin_height_m: f64,
    pub takeoff_seq: u16,
    /// (seq, position in the origin frame, hold s) of every waypoint after the take-off.
    pub points: Vec<(u16, Enu, f64)>,
    /// The photos each point takes (one per point, in `points`' order): the photo commands
    /// that follow its waypoint item before the next navigation item (see [`read_flight`]).
    pub photos: Vec<u32>,
    pub land_seq: Option<u16>,
}

fn degrees(e7: i32) -> f64 {
    f64::from(e7) / 1e7
}

/// Reads `items` (held by an autopilot of `flavour`) as a flight: the layout [`mission_items`]
/// uploads ([home at seq 0 on ArduPilot] NAV_TAKEOFF to the origin height, the waypoints, a
/// NAV_WAYPOINT back at the origin, NAV_LAND) or any other read as far as it goes: the take-off's
/// position and altitude give the origin, every NAV_WAYPOINT after it is a point, the first
/// landing or RTL ends the flight. The home altitude (AMSL) is
/// ArduPilot's home item when there is one, else `home_alt_m` (what only the geometry of the
/// positions needs: altitudes are relative to home).
///
/// The photo commands after a waypoint item, up to the next navigation item (a MAV_CMD below
/// MAV_CMD_NAV_LAST, 95: ArduPilot `AP_Mission::is_nav_cmd`), are its photos, taken as the
/// autopilot leaves it: DO_DIGICAM_CONTROL with its shoot parameter (param5, MISSION_ITEM_INT
/// `x`, read as an integer by ArduPilot `AP_Mission::mavlink_int_to_mission_cmd` and PX4) 1,
/// one photo; IMAGE_START_CAPTURE with no interval (param2 0) and a number of images (param3)
/// of one or more, that many. A capture at an interval is a series in time, not photos of the
/// point, and is not counted.
pub fn read_flight(
    items: &[MISSION_ITEM_INT_DATA],
    flavour: Flavour,
    home_alt_m: f64,
) -> Result<FlightItems, ReadItemsError> {
    let summary = || {
        items
            .iter()
            .map(|i| format!("{}:{:?}", i.seq, i.command))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let takeoff = items
        .iter()
        .find(|i| i.command == MavCmd::MAV_CMD_NAV_TAKEOFF)
        .ok_or_else(|| ReadItemsError::NoTakeoff(summary()))?;
    let home_item = (flavour == Flavour::ArduPilot)
        .then(|| items.iter().find(|i| i.seq == 0))
        .flatten();
    let home = Geodetic {
        lat_deg: degrees(takeoff.x),
        lon_deg: degrees(takeoff.y),
        alt_m: home_item.map_or(home_alt_m, |h| f64::from(h.z)),
    };
    #[allow(deprecated)]
    let relative = |i: &MISSION_ITEM_INT_DATA| {
        matches!(
            i.frame,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        )
    };
    if !relative(takeoff) {
        return Err(ReadItemsError::Item {
            seq: takeoff.seq,
            what: format!(
                "take-off in frame {:?}: only altitudes relative to home are read",
                takeoff.frame
            ),
        });
    }
    let origin = Origin {
        home,
        height_above_home_m: f64::from(takeoff.z),
    };
    let mut points: Vec<(u16, Enu, f64)> = Vec::new();
    // The photos the commands after each point take (until the next point: a delay or a
    // loiter where it is holds there, and its photos are its own).
    let mut photos: Vec<u32> = Vec::new();
    let mut land_seq = None;
    for item in items.iter().filter(|i| i.seq > takeoff.seq) {
        let here = |i: &MISSION_ITEM_INT_DATA| i.x == 0 && i.y == 0;
        let taken = match item.command {
            MavCmd::MAV_CMD_DO_DIGICAM_CONTROL => u32::from(item.x == 1),
            MavCmd::MAV_CMD_IMAGE_START_CAPTURE
                if item.param2 == 0.0 && item.param3 >= 1.0 && item.param3.is_finite() =>
            {
                item.param3.min(u32::MAX as f32) as u32
            }
            _ => 0,
        };
        if let Some(count) = photos.last_mut() {
            *count = count.saturating_add(taken);
        }
        match item.command {
            // A hold where the vehicle is: the waypoint before holds longer.
            MavCmd::MAV_CMD_NAV_DELAY => {
                if let Some(last) = points.last_mut() {
                    last.2 += f64::from(item.param1.max(0.0));
                }
            }
            MavCmd::MAV_CMD_NAV_LOITER_TIME if here(item) && !points.is_empty() => {
                if let Some(last) = points.last_mut() {
                    last.2 += f64::from(item.param1.max(0.0));
                }
            }
            MavCmd::MAV_CMD_NAV_WAYPOINT
            | MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT
            | MavCmd::MAV_CMD_NAV_LOITER_TIME => {
                if !relative(item) {
                    return Err(ReadItemsError::Item {
                        seq: item.seq,
                        what: format!(
                            "waypoint in frame {:?}: only altitudes relative to home are read",
                            item.frame
                        ),
                    });
                }
                let enu = origin.to_enu(Geodetic {
                    lat_deg: degrees(item.x),
                    lon_deg: degrees(item.y),
                    alt_m: home.alt_m + f64::from(item.z),
                });
                let hold_s = f64::from(item.param1.max(0.0));
                // A loiter within a metre of the waypoint before is a hold there.
                let same = points.last().filter(|(_, last, _)| {
                    item.command == MavCmd::MAV_CMD_NAV_LOITER_TIME
                        && (last.x_east_m - enu.x_east_m).hypot(last.y_north_m - enu.y_north_m)
                            <= 1.0
                        && (last.z_up_m - enu.z_up_m).abs() <= 1.0
                });
                match (same.is_some(), points.last_mut()) {
                    (true, Some(last)) => last.2 += hold_s,
                    _ => {
                        points.push((item.seq, enu, hold_s));
                        photos.push(0);
                    }
                }
            }
            MavCmd::MAV_CMD_NAV_LAND | MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                land_seq = Some(item.seq);
                break;
            }
            _ => {}
        }
    }
    if points.is_empty() {
        return Err(ReadItemsError::NoWaypoints);
    }
    Ok(FlightItems {
        home,
        origin_height_m: origin.height_above_home_m,
        takeoff_seq: takeoff.seq,
        points,
        photos,
        land_seq,
    })
}

/// The mission `items` (held by an autopilot of `flavour`) hold, as a mission file would give it
/// (`download OUT.plan`): home (ArduPilot's item 0; else the take-off's place at 0 m above sea
/// level, since only heights above home matter), the take-off, each waypoint with the commands
/// that follow it, read as `mission::load_str` reads a `.waypoints` file. The return to the
/// origin emplan appends before its landing (a waypoint at the take-off's place and height,
/// no hold, then NAV_LAND) is its ending, not a waypoint.
pub fn mission_of_items(
    items: &[MISSION_ITEM_INT_DATA],
    flavour: Flavour,
    name: &str,
) -> Result<Mission, crate::mission::MissionError> {
    let takeoff = items
        .iter()
        .find(|i| i.command == MavCmd::MAV_CMD_NAV_TAKEOFF);
    let home = match (flavour, items.first(), takeoff) {
        (Flavour::ArduPilot, Some(h), _) if h.seq == 0 => {
            (degrees(h.x), degrees(h.y), f64::from(h.z))
        }
        (_, _, Some(t)) => (degrees(t.x), degrees(t.y), 0.0),
        _ => (0.0, 0.0, 0.0),
    };
    let skip_home = flavour == Flavour::ArduPilot && items.first().is_some_and(|i| i.seq == 0);
    let body = if skip_home { &items[1..] } else { items };
    // emplan's ending: the return waypoint just before the landing, at the take-off.
    let ending = body.windows(2).position(|w| {
        w[1].command == MavCmd::MAV_CMD_NAV_LAND
            && w[0].command == MavCmd::MAV_CMD_NAV_WAYPOINT
            && w[0].param1 == 0.0
            && takeoff.is_some_and(|t| (t.x, t.y, t.z) == (w[0].x, w[0].y, w[0].z))
    });
    #[allow(deprecated)]
    let global = |f: MavFrame| {
        matches!(
            f,
            MavFrame::MAV_FRAME_GLOBAL
                | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                | MavFrame::MAV_FRAME_GLOBAL_INT
                | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        )
    };
    let mut text = format!(
        "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t{:.10}\t{:.10}\t{:.4}\t1\n",
        home.0, home.1, home.2
    );
    let param = |v: f32| {
        if v.is_nan() {
            "nan".to_string()
        } else {
            format!("{v}")
        }
    };
    for (k, i) in body.iter().enumerate() {
        if Some(k) == ending {
            continue;
        }
        let (x, y) = if global(i.frame) {
            (
                format!("{:.10}", degrees(i.x)),
                format!("{:.10}", degrees(i.y)),
            )
        } else {
            (i.x.to_string(), i.y.to_string())
        };
        text += &format!(
            "{}\t0\t{}\t{}\t{}\t{}\t{}\t{}\t{x}\t{y}\t{}\t1\n",
            k + 1,
            i.frame as u8,
            i.command as u16,
            param(i.param1),
            param(i.param2),
            param(i.param3),
            param(i.param4),
            param(i.z),
        );
    }
    let mut mission = crate::mission::load_str(
        &text,
        crate::mission::Format::Wpl,
        Some(std::path::Path::new(&format!("{name}.waypoints"))),
    )?;
    mission.source = None;
    Ok(mission)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{load, Format};

    fn sample() -> Mission {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-3wp.toml");
        let _ = Format::Toml;
        load(&path).unwrap()
    }

    #[test]
    fn px4_items_are_takeoff_waypoints_in_order_then_the_origin_and_a_landing_there() {
        let m = sample();
        let items = mission_items(&m, &[2, 0, 1], &ItemOptions::default()).unwrap();
        assert_eq!(items.len(), 6);
        assert_eq!(items[0].command, MavCmd::MAV_CMD_NAV_TAKEOFF);
        assert_eq!(items[0].z, 30.0);
        let (lat, lon, alt) = m.waypoint_relative(2).unwrap();
        assert_eq!((items[1].x, items[1].y), (deg_e7(lat), deg_e7(lon)));
        assert!((items[1].z as f64 - alt).abs() < 1e-3 && (alt - 54.0).abs() < 0.01);
        assert_eq!(items[1].param1, 5.0);
        // The return leg ends at the origin hover point (hold 0), then the landing there.
        let home = m.origin.home;
        assert_eq!(items[4].command, MavCmd::MAV_CMD_NAV_WAYPOINT);
        assert_eq!(
            (items[4].x, items[4].y, items[4].z, items[4].param1),
            (deg_e7(home.lat_deg), deg_e7(home.lon_deg), 30.0, 0.0)
        );
        assert_eq!(items[5].command, MavCmd::MAV_CMD_NAV_LAND);
        assert_eq!((items[5].x, items[5].y), (items[4].x, items[4].y));
        assert!(items.iter().enumerate().all(|(k, it)| it.seq as usize == k));
        assert!(items
            .iter()
            .all(|it| it.frame == MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT));
    }

    /// The sample's three points and a survey of three lines after them (waypoints 3..9).
    fn surveyed() -> Mission {
        let at = crate::mission::Enu {
            x_east_m: 40.0,
            y_north_m: 40.0,
            z_up_m: 0.0,
        };
        crate::mission::blocks::with_survey(sample(), "S", at, 3, 60.0, 15.0, 25.0)
    }

    /// The camera trigger distances each waypoint's commands set, in flown order.
    fn triggers(m: &Mission) -> Vec<Vec<f64>> {
        (m.waypoints.iter())
            .map(|w| {
                (w.actions.iter())
                    .filter(|c| c.command == id::DO_SET_CAM_TRIGG_DIST)
                    .map(|c| c.params[0])
                    .collect()
            })
            .collect()
    }

    #[test]
    fn a_reversed_survey_goes_up_whole_with_its_trigger_on_at_its_far_end_and_off_at_its_near_one()
    {
        let m = surveyed();
        for flavour in [Flavour::ArduPilot, Flavour::Px4] {
            let opts = ItemOptions {
                flavour,
                ..ItemOptions::default()
            };
            let order = [0, 8, 7, 6, 5, 4, 3, 1, 2];
            let items = mission_items(&m, &order, &opts).unwrap();
            let back = mission_of_items(&items, flavour, "held").unwrap();
            let names: Vec<String> = order.iter().map(|&k| m.waypoints[k].name.clone()).collect();
            for (w, name) in back.waypoints.iter().zip(&names) {
                let k = m.waypoints.iter().position(|v| &v.name == name).unwrap();
                let moved = (w.position.x_east_m - m.waypoints[k].position.x_east_m)
                    .hypot(w.position.y_north_m - m.waypoints[k].position.y_north_m);
                assert!(moved < 0.02, "{flavour:?} {name}: {moved} m");
            }
            // Nothing switches the camera on before the survey's far end: on there, off where
            // it is left, nothing between; its waypoints flown through.
            assert_eq!(
                triggers(&back),
                vec![
                    vec![],
                    vec![25.0],
                    vec![],
                    vec![],
                    vec![],
                    vec![],
                    vec![0.0],
                    vec![],
                    vec![]
                ],
                "{flavour:?}"
            );
            assert!(back.waypoints[1..7].iter().all(|w| w.hover_s == 0.0));
            assert!(back.waypoints[1..7].iter().all(|w| w.actions.len() <= 1));
            // Forward: as the file has it.
            let order = [0, 3, 4, 5, 6, 7, 8, 1, 2];
            let back =
                mission_of_items(&mission_items(&m, &order, &opts).unwrap(), flavour, "held")
                    .unwrap();
            assert_eq!(triggers(&back)[1], vec![25.0]);
            assert_eq!(triggers(&back)[6], vec![0.0]);
        }
        assert_eq!(reversed_runs(&m, &[0, 8, 7, 6, 5, 4, 3, 1, 2]), vec![3..9]);
        // Only a block's waypoints in a row make a run; points in any order do not.
        assert!(reversed_runs(&m, &[2, 1, 0, 3, 4, 5, 6, 7, 8]).is_empty());
    }

    #[test]
    fn return_to_launch_ends_with_one_rtl_item_in_the_mission_frame() {
        let opts = ItemOptions {
            ending: Ending::ReturnToLaunch,
            ..ItemOptions::default()
        };
        let items = mission_items(&sample(), &[2, 0, 1], &opts).unwrap();
        assert_eq!(items.len(), 5);
        assert_eq!(items[4].command, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH);
        assert_eq!(items[4].frame, MavFrame::MAV_FRAME_MISSION);
    }

    #[test]
    fn ardupilot_gets_its_home_item_at_seq_zero() {
        let m = sample();
        let opts = ItemOptions {
            flavour: Flavour::ArduPilot,
            cruise_speed_m_s: Some(5.0),
            ending: Ending::Land,
            ..ItemOptions::default()
        };
        let items = mission_items(&m, &[0, 1, 2], &opts).unwrap();
        assert_eq!(items[0].frame, MavFrame::MAV_FRAME_GLOBAL);
        assert_eq!(items[0].z, 16.0);
        assert_eq!(items[1].command, MavCmd::MAV_CMD_NAV_TAKEOFF);
        assert_eq!(items[2].command, MavCmd::MAV_CMD_DO_CHANGE_SPEED);
        assert_eq!(items.last().unwrap().command, MavCmd::MAV_CMD_NAV_LAND);
        assert_eq!(items.len(), 7);
    }

    #[test]
    fn the_items_of_a_mission_with_actions_read_back_as_that_mission_in_the_order_flown() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("missions/orchard-inspection.plan");
        let m = load(&path).unwrap();
        let order: Vec<usize> = (0..m.waypoints.len()).collect();
        for flavour in [Flavour::ArduPilot, Flavour::Generic] {
            let opts = ItemOptions {
                flavour,
                ..ItemOptions::default()
            };
            let items = mission_items(&m, &order, &opts).unwrap();
            let back = mission_of_items(&items, flavour, "held").unwrap();
            assert_eq!(back.waypoints.len(), m.waypoints.len(), "{flavour:?}");
            for (a, b) in m.waypoints.iter().zip(&back.waypoints) {
                let moved = (a.position.x_east_m - b.position.x_east_m)
                    .hypot(a.position.y_north_m - b.position.y_north_m);
                assert!(moved < 0.02, "{flavour:?} {}: {moved} m", a.name);
                // The same commands; the speed goes first (`speed_first`).
                let commands = |w: &crate::mission::Waypoint| {
                    let mut c: Vec<u16> = w.actions.iter().map(|c| c.command).collect();
                    c.sort_unstable();
                    c
                };
                assert_eq!(commands(a), commands(b), "{flavour:?} {}", a.name);
            }
        }
    }

    #[test]
    fn the_photo_commands_after_a_waypoint_up_to_the_next_navigation_item_are_its_photos() {
        let m = sample();
        let items = mission_items(&m, &[0, 1, 2], &ItemOptions::default()).unwrap();
        let command = |command: MavCmd, params: [f32; 4], x: i32| {
            item(command, MavFrame::MAV_FRAME_MISSION, params, x, 0, 0.0)
        };
        let digicam = |shoot: i32| command(MavCmd::MAV_CMD_DO_DIGICAM_CONTROL, [0.0; 4], shoot);
        let capture = |interval_s: f32, images: f32| {
            command(
                MavCmd::MAV_CMD_IMAGE_START_CAPTURE,
                [0.0, interval_s, images, 0.0],
                0,
            )
        };
        let delay = command(MavCmd::MAV_CMD_NAV_DELAY, [2.0, -1.0, -1.0, -1.0], 0);
        // take-off, A, a photo; B, a photo, a capture of one image, a shoot 0; C, a delay, a
        // photo (after C's delay, at C: C's); the origin, a capture of 3 images at once and a
        // series at an interval (no photo of the point); the landing.
        let mut with = vec![items[0].clone(), items[1].clone(), digicam(1)];
        with.extend([items[2].clone(), digicam(1), capture(0.0, 1.0), digicam(0)]);
        with.extend([items[3].clone(), delay, digicam(1)]);
        with.extend([items[4].clone(), capture(0.0, 3.0), capture(2.0, 5.0)]);
        with.push(items[5].clone());
        for (seq, it) in with.iter_mut().enumerate() {
            it.seq = seq as u16;
        }
        let read = read_flight(&with, Flavour::Px4, m.origin.home.alt_m).unwrap();
        assert_eq!(read.points.len(), 4);
        assert_eq!(read.photos, [1, 2, 1, 3]);
        // Without photo commands, none.
        let plain = read_flight(&items, Flavour::Px4, m.origin.home.alt_m).unwrap();
        assert_eq!(plain.photos, [0, 0, 0, 0]);
    }

    #[test]
    fn via_points_go_up_as_waypoints_without_a_hold_just_before_their_legs_end() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("missions/orchard-inspection.plan");
        let m = load(&path).unwrap();
        let order: Vec<usize> = (0..m.waypoints.len()).rev().collect();
        let enu = |x: f64, y: f64, z: f64| Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        };
        // Two via points on the second leg, one on the return leg.
        let mut via = vec![Vec::new(); order.len() + 1];
        via[1] = vec![enu(10.0, 20.0, 3.0), enu(15.0, 25.0, 4.0)];
        via[order.len()] = vec![enu(-5.0, 8.0, 0.0)];
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let opts = ItemOptions {
                flavour,
                acceptance_radius_m: 3.0,
                vehicle_speed_m_s: Some(5.0),
                ..ItemOptions::default()
            };
            let (plain, plain_notes, plain_layout) =
                mission_items_noted(&m, &order, &opts).unwrap();
            let (items, notes, layout) = flight_items_noted(&m, &order, &via, &opts).unwrap();
            assert_eq!(notes, plain_notes, "{flavour:?}");
            assert_eq!(layout.via_seqs.len(), order.len() + 1);
            assert!(plain_layout.via_seqs.iter().all(Vec::is_empty));
            // Each via item sits just before its leg's end, in the leg's order.
            for (k, seqs) in layout.via_seqs.iter().enumerate() {
                assert_eq!(seqs.len(), via[k].len(), "{flavour:?} leg {k}");
                for (j, (&seq, at)) in seqs.iter().zip(&via[k]).enumerate() {
                    assert_eq!(seq + (seqs.len() - j) as u16, layout.point_seqs[k]);
                    let it = &items[usize::from(seq)];
                    assert_eq!(it.command, MavCmd::MAV_CMD_NAV_WAYPOINT);
                    assert_eq!(it.frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
                    assert_eq!((it.param1, it.param2), (0.0, 3.0));
                    let g = m.origin.to_geodetic(*at);
                    assert_eq!((it.x, it.y), (deg_e7(g.lat_deg), deg_e7(g.lon_deg)));
                    let alt = g.alt_m - m.origin.home.alt_m;
                    assert!((f64::from(it.z) - alt).abs() < 1e-3);
                }
            }
            // Without the via items, the items are the straight flight's, item for item: every
            // waypoint's actions stay after it and the restoring commands keep their places.
            let vias: Vec<u16> = layout.via_seqs.concat();
            // (Compared as JSON: a NaN parameter is null there, equal to itself.)
            let unnumbered = |i: &MISSION_ITEM_INT_DATA| {
                item_json(&MISSION_ITEM_INT_DATA {
                    seq: 0,
                    ..i.clone()
                })
            };
            let rest: Vec<serde_json::Value> = items
                .iter()
                .filter(|i| !vias.contains(&i.seq))
                .map(unnumbered)
                .collect();
            let plain: Vec<serde_json::Value> = plain.iter().map(unnumbered).collect();
            assert_eq!(rest, plain, "{flavour:?}");
            assert!(items.iter().enumerate().all(|(k, it)| it.seq as usize == k));
            assert_eq!(items.len(), plain.len() + 3);
            // The leg's commands (the point left's actions) come before its via points.
            let second = usize::from(layout.point_seqs[0]);
            let first_via = usize::from(layout.via_seqs[1][0]);
            assert!(items[second + 1..first_via]
                .iter()
                .all(|i| i.command != MavCmd::MAV_CMD_NAV_WAYPOINT));
        }
    }

    #[test]
    fn degrees_become_rounded_e7_integers_and_a_bad_order_is_refused() {
        assert_eq!(deg_e7(38.536_200_04), 385_362_000);
        assert_eq!(deg_e7(-121.787_500_06), -1_217_875_001);
        assert_eq!(
            mission_items(&sample(), &[0, 7], &ItemOptions::default()),
            Err(ItemsError::UnknownWaypoint(7))
        );
    }
}
