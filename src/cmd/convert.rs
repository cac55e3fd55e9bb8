//! `emplan convert IN OUT`: convert a mission between emplan TOML, QGroundControl `.plan` and
//! `QGC WPL 110` `.waypoints`, each chosen by its file extension. Never writes over its input;
//! an existing output only with `--force`; a conversion that drops or changes a setting only
//! with `--lossy`, which lists what was lost.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

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
    if same_file(&args.input, &args.output) {
        anyhow::bail!(
            "{}: refusing to write over the input (give another output file)",
            args.output.display()
        );
    }
    if args.output.exists() && !args.force {
        anyhow::bail!(
            "{}: exists; refusing to replace it without --force",
            args.output.display()
        );
    }
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
    emplan::mission::write_file(&args.output, &text)?;
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

/// Whether two paths name one file (the output need not exist yet).
fn same_file(input: &Path, output: &Path) -> bool {
    let (Ok(input), Some(name)) = (input.canonicalize(), output.file_name()) else {
        return false;
    };
    let parent = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    parent.canonicalize().is_ok_and(|p| p.join(name) == input)
}
