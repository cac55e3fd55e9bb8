//! The precomputed energy table E(Xf, Zf) of one vehicle and flight profile: operation energy
//! and duration over horizontal distance 0..150 m (1 m apart) and vertical displacement -60..+60 m
//! (0.5 m apart), looked up by bilinear interpolation and never extrapolated.
//! Longer legs are composed from it by `physics::longleg` where that is exact.
//!
//! File format (`models/<vehicle>/<profile>.table`, text, version 1):
//! ```text
//! # emplan energy table
//! format 1
//! profile ptf
//! vehicle_hash 0123456789abcdef
//! xf_m 0 150 151
//! zf_m -60 60 241
//! columns xf_m zf_m energy_j duration_s settle_energy_j settle_duration_s
//! 0 -60 2991.2 9.87 412.5 1.2
//! ...
//! ```
//! Grid lines are `start end count`; rows run over Xf then Zf (Zf fastest). `vehicle_hash` is
//! [`Vehicle::parameter_hash`] of the parameters the table was built from: a table whose hash
//! differs from the vehicle file's is stale and refused.
//!
//! A `px4` leg's price depends on the leg before it (PX4 slows its trajectory for a vehicle
//! that starts behind it, not for one that starts ahead: [`Start`], `physics::px4`), so the px4
//! table holds one block of rows per start case, named by a `starts behind ahead` line after
//! the grid lines, the blocks in that order; a lookup picks its block and interpolates inside
//! it only. A table without that line holds one block, priced as starting behind: the other
//! profiles do not depend on the leg before, and a px4 table without the `ahead` block is
//! refused (rebuild it).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::power::{Model, Operation};
use super::px4::Start;
use super::vehicle::Vehicle;
use super::{PhysicsError, Profile};

/// Table format version written in the header.
pub const FORMAT_VERSION: u32 = 1;

/// One grid axis: `count` evenly spaced values from `start_m` to `end_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    pub start_m: f64,
    pub end_m: f64,
    pub count: usize,
}

impl Axis {
    /// `count` values from `start_m` to `end_m`.
    pub const fn new(start_m: f64, end_m: f64, count: usize) -> Axis {
        Axis {
            start_m,
            end_m,
            count,
        }
    }

    fn step_m(&self) -> f64 {
        (self.end_m - self.start_m) / (self.count - 1) as f64
    }

    fn value(&self, k: usize) -> f64 {
        self.start_m + self.step_m() * k as f64
    }

    /// The cell index and fraction of `x`, or None outside the axis.
    fn locate(&self, x: f64) -> Option<(usize, f64)> {
        let tolerance = 1e-9 * self.step_m();
        if !(x >= self.start_m - tolerance && x <= self.end_m + tolerance) {
            return None;
        }
        let pos = ((x - self.start_m) / self.step_m()).clamp(0.0, (self.count - 1) as f64);
        let k = (pos.floor() as usize).min(self.count - 2);
        Some((k, pos - k as f64))
    }
}

/// The default grid: Xf 0..150 m every 1 m, Zf -60..+60 m every 0.5 m (finer vertically: the
/// px4 profile has kinks where its binding speed limit switches with the climb angle).
pub const DEFAULT_XF: Axis = Axis::new(0.0, 150.0, 151);
/// See [`DEFAULT_XF`].
pub const DEFAULT_ZF: Axis = Axis::new(-60.0, 60.0, 241);

/// Energy and time of one leg, from the table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegEnergy {
    /// To the paper's 4 m rule.
    pub energy_j: f64,
    pub duration_s: f64,
    /// From there to settled hover at the end point.
    pub settle_energy_j: f64,
    pub settle_duration_s: f64,
}

impl LegEnergy {
    /// Everything the battery pays for the leg, start to settled hover.
    pub fn total_energy_j(&self) -> f64 {
        self.energy_j + self.settle_energy_j
    }

    /// Start to settled hover.
    pub fn total_duration_s(&self) -> f64 {
        self.duration_s + self.settle_duration_s
    }

