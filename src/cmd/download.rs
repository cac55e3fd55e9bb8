//! `emplan download`: read the autopilot's mission and write it as JSON mission items.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use emplan::link::connection::{Identity, Link};
use emplan::link::driver::download;
use emplan::link::transfer::TransferConfig;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// MAVLink connection: udpin:HOST:PORT, udpout:HOST:PORT, tcpin:, tcpout:, serial:DEV:BAUD
    #[arg(long)]
    connect: String,
    /// File to write: the mission items as JSON (MISSION_ITEM_INT fields; frame and command as
    /// MAVLink numbers, x/y in degE7, NaN params as null)
    out: PathBuf,
    #[arg(long, default_value_t = 1500)]
    timeout_ms: u64,
    #[arg(long, default_value_t = 5)]
    retries: u32,
    #[arg(long, default_value_t = 10.0)]
    discover_s: f64,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let link = Link::connect(&args.connect, Identity::default(), None).await?;
        let target = link
            .discover(Duration::from_secs_f64(args.discover_s))
            .await?;
        let cfg = TransferConfig {
            timeout: Duration::from_millis(args.timeout_ms),
            retries: args.retries,
            target_system: target.system_id,
            target_component: target.component_id,
        };
        let items = download(&link, &target, cfg)
            .await
            .with_context(|| format!("downloading from {}", args.connect))?;
        let json: Vec<serde_json::Value> =
            items.iter().map(emplan::link::items::item_json).collect();
        std::fs::write(&args.out, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("writing {}", args.out.display()))?;
        println!(
            "wrote {} ({} items from {:?} autopilot {})",
            args.out.display(),
            items.len(),
            target.flavour,
            target.system_id
        );
        Ok(ExitCode::SUCCESS)
    })
}
