//! `emplan calibrate --from-logs LOG_DIR...`: the vehicle's calibrated parameters refitted to the
//! leg energies of logged flights (`emplan::logfit`), per-leg error before and after with
//! leave-one-flight-out validation, and with `--out DIR` a new vehicle directory with rebuilt
//! tables.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use emplan::logfit::{self, error_pct, vehicle_dir, ErrorStats, LogCalibration};
use emplan::output::Output;
use emplan::physics::{Profile, Vehicle};

#[derive(Debug, Clone, clap::Args)]
#[command(group(clap::ArgGroup::new("logged").args(["from_logs", "from_ledger"])))]
pub struct LogArgs {
    /// Fit to the legs of logged flights instead of the paper: flight directories (as `fly`
    /// and `record` write them: plan.json, report.json), the flight controller's own logs
    /// (PX4 .ulg beside a plan.json, ArduPilot .bin), or folders of them
    #[arg(long, value_name = "LOG_DIR", num_args = 1.., conflicts_with = "fit")]
    from_logs: Vec<PathBuf>,
    /// Fit to the flights of the vehicle chosen (--vehicle: its vehicle file's name) that the
    /// ledger knows, its flight directories still on disk, as --from-logs fits them
    #[arg(long, conflicts_with_all = ["fit", "from_logs"])]
    from_ledger: bool,
    /// With --from-ledger: the ledger, a SQLite file or postgres://... [default:
    /// flights/ledger.sqlite]
    #[arg(long, value_name = "FILE|URL", requires = "from_ledger")]
    ledger: Option<String>,
    /// With --from-logs: the profile the flights flew (default: the one their plan.json says
    /// they were flown with, which must be the same for every flight; else the autopilot's,
    /// told by the mission's layout; else the vehicle's)
    #[arg(long, requires = "logged")]
    profile: Option<Profile>,
    /// With --from-logs: write the calibrated vehicle (vehicle.toml and tables) to this new
    /// directory
    #[arg(long, value_name = "DIR", requires = "logged")]
    out: Option<PathBuf>,
    /// With --out: the tables to rebuild, comma-separated, `all` or `none` (default: the
    /// profile the flights were flown with; the px4 and ptf tables take tens of seconds each,
    /// hvb a few). A table named here that cannot be built refuses the whole output; with the
    /// default or `all`, one that cannot be built is left out with a warning
    /// (vehicle.toml carries the fit; `emplan table build` builds the others)
    #[arg(long, value_name = "PROFILES", requires = "out")]
    tables: Option<String>,
    /// With --from-logs: the airframe's weighed take-off mass in kg (battery and payload on):
    /// set, not fitted, so the energies fit the propulsion, the drag and the descent
    /// (mass, efficiency and kappa all raise the hover power; a scale tells them apart)
    #[arg(long, value_name = "KG", requires = "logged")]
    mass_kg: Option<f64>,
    /// With --out: write into a directory that holds files already, replacing them (never the
    /// source vehicle's directory nor a flight directory)
    #[arg(long, requires = "out")]
    force: bool,
}

