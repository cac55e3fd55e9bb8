//! The missions folder: a task that owns the catalog of mission files (`.toml`, `.plan`,
//! `.waypoints`) and their plans. It watches the folder (`notify`; polling every 2 s when the
//! platform's watcher cannot start), waits for a change to settle (250 ms without events), and
//! plans every file that is new or whose bytes changed, one at a time on a blocking thread:
//! every order and baseline (what `emplan plan --json` prints) and, when one battery cannot
//! fly the mission, its sorties. An invalid file is listed with its located error (file, line
//! or item); it never stops the others. Handlers read the catalog from a watch channel.
//!
//! Missions are known by their file name (`paper-sample-8wp.toml`): unique in a folder, and
//! the `.toml`, `.plan` and `.waypoints` exports of one mission differ.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, UNIX_EPOCH};

use serde::Serialize;
use tokio::sync::{mpsc, watch};

use super::events::{Event, Hub};
use crate::mission::{Format, Mission, MissionError, Place};
use crate::physics::VehicleModel;
use crate::plan::solver;
use crate::plan::Objective;
use crate::planner::json::{energy_kj, plan_document};
use crate::planner::{plan_mission, Orders, Plan, PlanOptions};

/// The extensions planned (`.txt` is a WPL extension too, but a folder's README is not a
/// mission).
const EXTENSIONS: [&str; 3] = ["toml", "plan", "waypoints"];

/// How long the folder must be quiet before it is read again.
const SETTLE: Duration = Duration::from_millis(250);

/// A 64-bit FNV-1a digest of a file's bytes, as 16 hex digits: tells a client whether its copy
/// of a mission is the service's.
pub fn digest(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Why a mission has no plan, located.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MissionProblem {
    /// `mission` (the file cannot be read as a mission) or `plan` (it cannot be planned).
    pub stage: &'static str,
    pub message: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line: Option<usize>,
    /// The 0-based item of a `.plan` file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub item: Option<usize>,
}

impl MissionProblem {
    fn of_mission(e: &MissionError) -> MissionProblem {
        let (line, item) = match e {
            MissionError::Invalid {
                place: Place::Line(n),
                ..
            } => (Some(*n), None),
            MissionError::Invalid {
                place: Place::Item(k),
                ..
            } => (None, Some(*k)),
            _ => (None, None),
        };
        MissionProblem {
            stage: "mission",
            message: e.to_string(),
            line,
            item,
        }
    }
}

/// What became of a mission file.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// Being planned.
    Planning,
    Planned {
        plan: Arc<Plan>,
        /// `emplan plan --json` of it.
        document: Arc<serde_json::Value>,
        /// Why the sorties are missing, when one battery cannot fly it and no split was found.
        sorties_error: Option<String>,
    },
    Failed(MissionProblem),
}

/// One mission file of the folder.
#[derive(Debug, Clone)]
pub struct MissionEntry {
    /// The file name: the mission's key in the API.
    pub name: String,
    pub path: PathBuf,
    pub digest: String,
    /// The file's modification time (unix ms).
    pub modified_ms: u64,
    /// The mission, when the file reads as one.
    pub mission: Option<Arc<Mission>>,
    pub outcome: Outcome,
}

