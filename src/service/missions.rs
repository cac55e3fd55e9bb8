//! The missions folder: a task that owns the catalog of mission files (`.toml`, `.plan`,
//! `.waypoints`) and their plans. It watches the folder (`notify`; polling every 2 s when the
//! platform's watcher cannot start) and plans a file only once its size and modification time
//! have stayed the same for the settle time ([`WatchSettings::settle`]); until then it is
//! listed as `changing`, so a file being written is never planned half-written. The bytes
//! planned are the ones read then, and their digest is kept: before an upload the file is read
//! again ([`unchanged`]) and a file that changed since is refused and planned again.
//!
//! Each file is planned on a blocking thread of its own, a few at a time
//! ([`WatchSettings::plans_at_once`]), so a large file holds up neither the listing nor the
//! planning of the others: every order and baseline (what `emplan plan --json` prints) and,
//! when one battery cannot fly the mission, its sorties. A plan is stopped (its memory given
//! back) when its file is deleted or changes, and when it runs past the time limit (then the
//! file is listed as an error); see `tour::cancel`. An invalid file is listed with its located
//! error (file, line or item); it never stops the others. Handlers read the catalog from a
//! watch channel.
//!
//! Missions are known by their file name (`paper-sample-8wp.toml`): unique in a folder, and
//! the `.toml`, `.plan` and `.waypoints` exports of one mission differ.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use tokio::sync::{mpsc, watch, Semaphore};

use super::events::Hub;
use super::wire::{
    Event, MissionDetail, MissionProblem, MissionState, MissionStatus, OriginJson, PlannedNumbers,
    PointJson,
};
use super::Refusal;
use crate::mission::{Format, Mission, MissionError, Place};
use crate::physics::VehicleModel;
use crate::planner::json::{energy_kj, mission_document};
use crate::planner::{plan_mission, Orders, Plan, PlanOptions};
use crate::tour::cancel::{self, Cancel};
use crate::tour::solver;
use crate::tour::Objective;

/// The extensions planned (`.txt` is a WPL extension too, but a folder's README is not a
/// mission).
const EXTENSIONS: [&str; 3] = ["toml", "plan", "waypoints"];

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
            stage: "mission".into(),
            message: e.to_string(),
            line,
            item,
        }
    }
}

/// What became of a mission file.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// Its size or modification time changed less than the settle time ago: not read yet.
    Changing,
    /// Being planned (or waiting for a free planning thread).
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
    /// The digest of the bytes planned (empty while the file is changing).
    pub digest: String,
    /// The file's modification time (unix ms).
    pub modified_ms: u64,
    /// The mission, when the file reads as one.
    pub mission: Option<Arc<Mission>>,
    pub outcome: Outcome,
}

impl MissionEntry {
    fn status(&self) -> MissionState {
        match self.outcome {
            Outcome::Changing => MissionState::Changing,
            Outcome::Planning => MissionState::Planning,
            Outcome::Planned { .. } => MissionState::Planned,
            Outcome::Failed(_) => MissionState::Error,
        }
    }

