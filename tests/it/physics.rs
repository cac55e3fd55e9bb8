//! The energy model against the paper through the CLI, and the committed energy tables against
//! direct simulation: off-grid interpolation error, reproducibility, freshness.

use std::path::{Path, PathBuf};
use std::process::Command;

use emplan::physics::{simulate_operation, EnergyTable, Profile, Vehicle};

fn vehicle_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000")
}

/// `emplan energy --json` of one leg (run in the repository), its profile and Xf checked.
fn energy_doc(xf: f64, zf: f64, profile: &str) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args([
            "energy",
            "--xf",
            &xf.to_string(),
            "--zf",
            &zf.to_string(),
            "--profile",
            profile,
            "--json",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("emplan runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(doc["profile"], profile);
    assert_eq!(doc["xf_m"].as_f64(), Some(xf));
    doc
}

/// A leg's energy to the 4 m rule (kJ).
fn energy_kj(xf: f64, zf: f64, profile: &str) -> f64 {
    energy_doc(xf, zf, profile)["energy_kj"]
        .as_f64()
        .expect("energy_kj")
}

/// The paper's simulated operation energies, kJ.
const PTF: [(f64, f64, f64); 9] = [
    (40.0, 25.0, 7.04),
    (40.0, 1.0, 4.52),
    (40.0, -1.0, 4.36),
    (40.0, -25.0, 3.19),
    (56.6, 0.0, 5.74),
    (0.0, -24.0, 2.99),
    (50.0, 30.0, 8.2),
    (0.0, 30.0, 7.3),
    (50.0, 0.0, 5.2),
];
const HVB: [(f64, f64, f64); 6] = [
    (40.0, 25.0, 8.10),
    (40.0, 1.0, 5.67),
    (40.0, -1.0, 5.53),
    (40.0, -25.0, 4.77),
    (56.6, 0.0, 6.62),
    (0.0, -24.0, 4.97),
];

#[test]
fn emplan_energy_is_within_five_percent_of_every_ptf_value_and_three_percent_rms() {
    let errors: Vec<f64> = PTF
        .iter()
        .map(|&(x, z, paper)| energy_kj(x, z, "ptf") / paper - 1.0)
        .collect();
    for (e, (x, z, _)) in errors.iter().zip(PTF) {
        assert!(e.abs() <= 0.05, "PTF ({x}, {z}) off by {:.1}%", 100.0 * e);
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    assert!(rms <= 0.03, "PTF rms {:.2}%", 100.0 * rms);
}

#[test]
fn emplan_energy_is_within_five_percent_of_every_hvb_value() {
    for (x, z, paper) in HVB {
        let e = energy_kj(x, z, "hvb") / paper - 1.0;
        assert!(e.abs() <= 0.05, "HVB ({x}, {z}) off by {:.1}%", 100.0 * e);
    }
}

/// `emplan plan MISSION --profile P --pricing paper --json`.
fn paper_plan(mission: &str, profile: &str) -> serde_json::Value {
    let doc = crate::json(&[
        "plan",
        mission,
        "--profile",
        profile,
        "--pricing",
        "paper",
        "--json",
    ]);
    assert_eq!(doc["pricing"], "paper");
    doc
}

/// The energies of `objective`'s orders in `plan`, cheapest first.
fn energies(plan: &serde_json::Value, objective: &str) -> Vec<f64> {
    let mut e: Vec<f64> = plan["orders"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|o| o["objective"] == objective)
        .map(|o| o["energy_kj"].as_f64().unwrap())
        .collect();
    e.sort_by(f64::total_cmp);
    e
}

fn within(model_kj: f64, paper_kj: f64, what: &str) {
    let e = model_kj / paper_kj - 1.0;
    println!(
        "{what}: model {model_kj:.2} kJ, paper {paper_kj} kJ ({:+.1}%)",
        100.0 * e
    );
    assert!(
        e.abs() <= 0.05,
        "{what}: {model_kj:.2} kJ vs the paper's {paper_kj} kJ"
    );
}

#[test]
fn plan_with_the_papers_pricing_gives_the_papers_energies_of_both_sample_missions() {
    // From the paper: sums of the legs' 4 m-rule energies. Where the paper gives one
    // value for a distance tour flown two ways, it is its cheaper direction.
    let one = paper_plan("missions/paper-sample-8wp.toml", "ptf");
    let energy = &one["orders"][0];
    assert_eq!(energy["objective"], "energy");
    within(
        energy["energy_kj"].as_f64().unwrap(),
        35.3,
        "sample 1 min-energy",
    );
    within(energies(&one, "distance")[0], 40.6, "sample 1 min-D");
    within(energies(&one, "horizontal")[0], 45.5, "sample 1 min-X");
    let z = energies(&one, "vertical");
    within(z[0], 37.9, "sample 1 min-Z, cheaper direction");
    within(z[1], 39.4, "sample 1 min-Z, dearer direction");

    let two = paper_plan("missions/paper-sample-3wp.toml", "ptf");
    let energy = &two["orders"][0];
    assert_eq!(energy["sequence"], serde_json::json!(["B", "C", "A"]));
    within(
        energy["energy_kj"].as_f64().unwrap(),
        19.1,
        "sample 2 min-energy",
    );
    let d = energies(&two, "distance");
    within(d[0], 19.7, "sample 2 min-D, cheaper direction");
    within(d[1], 20.1, "sample 2 min-D, dearer direction");
    let climb = energy["legs"]
        .as_array()
        .unwrap()
        .iter()
        .chain(two["orders"][1]["legs"].as_array().unwrap())
        .chain(two["orders"][2]["legs"].as_array().unwrap())
        .find(|l| l["from"] == "origin" && l["to"] == "C")
        .expect("a leg origin -> C");
    within(
        climb["energy_kj"].as_f64().unwrap(),
        6.22,
        "sample 2 vertical climb O-C",
    );

    let hvb = paper_plan("missions/paper-sample-3wp.toml", "hvb");
    within(
        hvb["orders"][0]["energy_kj"].as_f64().unwrap(),
        24.07,
        "sample 2 min-energy (HVB)",
    );
    within(energies(&hvb, "distance")[0], 25.21, "sample 2 min-D (HVB)");
}

#[test]
fn plan_with_the_papers_pricing_finds_the_papers_min_energy_tour_of_sample_mission_1() {
    // The paper's min-energy tour is O-F-G-E-H-B-C-A-D-O (D 299.3, X 271.9, Z 108 m).
    // `calibrate` tries every order: the paper's tour must be the cheapest (gap 0), ahead of
    // every tour of another energy (margin > 0). Tours of the same legs cost the same: the
    // mission is symmetric about the line y = -x (C <-> D, G <-> H), which holds A, B and the
    // origin, so the paper's tour mirrored whole or after B is as cheap.
    let cal = crate::json(&["calibrate", "--json", "--pricing", "paper"]);
    let tour = &cal["missions"]["sample_1_tour"];
    let gap = tour["gap_pct"].as_f64().unwrap();
    let margin = tour["margin_pct"].as_f64().unwrap();
    assert!(
        gap.abs() < 1e-9 && margin > 0.0,
        "the paper's tour is {gap:.3}% dearer than the model's best, {margin:.3}% cheaper than \
         any tour of another energy"
    );
    let plan = paper_plan("missions/paper-sample-8wp.toml", "ptf");
    let energy = &plan["orders"][0];
    let found: String = std::iter::once("O".to_string())
        .chain(
            energy["sequence"]
                .as_array()
                .unwrap()
                .iter()
                .map(|w| w.as_str().unwrap().to_string()),
        )
        .chain(std::iter::once("O".to_string()))
        .collect();
    let best = tour["paper_tour_kj"].as_f64().unwrap();
    // The table (interpolated) and direct simulation agree to well under 0.1% here, and the
    // planned tour is one of the paper's tour's mirror images.
    let planned = energy["energy_kj"].as_f64().unwrap();
    assert!(
        (planned / best - 1.0).abs() < 1e-3,
        "planned {found} {planned} kJ vs the paper's tour {best} kJ"
    );
    // A symmetry of the mission as the letter pairs it swaps.
    let swap = |t: &str, pairs: &[(char, char)]| -> String {
        t.chars()
            .map(|c| {
                pairs
                    .iter()
                    .find_map(|&(a, b)| (c == a).then_some(b).or((c == b).then_some(a)))
                    .unwrap_or(c)
            })
            .collect()
    };
    // The mirror about y = -x, and the central symmetry (x, y) -> (-x, -y).
    let mirror = |t: &str| swap(t, &[('C', 'D'), ('G', 'H')]);
    let reversed_roles = |t: &str| swap(t, &[('A', 'B'), ('C', 'D'), ('E', 'F'), ('G', 'H')]);
    // The paper's tour, and it mirrored after B (B, A and the origin are on the mirror line),
    // each under the four symmetries of the mission.
    let paper = "OFGEHBCADO";
    let twin = format!("OFGEHB{}", mirror("CADO"));
    let mut equal: Vec<String> = Vec::new();
    for t in [paper.to_string(), twin] {
        equal.push(mirror(&t));
        equal.push(reversed_roles(&t));
        equal.push(reversed_roles(&mirror(&t)));
        equal.push(t);
    }
    assert!(
        equal.contains(&found),
        "planned {found}, not the paper's tour or a mirror image of it: {equal:?}"
    );
}

#[test]
fn plan_names_its_pricing_and_the_papers_leaves_out_the_settle_but_not_from_the_battery() {
    let settled = crate::json(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--profile",
        "ptf",
        "--json",
    ]);
    assert_eq!(settled["pricing"], "settled");
    let paper = paper_plan("missions/paper-sample-3wp.toml", "ptf");
    let (s, p) = (&settled["orders"][0], &paper["orders"][0]);
    assert_eq!(s["sequence"], p["sequence"]);
    for (ls, lp) in s["legs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(p["legs"].as_array().unwrap())
    {
        assert!(lp["energy_kj"].as_f64().unwrap() < ls["energy_kj"].as_f64().unwrap());
    }
    // The battery pays everything, whatever the pricing of the orders.
    assert_eq!(settled["battery"], paper["battery"]);
    let (ok, _, stderr) = crate::emplan(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--pricing",
        "paper",
        "--sorties",
    ]);
    assert!(!ok && stderr.contains("settled pricing"), "{stderr}");
}

/// A small deterministic generator (SplitMix64) for reproducible random points.
fn splitmix(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn table_interpolation_is_within_half_a_percent_of_direct_simulation_off_grid() {
    let vehicle = Vehicle::load(&vehicle_dir()).unwrap();
    let mut state = 2024;
    for profile in Profile::ALL {
        let table = EnergyTable::load(&vehicle_dir(), profile, &vehicle).unwrap();
        let (mut worst_total, mut worst_rule, mut sum, mut n) = (0.0f64, 0.0f64, 0.0, 0);
        for _ in 0..250 {
            // Off-grid by construction: fractional parts avoid 0.
            let x = 150.0 * splitmix(&mut state);
            let z = -60.0 + 120.0 * splitmix(&mut state);
            if x.fract() == 0.0 || z.fract() == 0.0 || x.hypot(z) < 10.0 {
                continue;
            }
            let direct = simulate_operation(&vehicle, profile, x, z).unwrap();
            let looked = table.lookup(x, z).unwrap();
            let total = (looked.total_energy_j() / direct.total_energy_j() - 1.0).abs();
            let rule = (looked.energy_j / direct.energy_j - 1.0).abs();
            worst_total = worst_total.max(total);
            worst_rule = worst_rule.max(rule);
            sum += total;
            n += 1;
        }
        assert!(n >= 200, "only {n} points");
        println!(
            "{profile}: {n} random off-grid legs: total energy worst {:.3}% mean {:.4}%, 4 m rule energy worst {:.3}%",
            100.0 * worst_total,
            100.0 * sum / n as f64,
            100.0 * worst_rule
        );
        assert!(worst_total < 0.005, "{profile}: {worst_total}");
        assert!(worst_rule < 0.005, "{profile}: {worst_rule}");
    }
}

#[test]
fn the_committed_tables_are_fresh_and_reproducible_cell_by_cell() {
    let vehicle = Vehicle::load(&vehicle_dir()).unwrap();
    for profile in Profile::ALL {
        let table =
            EnergyTable::load(&vehicle_dir(), profile, &vehicle).unwrap_or_else(|e| panic!("{e}"));
        for (i, j) in [(0, 0), (40, 170), (40, 70), (57, 121), (150, 240), (13, 7)] {
            let cell = table.cell(i, j).unwrap();
            let (x, z) = (i as f64, -60.0 + 0.5 * j as f64);
            let op = simulate_operation(&vehicle, profile, x, z).unwrap();
            assert!(
                (cell.energy_j - op.energy_j).abs() < 2e-3,
                "{profile} ({x},{z}): {} vs {}",
                cell.energy_j,
                op.energy_j
            );
            assert!((cell.settle_energy_j - op.settle_energy_j).abs() < 2e-3);
            assert!((cell.duration_s - op.duration_s).abs() < 2e-4);
        }
    }
}

/// `emplan energy --json` of one leg, start to settled hover (kJ).
fn total_energy_kj(xf: f64, zf: f64, profile: &str) -> f64 {
    let doc = energy_doc(xf, zf, profile);
    doc["energy_kj"].as_f64().expect("energy_kj")
        + doc["settle_energy_kj"].as_f64().expect("settle")
}

#[test]
fn a_mission_with_legs_beyond_the_table_plans_each_long_leg_priced_as_direct_simulation() {
    // missions/long-survey.toml: 800 m survey lines and a 90 m climb, beyond the table.
    for profile in ["px4", "hvb"] {
        let doc = crate::json(&[
            "plan",
            "missions/long-survey.toml",
            "--profile",
            profile,
            "--json",
        ]);
        let energy = &doc["orders"][0];
        assert_eq!(energy["objective"], "energy");
        let legs = energy["legs"].as_array().unwrap();
        let mut beyond = 0;
        for leg in legs {
            let (x, z) = (
                leg["horizontal_m"].as_f64().unwrap(),
                leg["vertical_m"].as_f64().unwrap(),
            );
            if x <= 150.0 && z.abs() <= 60.0 {
                continue;
            }
            beyond += 1;
            let planned = leg["energy_kj"].as_f64().unwrap();
            let direct = total_energy_kj(x, z, profile);
            let err = (planned - direct) / direct;
            eprintln!("{profile} ({x:.1}, {z:.1}): planned {planned:.3} kJ, direct {direct:.3} kJ, {:+.3}%", 100.0 * err);
            // FIXME: `emplan energy` simulates a px4 leg starting behind PX4's trajectory; a
            // leg after a turn of less than 90 degrees starts ahead and costs less, and is only
            // checked to do so here.
            if profile == "px4" && err < -0.005 {
                assert!(err > -0.1, "{profile} ({x}, {z}): {planned} vs {direct} kJ");
                continue;
            }
            assert!(
                err.abs() < 0.005,
                "{profile} ({x}, {z}): {planned} vs {direct} kJ"
            );
        }
        assert!(beyond >= 3, "{profile}: {beyond} legs beyond the table");
    }
    // The ptf quintic never cruises: its long legs are simulated directly, so they are the
    // `energy` command's numbers exactly.
    let doc = crate::json(&[
        "plan",
        "missions/long-survey.toml",
        "--profile",
        "ptf",
        "--json",
    ]);
    let legs = doc["orders"][0]["legs"].as_array().unwrap();
    let long: Vec<_> = legs
        .iter()
        .filter(|l| l["horizontal_m"].as_f64().unwrap() > 150.0)
        .collect();
    assert!(long.len() >= 3, "{} ptf legs beyond the table", long.len());
    for leg in long {
        let (x, z) = (
            leg["horizontal_m"].as_f64().unwrap(),
            leg["vertical_m"].as_f64().unwrap(),
        );
        let planned = leg["energy_kj"].as_f64().unwrap();
        let direct = total_energy_kj(x, z, "ptf");
        assert!(
            (planned - direct).abs() < 1e-4 * direct,
            "ptf ({x}, {z}): {planned} vs {direct} kJ"
        );
    }
}

#[test]
fn long_legs_composed_from_the_committed_tables_match_direct_simulation() {
    // Run with `-- --nocapture` to see each leg: composed price, direct simulation, error.
    use emplan::physics::{VehicleModel, VehicleSource};
    let legs = [
        (300.0, 0.0),
        (800.0, 0.0),
        (300.0, 45.0),
        (800.0, 100.0),
        (300.0, -45.0),
        (800.0, -100.0),
        (0.0, 120.0),
        (0.0, -120.0),
        (151.0, 0.0),
        (800.0, 5.0),
        (150.2, 60.3),
        (1000.0, -119.0),
    ];
    for profile in [Profile::Hvb, Profile::Px4] {
        let model = VehicleModel::open(&VehicleSource::BuiltIn, Some(profile)).unwrap();
        let mut worst: f64 = 0.0;
        for (x, z) in legs {
            let started = std::time::Instant::now();
            let composed = model.leg(x, z).unwrap();
            let took = started.elapsed();
            let started = std::time::Instant::now();
            let direct = simulate_operation(&model.vehicle, profile, x, z).unwrap();
            let took_direct = started.elapsed();
            let err =
                (composed.total_energy_j() - direct.total_energy_j()) / direct.total_energy_j();
            let err_4m = (composed.energy_j - direct.energy_j) / direct.energy_j;
            let dt = composed.total_duration_s() - direct.total_duration_s();
            eprintln!(
                "{profile} ({x}, {z}): composed {:.3} kJ, direct {:.3} kJ, {:+.3}% \
                 (4 m rule {:+.3}%), duration {dt:+.2} s, composed in {:.1} ms, simulated in \
                 {:.1} ms",
                composed.total_energy_j() / 1000.0,
                direct.total_energy_j() / 1000.0,
                100.0 * err,
                100.0 * err_4m,
                took.as_secs_f64() * 1000.0,
                took_direct.as_secs_f64() * 1000.0
            );
            worst = worst.max(err.abs()).max(err_4m.abs());
            assert!(
                dt.abs() < 0.5,
                "{profile} ({x}, {z}): duration off by {dt} s"
            );
        }
        eprintln!("{profile}: worst |error| {:.3}%", 100.0 * worst);
        assert!(worst < 0.001, "{profile}: worst {worst}");
    }
}

#[test]
fn a_leg_longer_than_the_vehicles_max_leg_m_is_refused_as_an_operating_limit_not_for_lack_of_table()
{
    // Priced (composed beyond the table) but longer than planning.max_leg_m = 1000 m.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("far.toml");
    std::fs::write(
        &file,
        "name = \"far\"\n[origin]\nlat_deg = 38.5\nlon_deg = -121.8\nhome_alt_amsl_m = 10.0\n\
         height_above_home_m = 20.0\n\
         [[waypoints]]\nname = \"near\"\nx_m = 400.0\ny_m = 0.0\nz_m = 0.0\n\
         [[waypoints]]\nname = \"far\"\nx_m = 1100.0\ny_m = 0.0\nz_m = 0.0\n",
    )
    .unwrap();
    let file = file.to_str().unwrap();
    let (ok, _, stderr) = crate::emplan(&["plan", file, "--json"]);
    assert!(!ok);
    assert!(
        stderr.contains("planning.max_leg_m = 1000 m") && stderr.contains("1100 m long"),
        "{stderr}"
    );
    assert!(!stderr.contains("energy table"), "{stderr}");
}
