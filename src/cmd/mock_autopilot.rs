//! `emplan mock-autopilot`: run the built-in mock autopilot until Ctrl-C.

use std::process::ExitCode;

use anyhow::anyhow;
use emplan::sim::{Faults, Flavour, MockAutopilot, MockConfig};

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FlavourArg {
    Px4,
    Ardupilot,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to listen: udpin:HOST:PORT
    #[arg(long, default_value = "udpin:127.0.0.1:14550")]
    listen: String,
    #[arg(long, value_enum, default_value = "px4")]
    flavour: FlavourArg,
    /// Probability a datagram from the ground is lost
    #[arg(long, default_value_t = 0.0)]
    loss_up: f64,
    /// Probability a datagram to the ground is lost
    #[arg(long, default_value_t = 0.0)]
    loss_down: f64,
    /// Probability a datagram to the ground is duplicated
    #[arg(long, default_value_t = 0.0)]
    duplicate: f64,
    /// Probability a datagram to the ground is held back behind the next one
    #[arg(long, default_value_t = 0.0)]
    reorder: f64,
    /// Delay added to every datagram to the ground (ms)
    #[arg(long, default_value_t = 0)]
    delay_ms: u64,
    /// NACK the upload when this item arrives
    #[arg(long)]
    nack_item: Option<u16>,
    /// The MAV_MISSION_RESULT of that NACK (name or number; default MAV_MISSION_ERROR)
    #[arg(long)]
    nack: Option<String>,
    /// Never send the final ACCEPTED ack
    #[arg(long)]
    drop_final_ack: bool,
    /// Reboot (lose the transfer) when this item arrives
    #[arg(long)]
    reboot_at_item: Option<u16>,
    /// MAVLink 2 signing key file (32 raw bytes or 64 hex characters): sign everything sent,
    /// drop frames not signed with this key
    #[arg(long)]
    signing_key: Option<std::path::PathBuf>,
    /// Seed of the fault generator
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulated-time speed-up for the simulated flight (accepted; the flight simulation is not
    /// built yet, so it has no effect today)
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Start flying the mission once uploaded (accepted; no effect until the flight simulation exists)
    #[arg(long)]
    autostart: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for (name, p) in [
        ("loss-up", args.loss_up),
        ("loss-down", args.loss_down),
        ("duplicate", args.duplicate),
        ("reorder", args.reorder),
    ] {
        if !(0.0..=1.0).contains(&p) {
            anyhow::bail!("--{name} {p}: a probability between 0 and 1 is required");
        }
    }
    let nack_result =
        match &args.nack {
            Some(text) => Some(emplan::link::parse_mission_result(text).ok_or_else(|| {
                anyhow!("--nack {text:?}: not a MAV_MISSION_RESULT name or number")
            })?),
            None => None,
        };
    let config = MockConfig {
        flavour: match args.flavour {
            FlavourArg::Px4 => Flavour::Px4,
            FlavourArg::Ardupilot => Flavour::ArduPilot,
        },
        faults: Faults {
            loss_up: args.loss_up,
            loss_down: args.loss_down,
            duplicate: args.duplicate,
            reorder: args.reorder,
            delay_ms: args.delay_ms,
            nack_item: args.nack_item,
            nack_result,
            drop_final_ack: args.drop_final_ack,
            reboot_at_item: args.reboot_at_item,
        },
        seed: args.seed,
        signing_key: match &args.signing_key {
            Some(path) => Some(emplan::link::read_signing_key(path)?),
            None => None,
        },
        ..MockConfig::default()
    };
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let mut mock = MockAutopilot::spawn(&args.listen, config).await?;
        eprintln!("mock autopilot ({:?}) listening on udpin:{}; Ctrl-C stops it", config.flavour, mock.local_addr());
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {
                let stats = mock.stats();
                mock.shutdown().await?;
                eprintln!("stopped: {} uploads accepted, {} rejected, {} abandoned", stats.uploads_accepted, stats.uploads_rejected, stats.uploads_abandoned);
            }
            result = mock.stopped() => result?,
        }
        Ok(ExitCode::SUCCESS)
    })
}
