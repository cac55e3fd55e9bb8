//! The study's random missions: the waypoints of mission `k` of a setting, drawn from their own
//! seeded stream, as legs for the study or as a mission file for `emplan generate`.

use super::{StudyError, StudySettings};
use crate::mission::{Enu, Geodetic, Mission, Origin, Waypoint};
use crate::rng::Rng;
use crate::tour::Geometry;

/// Name of waypoint `k` (0-based) of a random mission: `W1`, `W2`, ... (node 0 is `origin`).
pub fn waypoint_name(k: usize) -> String {
    format!("W{}", k + 1)
}

/// The waypoints (origin excluded) of random mission `mission` of a setting: each uniform in
/// [-xy_m, xy_m) x [-xy_m, xy_m) x [-z_m, z_m), drawn x, y, z in turn from
/// `Rng::stream(seed, mission)`. `settings.missions` is not used, so any mission number can be
/// regenerated on its own.
pub fn random_points(settings: &StudySettings, mission: u64) -> Vec<Enu> {
    draw_points(settings, &mut Rng::stream(settings.seed, mission))
}

/// The waypoints of [`random_points`], drawn from `rng` (which goes on to draw whatever the
/// mission has besides, its survey blocks).
pub(super) fn draw_points(settings: &StudySettings, rng: &mut Rng) -> Vec<Enu> {
    let (xy, z) = (settings.xy_m, settings.z_m);
    (0..settings.waypoints)
        .map(|_| {
            let x_east_m = rng.uniform(-xy, xy);
            let y_north_m = rng.uniform(-xy, xy);
            let z_up_m = rng.uniform(-z, z);
            Enu {
                x_east_m,
                y_north_m,
                z_up_m,
            }
        })
        .collect()
}

/// Most waypoints one generated mission may have.
pub const MAX_GENERATED_WAYPOINTS: usize = 1_000_000;

/// How far the origin of a generated mission hovers above its lowest possible waypoint: the
/// origin's height above home is Z + this, so every waypoint is at least this high above home
/// (the mission minimum is 2 m).
pub const CLEARANCE_M: f64 = 5.0;

/// Where a generated mission flies from, and how it hovers.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// Home: latitude, longitude and altitude above mean sea level.
    pub home: Geodetic,
    /// Hover time at every waypoint.
    pub hover_s: f64,
    /// The mission's name (default: `random-N-XY-Z-sS-K`).
    pub name: Option<String>,
}

/// Mission `mission` of the study `settings` as a mission file would hold it: waypoints W1..WN
/// in local x/y/z around an origin `Z + CLEARANCE_M` above `site.home`. Up to
/// [`MAX_GENERATED_WAYPOINTS`] waypoints (`settings.missions` is not used); errors name the
/// setting (`waypoints`, `xy_m`, `z_m`, `lat_deg`, `lon_deg`, `home_alt_amsl_m`, `hover_s`).
pub fn random_mission(
    settings: &StudySettings,
    mission: u64,
    site: &Site,
) -> Result<Mission, StudyError> {
    let bad = |setting: &'static str, value: String, problem: &str| {
        Err(StudyError::Setting {
            setting,
            value,
            problem: problem.to_string(),
        })
    };
    if settings.waypoints == 0 || settings.waypoints > MAX_GENERATED_WAYPOINTS {
        return bad(
            "waypoints",
            settings.waypoints.to_string(),
            &format!("allowed: 1 to {MAX_GENERATED_WAYPOINTS}"),
        );
    }
    for (setting, value) in [("xy_m", settings.xy_m), ("z_m", settings.z_m)] {
        if !(value.is_finite() && value >= 0.0) {
            return bad(
                setting,
                value.to_string(),
                "allowed: a finite half-width of 0 m or more",
            );
        }
    }
    let home = site.home;
    if !(home.lat_deg.is_finite() && (-90.0..=90.0).contains(&home.lat_deg)) {
        return bad("lat_deg", home.lat_deg.to_string(), "allowed: -90 to 90");
    }
    if !(home.lon_deg.is_finite() && (-180.0..=180.0).contains(&home.lon_deg)) {
        return bad("lon_deg", home.lon_deg.to_string(), "allowed: -180 to 180");
    }
    if !home.alt_m.is_finite() {
        return bad(
            "home_alt_amsl_m",
            home.alt_m.to_string(),
            "a finite altitude is required",
        );
    }
    if !(site.hover_s.is_finite() && site.hover_s >= 0.0) {
        return bad("hover_s", site.hover_s.to_string(), "allowed: 0 s or more");
    }
    let name = site.name.clone().unwrap_or_else(|| {
        format!(
            "random-{}-{}-{}-s{}-{}",
            settings.waypoints, settings.xy_m, settings.z_m, settings.seed, mission
        )
    });
    Ok(Mission {
        name,
        origin: Origin {
            home,
            height_above_home_m: settings.z_m + CLEARANCE_M,
        },
        waypoints: random_points(settings, mission)
            .into_iter()
            .enumerate()
            .map(|(k, position)| Waypoint {
                name: waypoint_name(k),
                position,
                hover_s: site.hover_s,
                ..Default::default()
            })
            .collect(),
        default_hover_s: site.hover_s,
        min_height_above_home_m: crate::mission::DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
        source: None,
        start_actions: Vec::new(),
        pois: Vec::new(),
        fence: Default::default(),
        rally: Vec::new(),
        blocks: Vec::new(),
    })
}

