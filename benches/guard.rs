//! Criterion bench of one energy-guard update (`flightlog::watch::Watch::update`) on a
//! 50-waypoint mission halfway flown: the correction learned again from the 75 parts flown
//! (a part has just completed), the projection of the rest and the way home from every point
//! still ahead, the verdict and the return decision. The flight's 900 s of battery samples at
//! 10 Hz are integrated once, before timing. Target: under 1 ms. Run with
//! `cargo bench --bench guard`.

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::flightlog::energy::{EnergyConfig, PowerSeries};
use emplan::flightlog::flight_plan::{FlightPlan, PlannedPoint, Predicted, PredictedLeg};
use emplan::flightlog::samples::PowerSample;
use emplan::flightlog::segment::{Segment, SegmentKind};
use emplan::flightlog::telemetry::{Battery, BatterySource};
use emplan::flightlog::watch::{GuardSetup, Policy, Watch};
use emplan::mission::{Enu, Geodetic};

const WAYPOINTS: usize = 50;

fn plan() -> FlightPlan {
    let mut points: Vec<PlannedPoint> = (0..WAYPOINTS)
        .map(|k| PlannedPoint {
            seq: k as u16 + 2,
            name: format!("W{k}"),
            enu: Enu {
                x_east_m: (k as f64 * 37.0) % 150.0 - 75.0,
                y_north_m: (k as f64 * 53.0) % 150.0 - 75.0,
                z_up_m: (k as f64 * 11.0) % 40.0 - 20.0,
            },
            hold_s: 5.0,
            photos: 0,
            via: Vec::new(),
        })
        .collect();
    points.push(PlannedPoint {
        seq: WAYPOINTS as u16 + 2,
        name: "origin".into(),
        enu: Enu::default(),
        hold_s: 0.0,
        photos: 0,
        via: Vec::new(),
    });
    let n = points.len();
    FlightPlan {
        mission: "bench".into(),
        home: Geodetic {
            lat_deg: 38.5362,
            lon_deg: -121.7875,
            alt_m: 16.0,
        },
        origin_height_m: 30.0,
        points,
        takeoff_seq: Some(1),
        land_seq: Some(WAYPOINTS as u16 + 3),
        predicted: Some(Predicted {
            takeoff_j: 9_000.0,
            landing_j: 10_000.0,
            legs: vec![
                PredictedLeg {
                    energy_j: 6_000.0,
                    duration_s: 11.0,
                    settle_energy_j: 1_500.0,
                    settle_duration_s: 3.0,
                };
                n
            ],
            hover_power_w: 530.0,
        }),
        resumes: None,
        wind: None,
        repricings: Vec::new(),
        priced_by: None,
        blocks: Vec::new(),
        pack: None,
        guard: Some(GuardSetup {
            policy: Policy::Rtl,
            usable_j: 720_000.0,
            reserve_pct: 20.0,
            cells: 6,
            capacity_ah: 10.0,
            internal_resistance_ohm: 0.02,
            ocv_soc: vec![0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0],
            ocv_cell_v: vec![
                3.50, 3.69, 3.73, 3.77, 3.80, 3.84, 3.87, 3.95, 4.02, 4.11, 4.20,
            ],
            home_j: (0..n).map(|k| 15_000.0 + 100.0 * k as f64).collect(),
            return_to: Vec::new(),
            return_rule: None,
            via_home_j: Vec::new(),
            start: None,
        }),
    }
}

fn series(seconds: f64) -> PowerSeries {
    let mut series = PowerSeries::new(EnergyConfig::default());
    let mut t = 0.0;
    while t < seconds {
        series.push(PowerSample {
            t_s: t,
            wall_us: 1_750_000_000_000_000 + (t * 1e6) as u64,
            battery: Battery {
                source: BatterySource::BatteryStatus {
                    id: 0,
                    component: 1,
                },
                voltage_v: Some(24.5 - t * 0.002),
                current_a: Some(22.0 + (t * 7.0).sin()),
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            },
            primary: true,
        });
        t += 0.1;
    }
    series
}

fn bench(c: &mut Criterion) {
    let plan = plan();
    let series = series(900.0);
    // Half the waypoints flown: take-off, then leg, settle, hover of each.
    let mut completed = vec![(
        Segment {
            kind: SegmentKind::Takeoff,
            start_s: 0.0,
            end_s: 15.0,
            complete: true,
            missed_radius: false,
            start_state: None,
        },
        Some(9_500.0),
    )];
    let mut t = 15.0;
    for k in 0..WAYPOINTS / 2 {
        for (kind, d, e) in [
            (SegmentKind::Leg(k), 11.0, 6_300.0 + 50.0 * (k % 7) as f64),
            (SegmentKind::Settle(k), 3.0, 1_600.0),
            (SegmentKind::Hover(k), 5.0, 2_700.0),
        ] {
            completed.push((
                Segment {
                    kind,
                    start_s: t,
                    end_s: t + d,
                    complete: true,
                    missed_radius: false,
                    start_state: None,
                },
                Some(e),
            ));
            t += d;
        }
    }
    let mut watch = Watch::new(&plan).expect("a guarded plan");
    let now = t + 4.0;
    watch.update(now, 0.0, &series, &completed[..completed.len() - 1], None);
    let in_progress = Some((SegmentKind::Leg(WAYPOINTS / 2), t));
    let mut flip = false;
    c.bench_function("guard_update_50_waypoints", |b| {
        b.iter(|| {
            // A part completed (or, next time, one less): the correction is learned again.
            flip = !flip;
            let n = completed.len() - usize::from(flip);
            watch.update(now, 0.0, &series, &completed[..n], in_progress)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