impl MissionEntry {
    fn status(&self) -> &'static str {
        match self.outcome {
            Outcome::Planning => "planning",
            Outcome::Planned { .. } => "planned",
            Outcome::Failed(_) => "error",
        }
    }

    /// The list view: status, the error, or the headline numbers of the plan.
    pub fn summary(&self) -> serde_json::Value {
        let mut doc = serde_json::json!({
            "name": self.name,
            "file": self.path,
            "digest": self.digest,
            "modified_ms": self.modified_ms,
            "status": self.status(),
            "mission": self.mission.as_ref().map(|m| m.name.clone()),
            "waypoints": self.mission.as_ref().map(|m| m.waypoints.len()),
        });
        let Some(map) = doc.as_object_mut() else {
            return doc;
        };
        match &self.outcome {
            Outcome::Planning => {}
            Outcome::Failed(problem) => {
                map.insert("error".into(), serde_json::json!(problem));
            }
            Outcome::Planned {
                plan,
                sorties_error,
                ..
            } => {
                let energy = plan.order(Objective::Energy).map(|o| energy_kj(&o.legs));
                let distance = plan
                    .cheapest(Objective::Distance)
                    .map(|o| energy_kj(&o.legs));
                let saving_pct = energy
                    .zip(distance)
                    .filter(|(_, d)| *d > 0.0)
                    .map(|(e, d)| (d - e) / d * 100.0);
                let battery = crate::planner::json::battery_json(plan);
                map.insert("profile".into(), serde_json::json!(plan.profile));
                map.insert("energy_kj".into(), serde_json::json!(energy));
                map.insert("distance_kj".into(), serde_json::json!(distance));
                map.insert("saving_pct".into(), serde_json::json!(saving_pct));
                map.insert("total_kj".into(), serde_json::json!(battery.total_kj));
                map.insert("budget_kj".into(), serde_json::json!(battery.budget_kj));
                map.insert("feasible".into(), serde_json::json!(battery.feasible));
                map.insert(
                    "sorties".into(),
                    serde_json::json!(plan.sorties.as_ref().map(|s| s.sorties.len())),
                );
                if let Some(e) = sorties_error {
                    map.insert("sorties_error".into(), serde_json::json!(e));
                }
            }
        }
        doc
    }

    /// The full view: the summary, the mission's points and the plan document.
    pub fn detail(&self) -> serde_json::Value {
        let mut doc = self.summary();
        if let Some(map) = doc.as_object_mut() {
            if let Some(m) = &self.mission {
                map.insert(
                    "origin".into(),
                    serde_json::json!({
                        "lat_deg": m.origin.home.lat_deg,
                        "lon_deg": m.origin.home.lon_deg,
                        "home_alt_amsl_m": m.origin.home.alt_m,
                        "height_above_home_m": m.origin.height_above_home_m,
                    }),
                );
                let points: Vec<serde_json::Value> = m
                    .waypoints
                    .iter()
                    .map(|w| {
                        serde_json::json!({
                            "name": w.name,
                            "x_m": w.position.x_east_m,
                            "y_m": w.position.y_north_m,
                            "z_m": w.position.z_up_m,
                            "hover_s": w.hover_s,
                        })
                    })
                    .collect();
                map.insert("points".into(), serde_json::Value::Array(points));
            }
            if let Outcome::Planned { document, .. } = &self.outcome {
                map.insert("plan".into(), (**document).clone());
            }
        }
        doc
    }
}

/// The missions of the folder, by file name.
#[derive(Debug, Clone, Default)]
pub struct Catalog {
    pub dir: PathBuf,
    pub entries: BTreeMap<String, Arc<MissionEntry>>,
}

impl Catalog {
    /// Every mission that reads as one.
    pub fn missions(&self) -> impl Iterator<Item = &Mission> {
        self.entries.values().filter_map(|e| e.mission.as_deref())
    }

    pub fn get(&self, name: &str) -> Option<&Arc<MissionEntry>> {
        self.entries.get(name)
    }
}

/// The catalog as it changes.
pub type CatalogRx = watch::Receiver<Arc<Catalog>>;

/// How the folder is planned.
#[derive(Debug, Clone)]
pub struct PlanSettings {
    pub model: Arc<VehicleModel>,
    pub solver: solver::Options,
}

/// A file seen in the folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Seen {
    len: u64,
    modified_ms: u64,
}

fn scan(dir: &Path) -> std::io::Result<BTreeMap<String, (PathBuf, Seen)>> {
    let mut found = BTreeMap::new();
    for entry in std::fs::read_dir(dir)? {
        let Ok(entry) = entry else { continue };
        let path = entry.path();
        let Some(name) = path
            .file_name()
            .and_then(|n| n.to_str())
            .map(str::to_string)
        else {
            continue;
        };
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let wanted = ext.as_deref().is_some_and(|e| EXTENSIONS.contains(&e));
        if !wanted || name.starts_with('.') || name.ends_with('~') {
            continue;
        }
        let Ok(meta) = entry.metadata() else { continue };
        if !meta.is_file() {
            continue;
        }
        let modified_ms = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_millis() as u64);
        found.insert(
            name,
            (
                path,
                Seen {
                    len: meta.len(),
                    modified_ms,
                },
            ),
        );
    }
    Ok(found)
}

