//! The energy cost matrix of a mission: the energy of every ordered leg from a leg-energy
//! function (in practice the vehicle's energy table, or a simulation in wind), asymmetric
//! because climbing costs more than descending (and, in wind, flying upwind more than
//! downwind). A leg the function cannot price is an error naming the leg. Rows are priced in
//! parallel, a block at a time; between blocks the planning thread's [`super::cancel`] token
//! is looked at.

use rayon::prelude::*;

use super::{CostMatrix, Geometry, PlanError};

/// Rows priced between two looks at the cancel token: a block of a 2000-waypoint mission
/// looked up in a table is a few ms; of a 100-waypoint one simulated in wind, about a second.
const ROWS_A_BLOCK: usize = 8;

/// Energy of every ordered leg (joules); `leg_energy(xf_m, zf_m)` prices one leg, `names[k]`
/// names node `k` for errors.
pub fn energy_matrix<E: std::fmt::Display + Send>(
    geometry: &Geometry,
    names: &[String],
    leg_energy: impl Fn(f64, f64) -> Result<f64, E> + Sync,
) -> Result<CostMatrix, PlanError> {
    energy_matrix_on_headings(geometry, names, |xf_m, zf_m, _| leg_energy(xf_m, zf_m))
}

/// [`energy_matrix`] for legs whose price depends on their direction too:
/// `leg_energy(xf_m, zf_m, heading_deg)`, the heading degrees clockwise from north
/// ([`Geometry::heading_deg`]).
pub fn energy_matrix_on_headings<E: std::fmt::Display + Send>(
    geometry: &Geometry,
    names: &[String],
    leg_energy: impl Fn(f64, f64, f64) -> Result<f64, E> + Sync,
) -> Result<CostMatrix, PlanError> {
    energy_matrix_of_legs(geometry, names, |_, _, x, z, heading| {
        leg_energy(x, z, heading)
    })
}

/// [`energy_matrix_on_headings`] for a leg energy that also depends on which nodes the leg
/// joins (`leg_energy(from, to, xf_m, zf_m, heading_deg)`): a speed or an action at its end.
pub fn energy_matrix_of_legs<E: std::fmt::Display + Send>(
    geometry: &Geometry,
    names: &[String],
    leg_energy: impl Fn(usize, usize, f64, f64, f64) -> Result<f64, E> + Sync,
) -> Result<CostMatrix, PlanError> {
    let n = geometry.len();
    let row = |i: usize| -> Result<Vec<f64>, PlanError> {
        (0..n)
            .map(|j| {
                if i == j {
                    return Ok(0.0);
                }
                let (xf_m, zf_m) = (geometry.horizontal_m(i, j), geometry.vertical_m(i, j));
                leg_energy(i, j, xf_m, zf_m, geometry.heading_deg(i, j)).map_err(|e| {
                    PlanError::LegEnergy {
                        from: names.get(i).cloned().unwrap_or_else(|| i.to_string()),
                        to: names.get(j).cloned().unwrap_or_else(|| j.to_string()),
                        xf_m,
                        zf_m,
                        reason: e.to_string(),
                    }
                })
            })
            .collect()
    };
    let mut costs = Vec::with_capacity(n * n);
    for first in (0..n).step_by(ROWS_A_BLOCK) {
        super::cancel::check()?;
        let rows: Vec<Result<Vec<f64>, PlanError>> = (first..(first + ROWS_A_BLOCK).min(n))
            .into_par_iter()
            .map(row)
            .collect();
        for r in rows {
            costs.extend(r?);
        }
    }
    Ok(CostMatrix::from_fn(n, |i, j| costs[i * n + j]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::Enu;

    #[test]
    fn a_leg_the_model_cannot_price_is_named_in_the_error() {
        let g = Geometry::from_points(vec![
            Enu::default(),
            Enu {
                x_east_m: 10.0,
                y_north_m: 0.0,
                z_up_m: 5.0,
            },
            Enu {
                x_east_m: 500.0,
                y_north_m: 0.0,
                z_up_m: 5.0,
            },
        ]);
        let names: Vec<String> = ["origin", "near", "far"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let err = energy_matrix(&g, &names, |x, _| {
            if x > 150.0 {
                Err("outside the table")
            } else {
                Ok(x)
            }
        })
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "energy of leg origin -> far (Xf 500.00 m, Zf 5.00 m): outside the table"
        );
        let m = energy_matrix(&g, &names, |x, z| Ok::<f64, String>(x + 10.0 * z.max(0.0))).unwrap();
        assert_eq!(m.cost(0, 1), 60.0);
        assert_eq!(m.cost(1, 0), 10.0);
    }
}
