//! What the binary says when it refuses: a wind given wrong (out of range, negative, huge) or
//! one the vehicle cannot fly, a `.txt` mission of another format, a `--mock-vehicle` the mock
//! cannot fly, a vehicle's home far away (near the pole), a study whose missions cannot be flown
//! in a wind, and the addresses `serve` prints.

use std::io::{Read, Write};
use std::path::Path;

use emplan::mission::Geodetic;
use emplan::sim::{FlightConfig, MockAutopilot, MockConfig};

use super::service::{root, spawn_serve, Reaped};
use super::{emplan, json};

const SAMPLE_8WP: &str = "missions/paper-sample-8wp.toml";

/// `emplan plan` of the 8-waypoint sample in `wind`: (success, stderr).
fn plan_in_wind(wind: &str) -> (bool, String) {
    let (ok, _, stderr) = emplan(&["plan", SAMPLE_8WP, "--wind", wind]);
    (ok, stderr)
}

#[test]
fn a_wind_from_outside_0_to_360_degrees_is_refused_naming_the_value_not_wrapped() {
    for (wind, value) in [("8@400", "400"), ("8@360", "360"), ("8@-10", "-10")] {
        let (ok, stderr) = plan_in_wind(wind);
        assert!(!ok, "--wind {wind} was taken");
        assert!(
            stderr.contains(&format!("wind direction {value} deg")) && stderr.contains("under 360"),
            "--wind {wind}: {stderr}"
        );
    }
    // The range's own ends are taken.
    assert!(plan_in_wind("3@0").0 && plan_in_wind("3@359.9").0);
}

#[test]
fn a_negative_wind_speed_is_read_as_the_value_and_refused_in_our_words() {
    let (ok, stderr) = plan_in_wind("-3@90");
    assert!(!ok);
    assert!(!stderr.contains("unexpected argument"), "clap's: {stderr}");
    assert!(stderr.contains("wind speed -3 m/s"), "{stderr}");
    // Every command with a wind takes it the same way.
    let (ok, _, stderr) = emplan(&[
        "study",
        "--waypoints",
        "3",
        "--xy",
        "20",
        "--z",
        "10",
        "--wind",
        "-3@90",
    ]);
    assert!(!ok && stderr.contains("wind speed -3 m/s"), "{stderr}");
}

#[test]
fn a_huge_wind_speed_is_refused_with_a_short_echo() {
    let (ok, stderr) = plan_in_wind("1e308@0");
    assert!(!ok);
    assert!(stderr.contains("wind speed 1.000e308 m/s"), "{stderr}");
    assert!(!stderr.contains("0000000000"), "{stderr}");
    let long = format!("6@{}", "1".repeat(500));
    let (ok, stderr) = plan_in_wind(&long);
    assert!(!ok);
    // Clap echoes the argument as given; our reason after it is short.
    let reason = stderr
        .split("--wind <SPEED@FROM_DEG>': ")
        .nth(1)
        .and_then(|r| r.lines().next())
        .unwrap_or_else(|| panic!("no reason: {stderr}"));
    assert!(reason.len() < 120 && !reason.contains("1111"), "{reason}");
}

#[test]
fn a_wind_the_vehicle_cannot_fly_is_named_in_the_refusal() {
    // A leg: the first leg's motors saturate in 12 m/s from the west.
    let (ok, stderr) = plan_in_wind("12@270");
    assert!(!ok);
    assert!(
        stderr.contains("in the wind of 12 m/s from 270 deg") && stderr.contains("leg"),
        "{stderr}"
    );
    // The take-off: 15 m/s is beyond it.
    let (ok, stderr) = plan_in_wind("15@270");
    assert!(!ok);
    assert!(
        stderr.contains("pricing the take-off: in the wind of 15 m/s from 270 deg"),
        "{stderr}"
    );
    assert!(!stderr.contains("NaN"), "{stderr}");
}

