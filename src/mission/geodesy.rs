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
