//! The energy cost matrix of a mission: the energy of every ordered leg from a leg-energy
//! function (in practice the vehicle's energy table), asymmetric because climbing costs more
//! than descending. A leg the function cannot price is an error naming the leg. Stops between
//! rows when the thread's [`super::cancel`] token asks.

use super::{CostMatrix, Geometry, PlanError};

/// Energy of every ordered leg (joules); `leg_energy(xf_m, zf_m)` prices one leg, `names[k]`
/// names node `k` for errors.
pub fn energy_matrix<E: std::fmt::Display>(
    geometry: &Geometry,
    names: &[String],
    leg_energy: impl Fn(f64, f64) -> Result<f64, E>,
) -> Result<CostMatrix, PlanError> {
    let n = geometry.len();
    let mut costs = vec![0.0; n * n];
    for i in 0..n {
        // A row of a 2000-waypoint mission prices 2000 legs: a few ms, a prompt stop.
        super::cancel::check()?;
        for j in 0..n {
            if i == j {
                continue;
            }
            let (xf_m, zf_m) = (geometry.horizontal_m(i, j), geometry.vertical_m(i, j));
            let energy = leg_energy(xf_m, zf_m).map_err(|e| PlanError::LegEnergy {
                from: names.get(i).cloned().unwrap_or_else(|| i.to_string()),
                to: names.get(j).cloned().unwrap_or_else(|| j.to_string()),
                xf_m,
                zf_m,
                reason: e.to_string(),
            })?;
            costs[i * n + j] = energy;
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