    /// The leg's energy under `pricing`.
    pub fn priced_energy_j(&self, pricing: Pricing) -> f64 {
        match pricing {
            Pricing::Settled => self.total_energy_j(),
            Pricing::Paper => self.energy_j,
        }
    }

    /// The leg's duration under `pricing`.
    pub fn priced_duration_s(&self, pricing: Pricing) -> f64 {
        match pricing {
            Pricing::Settled => self.total_duration_s(),
            Pricing::Paper => self.duration_s,
        }
    }
}

impl From<&Operation> for LegEnergy {
    /// A simulated operation's energies and times, as a table cell holds them.
    fn from(op: &Operation) -> LegEnergy {
        LegEnergy {
            energy_j: op.energy_j,
            duration_s: op.duration_s,
            settle_energy_j: op.settle_energy_j,
            settle_duration_s: op.settle_duration_s,
        }
    }
}

/// What a leg's energy counts (`--pricing`): to settled hover at the end point (what the
/// battery pays; emplan's default), or to the paper's 4 m rule only (the paper's own convention:
/// its published tables and mission energies).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pricing {
    /// From leaving hover to settled hover at the end point.
    #[default]
    Settled,
    /// From leaving hover until first within 4 m of the end point.
    Paper,
}

impl std::fmt::Display for Pricing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Pricing::Settled => "settled",
            Pricing::Paper => "paper",
        })
    }
}

impl std::str::FromStr for Pricing {
    type Err = crate::names::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::names::choose(
            "pricing",
            s,
            &[("settled", Pricing::Settled), ("paper", Pricing::Paper)],
        )
    }
}

/// A loaded (or freshly built) energy table.
#[derive(Debug, Clone, PartialEq)]
pub struct EnergyTable {
    pub profile: Profile,
    pub vehicle_hash: String,
    pub xf: Axis,
    pub zf: Axis,
    /// The start cases held, one block of cells each ([`Start::Behind`] alone for a profile
    /// that does not depend on the leg before).
    pub starts: Vec<Start>,
    /// Row-major over (start, xf, zf), zf fastest.
    cells: Vec<LegEnergy>,
}

/// The start cases a table of `profile` holds.
pub fn starts_of(profile: Profile) -> Vec<Start> {
    match profile {
        Profile::Px4 => Start::ALL.to_vec(),
        Profile::Ptf | Profile::Hvb | Profile::Ardupilot => vec![Start::Behind],
    }
}

impl EnergyTable {
    /// The table file of `profile` in a vehicle directory.
    pub fn path(dir: &Path, profile: Profile) -> PathBuf {
        dir.join(format!("{profile}.table"))
    }

    /// Builds the table by simulating every grid point (in parallel); `progress(done, total)`
    /// is called as cells finish.
    pub fn build(
        vehicle: &Vehicle,
        profile: Profile,
        xf: Axis,
        zf: Axis,
        progress: impl Fn(usize, usize) + Sync,
    ) -> Result<EnergyTable, PhysicsError> {
        let model = Model::new(vehicle);
        let starts = starts_of(profile);
        let block = xf.count * zf.count;
        let total = block * starts.len();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let cells = (0..total)
            .into_par_iter()
            .map(|k| {
                let (start, k) = (starts[k / block], k % block);
                let op = model.operation_from(
                    profile,
                    xf.value(k / zf.count),
                    zf.value(k % zf.count),
                    start,
                )?;
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if n.is_multiple_of(256) || n == total {
                    progress(n, total);
                }
                Ok(LegEnergy::from(&op))
            })
            .collect::<Result<Vec<_>, PhysicsError>>()?;
        Ok(EnergyTable {
            profile,
            vehicle_hash: vehicle.parameter_hash(profile),
            xf,
            zf,
            starts,
            cells,
        })
    }

    /// The cell at grid indices (i over Xf, j over Zf) of the first block (starting behind).
    pub fn cell(&self, i: usize, j: usize) -> Option<&LegEnergy> {
        self.cell_from(i, j, Start::Behind)
    }

