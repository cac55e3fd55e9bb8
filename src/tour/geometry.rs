//! Leg geometry between every ordered pair of mission points: horizontal distance Xf, signed
//! vertical displacement Zf and 3D distance (paper notes section 4). Point 0 is the origin.
//! A pair routed round a fence zone (the planner's detours) flies through its `via` points:
//! its lengths are the whole path's, so every solver and baseline sees the path it flies.

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
    /// The points the leg `(i, j)` passes through on its way round a zone (absent: straight).
    via: std::collections::HashMap<(usize, usize), Vec<Enu>>,
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
        Geometry {
            points,
            via: std::collections::HashMap::new(),
        }
    }

    /// The same points with the legs `(i, j)` of `via` flown through its points (in order,
    /// from `i` to `j`): their lengths become the path's.
    pub fn with_via(self, via: std::collections::HashMap<(usize, usize), Vec<Enu>>) -> Self {
        Geometry { via, ..self }
    }

    /// The points leg `i` -> `j` passes through (empty: it flies straight).
    pub fn via(&self, i: usize, j: usize) -> &[Enu] {
        if self.via.is_empty() {
            return &[];
        }
        self.via.get(&(i, j)).map_or(&[], Vec::as_slice)
    }

    /// The points leg `i` -> `j` flies through, its ends included.
    pub fn path(&self, i: usize, j: usize) -> Vec<Enu> {
        std::iter::once(self.points[i])
            .chain(self.via(i, j).iter().copied())
            .chain(std::iter::once(self.points[j]))
            .collect()
    }

    /// The horizontal direction (east, north; m) leg `i` -> `j` leaves `i` in (towards its
    /// first via point) and arrives at `j` in (from its last one).
    pub fn departure_and_arrival(&self, i: usize, j: usize) -> ((f64, f64), (f64, f64)) {
        let (a, b) = (self.points[i], self.points[j]);
        let via = self.via(i, j);
        let first = via.first().copied().unwrap_or(b);
        let last = via.last().copied().unwrap_or(a);
        (
            (first.x_east_m - a.x_east_m, first.y_north_m - a.y_north_m),
            (b.x_east_m - last.x_east_m, b.y_north_m - last.y_north_m),
        )
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

    /// Horizontal distance Xf from point `i` to point `j` (along its via points, if any).
    pub fn horizontal_m(&self, i: usize, j: usize) -> f64 {
        if !self.via(i, j).is_empty() {
            return self
                .path(i, j)
                .windows(2)
                .map(|w| (w[1].x_east_m - w[0].x_east_m).hypot(w[1].y_north_m - w[0].y_north_m))
                .sum();
        }
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

    /// 3D distance from point `i` to point `j`: straight, or along its via points.
    pub fn distance_m(&self, i: usize, j: usize) -> f64 {
        if !self.via(i, j).is_empty() {
            return self
                .path(i, j)
                .windows(2)
                .map(|w| {
                    (w[1].x_east_m - w[0].x_east_m)
                        .hypot(w[1].y_north_m - w[0].y_north_m)
                        .hypot(w[1].z_up_m - w[0].z_up_m)
                })
                .sum();
        }
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
