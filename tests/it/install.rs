//! emplan as an installed tool: the binary alone, run from a directory outside the repository
//! with nothing else on PATH, plans, studies, uploads and flies a mission given by absolute path
//! (the S1000 and its tables are built in); `convert` never destroys a file; a mission beyond
//! the vehicle's operating limits is refused; progress never reaches a pipe.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the binary from `cwd` with an empty environment but PATH (the binary's own directory)
/// and HOME: (success, stdout, stderr).
fn installed(cwd: &Path, args: &[&str]) -> (bool, String, String) {
    let exe = PathBuf::from(env!("CARGO_BIN_EXE_emplan"));
    let out = Command::new(&exe)
        .args(args)
        .current_dir(cwd)
        .env_clear()
        .env("PATH", exe.parent().expect("the binary's directory"))
        .env("HOME", cwd)
        .output()
        .expect("emplan runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn sample(file: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("missions")
        .join(file)
        .to_str()
        .expect("a UTF-8 path")
        .to_string()
}

fn parsed(run: (bool, String, String), what: &str) -> serde_json::Value {
    let (ok, stdout, stderr) = run;
    assert!(ok, "{what} failed: {stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{what}: not JSON ({e}): {stdout}"))
}

#[test]
fn plan_study_upload_and_fly_work_from_an_empty_directory_outside_the_repository() {
    let dir = tempfile::tempdir().unwrap();
    let cwd = dir.path();
    let mission = sample("paper-sample-8wp.toml");

    let plan = parsed(installed(cwd, &["plan", &mission, "--json"]), "plan");
    assert_eq!(plan["profile"], "px4");
    assert!(
        plan["orders"].as_array().is_some_and(|o| o.len() == 7),
        "{plan}"
    );

    let study = parsed(
        installed(
            cwd,
            &[
                "study",
                "--waypoints",
                "5",
                "--xy",
                "30",
                "--z",
                "25",
                "--missions",
                "20",
                "--json",
            ],
        ),
        "study",
    );
    assert!(study.to_string().contains("missions"), "{study}");

    let upload = parsed(installed(cwd, &["upload", &mission, "--json"]), "upload");
    assert_eq!(upload["report"]["verified"], true, "{upload}");

    let logs = cwd.join("flights");
    let fly = parsed(
        installed(
            cwd,
            &[
                "fly",
                &mission,
                "--log-dir",
                logs.to_str().unwrap(),
                "--json",
            ],
        ),
        "fly",
    );
    assert_eq!(fly["ok"], true);
    assert_eq!(fly["legs"].as_array().map(Vec::len), Some(9));
    assert!(Path::new(fly["log_dir"].as_str().unwrap()).starts_with(&logs));

    // Nothing was written where it ran but the flight log asked for.
    let left: Vec<_> = std::fs::read_dir(cwd)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from("flights")]);
}

#[test]
fn a_missing_vehicle_directory_is_named_with_the_flag_or_variable_that_chose_it_and_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let mission = sample("paper-sample-3wp.toml");
    let (ok, _, stderr) = installed(dir.path(), &["plan", &mission, "--vehicle", "no-such-dir"]);
    assert!(!ok);
    assert!(
        stderr.contains("the vehicle chosen by --vehicle no-such-dir"),
        "{stderr}"
    );
    assert!(stderr.contains("no-such-dir/vehicle.toml"), "{stderr}");
    assert_eq!(
        stderr.matches("No such file or directory").count(),
        1,
        "{stderr}"
    );

    let exe = env!("CARGO_BIN_EXE_emplan");
    let out = Command::new(exe)
        .args(["plan", &mission])
        .current_dir(dir.path())
        .env("EMPLAN_VEHICLE", "elsewhere")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("the vehicle chosen by EMPLAN_VEHICLE=elsewhere"),
        "{stderr}"
    );

    // --vehicle with the repository's directory is the same S1000 as the built-in one.
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let built_in = parsed(installed(dir.path(), &["plan", &mission, "--json"]), "plan");
    let from_dir = parsed(
        installed(
            dir.path(),
            &[
                "plan",
                &mission,
                "--json",
                "--vehicle",
                repo.to_str().unwrap(),
            ],
        ),
        "plan --vehicle",
    );
    let orders = |plan: &serde_json::Value| -> Vec<(String, String)> {
        let orders = plan["orders"].as_array().expect("orders");
        orders
            .iter()
            .map(|o| (o["sequence"].to_string(), o["energy_kj"].to_string()))
            .collect()
    };
    assert_eq!(orders(&built_in), orders(&from_dir));
}

