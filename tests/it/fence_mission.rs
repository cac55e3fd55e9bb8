//! The fenced orchard end to end through the binary, on a mock autopilot standing at its
//! origin: uploaded in the energy order and in an order with a leg across the exclusion square,
//! then downloaded as a `.plan`: the path the vehicle holds (take-off above home, every item's
//! point in order, the return home) never enters the square nor leaves the field, the leg that
//! would have crossed the square goes up round it, and the fence and the rally point come back
//! as they were sent.

use std::path::Path;

use emplan::link::Flavour;
use emplan::mission::fence::LocalZone;
use emplan::mission::Mission;
use emplan::sim::MockHandle;

use super::fence_link::{assert_same_fence, mock_at};
use super::service::root;
use crate::emplan;

const ORCHARD: &str = "missions/orchard-fenced.plan";

/// The path the downloaded mission flies, east and north of `origin` (m): home, each waypoint
/// in the order held, home again.
fn held_path(held: &Mission, sent: &Mission) -> Vec<[f64; 2]> {
    let origin = sent.origin;
    let mut path = vec![[0.0, 0.0]];
    for w in &held.waypoints {
        let g = held.origin.to_geodetic(w.position);
        let e = origin.to_enu(g);
        path.push([e.x_east_m, e.y_north_m]);
    }
    path.push([0.0, 0.0]);
    path
}

/// The zones `mission`'s fence has, in its local frame.
fn zones(mission: &Mission) -> Vec<LocalZone> {
    (mission.fence.zones.iter())
        .map(|z| z.local(&mission.origin))
        .collect()
}

/// The segments of `path` that break a zone (entering an exclusion zone, leaving an
/// inclusion zone), as (segment index, zone index).
fn breaking(path: &[[f64; 2]], zones: &[LocalZone]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (k, w) in path.windows(2).enumerate() {
        for (z, zone) in zones.iter().enumerate() {
            if zone.segment_violates(w[0], w[1], 0.0) {
                out.push((k, z));
            }
        }
    }
    out
}

/// Uploads `file` in `order` to `mock` and downloads what it holds as a `.plan` in `dir`.
fn upload_and_download(mock: &MockHandle, file: &Path, order: &str, dir: &Path) -> Mission {
    let url = format!("udpout:{}", mock.local_addr());
    let (ok, stdout, stderr) = emplan(&[
        "upload",
        file.to_str().expect("path"),
        "--order",
        order,
        "--connect",
        &url,
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(stdout.contains("verified: fence: 2 zones"), "{stdout}");
    assert!(
        stdout.contains("verified: rally points: 1 point"),
        "{stdout}"
    );
    let out = dir.join(format!("held-{order}.plan"));
    let (ok, stdout, stderr) = emplan(&["download", "--connect", &url, out.to_str().unwrap()]);
    assert!(ok, "{stdout}\n{stderr}");
    emplan::mission::load(&out).expect("the downloaded plan reads as a mission")
}

#[test]
fn the_fenced_orchard_goes_up_in_the_energy_order_inside_the_field_clear_of_the_square_and_comes_back_as_sent(
) {
    let sent = emplan::mission::load(&root().join(ORCHARD)).expect("mission");
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let mock = runtime.block_on(mock_at(&sent, Flavour::Px4));
    let tmp = tempfile::tempdir().expect("temp dir");
    let held = upload_and_download(&mock, &root().join(ORCHARD), "energy", tmp.path());

    assert_same_fence(&held.fence, &sent.fence);
    assert_eq!(held.rally.len(), 1);
    let (r, s) = (held.rally[0], sent.rally[0]);
    assert!((r.lat_deg - s.lat_deg).abs() < 2e-7 && (r.lon_deg - s.lon_deg).abs() < 2e-7);
    assert!(
        (r.alt_above_home_m - s.alt_above_home_m).abs() < 1e-3,
        "{r:?} {s:?}"
    );
    let path = held_path(&held, &sent);
    assert_eq!(breaking(&path, &zones(&sent)), [], "{path:?}");

    // The same points without the fence (the orchard as the team flew it before): its energy
    // order flies straight through the square.
    let bare = emplan::mission::load(&root().join("missions/orchard-inspection.plan"))
        .expect("the unfenced orchard");
    let doc = crate::json(&["plan", "missions/orchard-inspection.plan", "--json"]);
    let sequence: Vec<&str> = doc["orders"][0]["sequence"]
        .as_array()
        .expect("sequence")
        .iter()
        .filter_map(|s| s.as_str())
        .collect();
    let straight: Vec<[f64; 2]> = std::iter::once([0.0, 0.0])
        .chain(sequence.iter().map(|name| {
            let w = (bare.waypoints.iter())
                .find(|w| w.name == *name)
                .expect("a waypoint of the order");
            let e = sent.origin.to_enu(bare.origin.to_geodetic(w.position));
            [e.x_east_m, e.y_north_m]
        }))
        .chain(std::iter::once([0.0, 0.0]))
        .collect();
    let square = (sent.fence.zones.iter())
        .position(|z| !z.inclusion)
        .expect("a square");
    assert!(
        breaking(&straight, &zones(&sent))
            .iter()
            .any(|&(_, z)| z == square),
        "the straight energy order {sequence:?} does not cross the square"
    );
    runtime.block_on(mock.shutdown()).expect("mock stops");
}

#[test]
fn a_leg_across_the_square_goes_up_round_it_through_a_point_without_a_hold() {
    // The orchard listed with WP7 before WP6: its leg WP5 -> WP7 crosses the square.
    let tmp = tempfile::tempdir().expect("temp dir");
    let toml = tmp.path().join("orchard.toml");
    let (ok, _, stderr) = emplan(&["convert", ORCHARD, toml.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    let text = std::fs::read_to_string(&toml).expect("toml");
    let mut blocks: Vec<String> = text.split("\n[[waypoints]]").map(String::from).collect();
    let at = |name: &str| {
        blocks
            .iter()
            .position(|b| b.contains(&format!("name = \"{name}\"")))
            .unwrap_or_else(|| panic!("{name} in {text}"))
    };
    let (six, seven) = (at("WP6"), at("WP7"));
    blocks.swap(six, seven);
    let swapped = tmp.path().join("orchard-swapped.toml");
    std::fs::write(&swapped, blocks.join("\n[[waypoints]]")).expect("written");
    let sent = emplan::mission::load(&swapped).expect("the swapped orchard reads");
    let names: Vec<&str> = sent.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names[4..7], ["WP5", "WP7", "WP6"]);

    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let mock = runtime.block_on(mock_at(&sent, Flavour::Px4));
    let held = upload_and_download(&mock, &swapped, "listed", tmp.path());
    // Every waypoint, and one more point between WP5 and WP7 held without a hold.
    assert_eq!(held.waypoints.len(), sent.waypoints.len() + 1, "{held:?}");
    let via = &held.waypoints[5];
    assert_eq!(via.hover_s, 0.0, "{via:?}");
    let path = held_path(&held, &sent);
    assert_eq!(breaking(&path, &zones(&sent)), [], "{path:?}");
    // Straight, the listed order crosses the square.
    let square = (sent.fence.zones.iter())
        .position(|z| !z.inclusion)
        .expect("a square");
    let straight: Vec<[f64; 2]> = (path.iter().enumerate())
        .filter(|&(k, _)| k != 6)
        .map(|(_, p)| *p)
        .collect();
    assert!(
        breaking(&straight, &zones(&sent))
            .iter()
            .any(|&(_, z)| z == square),
        "{straight:?}"
    );
    runtime.block_on(mock.shutdown()).expect("mock stops");
}