    /// The list view: status, the error, or the headline numbers of the plan.
    pub fn summary(&self) -> MissionStatus {
        let (error, planned) = match &self.outcome {
            Outcome::Changing | Outcome::Planning => (None, None),
            Outcome::Failed(problem) => (Some(problem.clone()), None),
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
                    .map(|(e, d)| crate::planner::explain::saving_pct(e, d));
                let battery = crate::planner::json::battery_json(plan);
                let numbers = PlannedNumbers {
                    profile: plan.profile,
                    energy_kj: energy,
                    distance_kj: distance,
                    saving_pct,
                    total_kj: battery.total_kj,
                    budget_kj: battery.budget_kj,
                    feasible: battery.feasible,
                    sorties: plan.sorties.as_ref().map(|s| s.sorties.len()),
                    sorties_error: sorties_error.clone(),
                };
                (None, Some(numbers))
            }
        };
        MissionStatus {
            name: self.name.clone(),
            file: self.path.clone(),
            digest: self.digest.clone(),
            modified_ms: self.modified_ms,
            status: self.status(),
            mission: self.mission.as_ref().map(|m| m.name.clone()),
            waypoints: self.mission.as_ref().map(|m| m.waypoints.len()),
            error,
            planned,
        }
    }

    /// The full view: the summary, the mission's points and the plan document.
    pub fn detail(&self) -> MissionDetail {
        let origin = self.mission.as_ref().map(|m| OriginJson {
            lat_deg: m.origin.home.lat_deg,
            lon_deg: m.origin.home.lon_deg,
            home_alt_amsl_m: m.origin.home.alt_m,
            height_above_home_m: m.origin.height_above_home_m,
        });
        let points = self.mission.as_ref().map(|m| {
            m.waypoints
                .iter()
                .map(|w| PointJson {
                    name: w.name.clone(),
                    x_m: w.position.x_east_m,
                    y_m: w.position.y_north_m,
                    z_m: w.position.z_up_m,
                    hover_s: w.hover_s,
                })
                .collect()
        });
        let plan = match &self.outcome {
            Outcome::Planned { document, .. } => Some((**document).clone()),
            _ => None,
        };
        MissionDetail {
            status: self.summary(),
            origin,
            points,
            plan,
        }
    }
}

/// The missions of the folder, by file name.
#[derive(Debug, Clone, Default)]
pub struct Catalog {
    pub dir: PathBuf,
    pub entries: BTreeMap<String, Arc<MissionEntry>>,
    /// How long a file must stay unchanged before it is planned.
    pub settle: Duration,
    /// The folder has been read once: a file absent now is not in it.
    pub scanned: bool,
    /// Asks the missions task to read a file again (an upload found it changed).
    rechecks: Option<mpsc::UnboundedSender<String>>,
}

impl Catalog {
    /// Every mission that reads as one.
    pub fn missions(&self) -> impl Iterator<Item = &Mission> {
        self.entries.values().filter_map(|e| e.mission.as_deref())
    }

    pub fn get(&self, name: &str) -> Option<&Arc<MissionEntry>> {
        self.entries.get(name)
    }

    /// Asks the missions task to read file `name` again, as if it had just changed.
    pub fn recheck(&self, name: &str) {
        if let Some(tx) = &self.rechecks {
            let _ = tx.send(name.to_string());
        }
    }
}

/// The catalog as it changes.
pub type CatalogRx = watch::Receiver<Arc<Catalog>>;

/// How the folder is planned.
#[derive(Debug, Clone)]
pub struct PlanSettings {
    pub model: Arc<VehicleModel>,
    /// The solves' options. Its `time_limit` is also the wall-clock limit of planning one file,
    /// everything included (at least [`MIN_PLAN_LIMIT`]): a plan still running then is stopped
    /// and the file listed as an error.
    pub solver: solver::Options,
    pub watch: WatchSettings,
}

/// How long a file must stay unchanged before it is read and planned by default: 2 s. A copy
/// over SMB or scp, or a ground station exporting a mission, writes in bursts with pauses well
/// under a second, and FAT and exFAT (SD cards, USB sticks) stamp modification times to 2 s;
/// a file dropped in whole is still listed planned a couple of seconds later.
pub const DEFAULT_SETTLE: Duration = Duration::from_secs(2);

/// The least time planning one file is given, whatever the solver's time limit (a zero limit
/// asks the solves to be quick, not the file to fail).
pub const MIN_PLAN_LIMIT: Duration = Duration::from_secs(1);

/// The share of the time left that a plan's solves get; pricing the legs, the sorties' split
/// and the plan's JSON take the rest (at 2000 waypoints pricing alone takes seconds).
const SOLVE_SHARE: f64 = 0.5;

