//! `emplan convert IN OUT`: convert a mission between emplan TOML, QGroundControl `.plan` and
//! `QGC WPL 110` `.waypoints`, each chosen by its file extension. Never writes over its input;
//! an existing output only with `--force`; a conversion that drops or changes a setting only
//! with `--lossy`, which lists what was lost (the rules of every output, `emplan::output`).

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::output::Output;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission to read (.toml, .plan, .waypoints or .txt)
    input: PathBuf,
    /// File to write; its extension chooses the format
    output: PathBuf,
    /// Write even when the output format cannot hold every setting (lists what is lost)
    #[arg(long)]
    lossy: bool,
    /// Replace an existing output file (never the input)
    #[arg(long)]
    force: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.input)?;
    if let Some(warning) = mission.unknown_warning() {
        eprintln!("warning: {warning}");
    }
    let output = Output::new(&args.output, vec![args.input.clone()], args.force);
    output.check()?;
    let (text, losses) = emplan::mission::convert::convert(&mission, &args.output)?;
    if !losses.is_empty() && !args.lossy {
        let list: Vec<String> = losses.iter().map(|l| format!("  {l}")).collect();
        anyhow::bail!(
            "{}: this format cannot hold every setting of {}; nothing written (--lossy writes \
             it anyway):\n{}",
            args.output.display(),
            args.input.display(),
            list.join("\n")
        );
    }
    output.write(text.as_bytes())?;
    println!(
        "wrote {} ({} waypoints, mission {:?}) from {}",
        args.output.display(),
        mission.waypoints.len(),
        mission.name,
        args.input.display()
    );
    for loss in &losses {
        println!("  lost {loss}");
    }
    Ok(ExitCode::SUCCESS)
}
