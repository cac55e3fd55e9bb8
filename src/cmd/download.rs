//! `emplan download`: read the autopilot's mission, with its geofence and rally points, and
//! write it as a mission file or as JSON mission items.

use emplan::output::Output;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    link: super::LinkArgs,
    /// File to write: a mission file when it ends in .plan, .waypoints or .toml (the waypoints
    /// and their actions, the fence and the rally points as the vehicle holds them), else the
    /// mission items as JSON
    /// (MISSION_ITEM_INT fields; frame and command as MAVLink numbers, x/y in degE7, NaN params
    /// as null)
    out: PathBuf,
    /// Replace an existing file (never a file inside a flight directory)
    #[arg(long)]
    force: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.link.connect.is_none() {
        // A fresh built-in mock holds no mission: downloading from it would only ever say 0.
        anyhow::bail!(
            "download reads a vehicle's mission: give --connect URL (udpin:HOST:PORT, \
             tcpout:HOST:PORT, serial:DEV:BAUD; a mock started with `emplan mock-autopilot` \
             works too)"
        );
    }
    // Checked before any link work.
    let out = Output::new(&args.out, Vec::new(), args.force);
    out.check()?;
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let opened = args.link.open().await?;
        let target = opened.target;
        let held = emplan::session::download_held(&opened.link, &target, opened.transfer)
            .await
            .map_err(|e| {
                anyhow::Error::new(e).context(format!("downloading from {}", opened.describe))
            })?;
        let items = &held.items;
        let as_mission = emplan::mission::Format::from_path(&args.out).ok();
        match as_mission {
            Some(format) => {
                let name = args
                    .out
                    .file_stem()
                    .and_then(|s| s.to_str())
                    .unwrap_or("mission");
                let mission = held.mission(name)?;
                out.write(emplan::mission::to_string(&mission, format)?.as_bytes())?;
            }
            None => {
                let json: Vec<serde_json::Value> =
                    items.iter().map(emplan::link::items::item_json).collect();
                out.write(serde_json::to_string_pretty(&json)?.as_bytes())?;
            }
        }
        let lists = match (held.capabilities.fence, held.capabilities.rally) {
            (false, false) => String::new(),
            _ => format!(
                "; fence {} items, rally points {} items",
                held.fence_items.len(),
                held.rally_items.len()
            ),
        };
        println!(
            "wrote {} ({} items from {:?} autopilot {}{lists})",
            args.out.display(),
            items.len(),
            target.flavour,
            target.system_id
        );
        Ok(ExitCode::SUCCESS)
    })
}
