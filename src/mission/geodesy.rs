//! WGS84 geodesy: geodetic <-> ECEF <-> local east-north-up, exact to well below a millimetre
//! over the kilometres a mission spans (no flat-earth approximation).
//!
//! Constants: WGS84 (NIMA TR8350.2, table 3.1). Geodetic -> ECEF is the closed form; ECEF ->
//! geodetic iterates Bowring's latitude equation to convergence (Hofmann-Wellenhof,
//! "GNSS", 2008, section 10.2.1).

use nalgebra::{Matrix3, Vector3};

use super::{Enu, Geodetic, Origin};

/// WGS84 semi-major axis (m).
const A_M: f64 = 6_378_137.0;
/// WGS84 flattening.
const F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared.
const E2: f64 = F * (2.0 - F);

/// Earth-centred, Earth-fixed coordinates of a geodetic point.
pub fn to_ecef(g: Geodetic) -> Vector3<f64> {
    let (lat, lon) = (g.lat_deg.to_radians(), g.lon_deg.to_radians());
    let n = A_M / (1.0 - E2 * lat.sin().powi(2)).sqrt();
    Vector3::new(
        (n + g.alt_m) * lat.cos() * lon.cos(),
        (n + g.alt_m) * lat.cos() * lon.sin(),
        (n * (1.0 - E2) + g.alt_m) * lat.sin(),
    )
}

/// Geodetic coordinates of an ECEF point (iterated to 1e-14 rad; converges in a few steps
/// anywhere outside the Earth's core).
pub fn from_ecef(p: Vector3<f64>) -> Geodetic {
    let lon = p.y.atan2(p.x);
    let r = (p.x * p.x + p.y * p.y).sqrt();
    let mut lat = p.z.atan2(r * (1.0 - E2));
    let mut alt = 0.0;
    for _ in 0..10 {
        let n = A_M / (1.0 - E2 * lat.sin().powi(2)).sqrt();
        alt = if lat.cos().abs() > 1e-9 {
            r / lat.cos() - n
        } else {
            p.z.abs() - n * (1.0 - E2)
        };
        let next = p.z.atan2(r * (1.0 - E2 * n / (n + alt)));
        let done = (next - lat).abs() < 1e-14;
        lat = next;
        if done {
            break;
        }
    }
    Geodetic {
        lat_deg: lat.to_degrees(),
        lon_deg: lon.to_degrees(),
        alt_m: alt,
    }
}

/// The mean radius of the WGS84 ellipsoid, (2a + b) / 3 (m; Moritz, "Geodetic Reference System
/// 1980", Bulletin Geodesique 54, 1980: R1), for the spherical fallback of
/// [`geodesic_distance_m`].
const MEAN_RADIUS_M: f64 = A_M * (3.0 - F) / 3.0;

/// The length of the shortest path on the WGS84 ellipsoid between two points' ground positions
/// (m; altitudes ignored): Vincenty's inverse formula (T. Vincenty, "Direct and inverse
/// solutions of geodesics on the ellipsoid with application of nested equations", Survey
/// Review 23(176), 1975), good to a fraction of a millimetre. Near-antipodal points, where its
/// iteration does not converge, get the great-circle distance on the mean sphere (haversine;
/// within 0.5%). Never NaN for finite coordinates.
pub fn geodesic_distance_m(from: Geodetic, to: Geodetic) -> f64 {
    vincenty_m(from, to).unwrap_or_else(|| great_circle_m(from, to))
}

