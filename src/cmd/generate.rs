//! `emplan generate`: write one random mission (the study's distribution, from a seed) as a
//! mission file, e.g. 1000-waypoint missions for benchmarks or a study's worst mission to look
//! at with `emplan plan --plot`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use emplan::mission::{Format, Geodetic, Mission, Origin, Waypoint};
use emplan::plan::study::{random_points, waypoint_name, StudySettings};

/// Most waypoints one generated mission may have.
const MAX_WAYPOINTS: usize = 1_000_000;
/// How far the origin hovers above the lowest possible waypoint: the origin's height above home
/// is Z + this, so every waypoint is at least this high above home (the mission minimum is
/// 2 m).
const CLEARANCE_M: f64 = 5.0;

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
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.waypoints == 0 || args.waypoints > MAX_WAYPOINTS {
        bail!(
            "--waypoints {}: allowed: 1 to {MAX_WAYPOINTS}",
            args.waypoints
        );
    }
    for (option, value) in [("--xy", args.xy), ("--z", args.z)] {
        if !(value.is_finite() && value >= 0.0) {
            bail!("{option} {value}: allowed: a finite half-width of 0 m or more");
        }
    }
    if !(args.origin_lat.is_finite() && (-90.0..=90.0).contains(&args.origin_lat)) {
        bail!("--origin-lat {}: allowed: -90 to 90", args.origin_lat);
    }
    if !(args.origin_lon.is_finite() && (-180.0..=180.0).contains(&args.origin_lon)) {
        bail!("--origin-lon {}: allowed: -180 to 180", args.origin_lon);
    }
    if !args.home_alt_amsl.is_finite() {
        bail!(
            "--home-alt-amsl {}: a finite altitude is required",
            args.home_alt_amsl
        );
    }
    if !(args.hover_s.is_finite() && args.hover_s >= 0.0) {
        bail!("--hover-s {}: allowed: 0 s or more", args.hover_s);
    }
    let format = Format::from_path(&args.out)?;
    let settings = StudySettings {
        waypoints: args.waypoints,
        xy_m: args.xy,
        z_m: args.z,
        missions: 1,
        seed: args.seed,
    };
    let name = args.name.clone().unwrap_or_else(|| {
        format!(
            "random-{}-{}-{}-s{}-{}",
            args.waypoints, args.xy, args.z, args.seed, args.mission
        )
    });
    let mission = Mission {
        name,
        origin: Origin {
            home: Geodetic {
                lat_deg: args.origin_lat,
                lon_deg: args.origin_lon,
                alt_m: args.home_alt_amsl,
            },
            height_above_home_m: args.z + CLEARANCE_M,
        },
        waypoints: random_points(&settings, args.mission)
            .into_iter()
            .enumerate()
            .map(|(k, position)| Waypoint {
                name: waypoint_name(k),
                position,
                hover_s: args.hover_s,
            })
            .collect(),
        default_hover_s: args.hover_s,
        min_height_above_home_m: emplan::mission::DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
        source: None,
    };
    // Read it back before writing, so a file we write always loads.
    let text = emplan::mission::to_string(&mission, format)?;
    emplan::mission::load_str(&text, format, Some(&args.out))
        .context("the generated mission does not validate")?;
    std::fs::write(&args.out, text).with_context(|| format!("writing {}", args.out.display()))?;
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
