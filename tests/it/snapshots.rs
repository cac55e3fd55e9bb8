//! Every output of the `emplan` binary on the shipped missions, compared with snapshots taken
//! before a refactor (`tests/it/snapshots/*.snap`): JSON documents, text tables, error messages
//! and written files. Only timing is redacted (the solver's and the study's `seconds`, the
//! upload's `upload_s` and `verify_s`, durations printed as `N.NN s` in text, and the upload's
//! resend counts `count_sent`/`items_sent`, which depend on scheduling); every other byte, floats
//! included, must be as printed when the snapshot was taken.
//!
//! To re-bless after an intended change of output: `EMPLAN_BLESS=1 cargo test --test it
//! snapshots::` rewrites the files; review them with `git diff tests/it/snapshots`.

use std::path::{Path, PathBuf};

use crate::emplan;

/// JSON keys whose values are wall-clock times or depend on scheduling.
const TIMING_KEYS: [&str; 5] = [
    "seconds",
    "upload_s",
    "verify_s",
    "count_sent",
    "items_sent",
];

const TSPLIB: &str = "tests/fixtures/tsplib";
const LONG: &str = "missions/long-inspection.toml";
const SURVEY: &str = "missions/long-survey.toml";
const SAMPLE_3: &str = "missions/paper-sample-3wp.toml";
const SAMPLE_8: &str = "missions/paper-sample-8wp.toml";
const DAVIS: &str = "missions/davis-orchard-survey.toml";
const DAVIS_PLAN: &str = "missions/davis-orchard-survey.plan";
const DAVIS_WPL: &str = "missions/davis-orchard-survey.waypoints";

fn snapshot_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/it/snapshots")
        .join(format!("{name}.snap"))
}

/// Compares `actual` with snapshot `name`, or writes it when `EMPLAN_BLESS` is set.
fn assert_snapshot(name: &str, actual: &str) {
    let path = snapshot_path(name);
    if std::env::var_os("EMPLAN_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, actual).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "snapshot {} cannot be read ({e}); bless it with EMPLAN_BLESS=1",
            path.display()
        )
    });
    if expected == actual {
        return;
    }
    let (want, got): (Vec<&str>, Vec<&str>) =
        (expected.lines().collect(), actual.lines().collect());
    let first = want
        .iter()
        .zip(&got)
        .position(|(a, b)| a != b)
        .unwrap_or(want.len().min(got.len()));
    let from = first.saturating_sub(3);
    let show = |lines: &[&str]| {
        lines
            .iter()
            .enumerate()
            .skip(from)
            .take(8)
            .map(|(k, l)| format!("{:>5} {l}", k + 1))
            .collect::<Vec<_>>()
            .join("\n")
    };
    panic!(
        "output differs from snapshot {} at line {} ({} lines expected, {} got)\n--- snapshot\n{}\n--- now\n{}",
        path.display(),
        first + 1,
        want.len(),
        got.len(),
        show(&want),
        show(&got)
    );
}

/// Pretty-printed JSON with the values of [`TIMING_KEYS`] replaced, line by line, so that every
/// other value stays exactly as printed.
fn redact_json(text: &str) -> String {
    text.lines()
        .map(|line| {
            let trimmed = line.trim_start();
            for key in TIMING_KEYS {
                let prefix = format!("\"{key}\": ");
                if trimmed.starts_with(&prefix) {
                    let indent = &line[..line.len() - trimmed.len()];
                    let comma = if trimmed.ends_with(',') { "," } else { "" };
                    return format!("{indent}{prefix}\"[timing]\"{comma}");
                }
            }
            line.to_string()
        })
        .map(|l| l + "\n")
        .collect()
}

