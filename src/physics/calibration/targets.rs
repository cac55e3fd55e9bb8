//! The paper's published energies (docs/energy-model.md): its operation energies, its
//! two sample missions' waypoints and mission-level energies, and the marginal costs its PTF
//! table implies. Data only: what the model is compared with and fitted to.

use serde::Serialize;

use crate::physics::Profile;

/// One published operation energy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Target {
    pub xf_m: f64,
    pub zf_m: f64,
    pub profile: Profile,
    pub energy_kj: f64,
}

const fn target(xf_m: f64, zf_m: f64, profile: Profile, energy_kj: f64) -> Target {
    Target {
        xf_m,
        zf_m,
        profile,
        energy_kj,
    }
}

/// The paper's simulated operation energies for the S1000+ (docs/energy-model.md).
pub const PAPER: [Target; 15] = [
    target(40.0, 25.0, Profile::Ptf, 7.04),
    target(40.0, 1.0, Profile::Ptf, 4.52),
    target(40.0, -1.0, Profile::Ptf, 4.36),
    target(40.0, -25.0, Profile::Ptf, 3.19),
    target(56.6, 0.0, Profile::Ptf, 5.74),
    target(0.0, -24.0, Profile::Ptf, 2.99),
    target(50.0, 30.0, Profile::Ptf, 8.2),
    target(0.0, 30.0, Profile::Ptf, 7.3),
    target(50.0, 0.0, Profile::Ptf, 5.2),
    target(40.0, 25.0, Profile::Hvb, 8.10),
    target(40.0, 1.0, Profile::Hvb, 5.67),
    target(40.0, -1.0, Profile::Hvb, 5.53),
    target(40.0, -25.0, Profile::Hvb, 4.77),
    target(56.6, 0.0, Profile::Hvb, 6.62),
    target(0.0, -24.0, Profile::Hvb, 4.97),
];

/// Waypoints of the paper's sample missions (docs/energy-model.md), (x, y, z) metres from the
/// origin O. Geometry only: the same in every model.
pub const SAMPLE_1: [(char, [f64; 3]); 8] = [
    ('A', [-20.0, 20.0, 19.0]),
    ('B', [20.0, -20.0, 19.0]),
    ('C', [-12.0, -12.0, 11.0]),
    ('D', [12.0, 12.0, 11.0]),
    ('E', [-12.0, 12.0, -11.0]),
    ('F', [12.0, -12.0, -11.0]),
    ('G', [-20.0, -20.0, -19.0]),
    ('H', [20.0, 20.0, -19.0]),
];
/// See [`SAMPLE_1`].
pub const SAMPLE_2: [(char, [f64; 3]); 3] = [
    ('A', [0.0, 40.0, 25.0]),
    ('B', [40.0, 0.0, 25.0]),
    ('C', [0.0, 0.0, 24.0]),
];

/// Which of a target's candidate paths the published value is: the cheaper or the dearer one
/// (a distance tour flown in its two directions, when the paper gives one value or does not
/// say which direction is which).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Rank {
    Cheapest,
    Dearest,
}

/// One published mission-level energy (from the paper): a sum of the legs' 4 m-rule
/// operation energies along a path through a sample mission's waypoints ("O" = the origin).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MissionTarget {
    /// "sample-1" or "sample-2".
    pub mission: &'static str,
    /// What the paper calls it.
    pub label: &'static str,
    pub profile: Profile,
    /// Candidate paths, e.g. "OFGEHBCADO"; the value is the `rank` one of them in the model.
    pub paths: &'static [&'static str],
    pub rank: Rank,
    pub energy_kj: f64,
}

const fn mission_target(
    mission: &'static str,
    label: &'static str,
    profile: Profile,
    paths: &'static [&'static str],
    rank: Rank,
    energy_kj: f64,
) -> MissionTarget {
    MissionTarget {
        mission,
        label,
        profile,
        paths,
        rank,
        energy_kj,
    }
}

/// The three tours of sample mission 2 in both directions (its min-energy order under HVB).
const SAMPLE_2_TOURS: &[&str] = &["OABCO", "OACBO", "OBACO", "OBCAO", "OCABO", "OCBAO"];

