//! The documents of an upload, the same from `emplan upload --json` and from the service's
//! upload endpoint: what was uploaded and proven (the planning fields, the autopilot, the
//! transfer's report, the items sent, the fence and the rally points), or why not (`{"ok": false, "stage", "accepted", "error",
//! "item", "result"}`).

use serde::{Deserialize, Serialize};

use crate::link::connection::Autopilot;
use crate::link::driver::{UploadError, UploadReport};
use crate::planner::json::UploadPlanJson;

/// A verified upload: `emplan upload --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UploadJson {
    /// mission, order, sortie, sequence, predicted_mission_kj, budget_kj.
    #[serde(flatten)]
    pub plan: UploadPlanJson,
    pub autopilot: Autopilot,
    pub report: UploadReport,
    /// The items sent (and read back), as MISSION_ITEM_INT fields (`link::items::item_json`).
    pub items: Vec<serde_json::Value>,
    /// The fence uploaded and verified (0 zones: the vehicle's old fence cleared); null when
    /// the autopilot holds no fence.
    #[serde(default)]
    pub fence: Option<ListUpload>,
    /// The rally points uploaded and verified, as the fence.
    #[serde(default)]
    pub rally: Option<ListUpload>,
}

/// A fence or rally list uploaded and verified by read-back.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ListUpload {
    /// Zones of the fence, or rally points, sent (0: the vehicle's old list cleared).
    pub count: usize,
    /// Mission items sent and read back.
    pub items: usize,
    /// The autopilot's ACCEPTED ack arrived.
    pub acked: bool,
    /// The read-back matched what was sent.
    pub verified: bool,
}

impl ListUpload {
    /// `count` zones or points, uploaded as `report` says.
    pub fn new(count: usize, report: &UploadReport) -> ListUpload {
        ListUpload {
            count,
            items: report.items,
            acked: report.acked,
            verified: report.verified,
        }
    }
}

/// The document of a failed upload: the stage it failed in (`mission`, `plan`, `connect`,
/// `upload`, `read-back`, `verify`; the service adds `auth`, `vehicle` and `service`), whether
/// the autopilot had accepted the mission, the error, and for a transfer failure the item and
/// the autopilot's refusal.
pub fn failure_json(stage: &str, upload: Option<&UploadError>, error: &str) -> serde_json::Value {
    Failure::new(stage, upload, error).json()
}

/// The document of a failed upload, start or flight (`{"ok": false, "stage", "accepted",
/// "error", "item", "result"}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    pub ok: bool,
    pub stage: String,
    /// The autopilot had accepted the mission.
    pub accepted: bool,
    pub error: String,
    /// The item a transfer failed at.
    pub item: Option<u16>,
    /// The autopilot's answer (a MAV_MISSION_RESULT name, or a start's command result).
    pub result: Option<String>,
}

impl Failure {
    /// The failure at `stage`, with a transfer's item and refusal when it was one.
    pub fn new(stage: &str, upload: Option<&UploadError>, error: &str) -> Failure {
        Failure {
            ok: false,
            stage: stage.to_string(),
            accepted: upload.is_some_and(|e| e.accepted),
            error: error.to_string(),
            item: upload.and_then(|e| e.item),
            result: upload
                .and_then(|e| e.refusal)
                .map(|r| crate::link::transfer::result_name(r).to_string()),
        }
    }

    /// The document as JSON (its keys in the order every failure document prints them).
    pub fn json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
}
