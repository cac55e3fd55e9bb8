//! `emplan calibrate`: the model against the paper's published operation energies, and the fit
//! of the calibrated parameters (`--fit`); `--from-logs` fits to logged flights instead
//! (`calibrate_logs`).

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::physics::calibration::{calibrate, rms, rms_pct, Row, PAPER_MARGINAL_J_M};
use emplan::physics::{Pricing, VehicleSource};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Vehicle directory holding vehicle.toml (default: $EMPLAN_VEHICLE, else the S1000 built
    /// into emplan)
    #[arg(long, value_name = "DIR")]
    vehicle: Option<PathBuf>,
    /// Refit the calibrated parameters (PTF: mass, drags, induced power factor, speed limits,
    /// tracking lag; HVB: its limits) together to the operations, the sample missions and the
    /// paper's min-energy tour of sample 1, and print the values to put in vehicle.toml
    #[arg(long)]
    fit: bool,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
    /// How the model's energies are also shown priced: settled (to settled hover) or paper (to
    /// the 4 m rule); the comparison with the paper is always in the paper's own convention.
    /// With --from-logs the legs are always compared to the 4 m rule, as flights measure them
    #[arg(long, default_value = "settled")]
    pricing: Pricing,
    #[command(flatten)]
    logs: super::calibrate_logs::LogArgs,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    // --vehicle, else $EMPLAN_VEHICLE, else the built-in S1000 (as every command chooses).
    let (source, chosen) = super::VehicleArgs {
        vehicle: args.vehicle.clone(),
        profile: None,
    }
    .source();
    let dir = match &source {
        VehicleSource::Dir(dir) => Some(dir.as_path()),
        VehicleSource::BuiltIn => None,
    };
    let vehicle = source
        .vehicle()
        .map_err(|e| super::vehicle_error(e.into(), &chosen))?;
    if let Some(code) = super::calibrate_logs::run(&args.logs, &vehicle, dir, args.json)? {
        return Ok(code);
    }
    // The fit runs about a minute: a spinner with the time taken on a terminal.
    let c = if args.fit {
        super::progress::solving("fitting the calibrated parameters", || {
            calibrate(&vehicle, true, args.pricing)
        })?
    } else {
        calibrate(&vehicle, false, args.pricing)?
    };
    let settled = args.pricing == Pricing::Settled;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&c.to_json())?);
        return Ok(ExitCode::SUCCESS);
    }
    let (marginal, hover_w, v_min) = (c.marginal_j_m, c.hover_power_w, c.min_power_speed_m_s);
    if settled {
        println!("(settled_kJ: the model priced to settled hover, emplan's default; --pricing paper leaves it out)");
    }
    let print = |rows: &[Row]| {
        for r in rows {
            let extra = if settled {
                format!(" {:>10.2}", r.priced_kj)
            } else {
                String::new()
            };
            println!(
                "{:<4} {:>6.1} {:>6.1} {:>9.2} {:>9.2} {:>+8.1}%{extra}",
                r.profile.to_string(),
                r.xf_m,
                r.zf_m,
                r.paper_kj,
                r.model_kj,
                r.error_pct
            );
        }
        println!(
            "     rms {:.1}%, worst {:.1}%",
            rms_pct(rows),
            rows.iter().map(|r| r.error_pct.abs()).fold(0.0, f64::max)
        );
    };
    println!("operation energies to the 4 m rule, model vs paper (NOTES.md section 3)");
    let extra = if settled { " settled_kJ" } else { "" };
    println!(
        "{:<4} {:>6} {:>6} {:>9} {:>9} {:>9}{extra}",
        "", "Xf_m", "Zf_m", "paper_kJ", "model_kJ", "error"
    );
    print(&c.ptf);
    print(&c.hvb);
    println!(
        "sample missions: sums of the legs' energies to the 4 m rule, model vs paper (issue 13)"
    );
    println!(
        "{:<8} {:<4} {:<32} {:<11} {:>9} {:>9} {:>9}{extra}",
        "mission", "", "order", "path", "paper_kJ", "model_kJ", "error"
    );
    for r in &c.missions {
        let extra = if settled {
            format!(" {:>10.2}", r.priced_kj)
        } else {
            String::new()
        };
        println!(
            "{:<8} {:<4} {:<32} {:<11} {:>9.2} {:>9.2} {:>+8.1}%{extra}",
            r.mission,
            r.profile.to_string(),
            r.label,
            r.path,
            r.paper_kj,
            r.model_kj,
            r.error_pct
        );
    }
    let errors: Vec<f64> = c.missions.iter().map(|r| r.error_pct).collect();
    println!(
        "     rms {:.1}%, worst {:.1}%",
        rms(&errors),
        errors.iter().map(|e| e.abs()).fold(0.0, f64::max)
    );
    let t = &c.tour;
    println!(
        "sample mission 1: the paper's tour {} {:.2} kJ; the model's min-energy tour {} {:.2} kJ ({})",
        t.paper_tour,
        t.paper_tour_kj,
        t.model_tour,
        t.model_tour_kj,
        if t.gap_pct <= 1e-9 {
            format!(
                "the same energy: the paper's tour or a mirror image, {:.3}% cheaper than any tour of another energy",
                t.margin_pct
            )
        } else {
            format!("the paper's tour is {:.2}% dearer", t.gap_pct)
        }
    );
    println!(
        "PTF marginal cost, J/m (model / paper): climbing {:.0} / {:.0}, level {:.0} / {:.0}, descending saves {:.0} / {:.0}",
        marginal[0], PAPER_MARGINAL_J_M[0], marginal[1], PAPER_MARGINAL_J_M[1], marginal[2], PAPER_MARGINAL_J_M[2]
    );
    println!("hover power {hover_w:.0} W; least-power level speed {v_min:.2} m/s");
    if !c.fitted.is_empty() {
        println!("fitted values (put them in vehicle.toml):");
        for f in &c.fitted {
            println!(
                "  {} = {:.4}   (searched {} to {})",
                f.key, f.value, f.low, f.high
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
