//! `emplan calibrate`: the model against the paper's published operation energies, and the fit
//! of the calibrated parameters (`--fit`); `--from-logs` fits to logged flights instead
//! (`calibrate_logs`).

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::physics::calibration::{calibrate, rms_pct, Row, PAPER_MARGINAL_J_M};
use emplan::physics::Vehicle;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Vehicle directory holding vehicle.toml
    #[arg(long, default_value = "models/s1000")]
    vehicle: PathBuf,
    /// Refit the calibrated parameters (PTF: mass, drags, speed limits; HVB: its limits) and
    /// print the values to put in vehicle.toml
    #[arg(long)]
    fit: bool,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    logs: super::calibrate_logs::LogArgs,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if let Some(code) = super::calibrate_logs::run(&args.logs, &args.vehicle, args.json)? {
        return Ok(code);
    }
    let vehicle = Vehicle::load(&args.vehicle)?;
    // The fit runs about a minute: a spinner with the time taken on a terminal.
    let c = if args.fit {
        super::progress::solving("fitting the calibrated parameters", || {
            calibrate(&vehicle, true)
        })?
    } else {
        calibrate(&vehicle, false)?
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&c.to_json())?);
        return Ok(ExitCode::SUCCESS);
    }
    let (marginal, hover_w, v_min) = (c.marginal_j_m, c.hover_power_w, c.min_power_speed_m_s);
    let print = |rows: &[Row]| {
        for r in rows {
            println!(
                "{:<4} {:>6.1} {:>6.1} {:>9.2} {:>9.2} {:>+8.1}%",
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
    println!(
        "{:<4} {:>6} {:>6} {:>9} {:>9} {:>9}",
        "", "Xf_m", "Zf_m", "paper_kJ", "model_kJ", "error"
    );
    print(&c.ptf);
    print(&c.hvb);
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