/// Text with wall-clock durations replaced: a decimal number followed by " s" and then `)`,
/// `:`, ` (`, `;` or the end of the line, the link's round trip after an upload, and the last
/// column of the study's table rows.
fn redact_text(text: &str) -> String {
    text.lines()
        .map(|line| {
            let mut out = String::new();
            let mut rest = line;
            while let Some(at) = rest.find(" s") {
                let after = &rest[at + 2..];
                let timing_end = after.is_empty()
                    || after.starts_with(')')
                    || after.starts_with(':')
                    || after.starts_with(';')
                    || after.starts_with(" (");
                let head = &rest[..at];
                let start = head
                    .rfind(|c: char| !(c.is_ascii_digit() || c == '.'))
                    .map_or(0, |k| k + 1);
                let number = &head[start..];
                if timing_end && number.contains('.') && number.len() > 1 {
                    out.push_str(&head[..start]);
                    out.push_str("[t]");
                } else {
                    out.push_str(head);
                }
                out.push_str(" s");
                rest = after;
            }
            out.push_str(rest);
            // The link's round trip and restarts after an upload: "(round trip 0.4 ms)".
            if let Some(at) = out.find("(round trip ") {
                if let Some(end) = out[at..].find(')') {
                    out.replace_range(at..at + end + 1, "(round trip [t])");
                }
            }
            // The study's table: "... |     91.5%     68.5%      0.5%     0.04".
            if out.contains(" | ") && out.contains('%') {
                if let Some(k) = out.rfind(' ') {
                    if out[k + 1..].parse::<f64>().is_ok() {
                        out.truncate(k + 1);
                        out.push_str("[t]");
                    }
                }
            }
            out + "\n"
        })
        .collect()
}

/// Runs `emplan args` and returns its exit status, stdout and stderr as one snapshot text.
fn run(args: &[&str], json: bool) -> String {
    let (ok, stdout, stderr) = emplan(args);
    let (stdout, stderr) = if json {
        (redact_json(&stdout), redact_text(&stderr))
    } else {
        (redact_text(&stdout), redact_text(&stderr))
    };
    format!(
        "$ emplan {}\nsuccess: {ok}\n--- stdout\n{stdout}--- stderr\n{stderr}",
        args.join(" ")
    )
}

fn check(name: &str, args: &[&str]) {
    let json = args.contains(&"--json");
    assert_snapshot(name, &run(args, json));
}

/// 64-bit FNV-1a, to fingerprint large written files (SVG figures).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Checks every `(snapshot, command line)`; command lines are split at spaces.
fn check_all(cases: &[(&str, &str)]) {
    for (name, command) in cases {
        let args: Vec<&str> = command.split(' ').collect();
        check(name, &args);
    }
}

#[test]
fn plan_json_of_every_shipped_mission_matches_its_snapshot() {
    check_all(&[
        ("plan-json-davis-toml", &format!("plan {DAVIS} --json")),
        ("plan-json-davis-plan", &format!("plan {DAVIS_PLAN} --json")),
        (
            "plan-json-davis-waypoints",
            &format!("plan {DAVIS_WPL} --json"),
        ),
        ("plan-json-sample-3", &format!("plan {SAMPLE_3} --json")),
        ("plan-json-sample-8", &format!("plan {SAMPLE_8} --json")),
        ("plan-json-long", &format!("plan {LONG} --json")),
        ("plan-json-long-survey", &format!("plan {SURVEY} --json")),
    ]);
}

#[test]
fn plan_json_with_sorties_and_other_profiles_matches_its_snapshot() {
    check_all(&[
        (
            "plan-json-sorties-long",
            &format!("plan {LONG} --json --sorties"),
        ),
        (
            "plan-json-sorties-sample-8",
            &format!("plan {SAMPLE_8} --json --sorties"),
        ),
        (
            "plan-json-ptf-sample-8",
            &format!("plan {SAMPLE_8} --json --profile ptf"),
        ),
        (
            "plan-json-hvb-sample-8",
            &format!("plan {SAMPLE_8} --json --profile hvb"),
        ),
        (
            "plan-json-heuristic-sample-8",
            &format!("plan {SAMPLE_8} --json --solver heuristic"),
        ),
    ]);
}

#[test]
fn plan_text_matches_its_snapshot() {
    check_all(&[
        ("plan-text-sample-3", &format!("plan {SAMPLE_3}")),
        ("plan-text-sample-8", &format!("plan {SAMPLE_8}")),
        ("plan-text-davis", &format!("plan {DAVIS}")),
        ("plan-text-long", &format!("plan {LONG}")),
        ("plan-text-long-survey", &format!("plan {SURVEY}")),
        ("plan-text-sorties-long", &format!("plan {LONG} --sorties")),
        (
            "plan-text-branch-cut-sample-8",
            &format!("plan {SAMPLE_8} --solver branch-cut"),
        ),
    ]);
}