    /// The cell at grid indices (i over Xf, j over Zf) for a leg starting `start`.
    pub fn cell_from(&self, i: usize, j: usize, start: Start) -> Option<&LegEnergy> {
        if i >= self.xf.count || j >= self.zf.count {
            return None;
        }
        self.cells
            .get(self.block_of(start) * self.xf.count * self.zf.count + i * self.zf.count + j)
    }

    /// The block holding `start` (the only one when the table does not depend on the start).
    fn block_of(&self, start: Start) -> usize {
        self.starts.iter().position(|&s| s == start).unwrap_or(0)
    }

    /// Bilinear interpolation at (xf_m, zf_m) for a leg starting behind PX4's trajectory (the
    /// first leg; every leg of the profiles that do not depend on the leg before); outside the
    /// grid is an error naming the leg.
    pub fn lookup(&self, xf_m: f64, zf_m: f64) -> Result<LegEnergy, PhysicsError> {
        self.lookup_from(xf_m, zf_m, Start::Behind)
    }

    /// Bilinear interpolation at (xf_m, zf_m) inside the block of `start`; outside the grid
    /// is an error naming the leg.
    pub fn lookup_from(
        &self,
        xf_m: f64,
        zf_m: f64,
        start: Start,
    ) -> Result<LegEnergy, PhysicsError> {
        let outside = PhysicsError::OutsideTable {
            xf_m,
            zf_m,
            profile: self.profile,
            max_xf_m: self.xf.end_m,
            min_zf_m: self.zf.start_m,
            max_zf_m: self.zf.end_m,
        };
        let (Some((i, fx)), Some((j, fz))) = (self.xf.locate(xf_m), self.zf.locate(zf_m)) else {
            return Err(outside);
        };
        let n = self.zf.count;
        let base = self.block_of(start) * self.xf.count * n;
        let c = |di: usize, dj: usize| self.cells[base + (i + di) * n + j + dj];
        let (c00, c01, c10, c11) = (c(0, 0), c(0, 1), c(1, 0), c(1, 1));
        let mix = |f: fn(&LegEnergy) -> f64| {
            (1.0 - fx) * ((1.0 - fz) * f(&c00) + fz * f(&c01))
                + fx * ((1.0 - fz) * f(&c10) + fz * f(&c11))
        };
        Ok(LegEnergy {
            energy_j: mix(|c| c.energy_j),
            duration_s: mix(|c| c.duration_s),
            settle_energy_j: mix(|c| c.settle_energy_j),
            settle_duration_s: mix(|c| c.settle_duration_s),
        })
    }

    /// The table as text (the format in the module doc).
    pub fn to_text(&self) -> String {
        let mut out = format!(
            "# emplan energy table\nformat {FORMAT_VERSION}\nprofile {}\nvehicle_hash {}\n\
             xf_m {} {} {}\nzf_m {} {} {}\n\
             columns xf_m zf_m energy_j duration_s settle_energy_j settle_duration_s\n",
            self.profile,
            self.vehicle_hash,
            self.xf.start_m,
            self.xf.end_m,
            self.xf.count,
            self.zf.start_m,
            self.zf.end_m,
            self.zf.count
        );
        if self.starts != [Start::Behind] {
            let names: Vec<String> = self.starts.iter().map(Start::to_string).collect();
            out = out.replacen(
                "\ncolumns ",
                &format!("\nstarts {}\ncolumns ", names.join(" ")),
                1,
            );
        }
        let block = self.xf.count * self.zf.count;
        for (k, c) in self.cells.iter().enumerate() {
            let k = k % block;
            let _ = writeln!(
                out,
                "{} {} {:.3} {:.4} {:.3} {:.4}",
                self.xf.value(k / self.zf.count),
                self.zf.value(k % self.zf.count),
                c.energy_j,
                c.duration_s,
                c.settle_energy_j,
                c.settle_duration_s
            );
        }
        out
    }

