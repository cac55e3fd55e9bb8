//! `emplan upload`: plan a mission, check it against the battery, upload it to the autopilot and
//! prove it arrived by reading it back. Exit 0 only when the autopilot took the mission and the
//! read-back matched; otherwise the message names the stage (`mission`, `plan`, `connect`,
//! `upload`, `read-back`, `verify`), whether the autopilot had accepted the mission and the item,
//! and with `--json` a failure prints one JSON document too: `{"ok": false, "stage", "accepted",
//! "error", "item", "result"}`.

use anyhow::Context;
use emplan::link::driver::{upload_verified, UploadError};
use emplan::link::items::{mission_items, ItemOptions};
use emplan::planner::json::{upload_document, UploadPlanJson};
use serde::Serialize;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file: emplan .toml, QGroundControl .plan or .waypoints
    mission: PathBuf,
    #[command(flatten)]
    link: super::LinkArgs,
    #[command(flatten)]
    flight: super::FlightArgs,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct UploadJson<'a> {
    /// mission, order, sortie, sequence, predicted_mission_kj, budget_kj.
    #[serde(flatten)]
    plan: UploadPlanJson,
    autopilot: emplan::link::connection::Autopilot,
    report: &'a emplan::link::driver::UploadReport,
    /// The items sent (and read back), as MISSION_ITEM_INT fields.
    items: Vec<serde_json::Value>,
}

/// A failure tagged with the stage it happened in, where the error itself does not say.
#[derive(Debug, thiserror::Error)]
#[error("{cause:#}")]
struct Staged {
    stage: &'static str,
    cause: anyhow::Error,
}

/// The JSON document a failed `upload --json` prints.
fn failure_json(err: &anyhow::Error) -> serde_json::Value {
    let upload = err.downcast_ref::<UploadError>();
    let stage = match (upload, err.downcast_ref::<Staged>()) {
        (Some(e), _) => e.stage.to_string(),
        (None, Some(staged)) => staged.stage.to_string(),
        (None, None)
            if err
                .downcast_ref::<emplan::mission::MissionError>()
                .is_some() =>
        {
            "mission".to_string()
        }
        (None, None) => "plan".to_string(),
    };
    serde_json::json!({
        "ok": false,
        "stage": stage,
        "accepted": upload.is_some_and(|e| e.accepted),
        "error": format!("{err:#}"),
        "item": upload.and_then(|e| e.item),
        "result": upload.and_then(|e| e.refusal).map(emplan::link::transfer::result_name),
    })
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let json = args.json;
    match upload(args) {
        Err(err) if json => {
            println!("{}", serde_json::to_string_pretty(&failure_json(&err))?);
            eprintln!("error: {err:#}");
            Ok(ExitCode::FAILURE)
        }
        outcome => outcome,
    }
}

fn upload(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.mission)?;
    let (_, plan) = args.flight.plan(&mission)?;
    let flight = args.flight.flight(&plan)?;
    let planned = upload_document(&plan, &flight);
    let order = flight.waypoints();
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let opened = args
            .link
            .open()
            .await
            .map_err(|cause| Staged {
                stage: "connect",
                cause,
            })?;
        let (link, target, cfg) = (&opened.link, opened.target, opened.config);
        let opts = ItemOptions { flavour: target.flavour, acceptance_radius_m: args.flight.acceptance_radius_m, ..ItemOptions::default() };
        let items = mission_items(&mission, &order, &opts).context("building mission items")?;
        if !args.json {
            eprintln!("uploading {} items to {:?} autopilot {} on {}", items.len(), target.flavour, target.system_id, opened.describe);
        }
        let mut shown = std::time::Instant::now();
        let report = upload_verified(link, &target, &items, cfg, |done, total| {
            // At most ten progress lines a second: writing one per item would slow a fast link.
            if !args.json && (done == total || shown.elapsed().as_millis() >= 100) {
                shown = std::time::Instant::now();
                eprint!("\ritem {done}/{total}");
            }
        })
        .await
        .with_context(|| format!("uploading {} to {}", args.mission.display(), opened.describe))?;
        if args.json {
            let doc = UploadJson {
                plan: planned,
                autopilot: target,
                report: &report,
                items: items.iter().map(emplan::link::items::item_json).collect(),
            };
            println!("{}", serde_json::to_string_pretty(&doc)?);
        } else {
            eprintln!();
            let link_note = match (report.restarts, report.refusals, report.rtt_ms) {
                (0, 0, Some(rtt)) => format!("round trip {rtt:.1} ms"),
                (r, n, rtt) => format!(
                    "round trip {}, {r} fresh starts, {n} refusals waited out",
                    rtt.map_or("not measured".to_string(), |t| format!("{t:.1} ms"))
                ),
            };
            println!(
                "verified: {} items uploaded in {:.2} s ({}), read back and matched in {:.2} s ({link_note}); predicted mission energy {:.1} kJ of {:.1} kJ usable",
                report.items,
                report.upload_s,
                if report.acked { "accepted" } else { "final ack lost, settled by read-back" },
                report.verify_s,
                planned.predicted_mission_kj,
                planned.budget_kj
            );
        }
        Ok(ExitCode::SUCCESS)
    })
}
