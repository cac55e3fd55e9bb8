//! `emplan upload`: plan a mission, check it against the battery, check that the vehicle stands
//! at its origin (or, with `--origin vehicle`, plan it from the vehicle's home), upload it to
//! the autopilot and prove it arrived by reading it back, with its fence and rally points (an
//! empty one clears the vehicle's). Exit 0 only when the autopilot took the mission, the fence
//! and the rally points and every read-back matched; otherwise the message names the stage (`mission`,
//! `plan`, `connect`, `preflight`, `upload`, `read-back`, `verify`), whether the autopilot had
//! accepted the mission and the item, and with `--json` a failure prints one JSON document too:
//! `{"ok": false, "stage", "accepted", "error", "item", "result"}`.

use emplan::link::driver::UploadError;
use emplan::planner::json::upload_document;
use emplan::session::upload::UploadJson;
use emplan::session::{FlyError, Px4Parameters};
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
    let upload = err
        .downcast_ref::<UploadError>()
        .or(match err.downcast_ref::<FlyError>() {
            Some(FlyError::Upload(e)) => Some(e),
            _ => None,
        });
    let stage = match (upload, err.downcast_ref::<Staged>()) {
        (Some(e), _) => e.stage.to_string(),
        (None, Some(staged)) => staged.stage.to_string(),
        (None, None) if err.downcast_ref::<FlyError>().is_some() => err
            .downcast_ref::<FlyError>()
            .map(FlyError::stage)
            .unwrap_or_default(),
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

fn upload(mut args: Args) -> anyhow::Result<ExitCode> {
    if let Some(client) = args.service.client()? {
        return upload_through(&args, &client);
    }
    let mission = emplan::mission::load(&args.mission)?;
    if let Some(warning) = mission.unknown_warning() {
        eprintln!("warning: {warning}");
    }
    if args.flight.live_wind() {
        anyhow::bail!(
            "--wind live: only fly reads the wind from the vehicle; upload takes --wind SPEED@FROM_DEG"
        );
    }
    // Checked on the pack named as `fly` checks it (the ledger in `fly`'s default log
    // directory unless --ledger).
    args.flight
        .learn(std::path::Path::new(super::DEFAULT_LOG_DIR))?;
    if let (Some(pack), false) = (&args.flight.on_pack, args.json) {
        eprintln!("{}", pack.line());
    }
    let (model, planned) = args.flight.plan_first(&mission)?;
    let runtime = super::runtime()?;
    runtime.block_on(async {
        // The built-in mock stands at the mission's origin.
        let opened = args.link.open_at(mission.origin.home, &model.vehicle).await;
        let session = opened.map_err(|cause| Staged {
            stage: "connect",
            cause,
        })?;
        let (mission, plan) = (args.flight)
            .planned_at(&session, mission, planned, &model, args.json)
            .await?;
        let flight = args.flight.flight(&plan)?;
        let planned = upload_document(&plan, &flight);
        let load = (args.flight).load(&mission, &plan, &flight, &model.vehicle);
        let target = session.target;
        let bar = super::progress::bar(0, "{msg} [{bar:30}] item {pos}/{len}");
        // The session's load: the home check, the autopilot's parameter check (warned of here,
        // as `fly` warns), the items, the verified upload.
        let checked = |check: Option<&emplan::session::ParamCheck>| {
            if let Some(check) = check {
                super::flying::warn_params(&Px4Parameters::from(check), check.section);
            }
            // The items the session sends (an error is the session's own, below).
            let count = session.items(&load).map_or(0, |items| items.len());
            if !args.json {
                eprintln!(
                    "uploading {count} items to {:?} autopilot {} on {}",
                    target.flavour, target.system_id, session.describe
                );
            }
            bar.set_length(count as u64);
            bar.set_message("uploading");
        };
        let uploaded = session
            .load(None, &load, checked, |done, total| {
                if done == total {
                    bar.set_message("reading back");
                }
                bar.set_position(done as u64);
            })
            .await
            .map_err(|e| match e {
                FlyError::Items(_) => anyhow::Error::new(e).context("building mission items"),
                FlyError::Upload(_) => anyhow::Error::new(e).context(format!(
                    "uploading {} to {}",
                    args.mission.display(),
                    session.describe
                )),
                other => other.into(),
            })?;
        let report = uploaded.upload;
        if args.json {
            let doc = UploadJson {
                plan: planned,
                autopilot: target,
                report,
                items: uploaded
                    .items
                    .iter()
                    .map(emplan::link::items::item_json)
                    .collect(),
                fence: uploaded.fence,
                rally: uploaded.rally,
            };
            println!("{}", serde_json::to_string_pretty(&doc)?);
        } else {
            bar.finish_and_clear();
            println!(
                "{}",
                verified_line(&report, planned.predicted_mission_kj, planned.budget_kj)
            );
            for line in [
                list_line("fence", "zone", uploaded.fence.as_ref()),
                list_line("rally points", "point", uploaded.rally.as_ref()),
            ]
            .into_iter()
            .flatten()
            {
                println!("{line}");
            }
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

/// The line a verified fence or rally upload prints (None: the autopilot holds no such list).
fn list_line(
    list: &str,
    unit: &str,
    upload: Option<&emplan::session::upload::ListUpload>,
) -> Option<String> {
    let upload = upload?;
    Some(match upload.count {
        0 => format!("verified: {list} cleared on the vehicle (the mission has none)"),
        n => format!(
            "verified: {list}: {} in {} uploaded, read back and matched",
            counted(n, unit),
            counted(upload.items, "item")
        ),
    })
}

/// `n` of `unit`, plural when not one: "1 zone", "2 zones".
fn counted(n: usize, unit: &str) -> String {
    if n == 1 {
        format!("1 {unit}")
    } else {
        format!("{n} {unit}s")
    }
}

/// `upload --service URL`: the same through a running service.
fn upload_through(args: &Args, client: &emplan::service::Client) -> anyhow::Result<ExitCode> {
    use emplan::service::remote;
    let request = args.flight.service_request()?;
    super::runtime()?.block_on(async {
        let name =
            remote::find_mission(client, &args.mission, std::time::Duration::from_secs(60)).await?;
        let discover = std::time::Duration::from_secs_f64(args.link.discover_s.clamp(0.0, 3.2e7));
        remote::wait_for_vehicle(client, discover).await?;
        if !args.json {
            eprintln!("uploading {name} through the service at {}", client.url());
        }
        let answer = remote::upload(client, &name, &request).await?;
        if args.json {
            // `upload --json`'s document: the service adds the link's numbers.
            println!(
                "{}",
                serde_json::to_string_pretty(&serde_json::to_value(&answer.upload)?)?
            );
        } else {
            let report = emplan::link::driver::UploadReport {
                rtt_ms: answer.link.rtt_ms,
                restarts: answer.link.restarts,
                refusals: answer.link.refusals,
                ..answer.upload.report
            };
            let plan = &answer.upload.plan;
            println!(
                "{}",
                verified_line(&report, plan.predicted_mission_kj, plan.budget_kj)
            );
        }
        Ok(ExitCode::SUCCESS)
    })
}
