//! Leg geometry between every ordered pair of mission points: horizontal distance Xf, signed
//! vertical displacement Zf and 3D distance (paper notes section 4). Point 0 is the origin.

use crate::mission::{Enu, Mission};

use super::CostMatrix;

/// Lengths of a closed tour origin -> nodes -> origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TourLength {
    /// 3D distance.
    pub distance_m: f64,
    pub horizontal_m: f64,
    /// Total absolute vertical distance.
    pub vertical_m: f64,
}

/// The points of a tour in the origin's ENU frame: index 0 is the origin, index `k + 1` is
/// waypoint `k` of the mission.
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    points: Vec<Enu>,
}

impl Geometry {
    /// The origin followed by the mission's waypoints, in file order.
    pub fn from_mission(mission: &Mission) -> Self {
        Self::from_points(
            std::iter::once(Enu::default())
                .chain(mission.waypoints.iter().map(|w| w.position))
                .collect(),
        )
    }

    /// Geometry of explicit points; `points[0]` must be the origin.
    pub fn from_points(points: Vec<Enu>) -> Self {
        Geometry { points }
    }

    /// Number of points, the origin included.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are no points at all.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points, origin first.
    pub fn points(&self) -> &[Enu] {
        &self.points
    }

    /// Horizontal distance Xf from point `i` to point `j`.
    pub fn horizontal_m(&self, i: usize, j: usize) -> f64 {
        let (a, b) = (self.points[i], self.points[j]);
        (b.x_east_m - a.x_east_m).hypot(b.y_north_m - a.y_north_m)
    }

    /// Signed vertical displacement Zf from point `i` to point `j` (positive = climb).
    pub fn vertical_m(&self, i: usize, j: usize) -> f64 {
        self.points[j].z_up_m - self.points[i].z_up_m
    }

    /// The heading from point `i` to point `j`: degrees clockwise from north, in [0, 360); 0 for
    /// a vertical move ([`crate::mission::wind::heading_deg`]).
    pub fn heading_deg(&self, i: usize, j: usize) -> f64 {
        let (a, b) = (self.points[i], self.points[j]);
        crate::mission::wind::heading_deg(b.x_east_m - a.x_east_m, b.y_north_m - a.y_north_m)
    }

    /// Straight-line 3D distance from point `i` to point `j`.
    pub fn distance_m(&self, i: usize, j: usize) -> f64 {
        self.horizontal_m(i, j).hypot(self.vertical_m(i, j))
    }

    /// The lengths of the closed tour 0 -> `nodes` -> 0, summed leg by leg in flying order.
    pub fn tour_length(&self, nodes: &[usize]) -> TourLength {
        let stops: Vec<usize> = std::iter::once(0)
            .chain(nodes.iter().copied())
            .chain(std::iter::once(0))
            .collect();
        let legs = || stops.windows(2).map(|w| (w[0], w[1]));
        TourLength {
            distance_m: legs().map(|(i, j)| self.distance_m(i, j)).sum(),
            horizontal_m: legs().map(|(i, j)| self.horizontal_m(i, j)).sum(),
            vertical_m: legs().map(|(i, j)| self.vertical_m(i, j).abs()).sum(),
        }
    }

    /// 3D distance matrix.
    pub fn distance_matrix(&self) -> CostMatrix {
        CostMatrix::from_fn(self.len(), |i, j| self.distance_m(i, j))
    }

    /// Horizontal distance matrix.
    pub fn horizontal_matrix(&self) -> CostMatrix {
        CostMatrix::from_fn(self.len(), |i, j| self.horizontal_m(i, j))
    }

    /// Absolute vertical distance matrix.
    pub fn vertical_matrix(&self) -> CostMatrix {
        CostMatrix::from_fn(self.len(), |i, j| self.vertical_m(i, j).abs())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Enu {
        Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        }
    }

    #[test]
    fn a_three_four_twelve_leg_has_horizontal_five_vertical_twelve_and_length_thirteen() {
        let g = Geometry::from_points(vec![p(0.0, 0.0, 0.0), p(3.0, 4.0, 12.0)]);
        assert_eq!(g.horizontal_m(0, 1), 5.0);
        assert_eq!(g.vertical_m(0, 1), 12.0);
        assert_eq!(g.vertical_m(1, 0), -12.0);
        assert_eq!(g.distance_m(1, 0), 13.0);
        assert_eq!(g.vertical_matrix().cost(1, 0), 12.0);
    }
}