/// Reads and plans one mission file (blocking).
fn plan_file(path: &Path, bytes: &[u8], settings: &PlanSettings) -> (Option<Mission>, Outcome) {
    let mission = Format::from_path(path).and_then(|format| {
        let text = String::from_utf8(bytes.to_vec()).map_err(|e| MissionError::Invalid {
            file: path.display().to_string(),
            place: Place::File,
            problem: format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        })?;
        crate::mission::load_str(&text, format, Some(path))
    });
    let mission = match mission {
        Ok(m) => m,
        Err(e) => return (None, Outcome::Failed(MissionProblem::of_mission(&e))),
    };
    let options = PlanOptions {
        orders: Orders::All,
        solver: settings.solver,
        sorties: false,
        pricing: crate::physics::Pricing::Settled,
    };
    let failed = |e: crate::planner::PlannerError| {
        Outcome::Failed(MissionProblem {
            stage: "plan",
            message: e.to_string(),
            line: None,
            item: None,
        })
    };
    let mut plan = match plan_mission(&mission, &settings.model, &options) {
        Ok(p) => p,
        Err(e) => return (Some(mission), failed(e)),
    };
    let mut sorties_error = None;
    if !plan.battery.feasible {
        let split = PlanOptions {
            sorties: true,
            ..options
        };
        match plan_mission(&mission, &settings.model, &split) {
            Ok(p) => plan = p,
            Err(e) => sorties_error = Some(e.to_string()),
        }
    }
    let document = match serde_json::to_value(plan_document(&plan)) {
        Ok(d) => d,
        Err(e) => {
            return (
                Some(mission),
                Outcome::Failed(MissionProblem {
                    stage: "plan",
                    message: e.to_string(),
                    line: None,
                    item: None,
                }),
            )
        }
    };
    (
        Some(mission),
        Outcome::Planned {
            plan: Arc::new(plan),
            document: Arc::new(document),
            sorties_error,
        },
    )
}

/// Starts the missions task on `dir` (which must exist); it runs until `stop`.
pub fn spawn(
    dir: PathBuf,
    settings: PlanSettings,
    hub: Arc<Hub>,
    stop: watch::Receiver<bool>,
) -> (CatalogRx, tokio::task::JoinHandle<()>) {
    let (tx, rx) = watch::channel(Arc::new(Catalog {
        dir: dir.clone(),
        entries: BTreeMap::new(),
    }));
    let task = tokio::spawn(run(dir, settings, hub, tx, stop));
    (rx, task)
}

async fn run(
    dir: PathBuf,
    settings: PlanSettings,
    hub: Arc<Hub>,
    catalog: watch::Sender<Arc<Catalog>>,
    mut stop: watch::Receiver<bool>,
) {
    let (changes_tx, mut changes) = mpsc::unbounded_channel::<()>();
    let watcher = {
        use notify::Watcher;
        let tx = changes_tx.clone();
        notify::recommended_watcher(move |event: notify::Result<notify::Event>| {
            if event.is_ok() {
                let _ = tx.send(());
            }
        })
        .and_then(|mut w| {
            w.watch(&dir, notify::RecursiveMode::NonRecursive)?;
            Ok(w)
        })
    };
    let poll = match &watcher {
        Ok(_) => None,
        Err(e) => {
            tracing::warn!(
                "cannot watch {} ({e}); looking at it every 2 s instead",
                dir.display()
            );
            Some(Duration::from_secs(2))
        }
    };
    let mut known: BTreeMap<String, Seen> = BTreeMap::new();
    loop {
        rescan(&dir, &settings, &hub, &catalog, &mut known, &mut stop).await;
        if *stop.borrow() {
            return;
        }
        // Wait for a change, then for the folder to settle.
        tokio::select! {
            _ = stop.changed() => return,
            got = changes.recv() => if got.is_none() { return },
            _ = tokio::time::sleep(poll.unwrap_or(Duration::from_secs(3600))), if poll.is_some() => {}
        }
        loop {
            tokio::select! {
                _ = stop.changed() => return,
                got = tokio::time::timeout(SETTLE, changes.recv()) => match got {
                    Ok(Some(())) => continue,
                    Ok(None) | Err(_) => break,
                },
            }
        }
    }
}

fn publish(catalog: &watch::Sender<Arc<Catalog>>, entry: MissionEntry) -> Arc<MissionEntry> {
    let entry = Arc::new(entry);
    catalog.send_modify(|c| {
        let mut next = (**c).clone();
        next.entries.insert(entry.name.clone(), entry.clone());
        *c = Arc::new(next);
    });
    entry
}

