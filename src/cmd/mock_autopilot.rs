//! `emplan mock-autopilot`: run the built-in mock autopilot until Ctrl-C.

use std::process::ExitCode;

use anyhow::anyhow;
use emplan::link::Flavour;
use emplan::sim::{Faults, Home, MockAutopilot, MockConfig};

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FlavourArg {
    /// PX4: atomic uploads, requests every 250 ms, gives up after 5 s, _INT frames on read-back
    Px4,
    /// ArduPilot: item 0 is its home, unused parameters stored as 0, NO_SPACE while booting
    Ardupilot,
    /// MAVSDK's MissionRawServer: keeps items as received, gives up after 5 tries
    Generic,
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
    /// Answer read-backs of this item with its latitude 1 degE7 off (a vehicle holding
    /// something else than was sent: emplan must not report the upload verified)
    #[arg(long, value_name = "SEQ")]
    corrupt_readback: Option<u16>,
    /// Seconds after start during which the ArduPilot flavour refuses uploads with
    /// MAV_MISSION_NO_SPACE, as ArduPilot does while its storage boots
    #[arg(long, default_value_t = 2.0)]
    boot_s: f64,
    /// Altitude of the vehicle's own home above mean sea level (m), what the ArduPilot flavour
    /// answers for item 0 (ArduCopter SITL reports 16.1 m for a 16 m home)
    #[arg(long, default_value_t = 16.1)]
    home_alt_m: f32,
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
    if !(args.boot_s.is_finite() && (0.0..=3600.0).contains(&args.boot_s)) {
        anyhow::bail!("--boot-s {}: expected 0 to 3600 seconds", args.boot_s);
    }
    if !args.home_alt_m.is_finite() {
        anyhow::bail!(
            "--home-alt-m {}: expected a finite altitude",
            args.home_alt_m
        );
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
            FlavourArg::Generic => Flavour::Generic,
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
            corrupt_readback: args.corrupt_readback,
        },
        home: Home {
            alt_m: args.home_alt_m,
            ..Home::default()
        },
        boot: std::time::Duration::from_secs_f64(args.boot_s),
        seed: args.seed,
        signing_key: match &args.signing_key {
            Some(path) => Some(emplan::link::read_signing_key(path)?),
            None => None,
        },
        ..MockConfig::default()
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
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
