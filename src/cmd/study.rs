//! `emplan study`: the command line of `planner::study` (the paper's random-mission study with
//! the vehicle's energy table): its JSON view or a table, a progress bar on stderr, and
//! optionally a histogram of the baseline/minimum-energy energy ratios.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail};
use emplan::output::Output;
use emplan::physics::Profile;
use emplan::planner::study::blocks::{self, BlockSettings, BlockStudyJson, SavingStats};
use emplan::planner::study::{
    self, check_envelope, study_document, BaselineDirection, Stats, StudyJson, StudyRunError,
    StudySettings,
};

/// Arguments of `emplan study` (its help text is on the subcommand in main.rs).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Waypoints per mission (1 to 20: the energy order is solved exactly)
    #[arg(
        long,
        value_name = "N",
        required_unless_present = "all_paper_settings",
        conflicts_with = "all_paper_settings"
    )]
    waypoints: Option<usize>,
    /// Horizontal half-width: waypoints uniform in [-XY, XY] m east and north of the origin
    #[arg(
        long,
        value_name = "M",
        allow_negative_numbers = true,
        required_unless_present = "all_paper_settings",
        conflicts_with = "all_paper_settings"
    )]
    xy: Option<f64>,
    /// Vertical half-height: waypoints uniform in [-Z, Z] m around the origin's height
    #[arg(
        long,
        value_name = "M",
        allow_negative_numbers = true,
        required_unless_present = "all_paper_settings",
        conflicts_with = "all_paper_settings"
    )]
    z: Option<f64>,
    /// Random missions per setting
    #[arg(long, value_name = "K", default_value_t = 1000)]
    missions: usize,
    /// Seed: the same seed gives the same missions and results, whatever the thread count
    #[arg(long, value_name = "S", default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document (an array of them with --all-paper-settings)
    #[arg(long)]
    json: bool,
    /// Write a histogram of the baseline/minimum-energy energy ratios to this SVG file (with
    /// --all-paper-settings, one file per setting, suffixed -N-XY-Z)
    #[arg(long, value_name = "FILE.svg")]
    histogram: Option<PathBuf>,
    /// Replace an existing --histogram file (never the vehicle's files nor a flight's file)
    #[arg(long)]
    force: bool,
    /// What a leg's energy counts: settled (leaving hover to settled hover, what the battery
    /// pays) or paper (to the paper's 4 m rule, the convention of its published study)
    #[arg(long, default_value = "settled")]
    pricing: emplan::physics::Pricing,
    /// Which direction of each baseline tour is flown: better (the cheaper of the tour and its
    /// reverse, the fair comparison for a user) or solver (the direction an energy-blind solver
    /// returns, made reproducible: the one whose first waypoint comes earlier in the mission file;
    /// probably what the paper's study measured)
    #[arg(long, value_name = "DIRECTION", default_value = "better")]
    baseline_direction: BaselineDirection,
    /// Run the paper's six settings (N, XY, Z) = (6,30,25) (8,20,25) (8,30,25) (8,40,25)
    /// (8,30,15) (10,30,25) with the given --missions and --seed
    #[arg(long)]
    all_paper_settings: bool,
    /// Instead of the baselines: the study in a steady wind, SPEED@FROM_DEG (repeatable, e.g.
    /// --wind 4@270 --wind 8@270): for each wind, how often the minimum-energy order differs
    /// from the still-air one and what planning in the wind saves (every leg simulated on its
    /// heading)
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    wind: Vec<emplan::physics::Wind>,
    /// Instead of the baselines: every mission gains K random survey rectangles (QGroundControl's
    /// grid: parallel transects flown back and forth), each a block flown whole either way; what
    /// the energy order over points and blocks saves over the file's order (every block forward)
    /// and over the min-distance order, and how often it reverses a block
    #[arg(long, value_name = "K", conflicts_with_all = ["wind", "histogram"])]
    blocks: Option<usize>,
    /// The spacing of the --blocks surveys' transects
    #[arg(long, value_name = "M", default_value_t = blocks::DEFAULT_SPACING_M, requires = "blocks")]
    block_spacing: f64,
}

/// `emplan study --wind ... --json`: one setting's rows, a wind each.
#[derive(serde::Serialize)]
struct WindStudyJson {
    waypoints: usize,
    xy_m: f64,
    z_m: f64,
    seed: u64,
    profile: Profile,
    pricing: emplan::physics::Pricing,
    winds: Vec<emplan::planner::study::wind::WindRow>,
    seconds: f64,
}

