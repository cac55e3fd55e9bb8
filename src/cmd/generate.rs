//! `emplan generate`: write one random mission (the study's distribution, from a seed) as a
//! mission file, e.g. 1000-waypoint missions for benchmarks or a study's worst mission to look
//! at with `emplan plan --plot`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use emplan::mission::{Format, Geodetic};
use emplan::output::Output;
use emplan::planner::study::{random_mission, Site, StudySettings};

/// Arguments of `emplan generate` (its help text is on the subcommand in main.rs).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file to write; its extension chooses the format (.toml, .plan, .waypoints)
    out: PathBuf,
    /// Number of waypoints
    #[arg(long, value_name = "N")]
    waypoints: usize,
    /// Horizontal half-width: waypoints uniform in [-XY, XY] m east and north of the origin
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    xy: f64,
    /// Vertical half-height: waypoints uniform in [-Z, Z] m around the origin, which hovers
    /// Z + 5 m above home
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    z: f64,
    /// Seed of the random mission
    #[arg(long, value_name = "S", default_value_t = 1)]
    seed: u64,
    /// Which mission of the seed's stream (mission K of `emplan study`)
    #[arg(long, value_name = "K", default_value_t = 0)]
    mission: u64,
    /// Latitude of home (degrees)
    #[arg(long, default_value_t = 38.5362, allow_negative_numbers = true)]
    origin_lat: f64,
    /// Longitude of home (degrees)
    #[arg(long, default_value_t = -121.7875, allow_negative_numbers = true)]
    origin_lon: f64,
    /// Altitude of home above mean sea level (m)
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    home_alt_amsl: f64,
    /// Hover time at every waypoint (s)
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    hover_s: f64,
    /// Mission name (default: random-N-XY-Z-sS-K)
    #[arg(long)]
    name: Option<String>,
    /// Replace an existing file (never a file inside a flight directory)
    #[arg(long)]
    force: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let out = Output::new(&args.out, Vec::new(), args.force);
    out.check()?;
    let settings = StudySettings {
        waypoints: args.waypoints,
        xy_m: args.xy,
        z_m: args.z,
        missions: 1,
        seed: args.seed,
    };
    let site = Site {
        home: Geodetic {
            lat_deg: args.origin_lat,
            lon_deg: args.origin_lon,
            alt_m: args.home_alt_amsl,
        },
        hover_s: args.hover_s,
        name: args.name.clone(),
    };
    let mission = random_mission(&settings, args.mission, &site).map_err(super::setting_error)?;
    let format = Format::from_path(&args.out)?;
    // Read it back before writing, so a file we write always loads.
    let text = emplan::mission::to_string(&mission, format)?;
    emplan::mission::load_str(&text, format, Some(&args.out))
        .context("the generated mission does not validate")?;
    out.write(text.as_bytes())?;
    println!(
        "wrote {}: mission {:?}, {} waypoints in ±{} m x ±{} m x ±{} m around the origin, \
         which hovers {} m above home (seed {}, mission {})",
        args.out.display(),
        mission.name,
        mission.waypoints.len(),
        args.xy,
        args.xy,
        args.z,
        mission.origin.height_above_home_m,
        args.seed,
        args.mission
    );
    Ok(ExitCode::SUCCESS)
}
