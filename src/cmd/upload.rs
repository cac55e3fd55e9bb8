//! `emplan upload`: plan a mission, check it against the battery, upload it to the autopilot and
//! prove it arrived by reading it back. Exit 0 only when the autopilot took the mission and the
//! read-back matched; otherwise the message names the stage (`mission`, `plan`, `connect`,
//! `upload`, `read-back`, `verify`), whether the autopilot had accepted the mission and the item,
//! and with `--json` a failure prints one JSON document too: `{"ok": false, "stage", "accepted",
//! "error", "item", "result"}`.

use anyhow::Context;
use emplan::link::driver::{upload_verified, UploadError};
use emplan::link::items::{mission_items, ItemOptions};
use emplan::planner::json::upload_document;
use emplan::session::upload::UploadJson;
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
    #[command(flatten)]
    service: super::ServiceArgs,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
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
    if let Some(remote) = err.downcast_ref::<emplan::service::remote::RemoteError>() {
        return remote.document();
    }
    if err.downcast_ref::<emplan::service::ClientError>().is_some() {
        return emplan::session::upload::failure_json("service", None, &format!("{err:#}"));
    }
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
    emplan::session::upload::failure_json(&stage, upload, &format!("{err:#}"))
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
    if let Some(client) = args.service.client()? {
        return upload_through(&args, &client);
    }
    let mission = emplan::mission::load(&args.mission)?;
    let (_, plan) = args.flight.plan(&mission)?;
    let flight = args.flight.flight(&plan)?;
    let planned = upload_document(&plan, &flight);
    let order = flight.waypoints();
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let opened = args.link.open().await.map_err(|cause| Staged {
            stage: "connect",
            cause,
        })?;
        let (link, target, cfg) = (&opened.link, opened.target, opened.config);
        let opts = ItemOptions {
            flavour: target.flavour,
            acceptance_radius_m: args.flight.acceptance_radius_m,
            ..ItemOptions::default()
        };
        let items = mission_items(&mission, &order, &opts).context("building mission items")?;
        if !args.json {
            eprintln!(
                "uploading {} items to {:?} autopilot {} on {}",
                items.len(),
                target.flavour,
                target.system_id,
                opened.describe
            );
        }
        let bar = super::progress::bar(items.len() as u64, "{msg} [{bar:30}] item {pos}/{len}");
        bar.set_message("uploading");
        let report = upload_verified(link, &target, &items, cfg, |done, total| {
            if done == total {
                bar.set_message("reading back");
            }
            bar.set_position(done as u64);
        })
        .await
        .with_context(|| {
            format!(
                "uploading {} to {}",
                args.mission.display(),
                opened.describe
            )
        })?;
        if args.json {
            let doc = UploadJson {
                plan: planned,
                autopilot: target,
                report,
                items: items.iter().map(emplan::link::items::item_json).collect(),
            };
            println!("{}", serde_json::to_string_pretty(&doc)?);
        } else {
            bar.finish_and_clear();
            println!(
                "{}",
                verified_line(&report, planned.predicted_mission_kj, planned.budget_kj)
            );
        }
        Ok(ExitCode::SUCCESS)
    })
}

/// The line a verified upload prints.
fn verified_line(
    report: &emplan::link::driver::UploadReport,
    predicted_kj: f64,
    budget_kj: f64,
) -> String {
    let link_note = match (report.restarts, report.refusals, report.rtt_ms) {
        (0, 0, Some(rtt)) => format!("round trip {rtt:.1} ms"),
        (r, n, rtt) => format!(
            "round trip {}, {r} fresh starts, {n} refusals waited out",
            rtt.map_or("not measured".to_string(), |t| format!("{t:.1} ms"))
        ),
    };
    format!(
        "verified: {} items uploaded in {:.2} s ({}), read back and matched in {:.2} s ({link_note}); predicted mission energy {:.1} kJ of {:.1} kJ usable",
        report.items,
        report.upload_s,
        if report.acked {
            "accepted"
        } else {
            "final ack lost, settled by read-back"
        },
        report.verify_s,
        predicted_kj,
        budget_kj
    )
}

/// The upload report of a service's upload document (with its `"link"` numbers).
fn report_of(doc: &serde_json::Value) -> emplan::link::driver::UploadReport {
    let f = |path: &str| doc.pointer(path).and_then(|v| v.as_f64());
    let n = |path: &str| doc.pointer(path).and_then(|v| v.as_u64()).unwrap_or(0);
    emplan::link::driver::UploadReport {
        items: n("/report/items") as usize,
        acked: doc
            .pointer("/report/acked")
            .and_then(|v| v.as_bool())
            .unwrap_or(false),
        verified: doc
            .pointer("/report/verified")
            .and_then(|v| v.as_bool())
            .unwrap_or(false),
        upload_s: f("/report/upload_s").unwrap_or(0.0),
        verify_s: f("/report/verify_s").unwrap_or(0.0),
        count_sent: n("/report/count_sent") as u32,
        items_sent: n("/report/items_sent") as u32,
        restarts: n("/link/restarts") as u32,
        refusals: n("/link/refusals") as u32,
        rtt_ms: f("/link/rtt_ms"),
    }
}

/// `upload --service URL`: the same through a running service.
fn upload_through(args: &Args, client: &emplan::service::Client) -> anyhow::Result<ExitCode> {
    use emplan::service::remote;
    let request = args.flight.service_request()?;
    super::runtime()?.block_on(async {
        let name =
            remote::find_mission(client, &args.mission, std::time::Duration::from_secs(60)).await?;
        if !args.json {
            eprintln!("uploading {name} through the service at {}", client.url());
        }
        let mut doc = remote::upload(client, &name, &request).await?;
        let report = report_of(&doc);
        if args.json {
            // `upload --json`'s document: the service adds the link's numbers.
            if let Some(map) = doc.as_object_mut() {
                map.remove("link");
            }
            println!("{}", serde_json::to_string_pretty(&doc)?);
        } else {
            let kj = |key: &str| doc.get(key).and_then(|v| v.as_f64()).unwrap_or(f64::NAN);
            println!(
                "{}",
                verified_line(&report, kj("predicted_mission_kj"), kj("budget_kj"))
            );
        }
        Ok(ExitCode::SUCCESS)
    })
}