/// Runs `--from-logs` when it was given (None otherwise).
/// `vehicle` is the one chosen, read from `vehicle_dir` (None: the built-in S1000).
pub fn run(
    args: &LogArgs,
    vehicle: &Vehicle,
    vehicle_dir: Option<&Path>,
    json: bool,
) -> anyhow::Result<Option<ExitCode>> {
    let name = vehicle_dir.map_or(emplan::physics::builtin::NAME.to_string(), |d| {
        d.display().to_string()
    });
    let from_logs = if args.from_ledger {
        ledger_flights(args, vehicle, &name)?
    } else {
        args.from_logs.clone()
    };
    if from_logs.is_empty() {
        return Ok(None);
    }
    // The tables named (a failure to build one refuses the output) or implied (the default:
    // the flights' profile, known once they are read; `all`).
    let named: Option<Vec<Profile>> = match args.tables.as_deref() {
        None | Some("all") => None,
        Some("none") => Some(Vec::new()),
        Some(list) => Some(
            list.split(',')
                .map(|p| p.trim().parse::<Profile>().map_err(anyhow::Error::msg))
                .collect::<anyhow::Result<_>>()
                .with_context(|| format!("--tables {list}"))?,
        ),
    };
    // The output directory checked before the fit: never the source vehicle's, a flight's or
    // (unforced) one holding anything.
    let out = args.out.as_ref().map(|path| {
        let mut inputs = from_logs.clone();
        // The source vehicle's directory, or the built-in vehicle's (models/s1000), however
        // the output is spelled.
        let sources = match vehicle_dir {
            Some(dir) => vec![dir.to_path_buf()],
            None => emplan::physics::builtin::source_dirs().to_vec(),
        };
        for dir in &sources {
            inputs.push(dir.clone());
            inputs.extend(super::vehicle_files(dir));
        }
        Output::new(path, inputs, args.force)
    });
    if let Some(out) = &out {
        out.check_dir()?;
    }
    // An onboard log is measured against the plan beside it or the mission it holds (what
    // `emplan report FILE` does); the fit needs only its legs' geometry and energies.
    let onboard = |path: &Path| {
        emplan::session::replay_onboard(path, Default::default(), Default::default())
            .map(|a| (a.segmenter.plan().clone(), a.report))
            .map_err(|e| format!("{e:#}").into())
    };
    let flights = logfit::read_flights_with(&from_logs, &onboard)?;
    for skipped in &flights.skipped {
        eprintln!(
            "warning: flight {} left out: {}",
            skipped.dir.display(),
            skipped.reason
        );
    }
    let profile = match args.profile {
        Some(profile) => profile,
        None => match logfit::flights_profile(&flights.flights)? {
            Some(profile) => profile,
            None => {
                let profile = vehicle.default_profile();
                eprintln!(
                    "warning: no flight says which profile it was flown with: fitting with the vehicle's, {profile} (--profile chooses)"
                );
                profile
            }
        },
    };
    let (tables, required) = match named {
        Some(list) => (list, true),
        None if args.tables.is_some() => (Profile::ALL.to_vec(), false),
        None => (vec![profile], false),
    };
    let c = super::progress::solving("fitting to the logged legs", || {
        logfit::calibrate_weighed(vehicle, profile, &flights, args.mass_kg)
    })?;
    let mut written = Vec::new();
    let mut left_out = Vec::new();
    if let Some(out) = &out {
        let to = vehicle_dir::FittedTo {
            flights: c.flights.iter().map(|f| f.name.clone()).collect(),
            legs: c.legs.len(),
            hovers: flights.hovers.len(),
            held_out: c.held_out_errors(),
            profile,
        };
        // Every table built before anything is written: nothing half-written.
        let calibrated = vehicle_dir::calibrated_vehicle(vehicle_dir, out, &c.values(), &to)?;
        let (built, tables_left_out) = vehicle_dir::build_tables(&tables, required, |p| {
            let bar = super::progress::bar(0, "{prefix} [{bar:40}] {pos}/{len} cells, {eta} left");
            bar.set_prefix(format!("{p} table"));
            let table = vehicle_dir::build_table(&calibrated.vehicle, p, |done, total| {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            });
            bar.finish_and_clear();
            table
        })
        .with_context(|| format!("nothing written to {}", out.path.display()))?;
        for t in &tables_left_out {
            eprintln!(
                "warning: the {} table left out of {}: {} (vehicle.toml carries the fit)",
                t.profile,
                out.path.display(),
                t.reason
            );
        }
        left_out = tables_left_out;
        written.push(calibrated.write()?);
        for table in &built {
            written.push(vehicle_dir::write_built_table(out, table)?);
        }
    }
    if json {
        let mut doc = c.to_json();
        if let Some(map) = doc.as_object_mut() {
            map.insert("vehicle".into(), name.clone().into());
            map.insert(
                "out".into(),
                args.out.as_ref().map(|o| o.display().to_string()).into(),
            );
            map.insert("tables_left_out".into(), serde_json::to_value(&left_out)?);
            map.insert(
                "written".into(),
                written
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .into(),
            );
        }
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(Some(ExitCode::SUCCESS));
    }
    print(&c, &name);
    for path in &written {
        println!("wrote {}", path.display());
    }
    if args.out.is_none() {
        println!("(pass --out DIR to write the calibrated vehicle with its tables)");
    }
    Ok(Some(ExitCode::SUCCESS))
}

/// `--from-ledger`: the chosen vehicle's flight directories that the ledger knows and that are
/// still on disk; none is an error saying what the ledger holds of the vehicle.
fn ledger_flights(args: &LogArgs, vehicle: &Vehicle, chosen: &str) -> anyhow::Result<Vec<PathBuf>> {
    let ledger = super::ledger::LedgerArgs {
        ledger: args.ledger.clone(),
    };
    let mut store = ledger.open_existing()?;
    let found = emplan::session::ledger_read::vehicle_flight_dirs(&mut store, &vehicle.name)?;
    for dir in &found.missing {
        eprintln!(
            "warning: flight {} of the ledger left out: its directory is gone",
            dir.display()
        );
    }
    if found.dirs.is_empty() {
        anyhow::bail!(
            "--from-ledger: the ledger {} holds no flight directory of the vehicle {} (chosen: {chosen}): {} flight{} of it, {} imported from onboard logs, {} whose directory is gone",
            ledger.name(),
            vehicle.name,
            found.flights,
            if found.flights == 1 { "" } else { "s" },
            found.onboard,
            found.missing.len()
        );
    }
    Ok(found.dirs)
}

fn stats_line(what: &str, e: &ErrorStats) -> String {
    parts_line(what, e, "legs")
}

