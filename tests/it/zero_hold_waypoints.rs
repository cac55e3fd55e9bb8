//! ArduCopter's fast waypoints: a mission without holds is flown through, its corners blended
//! (`physics::ardupilot_chain`), so `fly` with the `ardupilot` profile predicts its legs
//! shorter than the same mission with holds (each leg rest to rest), the built-in mock flies it
//! that way (every leg within 3%), and `report --vehicle` re-prices the flight the same way.

use std::path::Path;

use serde_json::Value;

use crate::{emplan, json};

/// Flies the generated mission (`hover_s` at every waypoint) in its listed order with the
/// `ardupilot` profile on the built-in mock at its default speed-up: the flight directory and its
/// report.
fn fly(dir: &Path, hover_s: &str) -> (String, Value) {
    let mission = dir.join(format!("hover-{hover_s}.toml"));
    let mission = mission.to_str().unwrap();
    let (ok, _, stderr) = emplan(&[
        "generate",
        "--waypoints",
        "4",
        "--xy",
        "40",
        "--z",
        "10",
        "--seed",
        "5",
        "--hover-s",
        hover_s,
        "--force",
        mission,
    ]);
    assert!(ok, "{stderr}");
    let logs = dir.join(format!("logs-{hover_s}"));
    let report = json(&[
        "fly",
        mission,
        "--profile",
        "ardupilot",
        "--order",
        "listed",
        "--log-dir",
        logs.to_str().unwrap(),
        // The mock's default speed-up (20x), not 50x: an event between two 10 Hz position
        // anchors is stamped by wall time, and a 2 ms tick is 0.1 s of flight at 50x, 2.5% of
        // these 4 s legs (measured: legs -3.1..+2.1% at 50x, -0.6..+1.2% at 20x).
        "--json",
    ]);
    let flight = report["log_dir"].as_str().expect("the flight directory");
    (flight.to_string(), report)
}

fn leg_values(report: &Value, key: &str) -> Vec<f64> {
    (report["legs"].as_array().expect("legs").iter())
        .map(|l| l[key].as_f64().expect(key))
        .collect()
}

#[test]
fn a_mission_without_holds_is_predicted_with_blended_corners_by_fly_and_report() {
    let tmp = tempfile::tempdir().unwrap();
    let (flight, through) = fly(tmp.path(), "0");
    let (_, held) = fly(tmp.path(), "5");
    let (fast, rest) = (
        leg_values(&through, "predicted_duration_s"),
        leg_values(&held, "predicted_duration_s"),
    );
    assert_eq!(fast.len(), 5, "{through}");
    assert_eq!(fast.len(), rest.len());
    // Every leg after the first starts in a blended turn: no tracking lag, and no stop.
    for (k, (f, r)) in fast.iter().zip(&rest).enumerate().skip(1) {
        assert!(f < r, "leg {k}: {f} s blended, {r} s rest to rest");
    }
    let (sum_fast, sum_rest) = (fast.iter().sum::<f64>(), rest.iter().sum::<f64>());
    assert!(sum_fast < 0.9 * sum_rest, "{fast:?} vs {rest:?}");

    // report --vehicle re-prices the flight with the same blended legs.
    let repriced = json(&[
        "report",
        &flight,
        "--vehicle",
        "models/s1000",
        "--profile",
        "ardupilot",
        "--json",
    ]);
    let (flown, again) = (
        leg_values(&through, "predicted_kj"),
        leg_values(&repriced, "predicted_kj"),
    );
    for (a, b) in flown.iter().zip(&again) {
        assert!(
            (a - b).abs() <= 1e-6 * a.abs().max(1.0),
            "{flown:?} vs {again:?}"
        );
    }
    // The built-in mock flies the ardupilot profile as ArduCopter does, corners blended without
    // holds and rest to rest with them: every leg measured within 3% of its price.
    for report in [&through, &held] {
        let errors = leg_values(report, "error_pct");
        assert!(errors.iter().all(|e| e.abs() < 3.0), "{errors:?}");
    }
}