fn vincenty_m(from: Geodetic, to: Geodetic) -> Option<f64> {
    let b_m = A_M * (1.0 - F);
    let l = (to.lon_deg - from.lon_deg).to_radians();
    let u1 = ((1.0 - F) * from.lat_deg.to_radians().tan()).atan();
    let u2 = ((1.0 - F) * to.lat_deg.to_radians().tan()).atan();
    let (sin_u1, cos_u1) = u1.sin_cos();
    let (sin_u2, cos_u2) = u2.sin_cos();
    let mut lambda = l;
    for _ in 0..200 {
        let (sin_l, cos_l) = lambda.sin_cos();
        let sin_sigma = (cos_u2 * sin_l).hypot(cos_u1 * sin_u2 - sin_u1 * cos_u2 * cos_l);
        if sin_sigma == 0.0 {
            // The same point.
            return Some(0.0);
        }
        let cos_sigma = sin_u1 * sin_u2 + cos_u1 * cos_u2 * cos_l;
        let sigma = sin_sigma.atan2(cos_sigma);
        let sin_alpha = cos_u1 * cos_u2 * sin_l / sin_sigma;
        let cos2_alpha = 1.0 - sin_alpha * sin_alpha;
        // On the equator (cos2_alpha 0) the term vanishes (Vincenty 1975, eq. 17).
        let cos_2sigma_m = if cos2_alpha == 0.0 {
            0.0
        } else {
            cos_sigma - 2.0 * sin_u1 * sin_u2 / cos2_alpha
        };
        let c = F / 16.0 * cos2_alpha * (4.0 + F * (4.0 - 3.0 * cos2_alpha));
        let next = l
            + (1.0 - c)
                * F
                * sin_alpha
                * (sigma
                    + c * sin_sigma
                        * (cos_2sigma_m
                            + c * cos_sigma * (-1.0 + 2.0 * cos_2sigma_m * cos_2sigma_m)));
        if !next.is_finite() {
            return None;
        }
        let converged = (next - lambda).abs() < 1e-12;
        lambda = next;
        if converged {
            let u_sq = cos2_alpha * (A_M * A_M - b_m * b_m) / (b_m * b_m);
            let big_a =
                1.0 + u_sq / 16384.0 * (4096.0 + u_sq * (-768.0 + u_sq * (320.0 - 175.0 * u_sq)));
            let big_b = u_sq / 1024.0 * (256.0 + u_sq * (-128.0 + u_sq * (74.0 - 47.0 * u_sq)));
            let c2 = cos_2sigma_m * cos_2sigma_m;
            let delta_sigma = big_b
                * sin_sigma
                * (cos_2sigma_m
                    + big_b / 4.0
                        * (cos_sigma * (-1.0 + 2.0 * c2)
                            - big_b / 6.0
                                * cos_2sigma_m
                                * (-3.0 + 4.0 * sin_sigma * sin_sigma)
                                * (-3.0 + 4.0 * c2)));
            let s = b_m * big_a * (sigma - delta_sigma);
            return s.is_finite().then_some(s);
        }
    }
    None
}

fn great_circle_m(from: Geodetic, to: Geodetic) -> f64 {
    let (p1, p2) = (from.lat_deg.to_radians(), to.lat_deg.to_radians());
    let dp = p2 - p1;
    let dl = (to.lon_deg - from.lon_deg).to_radians();
    let h = (dp / 2.0).sin().powi(2) + p1.cos() * p2.cos() * (dl / 2.0).sin().powi(2);
    2.0 * MEAN_RADIUS_M * h.clamp(0.0, 1.0).sqrt().asin()
}

/// Rotation taking ECEF offsets into the ENU frame tangent at `g`.
fn ecef_to_enu_rotation(g: Geodetic) -> Matrix3<f64> {
    let (lat, lon) = (g.lat_deg.to_radians(), g.lon_deg.to_radians());
    let (sl, cl) = lat.sin_cos();
    let (so, co) = lon.sin_cos();
    Matrix3::new(-so, co, 0.0, -sl * co, -sl * so, cl, cl * co, cl * so, sl)
}

impl Origin {
    /// The origin itself as a geodetic point (home lat/lon, AMSL altitude of the hover point).
    pub fn geodetic(&self) -> Geodetic {
        Geodetic {
            alt_m: self.home.alt_m + self.height_above_home_m,
            ..self.home
        }
    }

    /// Geodetic position (altitude AMSL) of a point given in the origin's ENU frame.
    pub fn to_geodetic(&self, p: Enu) -> Geodetic {
        let o = self.geodetic();
        let offset =
            ecef_to_enu_rotation(o).transpose() * Vector3::new(p.x_east_m, p.y_north_m, p.z_up_m);
        from_ecef(to_ecef(o) + offset)
    }

    /// Position in the origin's ENU frame of a geodetic point (altitude AMSL).
    pub fn to_enu(&self, g: Geodetic) -> Enu {
        let o = self.geodetic();
        let v = ecef_to_enu_rotation(o) * (to_ecef(g) - to_ecef(o));
        Enu {
            x_east_m: v.x,
            y_north_m: v.y,
            z_up_m: v.z,
        }
    }