#[test]
fn files_written_by_plan_study_and_generate_match_their_snapshots() {
    let dir = tempfile::tempdir().unwrap();
    let at = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    let (svg, atsp, hist, generated) = (
        at("plan.svg"),
        at("plan.atsp"),
        at("hist.svg"),
        at("gen.toml"),
    );
    // Temporary paths hold no spaces.
    for command in [
        format!("plan {SAMPLE_8} --plot {svg} --export-atsp {atsp} --json"),
        format!("study --waypoints 8 --xy 30 --z 25 --missions 100 --histogram {hist} --json"),
        format!("generate {generated} --waypoints 6 --xy 30 --z 20 --seed 3 --mission 2"),
    ] {
        let args: Vec<&str> = command.split(' ').collect();
        let (ok, _, stderr) = emplan(&args);
        assert!(ok, "{command}: {stderr}");
    }
    let read = |p: &str| std::fs::read(p).unwrap();
    let fingerprint = |p: &str| {
        let bytes = read(p);
        format!("{} bytes, fnv1a {:016x}\n", bytes.len(), fnv1a(&bytes))
    };
    assert_snapshot("file-plan-svg", &fingerprint(&svg));
    assert_snapshot("file-study-histogram-svg", &fingerprint(&hist));
    assert_snapshot("file-plan-atsp", &String::from_utf8(read(&atsp)).unwrap());
    assert_snapshot(
        "file-generate-toml",
        &String::from_utf8(read(&generated)).unwrap(),
    );
}

#[test]
fn energy_json_and_text_of_a_few_legs_match_their_snapshots() {
    check_all(&[
        ("energy-json-40-25", "energy --xf 40 --zf 25 --json"),
        ("energy-json-30-minus-20", "energy --xf 30 --zf -20 --json"),
        ("energy-json-0-30", "energy --xf 0 --zf 30 --json"),
        (
            "energy-json-56.6-0-ptf",
            "energy --xf 56.6 --zf 0 --json --profile ptf",
        ),
        (
            "energy-json-40-minus-25-hvb",
            "energy --xf 40 --zf -25 --json --profile hvb",
        ),
        ("energy-text-40-25", "energy --xf 40 --zf 25"),
    ]);
}

#[test]
fn study_json_and_text_match_their_snapshots() {
    let one = "study --waypoints 8 --xy 30 --z 25 --missions 200 --seed 1";
    let ptf = "study --waypoints 6 --xy 30 --z 25 --missions 200 --seed 7 --profile ptf";
    let all = "study --all-paper-settings --missions 40 --seed 2";
    check_all(&[
        ("study-json-8-30-25", &format!("{one} --json")),
        ("study-json-6-30-25-ptf", &format!("{ptf} --json")),
        ("study-json-all-paper-settings", &format!("{all} --json")),
        ("study-text-8-30-25", one),
        ("study-text-all-paper-settings", all),
        (
            "study-error-xy-too-wide",
            "study --waypoints 8 --xy 60 --z 25 --json",
        ),
    ]);
}

#[test]
fn tsp_json_and_text_of_br17_and_ftv33_match_their_snapshots() {
    check_all(&[
        ("tsp-json-br17", &format!("tsp {TSPLIB}/br17.atsp --json")),
        ("tsp-json-ftv33", &format!("tsp {TSPLIB}/ftv33.atsp --json")),
        ("tsp-text-br17", &format!("tsp {TSPLIB}/br17.atsp")),
    ]);
}

#[test]
fn calibrate_json_and_text_match_their_snapshots() {
    check_all(&[
        ("calibrate-json", "calibrate --json"),
        ("calibrate-text", "calibrate"),
    ]);
}

#[test]
fn upload_json_to_the_built_in_mock_matches_its_snapshot_for_every_order_and_a_sortie() {
    let listed = "--order listed --allow-infeasible";
    check_all(&[
        (
            "upload-json-sample-8-energy",
            &format!("upload {SAMPLE_8} --order energy --json"),
        ),
        (
            "upload-json-sample-8-distance",
            &format!("upload {SAMPLE_8} --order distance --json"),
        ),
        (
            "upload-json-sample-8-listed",
            &format!("upload {SAMPLE_8} --order listed --json"),
        ),
        (
            "upload-json-sample-3-listed",
            &format!("upload {SAMPLE_3} --order listed --json"),
        ),
        (
            "upload-json-long-sortie-1",
            &format!("upload {LONG} --sortie 1 --json"),
        ),
        (
            "upload-json-long-sortie-2",
            &format!("upload {LONG} --sortie 2 --json"),
        ),
        (
            "upload-json-long-listed-allow-infeasible",
            &format!("upload {LONG} {listed} --json"),
        ),
        (
            "upload-json-davis-distance-ptf",
            &format!("upload {DAVIS_PLAN} --order distance --profile ptf --json"),
        ),
    ]);
}

