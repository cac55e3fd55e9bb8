//! A live session with a vehicle over a link: the telemetry streams emplan asks for (asked again
//! after every reconnect), the flight recorder that logs every flight from arming to disarming
//! (one directory per flight: flight.tlog, samples.csv, plan.json, report.json), and the flight
//! workflow, the one flight path: `open` (the built-in mock or a connection, the autopilot
//! waited for; the transfer settings), `fly`'s `load` (the autopilot's parameter check and
//! re-pricing, verified upload, the recorder's plan), `arm_and_start` and `fly` (start, record,
//! report, which failures count as accepted), used by `emplan upload`, `emplan fly` and the
//! service's vehicle actor alike; `home`, the check before any upload that the vehicle stands
//! at the mission's origin, and the re-planning from the vehicle's home; `held`, the mission a
//! vehicle holds measured (`emplan record`, the service); `download`, what a vehicle holds read
//! back whole, its mission with its fence and rally points (`emplan download`); `ledger`, every
//! finished flight written to the ledger by the recorder, and what earlier flights of a pack
//! and a vehicle taught the next one (its battery check, the guard's start); `import`,
//! flights into the ledger from their files, flight directories and onboard logs measured in
//! parallel (`emplan ledger rebuild|import`); `ledger_read`, what the commands that read the
//! ledger ask of it beyond its flights (the packs figure's points, a vehicle's flight
//! directories).
//!
//! This is the async glue above `link` (MAVLink, sans-IO machines), `flightlog` (files,
//! segmentation, energy; no tokio) and `planner`: what is decided lives in those layers, so a
//! `replay` of a recorded log gives the report the live run gave. The recorder's file work runs
//! on a thread of its own (blocking writes and fsyncs never stall the link's tasks).

pub mod download;
pub mod fly;
pub mod guard;
pub mod held;
pub mod home;
pub mod import;
pub mod ledger;
pub mod ledger_read;
pub mod onboard;
pub mod open;
pub mod params;
pub mod predict;
pub mod recorder;
pub mod replay;
pub mod upload;

pub use crate::link::commands::{keep_streams, request_streams};
pub use download::{download_held, DownloadError, Held};
pub use fly::{
    arm_and_start, discard_unflown, fly, load, Flown, FlyError, FlyFailure, FlyJson, FlyOptions,
    Load, Loaded, StartFailed, DISCARD_ENDED_WITHIN, DISCARD_OPENED_WITHIN,
};
pub use held::{held_flight_plan, same_flight, HeldError, Known};
pub use home::{
    check_home, replan_from_vehicle, vehicle_home, IfHomeUnknown, Moved, PlanOrigin,
    PreflightError, ReplanError, Replanned,
};
pub use onboard::{replay_onboard, OnboardReplayError, PlanFrom};
pub use open::{
    connect_until_open, open, transfer_config, LinkOptions, MockFlight, OpenError, Session, Target,
};
pub use params::{
    check_ardupilot_params, check_px4_params, parse_param, ParamCheck, ParamSection, Px4Parameters,
};
pub use predict::{
    flight_plan, flight_plan_predicted, plan_from_items, predicted, predicted_by_simulation,
    repriced, with_fast_waypoints, FlightItemsError,
};
pub use recorder::{
    flight_dirs, spawn_recorder, FlightEvent, Live, RecorderConfig, RecorderHandle, RepriceError,
};
pub use replay::{
    autopilot_profile, flown_profile, plan_for_tlog, replay, replay_priced, report_unfinished,
    resume_flight, FlightVisits, ReplayError, ResumeFlightError,
};
