//! The tour solvers against independent answers: Held-Karp against branch-and-cut on random
//! energy-priced missions, every TSPLIB instance up to ftv170 proven at its published optimum,
//! rbg323 within 1% with a lower bound, and `plan` beyond Held-Karp's size through the binary.

use std::path::Path;
use std::time::Duration;

use emplan::physics::{EnergyTable, Vehicle};
use emplan::planner::study::{mission_geometry, StudySettings};
use emplan::tour::energy::energy_matrix;
use emplan::tour::{held_karp, solver, tsplib, CostMatrix};

fn energy_mission(waypoints: usize, seed: u64) -> CostMatrix {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let vehicle = Vehicle::load(&dir).unwrap();
    let table = EnergyTable::load(&dir, vehicle.default_profile(), &vehicle).unwrap();
    let settings = StudySettings {
        waypoints,
        xy_m: 30.0,
        z_m: 25.0,
        missions: 1,
        seed,
    };
    let g = mission_geometry(&settings, 0);
    energy_matrix(&g, &[], |x, z| {
        table.lookup(x, z).map(|leg| leg.total_energy_j())
    })
    .expect("every leg inside the table")
}

fn options(solver: solver::Solver) -> solver::Options {
    solver::Options {
        solver,
        time_limit: Duration::from_secs(120),
        ..Default::default()
    }
}

#[test]
fn held_karp_and_branch_and_cut_agree_on_random_energy_missions_of_up_to_fifteen_waypoints() {
    for waypoints in 4..=15 {
        for seed in 1..=3 {
            let m = energy_mission(waypoints, seed);
            let hk = held_karp::solve(&m).unwrap();
            let bc = solver::solve(&m, &options(solver::Solver::BranchCut)).unwrap();
            assert!(bc.tour.optimal, "N={waypoints} seed={seed}");
            assert!(
                (bc.tour.cost - hk.cost).abs() <= 1e-7 * hk.cost,
                "N={waypoints} seed={seed}: branch-and-cut {} vs Held-Karp {}",
                bc.tour.cost,
                hk.cost
            );
            assert!((m.tour_cost(&bc.tour.order) - bc.tour.cost).abs() < 1e-9 * hk.cost);
        }
    }
}

fn tsplib_instance(name: &str) -> tsplib::Instance {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tests/fixtures/tsplib/{name}.atsp"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    tsplib::parse(&text).unwrap()
}

#[test]
fn every_tsplib_instance_up_to_ftv170_is_proven_optimal_at_its_published_optimum() {
    // TSPLIB95's published optima.
    let optima = [
        ("br17", 39.0),
        ("ftv33", 1286.0),
        ("ftv35", 1473.0),
        ("ftv38", 1530.0),
        ("p43", 5620.0),
        ("ftv44", 1613.0),
        ("ftv47", 1776.0),
        ("ry48p", 14422.0),
        ("ft53", 6905.0),
        ("ftv55", 1608.0),
        ("ftv64", 1839.0),
        ("ft70", 38673.0),
        ("ftv70", 1950.0),
        ("kro124p", 36230.0),
        ("ftv170", 2755.0),
    ];
    for (name, optimum) in optima {
        let inst = tsplib_instance(name);
        let solved = solver::solve(&inst.matrix, &options(solver::Solver::Auto)).unwrap();
        assert!(solved.tour.optimal, "{name} not proven: {solved:?}");
        assert_eq!(solved.tour.cost, optimum, "{name}");
        assert_eq!(solved.tour.lower_bound, optimum, "{name}");
        assert_eq!(inst.matrix.tour_cost(&solved.tour.order), optimum, "{name}");
    }
}

#[test]
fn rbg323_is_solved_within_one_percent_with_a_lower_bound() {
    let inst = tsplib_instance("rbg323");
    let solved = solver::solve(&inst.matrix, &options(solver::Solver::Auto)).unwrap();
    assert!(solved.tour.cost <= 1326.0 * 1.01, "{}", solved.tour.cost);
    assert!(solved.tour.lower_bound <= 1326.0);
    assert!(solved.tour.lower_bound >= 1326.0 * 0.99);
}

#[test]
fn plan_orders_a_forty_waypoint_mission_beyond_held_karp_and_proves_it() {
    let dir = tempfile::tempdir().unwrap();
    let m = crate::generated_mission(dir.path(), 40, 40, 20, 3);
    let m = m.as_str();
    // The ptf profile: a leg's price does not depend on the leg before (px4's pair costs are
    // proven only up to the pair dynamic programme's size).
    let plan = crate::json(&["plan", m, "--json", "--profile", "ptf"]);
    let energy = &plan["orders"][0];
    assert_eq!(energy["objective"], "energy");
    assert_eq!(energy["sequence"].as_array().unwrap().len(), 40);
    assert_eq!(energy["proof"]["solver"], "branch-cut");
    assert_eq!(energy["proof"]["optimal"], true);
    let best = energy["energy_kj"].as_f64().unwrap();
    for o in plan["orders"].as_array().unwrap() {
        assert!(o["energy_kj"].as_f64().unwrap() >= best - 1e-9, "{o}");
    }
}