#[test]
fn upload_text_and_refusals_match_their_snapshots() {
    let (ok, stdout, _) = emplan(&["upload", SAMPLE_8]);
    assert_snapshot(
        "upload-text-sample-8",
        &format!("success: {ok}\n--- stdout\n{}", redact_text(&stdout)),
    );
    check_all(&[
        (
            "upload-error-long-over-budget",
            &format!("upload {LONG} --json"),
        ),
        (
            "upload-error-long-distance-over-budget",
            &format!("upload {LONG} --order distance"),
        ),
        (
            "upload-error-long-sortie-beyond",
            &format!("upload {LONG} --sortie 3 --json"),
        ),
        (
            "upload-error-long-sortie-zero",
            &format!("upload {LONG} --sortie 0"),
        ),
    ]);
}

#[test]
fn planning_errors_match_their_snapshots() {
    let dir = tempfile::tempdir().unwrap();
    // A battery too small for any waypoint: the sortie split names the first one.
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let vehicle = std::fs::read_to_string(models.join("vehicle.toml"))
        .unwrap()
        .replace("usable_energy_wh = 200.0", "usable_energy_wh = 5.0");
    std::fs::write(dir.path().join("vehicle.toml"), vehicle).unwrap();
    std::fs::copy(models.join("px4.table"), dir.path().join("px4.table")).unwrap();
    let small = dir.path().to_str().unwrap();
    let (ok, stdout, stderr) =
        emplan(&["plan", SAMPLE_8, "--vehicle", small, "--sorties", "--json"]);
    assert_snapshot(
        "plan-error-unreachable-waypoint",
        &format!("success: {ok}\n--- stdout\n{stdout}--- stderr\n{stderr}"),
    );
    // The shipped battery over budget on the small vehicle's copy, without --sorties.
    let (ok, stdout, stderr) = emplan(&["plan", SAMPLE_8, "--vehicle", small]);
    assert_snapshot(
        "plan-text-small-battery-warning",
        &format!(
            "success: {ok}\n--- stdout\n{}--- stderr\n{}",
            redact_text(&stdout),
            stderr.replace(small, "[vehicle]")
        ),
    );
    // A leg beyond the vehicle's reach (max_leg_m 1000 m; every leg inside it is priced, beyond
    // the table too): the error names the mission and the leg.
    let wide = dir.path().join("wide.toml");
    let wide = wide.to_str().unwrap();
    let (ok, _, stderr) = emplan(&[
        "generate",
        wide,
        "--waypoints",
        "5",
        "--xy",
        "800",
        "--z",
        "10",
        "--seed",
        "4",
    ]);
    assert!(ok, "{stderr}");
    let (ok, stdout, stderr) = emplan(&["plan", wide, "--json"]);
    assert_snapshot(
        "plan-error-leg-beyond-reach",
        &format!(
            "success: {ok}\n--- stdout\n{stdout}--- stderr\n{}",
            stderr.replace(wide, "[mission]")
        ),
    );
    // A profile whose table is missing.
    std::fs::remove_file(dir.path().join("px4.table")).unwrap();
    let (ok, stdout, stderr) = emplan(&["plan", SAMPLE_8, "--vehicle", small, "--json"]);
    assert_snapshot(
        "plan-error-missing-table",
        &format!(
            "success: {ok}\n--- stdout\n{stdout}--- stderr\n{}",
            stderr.replace(small, "[vehicle]")
        ),
    );
}

#[test]
fn the_redactions_touch_timing_only() {
    assert_eq!(
        redact_json("{\n  \"seconds\": 0.5,\n  \"energy_kj\": 1.25\n}"),
        "{\n  \"seconds\": \"[timing]\",\n  \"energy_kj\": 1.25\n}\n"
    );
    assert_eq!(
        redact_text(
            "proven optimal (held-karp, 0.002 s)\nhovering 20 s; 3.50 kJ in 4.25 s to within 4 m"
        ),
        "proven optimal (held-karp, [t] s)\nhovering 20 s; 3.50 kJ in 4.25 s to within 4 m\n"
    );
    assert_eq!(
        redact_text("  8    30    25 |  7.91 | 91.5%     0.04"),
        "  8    30    25 |  7.91 | 91.5%     [t]\n"
    );
}