/// How long after its limit a plan whose thread has not stopped is listed as an error anyway
/// (every long loop looks at the cancel token; this only keeps the listing honest if one
/// does not).
const WATCHDOG_GRACE: Duration = Duration::from_secs(2);

/// The longest time limit honoured (keeps `Instant` arithmetic from overflowing).
const YEAR: Duration = Duration::from_secs(365 * 24 * 3600);

/// How the folder is watched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WatchSettings {
    /// How long a file's size and modification time must stay the same before it is read and
    /// planned (see [`DEFAULT_SETTLE`]).
    pub settle: Duration,
    /// Files planned at the same time, each on a blocking thread of its own.
    pub plans_at_once: usize,
}

impl Default for WatchSettings {
    fn default() -> Self {
        WatchSettings {
            settle: DEFAULT_SETTLE,
            plans_at_once: default_plans_at_once(),
        }
    }
}

/// One plan per core, at least two (so one large file never holds the only slot while a small
/// one waits) and at most four (each large plan holds its cost matrices).
pub fn default_plans_at_once() -> usize {
    std::thread::available_parallelism().map_or(2, |n| n.get().clamp(2, 4))
}

/// The wall-clock limit of planning one file.
fn plan_limit(solver: &solver::Options) -> Duration {
    solver.time_limit.clamp(MIN_PLAN_LIMIT, YEAR)
}

/// A file seen in the folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Seen {
    len: u64,
    modified_ms: u64,
}

fn seen_of(meta: &std::fs::Metadata) -> Seen {
    let modified_ms = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_millis() as u64);
    Seen {
        len: meta.len(),
        modified_ms,
    }
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
        found.insert(name, (path, seen_of(&meta)));
    }
    Ok(found)
}