/// The study in each `--wind`, for each setting.
fn run_in_wind(
    args: &Args,
    settings: &[StudySettings],
    model: &emplan::physics::VehicleModel,
) -> anyhow::Result<ExitCode> {
    let mut docs = Vec::new();
    for s in settings {
        let started = std::time::Instant::now();
        let mut winds = Vec::new();
        for &w in &args.wind {
            let bar = super::progress::bar(
                s.missions as u64,
                "{prefix} [{bar:40}] {pos}/{len} missions, {eta} left",
            );
            bar.set_prefix(format!(
                "N={} XY={} Z={} wind {w}",
                s.waypoints, s.xy_m, s.z_m
            ));
            let row =
                emplan::planner::study::wind::run_wind(s, model, args.pricing, w, &|| bar.inc(1))
                    .map_err(super::setting_error)?;
            bar.finish_and_clear();
            winds.push(row);
        }
        docs.push(WindStudyJson {
            waypoints: s.waypoints,
            xy_m: s.xy_m,
            z_m: s.z_m,
            seed: s.seed,
            profile: model.profile,
            pricing: args.pricing,
            winds,
            seconds: started.elapsed().as_secs_f64(),
        });
    }
    if args.json {
        if args.all_paper_settings {
            println!("{}", serde_json::to_string_pretty(&docs)?);
        } else if let Some(doc) = docs.first() {
            println!("{}", serde_json::to_string_pretty(doc)?);
        }
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "random-mission study in wind: {} missions per setting, seed {}, legs priced with the {} \
         profile ({} pricing); saving: the still-air order's price in the wind over the \
         wind-aware order's, %: mean / p90 / max",
        args.missions, args.seed, model.profile, args.pricing
    );
    println!(
        "{:>3} {:>5} {:>5} {:>9} {:>9} | {:>14} | {:^20} | {:>12} {:>11}",
        "N",
        "XY_m",
        "Z_m",
        "wind_m_s",
        "from_deg",
        "order_changed",
        "saving",
        "wind_effect",
        "infeasible"
    );
    // A column with no number (no mission flown in that wind) is "-", not 0.
    let or_dash = |value: Option<String>| value.unwrap_or_else(|| "-".into());
    for d in &docs {
        for r in &d.winds {
            println!(
                "{:>3} {:>5} {:>5} {:>9} {:>9} | {:>14} | {:>5} {:>6} {:>6} | {:>12} {:>11}",
                d.waypoints,
                d.xy_m,
                d.z_m,
                r.speed_m_s,
                r.from_deg,
                or_dash(r.order_changed_pct.map(|p| format!("{p:.1}%"))),
                or_dash(r.saving.map(|s| format!("{:.2}", s.mean_pct))),
                or_dash(r.saving.map(|s| format!("{:.2}", s.p90_pct))),
                or_dash(r.saving.map(|s| format!("{:.2}", s.max_pct))),
                or_dash(r.wind_effect_mean_pct.map(|p| format!("{p:+.1}%"))),
                r.infeasible_missions
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A refusal in the words of the command line.
fn refusal(e: StudyRunError) -> anyhow::Error {
    match e {
        StudyRunError::TooWide {
            xy_m,
            reach_m,
            profile,
            max_xf_m,
            allowed_xy_m,
        } => anyhow!(
            "--xy {xy_m}: legs between opposite corners reach {reach_m:.1} m horizontally \
             (2 sqrt(2) XY) but the {profile} energy table covers Xf 0..{max_xf_m} m \
             (allowed: --xy up to {allowed_xy_m:.2})"
        ),
        StudyRunError::TooHigh {
            z_m,
            reach_m,
            profile,
            min_zf_m,
            max_zf_m,
            allowed_z_m,
        } => anyhow!(
            "--z {z_m}: legs from the bottom to the top of the box climb {reach_m:.1} m (2 Z) \
             but the {profile} energy table covers Zf {min_zf_m}..{max_zf_m} m (allowed: --z up to {allowed_z_m:.2})"
        ),
        other => other.into(),
    }
}

fn histogram_path(base: &Path, s: &StudySettings, many: bool) -> PathBuf {
    if !many {
        return base.to_path_buf();
    }
    let stem = base.file_stem().and_then(|s| s.to_str()).unwrap_or("study");
    base.with_file_name(format!("{stem}-{}-{}-{}.svg", s.waypoints, s.xy_m, s.z_m))
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let settings: Vec<StudySettings> = if args.all_paper_settings {
        StudySettings::paper(args.missions, args.seed)
    } else {
        // clap requires all three unless --all-paper-settings.
        let (Some(waypoints), Some(xy_m), Some(z_m)) = (args.waypoints, args.xy, args.z) else {
            bail!("--waypoints, --xy and --z are required (or --all-paper-settings)");
        };
        vec![StudySettings {
            waypoints,
            xy_m,
            z_m,
            missions: args.missions,
            seed: args.seed,
        }]
    };
    for s in &settings {
        s.validate().map_err(super::setting_error)?;
    }
    let model = args.model.model()?;
    for s in &settings {
        check_envelope(s, &model.table).map_err(refusal)?;
    }
    if !args.wind.is_empty() {
        return run_in_wind(&args, &settings, &model);
    }
    if let Some(k) = args.blocks {
        return run_with_blocks(&args, &settings, &model, k);
    }
    // Every histogram checked before the first study runs.
    let histograms: Vec<Option<Output>> = settings
        .iter()
        .map(|s| {
            let Some(base) = &args.histogram else {
                return Ok(None);
            };
            let out = Output::new(
                histogram_path(base, s, settings.len() > 1),
                args.model.files(),
                args.force,
            );
            out.check().map(|()| Some(out))
        })
        .collect::<Result<_, _>>()?;

    let mut docs = Vec::with_capacity(settings.len());
    for (s, histogram) in settings.iter().zip(&histograms) {
        let bar = super::progress::bar(
            s.missions as u64,
            "{prefix} [{bar:40}] {pos}/{len} missions, {eta} left",
        );
        bar.set_prefix(format!("N={} XY={} Z={}", s.waypoints, s.xy_m, s.z_m));
        let done = study::run(s, &model, args.pricing, args.baseline_direction, &|| {
            bar.inc(1)
        })
        .map_err(refusal)?;
        bar.finish_and_clear();
        if let Some(out) = histogram {
            super::plot::study_histogram_svg(out, &done.study, done.profile)?;
            eprintln!("wrote {}", out.path.display());
        }
        docs.push(study_document(&done));
    }

    if args.json {
        if args.all_paper_settings {
            println!("{}", serde_json::to_string_pretty(&docs)?);
        } else if let Some(doc) = docs.first() {
            println!("{}", serde_json::to_string_pretty(doc)?);
        }
    } else {
        print_table(&docs, model.profile, &args);
    }
    Ok(ExitCode::SUCCESS)
}

fn print_table(docs: &[StudyJson], profile: Profile, args: &Args) {
    println!(
        "random-mission study: {} missions per setting, seed {}, legs priced with the {profile} \
         profile ({} pricing)",
        args.missions, args.seed, args.pricing
    );
    let direction = match args.baseline_direction {
        BaselineDirection::Better => "its better direction",
        BaselineDirection::Solver => "the solver's direction, first waypoint earlier in the file",
    };
    println!(
        "energy increase of each baseline ({direction}) over the minimum-energy order, %: \
         mean / p90 / max"
    );
    println!(
        "{:>3} {:>5} {:>5} | {:^20} | {:^20} | {:^20} | {:>9} {:>9} {:>9} {:>8}",
        "N",
        "XY_m",
        "Z_m",
        "min-D",
        "min-X",
        "min-Z",
        "D_differs",
        "Z_beats_D",
        "X_beats_D",
        "seconds"
    );
    let cell = |s: &Stats| format!("{:>5.2} {:>6.2} {:>6.2}", s.mean_pct, s.p90_pct, s.max_pct);
    for d in docs {
        println!(
            "{:>3} {:>5} {:>5} | {:^20} | {:^20} | {:^20} | {:>8.1}% {:>8.1}% {:>8.1}% {:>8.2}",
            d.waypoints,
            d.xy_m,
            d.z_m,
            cell(&d.summary.distance),
            cell(&d.summary.horizontal),
            cell(&d.summary.vertical),
            d.summary.distance_differs_pct,
            d.summary.vertical_beats_distance_pct,
            d.summary.horizontal_beats_distance_pct,
            d.seconds
        );
    }
    if let [d] = docs {
        println!(
            "worst missions (emplan generate --waypoints {} --xy {} --z {} --seed {} --mission K): \
             min-D K={}, min-X K={}, min-Z K={}",
            d.waypoints,
            d.xy_m,
            d.z_m,
            d.seed,
            d.worst_mission.distance.unwrap_or(0),
            d.worst_mission.horizontal.unwrap_or(0),
            d.worst_mission.vertical.unwrap_or(0)
        );
    }
}

/// The study with `k` survey blocks a mission, for each setting.
fn run_with_blocks(
    args: &Args,
    settings: &[StudySettings],
    model: &emplan::physics::VehicleModel,
    k: usize,
) -> anyhow::Result<ExitCode> {
    let block_settings = BlockSettings {
        blocks: k,
        spacing_m: args.block_spacing,
    };
    for s in settings {
        block_settings.validate(s).map_err(super::setting_error)?;
    }
    let mut docs = Vec::with_capacity(settings.len());
    for s in settings {
        let bar = super::progress::bar(
            s.missions as u64,
            "{prefix} [{bar:40}] {pos}/{len} missions, {eta} left",
        );
        bar.set_prefix(format!("N={} K={k} XY={} Z={}", s.waypoints, s.xy_m, s.z_m));
        let done = blocks::run_blocks(
            s,
            &block_settings,
            model,
            args.pricing,
            args.baseline_direction,
            &|| bar.inc(1),
        )
        .map_err(refusal)?;
        bar.finish_and_clear();
        docs.push(blocks::block_study_document(&done));
    }
    if args.json {
        if args.all_paper_settings {
            println!("{}", serde_json::to_string_pretty(&docs)?);
        } else if let Some(doc) = docs.first() {
            println!("{}", serde_json::to_string_pretty(doc)?);
        }
    } else {
        print_block_table(&docs, model.profile, args);
    }
    Ok(ExitCode::SUCCESS)
}

fn print_block_table(docs: &[BlockStudyJson], profile: Profile, args: &Args) {
    println!(
        "random-mission study with survey blocks: {} missions per setting, seed {}, transects {} m \
         apart, each survey a block flown whole either way; legs priced with the {profile} \
         profile ({} pricing)",
        args.missions, args.seed, args.block_spacing, args.pricing
    );
    let direction = match args.baseline_direction {
        BaselineDirection::Better => "its better direction",
        BaselineDirection::Solver => "the solver's direction",
    };
    println!(
        "energy saving of the minimum-energy order over the file's order (every block forward), \
         over the min-distance order ({direction}) and over the best order with every block \
         forward, % of that order: mean / median / max, missions saving > 1%"
    );
    println!(
        "{:>3} {:>2} {:>5} {:>5} | {:^28} | {:^28} | {:^28} | {:>11} {:>9} {:>9} {:>8}",
        "N",
        "K",
        "XY_m",
        "Z_m",
        "over file order",
        "over min-D",
        "over blocks forward",
        "reverses_1+",
        "reversed",
        "D_differs",
        "seconds"
    );
    let cell = |s: &SavingStats| {
        format!(
            "{:>5.2} {:>6.2} {:>6.2} {:>7.1}%",
            s.mean_pct, s.median_pct, s.max_pct, s.over_1pct_missions_pct
        )
    };
    for d in docs {
        println!(
            "{:>3} {:>2} {:>5} {:>5} | {:^28} | {:^28} | {:^28} | {:>10.1}% {:>8.1}% {:>8.1}% \
             {:>8.2}",
            d.waypoints,
            d.blocks,
            d.xy_m,
            d.z_m,
            cell(&d.summary.saving_over_file),
            cell(&d.summary.saving_over_distance),
            cell(&d.summary.saving_over_forward_blocks),
            d.summary.reverses_a_block_pct,
            d.summary.blocks_reversed_pct,
            d.summary.distance_differs_pct,
            d.seconds
        );
        if d.summary.unproven_missions > 0 {
            println!(
                "    {} missions' energy orders are not proven optimal",
                d.summary.unproven_missions
            );
        }
    }
    if let [d] = docs {
        println!(
            "largest savings: over the file's order mission {}, over min-D mission {}",
            d.best_mission.file.unwrap_or(0),
            d.best_mission.distance.unwrap_or(0)
        );
    }
}