#[test]
fn convert_refuses_to_write_over_its_input_or_another_file_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("m.toml");
    std::fs::copy(sample("paper-sample-8wp.toml"), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let input_s = input.to_str().unwrap();

    let (ok, _, stderr) = installed(dir.path(), &["convert", input_s, input_s]);
    assert!(!ok);
    assert!(
        stderr.contains("refusing to write over the input"),
        "{stderr}"
    );
    // The same file by another name: relative, through "./".
    let (ok, _, stderr) = installed(dir.path(), &["convert", "m.toml", "./m.toml", "--force"]);
    assert!(!ok, "{stderr}");
    assert_eq!(std::fs::read(&input).unwrap(), before);

    let other = dir.path().join("other.plan");
    std::fs::write(&other, "keep me").unwrap();
    let (ok, _, stderr) = installed(dir.path(), &["convert", "m.toml", "other.plan"]);
    assert!(!ok);
    assert!(
        stderr.contains("exists; refusing to replace it without --force"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&other).unwrap(), "keep me");
    let (ok, _, stderr) = installed(dir.path(), &["convert", "m.toml", "other.plan", "--force"]);
    assert!(ok, "{stderr}");
    assert!(std::fs::read_to_string(&other)
        .unwrap()
        .contains("\"fileType\""));
}

#[test]
fn convert_refuses_a_lossy_conversion_and_with_lossy_lists_what_was_lost() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("orchard.toml");
    std::fs::copy(sample("davis-orchard-survey.toml"), &input).unwrap();
    let (ok, stdout, stderr) = installed(
        dir.path(),
        &["convert", "orchard.toml", "orchard.waypoints"],
    );
    assert!(!ok, "{stdout}");
    assert!(
        stderr.contains("min_height_above_home_m: 5 -> 2"),
        "{stderr}"
    );
    assert!(stderr.contains("default_hover_s: 8 -> 0"), "{stderr}");
    assert!(stderr.contains("nothing written"), "{stderr}");
    assert!(!dir.path().join("orchard.waypoints").exists());

    let (ok, stdout, stderr) = installed(
        dir.path(),
        &["convert", "orchard.toml", "orchard.waypoints", "--lossy"],
    );
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("lost min_height_above_home_m: 5 -> 2"),
        "{stdout}"
    );
    assert!(dir.path().join("orchard.waypoints").exists());

    // A conversion the target format holds completely needs no flag.
    let (ok, stdout, stderr) = installed(dir.path(), &["convert", "orchard.toml", "orchard.plan"]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("lost"), "{stdout}");
}

#[test]
fn an_origin_a_billion_metres_up_is_refused_naming_the_waypoint_and_the_limit_even_when_allowing_infeasible(
) {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(sample("paper-sample-3wp.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("height_above_home_m"))
        .expect("the sample sets its origin height");
    let high = text.replace(line, "height_above_home_m = 1e9");
    let path = dir.path().join("high.toml");
    std::fs::write(&path, high).unwrap();
    let path = path.to_str().unwrap();
    for args in [
        vec!["plan", path],
        vec!["upload", path, "--allow-infeasible"],
        vec!["fly", path, "--allow-infeasible"],
    ] {
        let (ok, stdout, stderr) = installed(dir.path(), &args);
        assert!(!ok, "{args:?}: {stdout}");
        assert!(stderr.contains("waypoint A"), "{args:?}: {stderr}");
        assert!(
            stderr.contains(": 1000000025 m above home"),
            "{args:?}: {stderr}"
        );
        assert!(
            stderr.contains("planning.max_height_above_home_m = 120 m"),
            "{args:?}: {stderr}"
        );
        assert!(!stdout.contains("verified"), "{args:?}: {stdout}");
    }
}

#[test]
fn progress_never_reaches_stderr_when_it_is_not_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let ftv33 = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tsplib/ftv33.atsp");
    let mission = sample("paper-sample-8wp.toml");
    let logs = dir.path().join("flights");
    let runs: Vec<Vec<&str>> = vec![
        vec!["plan", &mission],
        vec!["upload", &mission],
        vec![
            "study",
            "--waypoints",
            "6",
            "--xy",
            "30",
            "--z",
            "25",
            "--missions",
            "50",
        ],
        vec!["fly", &mission, "--log-dir", logs.to_str().unwrap()],
    ];
    let mut runs = runs;
    if ftv33.exists() {
        runs.push(vec!["tsp", ftv33.to_str().unwrap()]);
    }
    for args in &runs {
        let (ok, stdout, stderr) = installed(dir.path(), args);
        assert!(ok, "{args:?}: {stderr}");
        for text in [&stdout, &stderr] {
            assert!(
                !text.contains('\r'),
                "{args:?}: a progress line reached a pipe: {text:?}"
            );
            assert!(
                !text.contains("\u{1b}["),
                "{args:?}: an escape reached a pipe: {text:?}"
            );
        }
        assert!(!stderr.contains("kick "), "{args:?}: {stderr}");
        assert!(!stderr.contains("missions,"), "{args:?}: {stderr}");
    }
}
