//! The documents of an upload, the same from `emplan upload --json` and from the service's
//! upload endpoint: what was uploaded and proven (the planning fields, the autopilot, the
//! transfer's report, the items sent), or why not (`{"ok": false, "stage", "accepted", "error",
//! "item", "result"}`).

use serde::Serialize;

use crate::link::connection::Autopilot;
use crate::link::driver::{UploadError, UploadReport};
use crate::planner::json::UploadPlanJson;

/// A verified upload: `emplan upload --json`.
#[derive(Debug, Clone, Serialize)]
pub struct UploadJson {
    /// mission, order, sortie, sequence, predicted_mission_kj, budget_kj.
    #[serde(flatten)]
    pub plan: UploadPlanJson,
    pub autopilot: Autopilot,
    pub report: UploadReport,
    /// The items sent (and read back), as MISSION_ITEM_INT fields (`link::items::item_json`).
    pub items: Vec<serde_json::Value>,
}

/// The document of a failed upload: the stage it failed in (`mission`, `plan`, `connect`,
/// `upload`, `read-back`, `verify`; the service adds `auth`, `vehicle` and `service`), whether
/// the autopilot had accepted the mission, the error, and for a transfer failure the item and
/// the autopilot's refusal.
pub fn failure_json(stage: &str, upload: Option<&UploadError>, error: &str) -> serde_json::Value {
    serde_json::json!({
        "ok": false,
        "stage": stage,
        "accepted": upload.is_some_and(|e| e.accepted),
        "error": error,
        "item": upload.and_then(|e| e.item),
        "result": upload.and_then(|e| e.refusal).map(crate::link::transfer::result_name),
    })
}