/// Mission `mission` of a study as legs: the origin (node 0) and its random waypoints.
pub fn mission_geometry(settings: &StudySettings, mission: u64) -> Geometry {
    Geometry::from_points(
        std::iter::once(Enu::default())
            .chain(random_points(settings, mission))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::super::tests::settings;
    use super::*;

    #[test]
    fn random_points_stay_inside_the_box_and_fill_it() {
        let s = StudySettings {
            waypoints: 500,
            xy_m: 40.0,
            z_m: 15.0,
            missions: 1,
            seed: 3,
        };
        let points = random_points(&s, 7);
        assert_eq!(points.len(), 500);
        for p in &points {
            assert!(p.x_east_m.abs() <= 40.0 && p.y_north_m.abs() <= 40.0);
            assert!(p.z_up_m.abs() <= 15.0);
        }
        let max_z = points.iter().map(|p| p.z_up_m).fold(f64::MIN, f64::max);
        let min_x = points.iter().map(|p| p.x_east_m).fold(f64::MAX, f64::min);
        assert!(max_z > 14.0 && min_x < -38.0);
        assert_eq!(points, random_points(&s, 7));
        assert_ne!(points, random_points(&s, 8));
    }

    #[test]
    fn a_generated_mission_is_the_study_mission_above_home_and_bad_settings_are_named() {
        let s = settings(6, 1, 4);
        let site = Site {
            home: Geodetic {
                lat_deg: 38.5,
                lon_deg: -121.7,
                alt_m: 16.0,
            },
            hover_s: 3.0,
            name: None,
        };
        let m = random_mission(&s, 2, &site).unwrap();
        assert_eq!(m.name, format!("random-6-{}-{}-s4-2", s.xy_m, s.z_m));
        assert_eq!(m.origin.height_above_home_m, s.z_m + CLEARANCE_M);
        let points: Vec<Enu> = m.waypoints.iter().map(|w| w.position).collect();
        assert_eq!(points, random_points(&s, 2));
        assert!(m.waypoints.iter().all(|w| w.hover_s == 3.0));
        assert_eq!(m.waypoints[5].name, "W6");
        let refused = |s: &StudySettings, site: &Site| match random_mission(s, 0, site) {
            Err(StudyError::Setting { setting, .. }) => setting,
            other => panic!("{other:?}"),
        };
        assert_eq!(refused(&settings(0, 1, 1), &site), "waypoints");
        let mut far = site.clone();
        far.home.lat_deg = 91.0;
        assert_eq!(refused(&s, &far), "lat_deg");
        let mut negative = site.clone();
        negative.hover_s = -1.0;
        assert_eq!(refused(&s, &negative), "hover_s");
    }
}