    /// Parses a table; `file` names it in errors.
    pub fn from_text(text: &str, file: &str) -> Result<EnergyTable, PhysicsError> {
        let bad = |line: usize, problem: String| PhysicsError::TableFormat {
            file: file.to_string(),
            line,
            problem,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
            .peekable();
        // The next line if it is the `key` line (None when it is not and `optional`).
        let mut header_or =
            |key: &str, optional: bool| -> Result<Option<(usize, Vec<String>)>, PhysicsError> {
                let &(n, line) = lines
                    .peek()
                    .ok_or_else(|| bad(0, format!("the file ends before the {key:?} line")))?;
                let mut words = line.split_whitespace();
                if words.next() != Some(key) {
                    if optional {
                        return Ok(None);
                    }
                    return Err(bad(n, format!("expected the {key:?} line, found {line:?}")));
                }
                lines.next();
                Ok(Some((n, words.map(String::from).collect())))
            };
        let mut header = |key: &str| -> Result<(usize, Vec<String>), PhysicsError> {
            header_or(key, false)?.ok_or_else(|| bad(0, format!("no {key:?} line")))
        };
        let (n, format) = header("format")?;
        if format.first().map(String::as_str) != Some("1") {
            return Err(bad(n, format!("table format {format:?} is not supported (this emplan reads format {FORMAT_VERSION})")));
        }
        let (n, profile) = header("profile")?;
        let profile: Profile = profile
            .first()
            .ok_or_else(|| bad(n, "no profile".into()))?
            .parse()
            .map_err(|e: crate::names::UnknownName| bad(n, e.to_string()))?;
        let (_, hash) = header("vehicle_hash")?;
        let vehicle_hash = hash.first().cloned().unwrap_or_default();
        let mut axis = |key: &str| -> Result<Axis, PhysicsError> {
            let (n, words) = header(key)?;
            let parsed: Option<(f64, f64, usize)> = match words.as_slice() {
                [a, b, c] => a
                    .parse()
                    .ok()
                    .zip(b.parse().ok())
                    .zip(c.parse().ok())
                    .map(|((a, b), c)| (a, b, c)),
                _ => None,
            };
            match parsed {
                Some((start_m, end_m, count))
                    if (2..=100_000).contains(&count) && end_m > start_m =>
                {
                    Ok(Axis::new(start_m, end_m, count))
                }
                _ => Err(bad(
                    n,
                    format!("{key}: expected `start end count` with count >= 2, found {words:?}"),
                )),
            }
        };
        let xf = axis("xf_m")?;
        let zf = axis("zf_m")?;
        let starts = match header_or("starts", true)? {
            None => vec![Start::Behind],
            Some((n, words)) => {
                let starts = words
                    .iter()
                    .map(|w| match w.as_str() {
                        "behind" => Ok(Start::Behind),
                        "ahead" => Ok(Start::Ahead),
                        _ => Err(bad(
                            n,
                            format!("unknown start {w:?} (allowed: behind, ahead)"),
                        )),
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                if starts.is_empty() || (1..starts.len()).any(|k| starts[..k].contains(&starts[k]))
                {
                    return Err(bad(
                        n,
                        format!("starts: expected distinct start cases, found {words:?}"),
                    ));
                }
                starts
            }
        };
        header_or("columns", false)?;
        let block = xf.count * zf.count;
        let mut cells = Vec::with_capacity(block * starts.len());
        for (n, line) in lines {
            let values: Vec<f64> = line
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| bad(n, format!("not six numbers: {line:?}")))?;
            if values.len() != 6 || values.iter().any(|v| !v.is_finite()) {
                return Err(bad(
                    n,
                    format!("expected six finite numbers, found {line:?}"),
                ));
            }
            let k = cells.len() % block;
            let (x, z) = (xf.value(k / zf.count), zf.value(k % zf.count));
            if (values[0] - x).abs() > 1e-6 || (values[1] - z).abs() > 1e-6 {
                return Err(bad(
                    n,
                    format!(
                        "row for ({}, {}) where ({x}, {z}) was expected",
                        values[0], values[1]
                    ),
                ));
            }
            cells.push(LegEnergy {
                energy_j: values[2],
                duration_s: values[3],
                settle_energy_j: values[4],
                settle_duration_s: values[5],
            });
        }
        if cells.len() != block * starts.len() {
            return Err(bad(
                text.lines().count(),
                format!("{} rows, {} expected", cells.len(), block * starts.len()),
            ));
        }
        Ok(EnergyTable {
            profile,
            vehicle_hash,
            xf,
            zf,
            starts,
            cells,
        })
    }

    /// Loads the `profile` table of the vehicle in `dir`, refusing a stale one.
    pub fn load(
        dir: &Path,
        profile: Profile,
        vehicle: &Vehicle,
    ) -> Result<EnergyTable, PhysicsError> {
        let path = Self::path(dir, profile);
        let file = path.display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|e| PhysicsError::Io {
            file: file.clone(),
            source_text: format!("{e} (build it with `emplan table build --profile {profile}`)"),
        })?;
        Self::from_text(&text, &file)?.checked(profile, vehicle, file)
    }

    /// This table if it holds `profile` and was built from `vehicle` (`file` names it).
    pub fn checked(
        self,
        profile: Profile,
        vehicle: &Vehicle,
        file: String,
    ) -> Result<EnergyTable, PhysicsError> {
        let expected = vehicle.parameter_hash(profile);
        if self.profile != profile {
            return Err(PhysicsError::TableFormat {
                file,
                line: 3,
                problem: format!("holds the {} profile, not {profile}", self.profile),
            });
        }
        if let Some(missing) = starts_of(profile)
            .into_iter()
            .find(|s| !self.starts.contains(s))
        {
            return Err(PhysicsError::TableFormat {
                file,
                line: 6,
                problem: format!(
                    "holds no {missing:?} start block (a {profile} leg's price depends on the \
                     leg before it): rebuild it with `emplan table build --profile {profile}`"
                ),
            });
        }
        if self.vehicle_hash != expected {
            return Err(PhysicsError::StaleTable {
                file,
                profile,
                table_hash: self.vehicle_hash,
                vehicle_hash: expected,
            });
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    fn small(vehicle: &Vehicle) -> EnergyTable {
        let xf = Axis::new(0.0, 20.0, 3);
        let zf = Axis::new(-10.0, 10.0, 3);
        EnergyTable::build(vehicle, Profile::Px4, xf, zf, |_, _| {}).unwrap()
    }

    #[test]
    fn a_table_round_trips_through_its_text_format() {
        let v = shipped();
        let table = small(&v);
        let back = EnergyTable::from_text(&table.to_text(), "t").unwrap();
        assert_eq!(back.profile, Profile::Px4);
        assert_eq!(back.xf, table.xf);
        for (a, b) in back.cells.iter().zip(&table.cells) {
            assert!(
                (a.energy_j - b.energy_j).abs() < 1e-3
                    && (a.settle_duration_s - b.settle_duration_s).abs() < 1e-4
            );
        }
    }

    #[test]
    fn lookups_hit_grid_points_exactly_and_refuse_to_extrapolate() {
        let v = shipped();
        let table = small(&v);
        let at = table.lookup(10.0, 0.0).unwrap();
        assert_eq!(at, *table.cell(1, 1).unwrap());
        let mid = table.lookup(15.0, 5.0).unwrap();
        let corners = [
            table.cell(1, 1),
            table.cell(1, 2),
            table.cell(2, 1),
            table.cell(2, 2),
        ];
        let mean: f64 = corners.iter().map(|c| c.unwrap().energy_j).sum::<f64>() / 4.0;
        assert!((mid.energy_j - mean).abs() < 1e-9);
        for (x, z) in [(20.5, 0.0), (-0.1, 0.0), (5.0, 10.01), (f64::NAN, 0.0)] {
            let err = table.lookup(x, z).unwrap_err();
            assert!(matches!(err, PhysicsError::OutsideTable { .. }), "{err}");
        }
    }

    #[test]
    fn a_damaged_or_foreign_table_is_rejected_with_its_line() {
        let v = shipped();
        let text = small(&v).to_text();
        let broken = text.replacen("format 1", "format 9", 1);
        assert!(matches!(
            EnergyTable::from_text(&broken, "t"),
            Err(PhysicsError::TableFormat { line: 2, .. })
        ));
        let truncated: String = text.lines().take(10).collect::<Vec<_>>().join("\n");
        let err = EnergyTable::from_text(&truncated, "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("rows") && err.contains("expected"), "{err}");
        let garbled = text.replacen("\n0 0 ", "\n0 0 x", 1);
        assert!(EnergyTable::from_text(&garbled, "t").is_err());
    }

    /// The lowest mean power of a short leg (at most 5 m across and 5 m up or down), as a share
    /// of the hover power: such a leg is mostly accelerating and braking near hover (the lowest
    /// cell of the committed tables is 0.88, px4 (0, -1)). What draws less than hovering is
    /// cruise and descent, which long legs have and short ones hardly do: "at least the hover
    /// power's share" holds only for short legs (the tables' fast descents draw 0.60 of it).
    const SHORT_LEG_MIN_POWER_SHARE: f64 = 0.85;

    #[test]
    fn no_short_leg_costs_less_than_nothing_or_much_less_than_hovering_for_its_duration() {
        let v = shipped();
        let hover_w = crate::physics::hover_power_w(&v).unwrap();
        for profile in Profile::ALL {
            let table = crate::physics::builtin::table(profile, &v).unwrap();
            for i in 0..=100 {
                for j in 0..=200 {
                    let (xf_m, zf_m) = (0.05 * i as f64, -5.0 + 0.05 * j as f64);
                    let leg = table.lookup(xf_m, zf_m).unwrap();
                    let at = format!("{profile} ({xf_m:.2}, {zf_m:.2}): {leg:?}");
                    assert!(leg.energy_j >= 0.0 && leg.settle_energy_j >= 0.0, "{at}");
                    assert!(
                        leg.duration_s >= 0.0 && leg.settle_duration_s >= 0.0,
                        "{at}"
                    );
                    let (energy_j, duration_s) = (leg.total_energy_j(), leg.total_duration_s());
                    assert!(
                        energy_j >= SHORT_LEG_MIN_POWER_SHARE * hover_w * duration_s,
                        "{at}: {:.2} of the hover power",
                        energy_j / duration_s / hover_w
                    );
                    assert!(duration_s == 0.0 || energy_j > 0.0, "{at}");
                }
            }
        }
    }

    #[test]
    fn the_committed_px4_cells_of_legs_inside_the_acceptance_are_what_the_model_builds() {
        let v = shipped();
        let built = EnergyTable::build(
            &v,
            Profile::Px4,
            Axis::new(0.0, 2.0, 3),
            Axis::new(-0.5, 0.5, 3),
            |_, _| {},
        )
        .unwrap();
        let committed = crate::physics::builtin::table(Profile::Px4, &v).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let (a, b) = (
                    built.cell(i, j).unwrap(),
                    committed.cell(i, 119 + j).unwrap(),
                );
                assert!(
                    (a.total_energy_j() - b.total_energy_j()).abs() < 2e-3
                        && (a.total_duration_s() - b.total_duration_s()).abs() < 2e-4,
                    "({i}, {j}): built {a:?}, committed {b:?}"
                );
                assert!(a.settle_energy_j >= 0.0, "({i}, {j}): {a:?}");
            }
        }
    }

    #[test]
    fn a_table_built_from_other_parameters_is_reported_stale() {
        let v = shipped();
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            EnergyTable::path(dir.path(), Profile::Px4),
            small(&v).to_text(),
        )
        .unwrap();
        assert!(EnergyTable::load(dir.path(), Profile::Px4, &v).is_ok());
        let mut heavier = v.clone();
        heavier.body.mass_kg += 0.5;
        let err = EnergyTable::load(dir.path(), Profile::Px4, &heavier).unwrap_err();
        assert!(matches!(err, PhysicsError::StaleTable { .. }), "{err}");
        assert!(err.to_string().contains("emplan table build --profile px4"));
    }
}