/// Reads the folder and plans what changed.
async fn rescan(
    dir: &Path,
    settings: &PlanSettings,
    hub: &Hub,
    catalog: &watch::Sender<Arc<Catalog>>,
    known: &mut BTreeMap<String, Seen>,
    stop: &mut watch::Receiver<bool>,
) {
    let found = match scan(dir) {
        Ok(found) => found,
        Err(e) => {
            tracing::error!("missions folder {}: {e}", dir.display());
            return;
        }
    };
    let gone: Vec<String> = known
        .keys()
        .filter(|name| !found.contains_key(*name))
        .cloned()
        .collect();
    for name in gone {
        known.remove(&name);
        catalog.send_modify(|c| {
            let mut next = (**c).clone();
            next.entries.remove(&name);
            *c = Arc::new(next);
        });
        tracing::info!(mission = %super::escape_controls(&name), "mission file removed");
        hub.publish(&Event::MissionRemoved { name });
    }
    for (name, (path, seen)) in found {
        if *stop.borrow() {
            return;
        }
        if known.get(&name) == Some(&seen) {
            continue;
        }
        known.insert(name.clone(), seen);
        let bytes = match tokio::fs::read(&path).await {
            Ok(b) => b,
            Err(e) => {
                tracing::warn!(mission = %super::escape_controls(&name), "not read: {e}");
                continue;
            }
        };
        let digest = digest(&bytes);
        let previous = catalog.borrow().get(&name).cloned();
        if let Some(prev) = previous.filter(|p| p.digest == digest) {
            // Touched, not changed.
            publish(
                catalog,
                MissionEntry {
                    modified_ms: seen.modified_ms,
                    ..(*prev).clone()
                },
            );
            continue;
        }
        let span = tracing::info_span!("plan", mission = %super::escape_controls(&name));
        publish(
            catalog,
            MissionEntry {
                name: name.clone(),
                path: path.clone(),
                digest: digest.clone(),
                modified_ms: seen.modified_ms,
                mission: None,
                outcome: Outcome::Planning,
            },
        );
        let started = std::time::Instant::now();
        let job_settings = settings.clone();
        let job_path = path.clone();
        let planned =
            tokio::task::spawn_blocking(move || plan_file(&job_path, &bytes, &job_settings)).await;
        let (mission, outcome) = match planned {
            Ok(done) => done,
            Err(e) => (
                None,
                Outcome::Failed(MissionProblem {
                    stage: "plan",
                    message: format!("planning stopped: {e}"),
                    line: None,
                    item: None,
                }),
            ),
        };
        let entry = publish(
            catalog,
            MissionEntry {
                name: name.clone(),
                path,
                digest,
                modified_ms: seen.modified_ms,
                mission: mission.map(Arc::new),
                outcome,
            },
        );
        span.in_scope(|| match &entry.outcome {
            Outcome::Failed(p) => tracing::warn!("{}", super::escape_controls(&p.message)),
            _ => tracing::info!(seconds = started.elapsed().as_secs_f64(), "planned"),
        });
        hub.publish(&match entry.outcome {
            Outcome::Failed(_) => Event::MissionError(entry.summary()),
            _ => Event::MissionPlanned(entry.summary()),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digests_differ_for_different_bytes_and_match_fnv1a() {
        // FNV-1a 64 of "a" (the published test vector).
        assert_eq!(digest(b"a"), "af63dc4c8601ec8c");
        assert_eq!(digest(b""), "cbf29ce484222325");
        assert_ne!(digest(b"ab"), digest(b"ba"));
    }

    #[test]
    fn only_mission_files_are_scanned() {
        let dir = tempfile::tempdir().expect("temp dir");
        for name in [
            "a.toml",
            "b.PLAN",
            "c.waypoints",
            "README.txt",
            ".hidden.toml",
            "d.toml~",
        ] {
            std::fs::write(dir.path().join(name), "x").expect("written");
        }
        std::fs::create_dir(dir.path().join("sub.toml")).expect("dir");
        let names: Vec<String> = scan(dir.path()).expect("scanned").into_keys().collect();
        assert_eq!(names, ["a.toml", "b.PLAN", "c.waypoints"]);
    }
}
