//! Every command that writes a file the user named goes through `emplan::output`: never over an
//! input (`plan --plot` / `--export-atsp` onto the mission), never inside a flight directory
//! (`report --plot` onto its flight.tlog or report.json), an existing file only with `--force`
//! (`generate`, `download`, `plan --plot`, `report --plot`, `study --histogram`), and written
//! beside and renamed, leaving no temporary file behind.

use std::path::{Path, PathBuf};

use emplan::flightlog::recorder::{write_report, Recorder, REPORT_FILE, TLOG_FILE};
use emplan::flightlog::segment::SegmentConfig;
use emplan::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
use emplan::link::telemetry::{analyse_flight_dir, encode, frame_bytes, Telemetry};
use emplan::link::Flavour;
use emplan::sim::{MockAutopilot, MockConfig};
use mavlink::MavHeader;

use crate::emplan;

const MISSION: &str = "missions/paper-sample-3wp.toml";

fn s(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 temp path")
}

/// The names in `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("readable")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A flight directory under `log_dir` as the recorder writes it (a scripted flight of the
/// square plan), with its report.json.
fn recorded_flight(log_dir: &Path) -> PathBuf {
    let plan = square_plan();
    let cfg = SyntheticConfig {
        speedup: 10.0,
        ..SyntheticConfig::default()
    };
    let flight = SyntheticFlight::fly(&plan, &cfg);
    let mut recorder = Recorder::create(log_dir, &plan.mission, cfg.start_wall_us).expect("new");
    recorder.write_plan(&plan).expect("plan written");
    let mut telemetry = Telemetry::new();
    for (k, m) in flight.messages.iter().enumerate() {
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: k as u8,
        };
        let frame = frame_bytes(&header, &encode(&m.reading, Flavour::Px4));
        let stamped = telemetry.frame(m.wall_us, &frame);
        recorder
            .record(m.wall_us, &frame, stamped.as_ref())
            .expect("recorded");
    }
    let dir = recorder.close().expect("closed");
    let analysis = analyse_flight_dir(&dir, SegmentConfig::default()).expect("replays");
    write_report(&dir, &analysis.report).expect("report written");
    dir
}

#[test]
fn report_plot_onto_a_flights_log_or_report_is_refused_even_forced_and_leaves_it_untouched() {
    let tmp = tempfile::tempdir().unwrap();
    let flight = recorded_flight(tmp.path());
    let (ok, _, stderr) = emplan(&["report", s(&flight), "--json"]);
    assert!(ok, "the flight reports: {stderr}");
    let files_before = entries(&flight);
    for name in [TLOG_FILE, REPORT_FILE] {
        let path = flight.join(name);
        let before = std::fs::read(&path).unwrap();
        for force in [false, true] {
            let mut args = vec!["report", s(&flight), "--plot", s(&path)];
            if force {
                args.push("--force");
            }
            let (ok, _, stderr) = emplan(&args);
            assert!(!ok, "{args:?} must be refused");
            assert!(
                stderr.contains("inside the flight directory") && stderr.contains(s(&path)),
                "{stderr}"
            );
            assert_eq!(std::fs::read(&path).unwrap(), before, "{name} changed");
        }
    }
    // A new file in the flight directory is refused too; beside it is fine.
    let (ok, _, stderr) = emplan(&["report", s(&flight), "--plot", s(&flight.join("a.svg"))]);
    assert!(
        !ok && stderr.contains("inside the flight directory"),
        "{stderr}"
    );
    assert_eq!(entries(&flight), files_before);
    let (ok, _, stderr) = emplan(&["report", s(&flight), "--plot", s(&tmp.path().join("a.svg"))]);
    assert!(ok, "{stderr}");
    let (ok, _, stderr) = emplan(&["replay", s(&flight.join(TLOG_FILE)), "--json"]);
    assert!(ok, "the flight still replays: {stderr}");
}

#[test]
fn plan_plot_or_export_atsp_onto_the_input_mission_is_refused_even_forced() {
    let tmp = tempfile::tempdir().unwrap();
    let mission = tmp.path().join("m.toml");
    std::fs::copy(MISSION, &mission).unwrap();
    let before = std::fs::read(&mission).unwrap();
    let dotted = tmp.path().join(".").join("m.toml");
    for option in ["--plot", "--export-atsp"] {
        for (output, force) in [(&mission, false), (&dotted, false), (&mission, true)] {
            let mut args = vec!["plan", s(&mission), option, s(output)];
            if force {
                args.push("--force");
            }
            let (ok, _, stderr) = emplan(&args);
            assert!(!ok, "{args:?} must be refused");
            assert!(
                stderr.contains("refusing to write over the input"),
                "{stderr}"
            );
            assert_eq!(std::fs::read(&mission).unwrap(), before);
        }
    }
    // Nor may the two outputs be one file.
    let same = tmp.path().join("out");
    let (ok, _, stderr) = emplan(&[
        "plan",
        s(&mission),
        "--plot",
        s(&same),
        "--export-atsp",
        s(&same),
    ]);
    assert!(!ok, "{stderr}");
    assert_eq!(entries(tmp.path()), ["m.toml"]);
}