    /// Altitude above home (what MAVLink's relative-altitude frame carries) of an ENU point.
    pub fn height_above_home_m(&self, p: Enu) -> f64 {
        self.to_geodetic(p).alt_m - self.home.alt_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn davis() -> Origin {
        Origin {
            home: Geodetic {
                lat_deg: 38.5382,
                lon_deg: -121.7617,
                alt_m: 16.0,
            },
            height_above_home_m: 30.0,
        }
    }

    #[test]
    fn enu_round_trips_through_geodetic_to_a_tenth_of_a_millimetre_over_kilometres() {
        let o = davis();
        for &(x, y, z) in &[
            (0.0, 0.0, 0.0),
            (-20.0, 20.0, 19.0),
            (3000.0, -2500.0, 120.0),
            (-5000.0, 5000.0, -25.0),
        ] {
            let p = Enu {
                x_east_m: x,
                y_north_m: y,
                z_up_m: z,
            };
            let back = o.to_enu(o.to_geodetic(p));
            assert!((back.x_east_m - x).abs() < 1e-4, "{back:?}");
            assert!((back.y_north_m - y).abs() < 1e-4, "{back:?}");
            assert!((back.z_up_m - z).abs() < 1e-4, "{back:?}");
        }
    }

    #[test]
    fn one_kilometre_north_is_about_nine_thousandths_of_a_degree_and_drops_below_the_horizon() {
        let o = davis();
        let g = o.to_geodetic(Enu {
            x_east_m: 0.0,
            y_north_m: 1000.0,
            z_up_m: 0.0,
        });
        // Meridional radius M = a(1-e^2)/(1-e^2 sin^2 lat)^1.5 = 6.36024e6 m at 38.54 deg, so
        // 1000 m north is 1000/M rad = 0.0090084 deg (hand-computed).
        assert!(
            (g.lat_deg - o.home.lat_deg - 0.0090084).abs() < 2e-7,
            "{g:?}"
        );
        // Earth curvature: a tangent-plane point 1 km away is d^2 / 2R = 7.8 cm above the
        // ellipsoid through the origin.
        let rise = g.alt_m - o.geodetic().alt_m;
        assert!((rise - 0.0786).abs() < 0.002, "rise {rise}");
    }

    fn at(lat_deg: f64, lon_deg: f64) -> Geodetic {
        Geodetic {
            lat_deg,
            lon_deg,
            alt_m: 0.0,
        }
    }

    #[test]
    fn the_geodesic_distance_meets_published_lengths() {
        // Flinders Peak to Buninyong, Vincenty's method as Geoscience Australia publishes it
        // (Geodetic Calculations, "Vincenty's Inverse formulae" worked example): 54 972.271 m.
        let flinders = at(
            -(37.0 + 57.0 / 60.0 + 3.72030 / 3600.0),
            144.0 + 25.0 / 60.0 + 29.52440 / 3600.0,
        );
        let buninyong = at(
            -(37.0 + 39.0 / 60.0 + 10.15610 / 3600.0),
            143.0 + 55.0 / 60.0 + 35.38390 / 3600.0,
        );
        let d = geodesic_distance_m(flinders, buninyong);
        assert!((d - 54_972.271).abs() < 0.001, "{d}");
        // A quarter of the equator is a pi / 2; a quarter meridian, the meridian quadrant of
        // WGS84, 10 001 965.729 m (NIMA TR8350.2).
        let d = geodesic_distance_m(at(0.0, 0.0), at(0.0, 90.0));
        assert!((d - A_M * std::f64::consts::FRAC_PI_2).abs() < 1e-3, "{d}");
        let d = geodesic_distance_m(at(0.0, 17.0), at(90.0, 17.0));
        assert!((d - 10_001_965.729).abs() < 0.01, "{d}");
        assert_eq!(geodesic_distance_m(at(12.0, 34.0), at(12.0, 34.0)), 0.0);
        // Antipodes: Vincenty does not converge; the mean sphere's half circumference.
        let d = geodesic_distance_m(at(0.0, 0.0), at(0.0, 180.0));
        assert!(
            d.is_finite() && (d / 20_003_931.0 - 1.0).abs() < 0.005,
            "{d}"
        );
        let d = geodesic_distance_m(at(0.5, 0.0), at(-0.5, 179.7));
        assert!(
            d.is_finite() && (d / 20_003_931.0 - 1.0).abs() < 0.005,
            "{d}"
        );
    }

    #[test]
    fn ecef_of_the_equator_at_greenwich_is_the_semi_major_axis() {
        let p = to_ecef(Geodetic {
            lat_deg: 0.0,
            lon_deg: 0.0,
            alt_m: 0.0,
        });
        assert!((p.x - A_M).abs() < 1e-6 && p.y.abs() < 1e-6 && p.z.abs() < 1e-6);
        let pole = from_ecef(to_ecef(Geodetic {
            lat_deg: 90.0,
            lon_deg: 0.0,
            alt_m: 100.0,
        }));
        assert!((pole.lat_deg - 90.0).abs() < 1e-9 && (pole.alt_m - 100.0).abs() < 1e-6);
    }
}