#[test]
fn a_txt_mission_of_another_format_is_told_what_was_expected_and_what_was_found() {
    let dir = tempfile::tempdir().expect("dir");
    let toml = dir.path().join("survey.txt");
    std::fs::copy(root().join(SAMPLE_8WP), &toml).expect("copied");
    let (ok, _, stderr) = emplan(&["plan", toml.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains("survey.txt: line ")
            && stderr.contains("expected the QGroundControl waypoint file header \"QGC WPL 110\"")
            && stderr.contains("found \"")
            && stderr.contains("TOML"),
        "{stderr}"
    );
    let plan = dir.path().join("plan.txt");
    std::fs::copy(root().join("missions/orchard-inspection.plan"), &plan).expect("copied");
    let (ok, _, stderr) = emplan(&["plan", plan.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains("found \"{") && stderr.contains("JSON"),
        "{stderr}"
    );
    // A real one is read.
    let wpl = dir.path().join("wpl.txt");
    std::fs::copy(root().join("missions/davis-orchard-survey.waypoints"), &wpl).expect("copied");
    assert!(emplan(&["plan", wpl.to_str().unwrap()]).0);
}

/// The shipped S1000 weighing 40 kg: more than its motors and pack can hold in the air.
fn unflyable_vehicle(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("models/s1000/vehicle.toml")).expect("vehicle");
    assert!(text.contains("mass_kg = 5.8069"));
    let vehicle = dir.join("heavy");
    std::fs::create_dir_all(&vehicle).expect("dir");
    std::fs::write(
        vehicle.join("vehicle.toml"),
        text.replace("mass_kg = 5.8069", "mass_kg = 40.0"),
    )
    .expect("written");
    vehicle
}

#[test]
fn a_mock_vehicle_the_mock_cannot_fly_is_refused_with_its_own_reason() {
    let dir = tempfile::tempdir().expect("dir");
    let heavy = unflyable_vehicle(dir.path());
    let logs = dir.path().join("flights");
    let (ok, _, stderr) = emplan(&[
        "fly",
        "missions/paper-sample-3wp.toml",
        "--mock-vehicle",
        heavy.to_str().unwrap(),
        "--log-dir",
        logs.to_str().unwrap(),
        "--discover-s",
        "3",
    ]);
    assert!(!ok);
    assert!(!stderr.contains("heartbeat"), "{stderr}");
    assert!(
        stderr.contains("--mock-vehicle") && stderr.contains("the mock cannot fly it"),
        "{stderr}"
    );
    assert!(
        stderr.contains("battery overloaded"),
        "its reason: {stderr}"
    );
}

/// The great-circle distance on a sphere of radius 6 371 008.8 m (haversine), degrees in.
fn on_the_sphere_m(a: (f64, f64), b: (f64, f64)) -> f64 {
    let (p1, p2) = (a.0.to_radians(), b.0.to_radians());
    let dl = (b.1 - a.1).to_radians();
    let h = ((p2 - p1) / 2.0).sin().powi(2) + p1.cos() * p2.cos() * (dl / 2.0).sin().powi(2);
    2.0 * 6_371_008.8 * h.sqrt().asin()
}

#[test]
fn a_vehicle_home_near_the_pole_is_its_distance_along_the_earth_and_no_nan_is_said() {
    let home = Geodetic {
        lat_deg: 89.99,
        lon_deg: 10.0,
        alt_m: 16.0,
    };
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let config = MockConfig {
        flight: Some(FlightConfig {
            home,
            ..FlightConfig::default()
        }),
        speedup: 40.0,
        ..MockConfig::default()
    };
    let mock = runtime
        .block_on(MockAutopilot::spawn("udpin:127.0.0.1:0", config))
        .expect("mock");
    let logs = tempfile::tempdir().expect("dir");
    let url = format!("udpout:{}", mock.local_addr());
    let (ok, _, stderr) = emplan(&[
        "fly",
        SAMPLE_8WP,
        "--connect",
        &url,
        "--origin",
        "vehicle",
        "--log-dir",
        logs.path().to_str().unwrap(),
    ]);
    runtime.block_on(mock.shutdown()).expect("mock stops");
    // Legs of thousands of km are not flown; what matters is what is said.
    assert!(!ok, "{stderr}");
    assert!(!stderr.contains("NaN"), "{stderr}");
    let moved = stderr
        .lines()
        .find(|l| l.starts_with("origin moved to the vehicle's home"))
        .unwrap_or_else(|| panic!("no origin line: {stderr}"));
    let printed_m: f64 = moved
        .split(" m from the mission's")
        .next()
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no distance: {moved}"));
    // The ellipsoid's geodesic is within 0.5% of the sphere's great circle; the plane tangent
    // at the origin made it 13% short.
    let sphere_m = on_the_sphere_m((38.5362, -121.7875), (89.99, 10.0));
    assert!(
        (printed_m / sphere_m - 1.0).abs() < 0.005,
        "{printed_m} m against {sphere_m} m on the sphere: {moved}"
    );
}

#[test]
fn a_study_whose_missions_cannot_be_flown_in_a_wind_has_no_numbers_rather_than_zeros() {
    let args = [
        "study",
        "--waypoints",
        "4",
        "--missions",
        "2",
        "--xy",
        "40",
        "--z",
        "20",
        "--wind",
        "13@270",
    ];
    let mut with_json = args.to_vec();
    with_json.push("--json");
    let doc = json(&with_json);
    let row = &doc["winds"][0];
    assert_eq!(
        (
            row["missions"].as_u64(),
            row["infeasible_missions"].as_u64()
        ),
        (Some(0), Some(2)),
        "{row}"
    );
    for key in ["order_changed_pct", "saving", "wind_effect_mean_pct"] {
        assert!(row[key].is_null(), "{key}: {row}");
    }
    let (ok, stdout, stderr) = emplan(&args);
    assert!(ok, "{stderr}");
    let line = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("4 "))
        .unwrap_or_else(|| panic!("no row: {stdout}"));
    assert!(
        !line.contains("0.0"),
        "a number where there is none: {line}"
    );
    let dashes = line.split_whitespace().filter(|w| *w == "-").count();
    assert_eq!(dashes, 5, "{line}");
}

