//! `emplan fly` on the mock autopilot's ArduPilot flavour: `fly` reads ArduCopter's navigation
//! parameters by name, prices with the `ardupilot` profile (the autopilot's own) unless
//! `--profile` says otherwise, and the mock flies that profile, so every leg agrees with its
//! price.

use std::time::Duration;

use serde_json::Value;

use emplan::link::Flavour;
use emplan::sim::{FlightConfig, MockAutopilot, MockConfig};

/// Flies the 8-waypoint sample with `emplan fly --arm` on an ArduPilot-flavoured mock (its
/// navigation parameters `held`, ArduCopter names), with `extra` arguments: (ok, report,
/// stderr).
async fn fly_on_ardupilot(extra: &[&str], held: Vec<(String, f64)>) -> (bool, Value, String) {
    let mission = emplan::mission::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/missions/paper-sample-8wp.toml"
    )))
    .unwrap();
    let mut vehicle = emplan::physics::builtin::vehicle().unwrap();
    vehicle.ardupilot = vehicle.ardupilot.with_autopilot_values(&held);
    let config = MockConfig {
        flavour: Flavour::ArduPilot,
        boot: Duration::ZERO,
        speedup: 50.0,
        flight: Some(FlightConfig {
            home: mission.origin.home,
            ..FlightConfig::default()
        }),
        ..MockConfig::default()
    };
    let mock = MockAutopilot::spawn_with_vehicle("udpin:127.0.0.1:0", config, vehicle)
        .await
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let connect = format!("udpout:{}", mock.local_addr());
    let log = dir.path().to_str().unwrap().to_string();
    let extra: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    let (ok, stdout, stderr) = tokio::task::spawn_blocking(move || {
        let mut args = vec![
            "fly",
            "missions/paper-sample-8wp.toml",
            "--connect",
            &connect,
            "--arm",
            "--json",
            "--log-dir",
            &log,
        ];
        args.extend(extra.iter().map(String::as_str));
        crate::emplan(&args)
    })
    .await
    .unwrap();
    drop(mock);
    let report = serde_json::from_str(&stdout).unwrap_or(Value::Null);
    (ok, report, stderr)
}

fn legs_within(report: &Value, tolerance_pct: f64) -> Result<(), String> {
    let legs = report["legs"].as_array().ok_or("no legs")?;
    if legs.len() != 9 {
        return Err(format!("{} legs", legs.len()));
    }
    for leg in legs {
        let error = leg["error_pct"].as_f64();
        if !error.is_some_and(|e| e.abs() <= tolerance_pct) {
            return Err(format!("leg {} -> {}: {error:?}%", leg["from"], leg["to"]));
        }
    }
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_ardupilot_fly_reads_its_parameters_prices_with_the_ardupilot_profile_and_every_leg_agrees(
) {
    let (ok, report, stderr) = fly_on_ardupilot(&[], Vec::new()).await;
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("pricing with the ardupilot profile"),
        "{stderr}"
    );
    let params = &report["ardupilot_parameters"];
    assert_eq!(params["read"], 17, "{params}");
    assert_eq!(params["differing"].as_array().map(Vec::len), Some(0));
    assert!(report["px4_parameters"].is_null());
    legs_within(&report, 3.0).unwrap();
    assert_eq!(report["complete"], true);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_ardupilot_holding_another_wp_spd_is_warned_of_and_priced_with_its_own() {
    let held = vec![("WP_SPD".to_string(), 5.0), ("WP_ACC".to_string(), 1.5)];
    let (ok, report, stderr) = fly_on_ardupilot(&[], held).await;
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("warning: ArduPilot parameter WP_SPD is 5 on the vehicle, 10 in the vehicle file's [ardupilot] section"),
        "{stderr}"
    );
    let differing: Vec<&str> = report["ardupilot_parameters"]["differing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["name"].as_str().unwrap())
        .collect();
    assert_eq!(differing, ["WP_SPD", "WP_ACC"]);
    // Priced as this ArduPilot flies (slower), so the legs still agree.
    legs_within(&report, 3.0).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_explicit_profile_is_kept_on_ardupilot() {
    let (ok, report, stderr) = fly_on_ardupilot(&["--profile", "px4"], Vec::new()).await;
    assert!(ok, "{stderr}");
    assert!(!stderr.contains("pricing with the"), "{stderr}");
    // No parameters read (a px4 price on an ArduPilot), and the mock flying ArduCopter's
    // S-curves is measured off the px4 price.
    assert!(report["ardupilot_parameters"].is_null() && report["px4_parameters"].is_null());
    assert!(legs_within(&report, 3.0).is_err());
}