/// The paper's mission-level energies for its two sample missions, kJ. The tours of
/// the distance baselines are geometry (`emplan plan` finds them; tests/it/physics.rs checks);
/// where the paper gives one value for a tour flown two ways, it is matched to the cheaper
/// direction, and its two values to the cheaper and the dearer.
pub const PAPER_MISSIONS: [MissionTarget; 11] = [
    mission_target(
        "sample-1",
        "min-energy O-F-G-E-H-B-C-A-D-O",
        Profile::Ptf,
        &["OFGEHBCADO"],
        Rank::Cheapest,
        35.3,
    ),
    mission_target(
        "sample-1",
        "min-D",
        Profile::Ptf,
        &["OAEGCBFHDO", "ODHFBCGEAO"],
        Rank::Cheapest,
        40.6,
    ),
    mission_target(
        "sample-1",
        "min-X",
        Profile::Ptf,
        &["OCGAEDHBFO", "OFBHDEAGCO"],
        Rank::Cheapest,
        45.5,
    ),
    mission_target(
        "sample-1",
        "min-Z, cheaper direction",
        Profile::Ptf,
        &["OCABDHGEFO", "OFEGHDBACO"],
        Rank::Cheapest,
        37.9,
    ),
    mission_target(
        "sample-1",
        "min-Z, dearer direction",
        Profile::Ptf,
        &["OCABDHGEFO", "OFEGHDBACO"],
        Rank::Dearest,
        39.4,
    ),
    mission_target(
        "sample-2",
        "min-energy O-B-C-A-O",
        Profile::Ptf,
        &["OBCAO"],
        Rank::Cheapest,
        19.1,
    ),
    mission_target(
        "sample-2",
        "min-D, cheaper direction",
        Profile::Ptf,
        &["OABCO", "OCBAO"],
        Rank::Cheapest,
        19.7,
    ),
    mission_target(
        "sample-2",
        "min-D, dearer direction",
        Profile::Ptf,
        &["OABCO", "OCBAO"],
        Rank::Dearest,
        20.1,
    ),
    mission_target(
        "sample-2",
        "vertical climb O-C",
        Profile::Ptf,
        &["OC"],
        Rank::Cheapest,
        6.22,
    ),
    mission_target(
        "sample-2",
        "min-energy (HVB)",
        Profile::Hvb,
        SAMPLE_2_TOURS,
        Rank::Cheapest,
        24.07,
    ),
    mission_target(
        "sample-2",
        "min-D (HVB)",
        Profile::Hvb,
        &["OABCO", "OCBAO"],
        Rank::Cheapest,
        25.21,
    ),
];

/// The legs (Xf, Zf) of `path` through `mission`'s waypoints ("O" = origin), or None for a
/// letter the mission does not have.
pub fn path_legs(mission: &str, path: &str) -> Option<Vec<(f64, f64)>> {
    let points: &[(char, [f64; 3])] = match mission {
        "sample-1" => &SAMPLE_1,
        "sample-2" => &SAMPLE_2,
        _ => return None,
    };
    let at = |c: char| -> Option<[f64; 3]> {
        if c == 'O' {
            return Some([0.0; 3]);
        }
        points.iter().find(|(n, _)| *n == c).map(|(_, p)| *p)
    };
    let stops: Vec<[f64; 3]> = path.chars().map(at).collect::<Option<_>>()?;
    Some(
        stops
            .windows(2)
            .map(|w| {
                (
                    (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]),
                    w[1][2] - w[0][2],
                )
            })
            .collect(),
    )
}

/// Marginal costs the paper's PTF table implies (research section 5.1), J/m: climbing at
/// X = 40 m (E(40,25) - E(40,1)) / 24, level flight (E(56.6,0) - mean E(40,+-1)) / 16.6,
/// descending (E(40,-1) - E(40,-25)) / 24 (energy saved per metre descended).
pub const PAPER_MARGINAL_J_M: [f64; 3] = [105.0, 78.3, 48.75];