/// GETs `url` (http://HOST:PORT/PATH) and returns its status code.
fn status_of(url: &str) -> u16 {
    let rest = url.strip_prefix("http://").expect("an http URL");
    let (host, path) = rest.split_at(rest.find('/').unwrap_or(rest.len()));
    let path = if path.is_empty() { "/" } else { path };
    let mut stream = std::net::TcpStream::connect(host).expect("the service answers");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .expect("sent");
    let mut answer = String::new();
    let _ = stream.read_to_string(&mut answer);
    answer
        .split_whitespace()
        .nth(1)
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("no status: {answer}"))
}

#[test]
fn serve_prints_the_dashboards_address_and_an_api_address_that_answers() {
    let work = tempfile::tempdir().expect("dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("dir");
    let log = work.path().join("serve.log");
    let log_dir = work.path().join("flights");
    let token = work.path().join("token");
    let (serve, url) = spawn_serve(
        &[
            "--missions",
            missions.to_str().unwrap(),
            "--log-dir",
            log_dir.to_str().unwrap(),
            "--http",
            "127.0.0.1:0",
            "--token-file",
            token.to_str().unwrap(),
        ],
        &log,
    );
    let _serve = Reaped(serve);
    let text = std::fs::read_to_string(&log).expect("log");
    let line = text
        .lines()
        .find(|l| l.starts_with("emplan serve:"))
        .unwrap_or_else(|| panic!("no address line: {text}"));
    let after = |label: &str| -> String {
        line.split(label)
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .unwrap_or_else(|| panic!("no {label:?} in {line}"))
            .to_string()
    };
    let dashboard = after("dashboard on ");
    assert_eq!(dashboard, format!("{url}/"), "{line}");
    let api = after("API on ");
    assert!(api.starts_with(&format!("{url}/api/")), "{line}");
    assert_eq!(status_of(&dashboard), 200, "{dashboard}");
    assert_eq!(status_of(&api), 200, "{api}");
}
