//! Criterion bench of ordering points and blocks together (`tour::clusters::solve` with the
//! default options, as the planner runs it): 40 points and 8 two-way survey blocks in a
//! 100 m field, every leg priced with the shipped S1000 energy table (the vehicle's default
//! profile; climbs dearer than descents), each block a lawnmower of 4 to 6 lines on a sloping
//! field whose inner cost is its legs in the flown direction. Run with `cargo bench --bench
//! blocks`; it prints the solver, gap and time of one solve first.

use std::path::Path;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::mission::Enu;
use emplan::physics::{EnergyTable, Vehicle};
use emplan::rng::Rng;
use emplan::tour::clusters::{self, Stop, Way};
use emplan::tour::energy::energy_matrix;
use emplan::tour::{solver, CostMatrix, Geometry};

/// The energy matrix (J) of the origin, `points` random points and `blocks` survey blocks,
/// with the stops (points first, then the blocks, forward and reversed).
fn points_and_blocks(points: usize, blocks: usize, seed: u64) -> (CostMatrix, Vec<Stop>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let vehicle = Vehicle::load(&dir).expect("shipped vehicle");
    let table = EnergyTable::load(&dir, vehicle.default_profile(), &vehicle).expect("table");
    let mut rng = Rng::new(seed);
    let enu = |x_east_m, y_north_m, z_up_m| Enu {
        x_east_m,
        y_north_m,
        z_up_m,
    };
    let mut nodes = vec![enu(0.0, 0.0, 0.0)];
    for _ in 0..points {
        nodes.push(enu(
            rng.uniform(-50.0, 50.0),
            rng.uniform(-50.0, 50.0),
            rng.uniform(10.0, 40.0),
        ));
    }
    let mut runs = Vec::new();
    for _ in 0..blocks {
        // A rectangle of `lines` lines `length_m` long, 6 m apart, its altitude rising along
        // the lines (a survey over a slope at constant height above ground).
        let lines = 4 + rng.below(3);
        let length_m = rng.uniform(15.0, 30.0);
        let (x0, y0) = (
            rng.uniform(-45.0, 45.0 - length_m),
            rng.uniform(-45.0, 15.0),
        );
        let (base_m, slope) = (rng.uniform(15.0, 30.0), rng.uniform(0.1, 0.5));
        let first = nodes.len();
        for line in 0..lines {
            let y = y0 + 6.0 * line as f64;
            let ends = [x0, x0 + length_m];
            let ends = if line % 2 == 0 {
                ends
            } else {
                [ends[1], ends[0]]
            };
            for x in ends {
                nodes.push(enu(x, y, base_m + slope * (x - x0)));
            }
        }
        runs.push(first..nodes.len());
    }
    let m = energy_matrix(&Geometry::from_points(nodes), &[], |x, z| {
        table.lookup(x, z).map(|leg| leg.total_energy_j())
    })
    .expect("every leg inside the table");
    let inner = |path: Vec<usize>| path.windows(2).map(|w| m.cost(w[0], w[1])).sum::<f64>();
    let mut stops: Vec<Stop> = (1..=points).map(Stop::point).collect();
    for run in runs {
        let (a, b) = (run.start, run.end - 1);
        stops.push(Stop {
            ways: vec![
                Way {
                    entry: a,
                    exit: b,
                    inner: inner(run.clone().collect()),
                },
                Way {
                    entry: b,
                    exit: a,
                    inner: inner(run.rev().collect()),
                },
            ],
        });
    }
    (m, stops)
}

fn blocks_bench(c: &mut Criterion) {
    let (m, stops) = points_and_blocks(40, 8, 1);
    let options = solver::Options::default();
    let started = Instant::now();
    let once = clusters::solve(&m, &stops, &options).expect("solved");
    println!(
        "40 points + 8 blocks: {} in {:.3} s, cost {:.0} J, bound {:.0} J, gap {:.4}%, optimal {}",
        once.solver,
        started.elapsed().as_secs_f64(),
        once.cost,
        once.lower_bound,
        once.gap_pct,
        once.optimal
    );
    let heuristic = solver::Options {
        solver: solver::Solver::Heuristic,
        ..options
    };
    let started = Instant::now();
    let alone = clusters::solve(&m, &stops, &heuristic).expect("solved");
    println!(
        "the heuristic alone: {:.3} s, cost {:.0} J ({:+.4}% of the optimum), bound {:.0} J, gap {:.4}%",
        started.elapsed().as_secs_f64(),
        alone.cost,
        100.0 * (alone.cost - once.cost) / once.cost,
        alone.lower_bound,
        alone.gap_pct
    );
    let mut group = c.benchmark_group("blocks");
    group.sample_size(10);
    group.bench_function("40_points_8_blocks", |b| {
        b.iter(|| clusters::solve(&m, &stops, &options).expect("solved"))
    });
    group.finish();
}

criterion_group!(benches, blocks_bench);
criterion_main!(benches);
