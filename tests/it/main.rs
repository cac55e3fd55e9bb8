//! The integration test binary: one crate, one link step (modules below).

mod actions;
mod ardupilot;
mod block_files;
mod blocks_flight;
mod camera;
mod cli;
mod crashes;
mod detour_flight;
mod docrefs;
mod early_failures;
mod fence_files;
mod fence_link;
mod fence_mission;
mod flight;
mod flightlog;
mod flownprofile;
mod fly;
mod fly_through_service;
mod fromlogs;
mod guard;
mod home;
mod install;
mod ledger_cli;
mod ledger_flights;
mod ledger_records;
mod messages;
mod mission;
mod onboard;
mod onboard_corrupt;
mod onboard_dataflash;
mod onboard_ulog;
mod outputs;
mod physics;
mod preflight;
mod races;
mod radio;
mod rally;
mod reprice;
mod resume;
mod service;
mod service_guard;
mod service_http_hardening;
mod service_ledger;
mod service_missions_folder;
mod service_refused_starts;
mod snapshots;
mod solvers;
mod sorties;
mod study;
mod tidy;
mod tlogcorrupt;
mod upload;
mod wind;
mod zero_hold_waypoints;

/// Runs the `emplan` binary from the crate root: (success, stdout, stderr).
pub fn emplan(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("emplan runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `emplan` and parses the one JSON document it prints; fails the test if it fails.
pub fn json(args: &[&str]) -> serde_json::Value {
    let (ok, stdout, stderr) = emplan(args);
    assert!(ok, "emplan {args:?} failed: {stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {stdout}"))
}

/// Writes a random mission (`emplan generate`, seed `seed`) of `waypoints` waypoints in
/// +-`xy` m x +-`z` m to `dir` and returns its path as a string.
pub fn generated_mission(
    dir: &std::path::Path,
    waypoints: u32,
    xy: u32,
    z: u32,
    seed: u64,
) -> String {
    let path = dir.join(format!("random-{waypoints}.toml"));
    let path = path.to_str().expect("a UTF-8 temp path").to_string();
    let (ok, _, stderr) = emplan(&[
        "generate",
        &path,
        "--waypoints",
        &waypoints.to_string(),
        "--xy",
        &xy.to_string(),
        "--z",
        &z.to_string(),
        "--seed",
        &seed.to_string(),
    ]);
    assert!(ok, "generate failed: {stderr}");
    path
}
