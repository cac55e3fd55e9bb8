//! Failing at once, and saying where (issue 25): `fly` with a log directory it cannot write
//! ends before anything is uploaded or armed; `--connect` URLs of no known form fail before any
//! waiting, listing the forms.

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