/// A line of error statistics over `e.legs` parts called `parts`.
fn parts_line(what: &str, e: &ErrorStats, parts: &str) -> String {
    format!(
        "{what:<34} rms {:>5.1}%, mean {:>+6.1}%, worst {:>5.1}% ({} {parts})",
        e.rms_pct, e.mean_pct, e.worst_pct, e.legs
    )
}

fn print(c: &LogCalibration, vehicle: &str) {
    let used: usize = c.flights.iter().map(|f| f.legs).sum();
    let skipped: usize = c.flights.iter().map(|f| f.skipped).sum();
    println!(
        "leg energies of {} flights ({used} legs used, {skipped} flagged or unmeasured left out), {} profile, vehicle {}",
        c.flights.len(),
        c.profile,
        vehicle
    );
    if !c.skipped.is_empty() {
        println!(
            "{} flight directories left out (unreadable; named in the warnings)",
            c.skipped.len()
        );
    }
    println!(
        "{:<28} {:>6} {:>6} {:>9} {:>8} {:>8} {:>9}",
        "leg", "Xf_m", "Zf_m", "meas_kJ", "before", "after", "left_out"
    );
    for l in &c.legs {
        let name = format!("{}: {} -> {}", l.leg.flight + 1, l.leg.from, l.leg.to);
        let m = l.leg.measured_j;
        println!(
            "{name:<28} {:>6.1} {:>6.1} {:>9.3} {:>+7.1}% {:>+7.1}% {:>9}",
            l.leg.xf_m,
            l.leg.zf_m,
            m / 1000.0,
            error_pct(l.before_j, m),
            error_pct(l.after_j, m),
            l.held_out_j
                .map_or("-".to_string(), |p| format!("{:+.1}%", error_pct(p, m)))
        );
    }
    println!("per-leg error (measured vs predicted):");
    println!("  {}", stats_line("before (the vehicle file)", &c.before()));
    println!(
        "  {}",
        stats_line("after (fitted to every flight)", &c.after())
    );
    match c.held_out_errors() {
        Some(e) => println!("  {}", stats_line("leave-one-flight-out", &e)),
        None => println!("  leave-one-flight-out: needs two flights or more"),
    }
    match &c.hovers {
        Some((before, after)) => {
            println!("holds at the waypoints (hover power x measured time vs measured):");
            println!(
                "  {}",
                parts_line("before (the vehicle file)", before, "holds")
            );
            println!(
                "  {}",
                parts_line("after (fitted to every flight)", after, "holds")
            );
        }
        None => println!("holds at the waypoints: none measured cleanly; not fitted to"),
    }
    for h in &c.held_out {
        let name = c.flights.get(h.flight).map_or("?", |f| f.name.as_str());
        let values: Vec<String> = h
            .fitted
            .iter()
            .map(|f| format!("{} {:.4}", f.key, f.value))
            .collect();
        println!(
            "    {}: {name} left out: rms {:.1}%, worst {:.1}% (fitted on the others: {})",
            h.flight + 1,
            h.errors.rms_pct,
            h.errors.worst_pct,
            values.join(", ")
        );
    }
    match &c.battery {
        Some(b) => println!(
            "pack, from the voltage and current of {} flights ({} samples): voltage residual rms {:.3} V (was {:.3} V); starting charge {}",
            b.flights,
            b.samples,
            b.voltage_rms_v,
            b.before_voltage_rms_v,
            b.initial_soc
                .iter()
                .map(|s| format!("{:.0}%", 100.0 * s))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        None => println!("pack: no flight has voltage and current samples; not fitted"),
    }
    println!("fitted values:");
    for f in &c.values() {
        if f.key == "planning.usable_energy_wh" {
            println!(
                "  {} = {:.4}   (was {}, scaled with the capacity)",
                f.key, f.value, f.before
            );
        } else {
            println!(
                "  {} = {:.4}   (was {}, searched {:.4} to {:.4}){}",
                f.key,
                f.value,
                f.before,
                f.low,
                f.high,
                f.at_bound.map_or(String::new(), |b| format!(
                    "  AT ITS {} BOUND",
                    b.to_uppercase()
                ))
            );
        }
    }
    if let Some(e) = &c.envelope {
        println!(
            "warning: the fit was held to vehicles that can fly the {} profile's legs (Xf 0-150 m, Zf -60..+60 m): one that fitted these flights better (objective {:.4} against {:.4}) cannot fly them {:.0}% heavier: {}",
            c.profile, e.refused_objective, e.objective,
            (logfit::ENVELOPE_MASS_MARGIN - 1.0) * 100.0, e.refused_because
        );
    }
    if !c.at_bound().is_empty() {
        println!(
            "warning: {} at a bound: the flights ask for more than {} can physically give; the rest stays in the errors",
            c.at_bound().iter().map(|f| f.key).collect::<Vec<_>>().join(", "),
            if c.at_bound().len() == 1 { "it" } else { "they" }
        );
    }
}
