//! Failing at once, and saying where: `fly` with a log directory it cannot write
//! ends before anything is uploaded or armed; `--connect` URLs of no known form fail before any
//! waiting, listing the forms; `calibrate --from-logs` leaves out each flight directory it
//! cannot read (a recording cut off and never resumed, a torn report.json, a short samples.csv
//! row, a non-physical sample), naming it with its reason, and fits the others.

use std::path::Path;

use serde_json::Value;

use crate::emplan;

/// `fly --json` of the 3-waypoint sample on the built-in mock into `log_dir` (exit status,
/// stdout, stderr). `--timeout-s 30`: a regression waiting for a flight that is not recorded
/// ends in seconds, not in the default hour.
fn fly(log_dir: &Path) -> (bool, String, String) {
    emplan(&[
        "fly",
        "missions/paper-sample-3wp.toml",
        "--profile",
        "hvb",
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--speedup",
        "50",
        "--timeout-s",
        "30",
        "--json",
    ])
}

#[test]
fn fly_into_a_log_dir_it_cannot_write_ends_at_once_naming_it_before_any_upload() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("flights");
    std::fs::write(&file, "a file, not a directory\n").unwrap();
    // (Tests run as root, which writes into read-only directories: a file and a path under a
    // file stand for every directory that cannot be written.)
    for (log_dir, reason) in [
        (file.clone(), "exists and is not a directory"),
        (file.join("sub"), "Not a directory (os error 20)"),
    ] {
        let (ok, stdout, stderr) = fly(&log_dir);
        assert!(!ok, "{stderr}");
        let doc: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"));
        let error = doc["error"].as_str().unwrap();
        assert!(
            error.contains(&format!("log directory {}", log_dir.display()))
                && error.contains(reason),
            "{error}"
        );
        // Refused in the record stage, the vehicle never reached: nothing uploaded, nothing
        // armed, nothing flown.
        assert_eq!(doc["stage"], "record", "{doc}");
        assert_eq!(doc["accepted"], false, "{doc}");
        assert!(
            !stderr.contains("flying") && !stderr.contains("armed"),
            "{stderr}"
        );
    }
    assert_eq!(
        std::fs::read_to_string(&file).unwrap(),
        "a file, not a directory\n"
    );
}

#[test]
fn connect_urls_of_no_known_form_fail_at_once_listing_the_forms() {
    for (url, reason) in [
        ("udp:127.0.0.1:1", "unknown scheme \"udp\""),
        ("http://x", "unknown scheme \"http\""),
        ("serial:/dev/ttyACM0", "no baud rate"),
        (
            "serial:/dev/does-not-exist:57600",
            "no serial device /dev/does-not-exist",
        ),
    ] {
        // --discover-s 2: a regression that waits for the link gives up in seconds.
        let (ok, stdout, stderr) = emplan(&[
            "upload",
            "missions/paper-sample-8wp.toml",
            "--connect",
            url,
            "--discover-s",
            "2",
            "--json",
        ]);
        assert!(!ok, "{url}: {stdout}");
        let doc: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"));
        assert_eq!(doc["stage"], "connect", "{url}: {doc}");
        assert!(
            stderr.contains(url)
                && stderr.contains(reason)
                && stderr.contains("udpin:HOST:PORT, udpout:HOST:PORT")
                && stderr.contains("tcpout:HOST:PORT or serial:DEVICE:BAUD"),
            "{url}: {stderr}"
        );
    }
}

/// Copies the flight directory `from` to `to` (its files only: a flight directory is flat).
fn copy_flight(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
    }
}

/// samples.csv of `dir` with line `line` (1-based, the header is line 1) changed by `edit`.
fn edit_samples(dir: &Path, line: usize, edit: impl Fn(&mut Vec<String>)) {
    let path = dir.join("samples.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut fields: Vec<String> = lines[line - 1].split(',').map(str::to_string).collect();
    edit(&mut fields);
    lines[line - 1] = fields.join(",");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
}

#[test]
fn calibrate_from_logs_leaves_out_each_unreadable_flight_naming_it_and_fits_the_others() {
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    let (ok, _, stderr) = fly(&logs);
    assert!(ok, "{stderr}");
    // The flight directory (the ledger is beside it).
    let good = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.is_dir())
        .expect("the flight directory");
    // A flight killed mid-flight and never resumed: no report.json.
    let killed = logs.join("killed");
    copy_flight(&good, &killed);
    std::fs::remove_file(killed.join("report.json")).unwrap();
    // A truncated report.json.
    let torn = logs.join("torn");
    copy_flight(&good, &torn);
    let report = std::fs::read(good.join("report.json")).unwrap();
    std::fs::write(torn.join("report.json"), &report[..report.len() / 2]).unwrap();
    // A short row in the middle of samples.csv.
    let short = logs.join("short");
    copy_flight(&good, &short);
    edit_samples(&short, 10, |fields| {
        fields.pop();
    });
    // A sample of 1e308 volts.
    let huge = logs.join("huge");
    copy_flight(&good, &huge);
    edit_samples(&huge, 20, |fields| fields[6] = "1e308".into());

    let (ok, stdout, stderr) = emplan(&[
        "calibrate",
        "--from-logs",
        logs.to_str().unwrap(),
        "--profile",
        "hvb",
        "--json",
    ]);
    assert!(ok, "{stderr}");
    let c: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"));
    // The good flight is fitted, its pack too, with a finite voltage residual.
    assert_eq!(
        c["flights"].as_array().unwrap().len(),
        1,
        "{}",
        c["flights"]
    );
    assert_eq!(c["flights"][0]["dir"], good.to_str().unwrap());
    let rms = c["battery"]["voltage_rms_v"].as_f64().expect("a pack fit");
    assert!(rms.is_finite() && rms < 1.0, "{}", c["battery"]);
    // Each bad one is left out, named with its reason, in the JSON and on stderr.
    let csv = |dir: &Path| dir.join("samples.csv").display().to_string();
    let expected = [
        (
            &huge,
            format!("{} line 20, column voltage_v: 1e308 V", csv(&huge)),
        ),
        (&killed, "no report.json".to_string()),
        (
            &short,
            format!("{} line 10, column speed_m_s: missing", csv(&short)),
        ),
        (&torn, torn.join("report.json").display().to_string()),
    ];
    let skipped = c["skipped_flights"].as_array().expect("skipped_flights");
    assert_eq!(skipped.len(), expected.len(), "{skipped:?}");
    for ((dir, reason), s) in expected.iter().zip(skipped) {
        assert_eq!(s["dir"], dir.to_str().unwrap());
        let said = s["reason"].as_str().unwrap();
        assert!(said.contains(reason.as_str()), "{said} lacks {reason}");
        assert!(
            stderr.contains(&format!("flight {} left out: {said}", dir.display())),
            "{stderr}"
        );
    }

    // With only bad flights there is nothing to fit: a clear error naming them.
    let (ok, _, stderr) = emplan(&[
        "calibrate",
        "--from-logs",
        killed.to_str().unwrap(),
        huge.to_str().unwrap(),
        "--profile",
        "hvb",
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("no usable flight")
            && stderr.contains(killed.to_str().unwrap())
            && stderr.contains(huge.to_str().unwrap()),
        "{stderr}"
    );
}