/// `args` (whose output is `path`) refused while `path` exists, then with `--force` replacing
/// it; no temporary file left beside it.
fn refused_unforced_replaced_forced(args: &[&str], path: &Path) {
    std::fs::write(path, "keep me").unwrap();
    let dir = path.parent().unwrap();
    let names = entries(dir);
    let (ok, _, stderr) = emplan(args);
    assert!(!ok, "{args:?} must be refused without --force");
    assert!(
        stderr.contains("exists; refusing to replace it without --force")
            && stderr.contains(s(path)),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(path).unwrap(), "keep me");
    let mut forced = args.to_vec();
    forced.push("--force");
    let (ok, _, stderr) = emplan(&forced);
    assert!(ok, "{forced:?}: {stderr}");
    assert_ne!(std::fs::read_to_string(path).unwrap(), "keep me");
    assert_eq!(entries(dir), names, "only the output, no temporary file");
}

#[test]
fn generate_onto_an_existing_file_is_refused_without_force_and_replaces_it_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("g.toml");
    let args = [
        "generate",
        s(&out),
        "--waypoints",
        "4",
        "--xy",
        "20",
        "--z",
        "10",
    ];
    refused_unforced_replaced_forced(&args, &out);
    let (ok, _, stderr) = emplan(&["plan", s(&out), "--json"]);
    assert!(ok, "the generated mission plans: {stderr}");
}

#[test]
fn plan_plot_and_export_atsp_onto_an_existing_file_are_refused_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let plot = tmp.path().join("p.svg");
    refused_unforced_replaced_forced(&["plan", MISSION, "--plot", s(&plot)], &plot);
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
    let atsp = tmp.path().join("p.atsp");
    refused_unforced_replaced_forced(&["plan", MISSION, "--export-atsp", s(&atsp)], &atsp);
    assert!(std::fs::read_to_string(&atsp).unwrap().contains("ATSP"));
}

#[test]
fn report_plot_onto_an_existing_file_is_refused_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let flight = recorded_flight(&tmp.path().join("flights"));
    let plot = tmp.path().join("f.svg");
    refused_unforced_replaced_forced(&["report", s(&flight), "--plot", s(&plot)], &plot);
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
}

#[test]
fn study_histogram_onto_an_existing_file_is_refused_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let svg = tmp.path().join("h.svg");
    let args = [
        "study",
        "--waypoints",
        "3",
        "--xy",
        "20",
        "--z",
        "10",
        "--missions",
        "4",
        "--histogram",
        s(&svg),
    ];
    refused_unforced_replaced_forced(&args, &svg);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
}

#[test]
fn download_onto_an_existing_file_is_refused_before_connecting_and_replaces_it_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("items.json");
    // Refused before any link work: nothing listens on this port.
    std::fs::write(&out, "keep me").unwrap();
    let (ok, _, stderr) = emplan(&[
        "download",
        "--connect",
        "tcpout:127.0.0.1:9",
        "--discover-s",
        "3",
        s(&out),
    ]);
    assert!(!ok);
    assert!(stderr.contains("without --force"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep me");

    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mock = runtime
        .block_on(MockAutopilot::spawn(
            "udpin:127.0.0.1:0",
            MockConfig::default(),
        ))
        .unwrap();
    let url = format!("udpout:{}", mock.local_addr());
    refused_unforced_replaced_forced(&["download", "--connect", &url, s(&out)], &out);
    runtime.block_on(mock.shutdown()).unwrap();
    let items: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(items.is_array(), "{items}");
}

#[test]
fn convert_writes_its_output_whole_with_no_temporary_file_beside_it() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("m.plan");
    let (ok, _, stderr) = emplan(&["convert", MISSION, s(&out)]);
    assert!(ok, "{stderr}");
    assert_eq!(entries(tmp.path()), ["m.plan"]);
}

#[test]
fn no_command_writes_a_file_but_through_emplan_output() {
    let cmd = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cmd");
    let mut offenders = Vec::new();
    for entry in std::fs::read_dir(&cmd).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        for (k, line) in text.lines().enumerate() {
            for call in ["fs::write(", "File::create(", "fs::rename(", "OpenOptions"] {
                if line.contains(call) {
                    offenders.push(format!("{}:{}: {}", path.display(), k + 1, line.trim()));
                }
            }
        }
    }
    assert!(offenders.is_empty(), "{offenders:#?}");
}