/// Reads and plans one mission file (blocking; stopped by the thread's cancel token).
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
    // The solves get a share of the time left, the rest is for everything else.
    let solves = || solver::Options {
        time_limit: cancel::limit(settings.solver.time_limit).mul_f64(SOLVE_SHARE),
        ..settings.solver
    };
    let options = PlanOptions {
        orders: Orders::All,
        solver: solves(),
        sorties: false,
        pricing: crate::physics::Pricing::Settled,
    };
    let failed = |e: crate::planner::PlannerError| {
        Outcome::Failed(MissionProblem {
            stage: "plan".into(),
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
            solver: solves(),
            ..options
        };
        match plan_mission(&mission, &settings.model, &split) {
            Ok(p) => plan = p,
            Err(e) => sorties_error = Some(e.to_string()),
        }
    }
    let document = match serde_json::to_value(mission_document(&plan, &mission)) {
        Ok(d) => d,
        Err(e) => {
            return (
                Some(mission),
                Outcome::Failed(MissionProblem {
                    stage: "plan".into(),
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

/// Checks, before an upload, that `entry`'s file still holds the bytes that were planned.
/// Refused (409) while the file is changing, or when its bytes differ from the planned ones
/// (then the missions task reads and plans it again).
pub async fn unchanged(catalog: &Catalog, entry: &MissionEntry) -> Result<(), Refusal> {
    if matches!(entry.outcome, Outcome::Changing) {
        return Err(Refusal::new(
            409,
            "mission",
            &format!(
                "{} is changing (being written): it is planned once it has stayed unchanged \
                 for {} ms; upload it then",
                entry.path.display(),
                catalog.settle.as_millis()
            ),
        ));
    }
    let now = match tokio::fs::read(&entry.path).await {
        Ok(bytes) => digest(&bytes),
        Err(e) => {
            catalog.recheck(&entry.name);
            return Err(Refusal::new(
                409,
                "mission",
                &format!(
                    "{} cannot be read again before uploading it ({e}): not uploaded",
                    entry.path.display()
                ),
            ));
        }
    };
    if now != entry.digest {
        catalog.recheck(&entry.name);
        return Err(Refusal::new(
            409,
            "mission",
            &format!(
                "{} changed since it was planned (digest {} planned, {now} now): not uploaded; \
                 it is planned again once it has stayed unchanged for {} ms",
                entry.path.display(),
                entry.digest,
                catalog.settle.as_millis()
            ),
        ));
    }
    Ok(())
}

/// Starts the missions task on `dir` (which must exist); it runs until `stop`.
pub fn spawn(
    dir: PathBuf,
    settings: PlanSettings,
    hub: Arc<Hub>,
    stop: watch::Receiver<bool>,
) -> (CatalogRx, tokio::task::JoinHandle<()>) {
    let (recheck_tx, recheck) = mpsc::unbounded_channel();
    let (tx, rx) = watch::channel(Arc::new(Catalog {
        dir: dir.clone(),
        entries: BTreeMap::new(),
        settle: settings.watch.settle,
        scanned: false,
        rechecks: Some(recheck_tx),
    }));
    let (done_tx, done) = mpsc::unbounded_channel();
    let folder = Folder {
        permits: Arc::new(Semaphore::new(settings.watch.plans_at_once.max(1))),
        dir,
        settings,
        hub,
        catalog: tx,
        files: BTreeMap::new(),
        done_tx,
        next_job: 0,
    };
    let task = tokio::spawn(run(folder, recheck, done, stop));
    (rx, task)
}

/// One plan in progress.
#[derive(Debug)]
struct Job {
    id: u64,
    cancel: Cancel,
}

/// What the missions task knows of one file.
#[derive(Debug)]
struct Watched {
    path: PathBuf,
    seen: Seen,
    /// When `seen` last changed (or the file appeared, or an upload found it changed).
    changed_at: Instant,
    /// First seen already older than the settle time: read at once.
    old: bool,
    /// The digest of the bytes read since the last change (planned, being planned or reused).
    read: Option<String>,
    job: Option<Job>,
    /// The last finished entry (planned or failed): reused when the file settles with the same
    /// bytes (touched, or written back as it was).
    done: Option<Arc<MissionEntry>>,
}

/// How a plan job ended.
#[derive(Debug)]
enum Ended {
    Finished {
        mission: Option<Box<Mission>>,
        outcome: Outcome,
        seconds: f64,
    },
    /// The file's bytes changed while it was planned: the plan is not theirs.
    Stale,
}

#[derive(Debug)]
struct Done {
    name: String,
    id: u64,
    ended: Ended,
}

/// The missions task's state: the folder, its files, the plans in progress.
struct Folder {
    dir: PathBuf,
    settings: PlanSettings,
    hub: Arc<Hub>,
    catalog: watch::Sender<Arc<Catalog>>,
    files: BTreeMap<String, Watched>,
    /// Bounds the plans running at once.
    permits: Arc<Semaphore>,
    done_tx: mpsc::UnboundedSender<Done>,
    next_job: u64,
}

async fn run(
    mut folder: Folder,
    mut rechecks: mpsc::UnboundedReceiver<String>,
    mut done: mpsc::UnboundedReceiver<Done>,
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
            w.watch(&folder.dir, notify::RecursiveMode::NonRecursive)?;
            Ok(w)
        })
    };
    let poll = match &watcher {
        Ok(_) => None,
        Err(e) => {
            tracing::warn!(
                "cannot watch {} ({e}); looking at it every 2 s instead",
                folder.dir.display()
            );
            Some(Duration::from_secs(2))
        }
    };
    let mut rescan_at = Some(Instant::now());
    loop {
        if rescan_at.is_some_and(|at| Instant::now() >= at) {
            rescan_at = None;
            folder.rescan().await;
            folder
                .catalog
                .send_if_modified(|c| !std::mem::replace(&mut Arc::make_mut(c).scanned, true));
        }
        if *stop.borrow() {
            break;
        }
        // The next look: a change seen (250 ms after its first event, so a burst of events
        // is one look and a file written for a long time is still seen changing), a file
        // due to settle, or the poll.
        let wake = [
            rescan_at,
            folder.next_settle(),
            poll.map(|p| Instant::now() + p),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or_else(|| Instant::now() + YEAR);
        tokio::select! {
            _ = stop.changed() => break,
            got = changes.recv() => match got {
                Some(()) => {
                    rescan_at.get_or_insert_with(|| Instant::now() + THROTTLE);
                }
                None => break,
            },
            Some(name) = rechecks.recv() => {
                folder.recheck(&name);
                rescan_at = Some(Instant::now());
            }
            Some(finished) = done.recv() => folder.finished(finished),
            _ = tokio::time::sleep_until(wake.into()) => {
                rescan_at.get_or_insert_with(Instant::now);
            }
        }
    }
    // Stopping: the plans in progress stop too (their threads would hold the runtime's
    // shutdown).
    for w in folder.files.values_mut() {
        if let Some(job) = w.job.take() {
            job.cancel.cancel();
        }
    }
}

/// How long after the first event of a burst the folder is read.
const THROTTLE: Duration = Duration::from_millis(250);

impl Folder {
    fn publish(&self, entry: MissionEntry) -> Arc<MissionEntry> {
        let entry = Arc::new(entry);
        self.publish_arc(entry.clone());
        entry
    }

    fn publish_arc(&self, entry: Arc<MissionEntry>) {
        self.catalog.send_modify(|c| {
            let mut next = (**c).clone();
            next.entries.insert(entry.name.clone(), entry);
            *c = Arc::new(next);
        });
    }

    /// Lists `name` as changing: no plan until it settles.
    fn changing(&self, name: &str) {
        let Some(w) = self.files.get(name) else {
            return;
        };
        let already = self
            .catalog
            .borrow()
            .get(name)
            .is_some_and(|e| matches!(e.outcome, Outcome::Changing));
        if already {
            return;
        }
        self.publish(MissionEntry {
            name: name.to_string(),
            path: w.path.clone(),
            digest: String::new(),
            modified_ms: w.seen.modified_ms,
            mission: None,
            outcome: Outcome::Changing,
        });
    }

    /// The earliest time a changing file is due to settle.
    fn next_settle(&self) -> Option<Instant> {
        self.files
            .values()
            .filter(|w| w.read.is_none())
            .map(|w| w.changed_at + self.settings.watch.settle)
            .min()
    }

    /// Forgets what was read of `name` (an upload found its bytes changed): it settles and is
    /// read again.
    fn recheck(&mut self, name: &str) {
        if let Some(w) = self.files.get_mut(name) {
            w.changed_at = Instant::now();
            w.old = false;
            w.read = None;
            if let Some(job) = w.job.take() {
                job.cancel.cancel();
            }
            self.changing(name);
        }
    }

    /// Reads the folder: files gone are dropped (their plans stopped), files changed listed
    /// as changing (their plans stopped), files settled read and planned.
    async fn rescan(&mut self) {
        let found = match scan(&self.dir) {
            Ok(found) => found,
            Err(e) => {
                tracing::error!("missions folder {}: {e}", self.dir.display());
                return;
            }
        };
        let gone: Vec<String> = self
            .files
            .keys()
            .filter(|name| !found.contains_key(*name))
            .cloned()
            .collect();
        for name in gone {
            if let Some(job) = self.files.remove(&name).and_then(|w| w.job) {
                job.cancel.cancel();
                tracing::info!(mission = %super::escape_controls(&name), "mission file removed while planned: planning stopped");
            } else {
                tracing::info!(mission = %super::escape_controls(&name), "mission file removed");
            }
            self.catalog.send_modify(|c| {
                let mut next = (**c).clone();
                next.entries.remove(&name);
                *c = Arc::new(next);
            });
            self.hub.publish(&Event::MissionRemoved { name });
        }
        let now = Instant::now();
        let settle = self.settings.watch.settle;
        for (name, (path, seen)) in found {
            match self.files.get_mut(&name) {
                None => {
                    // A file already older than the settle time (there when the service
                    // started, or moved in whole) is read at once; FAT's 2 s stamps are
                    // allowed for.
                    let age_ms = SystemTime::now()
                        .duration_since(UNIX_EPOCH)
                        .map_or(0, |d| d.as_millis() as u64)
                        .saturating_sub(seen.modified_ms);
                    let old = u128::from(age_ms) >= settle.as_millis() + 2000;
                    self.files.insert(
                        name.clone(),
                        Watched {
                            path,
                            seen,
                            changed_at: now,
                            old,
                            read: None,
                            job: None,
                            done: None,
                        },
                    );
                    if !old {
                        self.changing(&name);
                    }
                }
                Some(w) if w.seen != seen => {
                    w.seen = seen;
                    w.changed_at = now;
                    w.old = false;
                    w.read = None;
                    if let Some(job) = w.job.take() {
                        job.cancel.cancel();
                        tracing::info!(mission = %super::escape_controls(&name), "mission file changed while planned: planning stopped");
                    }
                    self.changing(&name);
                }
                Some(_) => {}
            }
            let Some(w) = self.files.get(&name) else {
                continue;
            };
            if w.read.is_none() && (w.old || now >= w.changed_at + settle) {
                self.settled(&name).await;
            }
        }
    }

    /// Reads a file that has settled: plans it, or lists its last plan again if its bytes are
    /// the ones planned.
    async fn settled(&mut self, name: &str) {
        let Some(path) = self.files.get(name).map(|w| w.path.clone()) else {
            return;
        };
        let read = tokio::fs::read(&path).await;
        let after = std::fs::metadata(&path).ok().map(|m| seen_of(&m));
        let Some(w) = self.files.get_mut(name) else {
            return;
        };
        let bytes = match read {
            Ok(bytes) if after == Some(w.seen) => bytes,
            Ok(_) => {
                // Written while read: it settles again.
                if let Some(seen) = after {
                    w.seen = seen;
                }
                w.changed_at = Instant::now();
                w.old = false;
                self.changing(name);
                return;
            }
            Err(e) => {
                // Listed with why, and read again when it changes.
                tracing::warn!(mission = %super::escape_controls(name), "not read: {e}");
                w.read = Some(String::new());
                w.done = None;
                let entry = MissionEntry {
                    name: name.to_string(),
                    path: path.clone(),
                    digest: String::new(),
                    modified_ms: w.seen.modified_ms,
                    mission: None,
                    outcome: Outcome::Failed(MissionProblem {
                        stage: "mission".into(),
                        message: format!("{}: cannot be read ({e})", path.display()),
                        line: None,
                        item: None,
                    }),
                };
                let entry = self.publish(entry);
                self.hub.publish(&Event::MissionError(entry.summary()));
                return;
            }
        };
        let digest = digest(&bytes);
        w.read = Some(digest.clone());
        let seen = w.seen;
        if let Some(done) = w.done.clone().filter(|d| d.digest == digest) {
            // Touched, or written back as it was: its plan still holds.
            self.publish(MissionEntry {
                modified_ms: seen.modified_ms,
                ..(*done).clone()
            });
            return;
        }
        self.start(name, path, bytes, digest, seen);
    }

    /// Plans `bytes` of file `name` on a blocking thread, once a permit is free.
    fn start(&mut self, name: &str, path: PathBuf, bytes: Vec<u8>, digest: String, seen: Seen) {
        let id = self.next_job;
        self.next_job += 1;
        let cancel = Cancel::new();
        if let Some(w) = self.files.get_mut(name) {
            w.job = Some(Job {
                id,
                cancel: cancel.clone(),
            });
        }
        self.publish(MissionEntry {
            name: name.to_string(),
            path: path.clone(),
            digest: digest.clone(),
            modified_ms: seen.modified_ms,
            mission: None,
            outcome: Outcome::Planning,
        });
        let permits = self.permits.clone();
        let settings = self.settings.clone();
        let done = self.done_tx.clone();
        let name = name.to_string();
        tokio::spawn(async move {
            let Ok(permit) = permits.acquire_owned().await else {
                return;
            };
            if cancel.cancelled() {
                return;
            }
            let limit = plan_limit(&settings.solver);
            let started = Instant::now();
            let token = cancel.clone().with_deadline(started + limit);
            let thread_token = token.clone();
            let span = tracing::info_span!("plan", mission = %super::escape_controls(&name));
            let thread = tokio::task::spawn_blocking(move || {
                // Held until the thread ends, whatever the watchdog below decides.
                let _permit = permit;
                let planned = span.in_scope(|| {
                    cancel::within(&thread_token, || plan_file(&path, &bytes, &settings))
                });
                // The bytes planned must still be the file's.
                let now = std::fs::read(&path).ok().map(|b| self::digest(&b));
                (planned, now == Some(digest))
            });
            let exceeded = || {
                Outcome::Failed(MissionProblem {
                    stage: "plan".into(),
                    message: format!(
                        "planning exceeded the {} s limit (serve --time-limit) and was stopped",
                        limit.as_secs_f64()
                    ),
                    line: None,
                    item: None,
                })
            };
            let ended = match tokio::time::timeout(limit + WATCHDOG_GRACE, thread).await {
                Ok(Ok(_)) if cancel.cancelled() => return,
                Ok(Ok((_, false))) => Ended::Stale,
                Ok(Ok(((mission, outcome), true))) => Ended::Finished {
                    outcome: if token.expired() { exceeded() } else { outcome },
                    mission: mission.map(Box::new),
                    seconds: started.elapsed().as_secs_f64(),
                },
                Ok(Err(e)) => Ended::Finished {
                    mission: None,
                    outcome: Outcome::Failed(MissionProblem {
                        stage: "plan".into(),
                        message: format!("planning stopped: {e}"),
                        line: None,
                        item: None,
                    }),
                    seconds: started.elapsed().as_secs_f64(),
                },
                Err(_) => {
                    token.cancel();
                    Ended::Finished {
                        mission: None,
                        outcome: exceeded(),
                        seconds: started.elapsed().as_secs_f64(),
                    }
                }
            };
            let _ = done.send(Done { name, id, ended });
        });
    }

    /// A plan ended: listed, unless its file changed or went away meanwhile.
    fn finished(&mut self, done: Done) {
        let Some(w) = self.files.get_mut(&done.name) else {
            return;
        };
        if w.job.as_ref().map(|j| j.id) != Some(done.id) {
            return;
        }
        w.job = None;
        let (mission, outcome, seconds) = match done.ended {
            Ended::Stale => {
                w.changed_at = Instant::now();
                w.old = false;
                w.read = None;
                self.changing(&done.name);
                return;
            }
            Ended::Finished {
                mission,
                outcome,
                seconds,
            } => (mission.map(|m| *m), outcome, seconds),
        };
        let entry = Arc::new(MissionEntry {
            name: done.name.clone(),
            path: w.path.clone(),
            digest: w.read.clone().unwrap_or_default(),
            modified_ms: w.seen.modified_ms,
            mission: mission.map(Arc::new),
            outcome,
        });
        w.done = Some(entry.clone());
        self.publish_arc(entry.clone());
        let span = tracing::info_span!("plan", mission = %super::escape_controls(&done.name));
        span.in_scope(|| match &entry.outcome {
            Outcome::Failed(p) => tracing::warn!("{}", super::escape_controls(&p.message)),
            _ => tracing::info!(seconds, "planned"),
        });
        self.hub.publish(&match entry.outcome {
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
