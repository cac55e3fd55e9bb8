//! Blocks: a fixed run of a mission's waypoints flown whole, entered at one end and left at the
//! other (a QGroundControl survey, corridor scan or structure scan, or a list written by hand in
//! TOML). The planner orders blocks with the single points, each block as a cluster of its
//! directions; a block's waypoints stay contiguous in every order, forward or (when reversible)
//! reversed, and its camera trigger stays on its own lines.
//!
//! Invariant: a block's waypoints are `first..first + len` of the mission's waypoints, at least
//! two, and no waypoint belongs to two blocks.
//!
//! The reversal ([`super::Mission::oriented`]): a reversed block flies the same lines last to
//! first. Each line is flown in the state (speed, camera trigger distance, region of interest,
//! gimbal: `mission::actions::Setting`) the file flies it in, and after the block the state is
//! the file's state after it; commands that are not settings (a photo, a hold, a yaw) stay with
//! their waypoint, each run in the state the file runs it in. So a survey entered at its far end
//! turns its trigger on at that end and off at the one it leaves from, and the points around it
//! see the states they see in the file.

use std::ops::Range;

use super::actions::{self, Action, Command, State};

/// What made a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BlockKind {
    /// QGroundControl's `survey` complex item (a polygon's grid of transects).
    Survey,
    /// QGroundControl's `CorridorScan` complex item (transects along a polyline).
    Corridor,
    /// QGroundControl's `StructureScan` complex item (layers round a structure).
    Structure,
    /// A list of waypoints written by hand (TOML `[[blocks]]`).
    Listed,
}

impl BlockKind {
    /// The word a plan prints for it.
    pub fn word(self) -> &'static str {
        match self {
            BlockKind::Survey => "survey",
            BlockKind::Corridor => "corridor scan",
            BlockKind::Structure => "structure scan",
            BlockKind::Listed => "block",
        }
    }
}

/// A block of a mission: waypoints `first..first + len`, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    pub name: String,
    pub kind: BlockKind,
    /// Index into the mission's waypoints of its first waypoint (in file order).
    pub first: usize,
    /// How many waypoints it has (at least two).
    pub len: usize,
    /// Whether it may be flown last waypoint first (the same lines, each reversed).
    pub reversible: bool,
    /// The complex item as a `.plan` gave it, kept to write it back as QGroundControl reads it
    /// (None for a block written by hand).
    pub source: Option<serde_json::Value>,
}

impl Block {
    /// Its waypoints, as indices into the mission's waypoints, in file order.
    pub fn waypoints(&self) -> Range<usize> {
        self.first..self.first + self.len
    }

    /// Whether waypoint `k` (0-based) is one of its.
    pub fn contains(&self, k: usize) -> bool {
        self.waypoints().contains(&k)
    }

    /// The waypoint it is entered at, flown forward or reversed.
    pub fn entry(&self, reversed: bool) -> usize {
        if reversed {
            self.first + self.len - 1
        } else {
            self.first
        }
    }

    /// The waypoint it is left from, flown forward or reversed.
    pub fn exit(&self, reversed: bool) -> usize {
        self.entry(!reversed)
    }

    /// Its waypoints in the order they are flown.
    pub fn flown(&self, reversed: bool) -> Vec<usize> {
        let mut w: Vec<usize> = self.waypoints().collect();
        if reversed {
            w.reverse();
        }
        w
    }
}

impl super::Mission {
    /// The block waypoint `k` (0-based) belongs to, if any (an index into `blocks`).
    pub fn block_of(&self, k: usize) -> Option<usize> {
        self.blocks.iter().position(|b| b.contains(k))
    }

    /// Whether the mission has blocks.
    pub fn has_blocks(&self) -> bool {
        !self.blocks.is_empty()
    }

    /// The mission with each block listed in `reversed` (indices into `blocks`; an unknown one
    /// is left out) laid out reversed in place: the waypoint at `first + i` moves to
    /// `first + len - 1 - i`, its setting commands rewritten by the reversal rule (module doc),
    /// its other commands and its hover kept. Flown in file order, the result flies every
    /// waypoint outside the reversed blocks in the file's state, every line of a reversed block
    /// in the file's state on that line, and leaves each block in the file's state after it.
    pub fn oriented(&self, reversed: &[usize]) -> super::Mission {
        let runs: Vec<Range<usize>> = reversed
            .iter()
            .filter_map(|&b| self.blocks.get(b))
            .map(Block::waypoints)
            .collect();
        self.reversing(&runs)
    }

    /// [`Self::oriented`] for runs of waypoints (file indices) rather than whole blocks: a part
    /// of a block a sortie flies reversed is flown by the same rule. A run that is shorter than
    /// two, goes beyond the waypoints or overlaps one before it is left as it is.
    pub fn reversing(&self, runs: &[Range<usize>]) -> super::Mission {
        let states = self.file_states();
        let mut out = self.clone();
        let mut taken = vec![false; self.waypoints.len()];
        for run in runs {
            if run.len() < 2 || run.end > self.waypoints.len() || run.clone().any(|k| taken[k]) {
                continue;
            }
            let (a, z) = (run.start, run.end - 1);
            // A setting the run clears is cleared by the run's own command (a survey's trigger
            // off as QGroundControl wrote it).
            let clearing: Vec<Command> = self.waypoints[run.clone()]
                .iter()
                .flat_map(|w| &w.actions)
                .filter(|c| matches!(c.action(), Action::Set(_)))
                .filter(|c| State::default().after(std::slice::from_ref(*c)) == State::default())
                .cloned()
                .collect();
            let setting_commands = |from: &State, to: &State| setting_commands(from, to, &clearing);
            // Arriving at the reversed entry in the state the file arrives at the block in.
            let mut state = states.before[a].clone();
            for k in (a..=z).rev() {
                taken[k] = true;
                let w = &self.waypoints[k];
                let mut commands = Vec::with_capacity(w.actions.len());
                let mut file_state = states.before[k].clone();
                for c in &w.actions {
                    if matches!(c.action(), Action::Set(_)) {
                        file_state = file_state.after(std::slice::from_ref(c));
                        continue;
                    }
                    // A photo, a hold or a yaw runs in the file's state at it.
                    let set = setting_commands(&state, &file_state);
                    state = state.after(&set);
                    commands.extend(set);
                    commands.push(c.clone());
                }
                // Leaving k reversed flies the file's line k - 1 (to k), in the file's state
                // on it; leaving the block's first waypoint, the file's state after the block.
                let leaving = if k > a {
                    &states.after[k - 1]
                } else {
                    &states.after[z]
                };
                let set = setting_commands(&state, leaving);
                state = state.after(&set);
                commands.extend(set);
                out.waypoints[a + z - k] = super::Waypoint {
                    actions: commands,
                    ..w.clone()
                };
            }
        }
        out
    }
}

/// The commands that take the settings in force from `from` to `to`, one per setting that
/// differs (the command that set it in the file, or the one that returns it to the vehicle's
/// own: the last of `clearing` that clears it, else the vehicle's own by
/// `actions::restoring`).
fn setting_commands(from: &State, to: &State, clearing: &[Command]) -> Vec<Command> {
    from.differences(to)
        .into_iter()
        .map(|setting| match to.get(setting) {
            Some(c) => c.clone(),
            None => clearing
                .iter()
                .rev()
                .find(|c| c.action() == Action::Set(setting))
                .cloned()
                .unwrap_or_else(|| actions::restoring(setting, None, None)),
        })
        .collect()
}

/// A test mission's survey: `lines` lines `length_m` long, `spacing_m` apart northwards from
/// `at`, flown back and forth as waypoints without a hold named `{name}1..`, the camera
/// trigger on every `trigger_m` at its entry and off at its exit (as QGroundControl writes a
/// survey's items), appended to `mission` as a reversible survey block.
#[cfg(test)]
pub(crate) fn with_survey(
    mut mission: super::Mission,
    name: &str,
    at: super::Enu,
    lines: usize,
    length_m: f64,
    spacing_m: f64,
    trigger_m: f64,
) -> super::Mission {
    let first = mission.waypoints.len();
    let trigger = |d: f64| {
        Command::new(
            actions::id::DO_SET_CAM_TRIGG_DIST,
            [d, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        )
    };
    for k in 0..2 * lines {
        let line = k / 2;
        let east = if (k % 2 == 0) == (line % 2 == 0) {
            0.0
        } else {
            length_m
        };
        mission.waypoints.push(super::Waypoint {
            name: format!("{name}{}", k + 1),
            position: super::Enu {
                x_east_m: at.x_east_m + east,
                y_north_m: at.y_north_m + spacing_m * line as f64,
                z_up_m: at.z_up_m,
            },
            hover_s: 0.0,
            actions: match k {
                0 => vec![trigger(trigger_m)],
                k if k + 1 == 2 * lines => vec![trigger(0.0)],
                _ => Vec::new(),
            },
            ..super::Waypoint::default()
        });
    }
    mission.blocks.push(Block {
        name: name.to_string(),
        kind: BlockKind::Survey,
        first,
        len: 2 * lines,
        reversible: true,
        source: None,
    });
    mission
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::actions::{id, FileStates};
    use crate::mission::{Enu, Geodetic, Mission, Origin, Waypoint};
    use proptest::prelude::*;

    fn speed(v: f64) -> Command {
        Command::new(id::DO_CHANGE_SPEED, [1.0, v, -1.0, 0.0, 0.0, 0.0, 0.0])
    }
    fn trigger(d: f64) -> Command {
        let now = if d > 0.0 { 1.0 } else { 0.0 };
        Command::new(id::DO_SET_CAM_TRIGG_DIST, [d, 0.0, now, 0.0, 0.0, 0.0, 0.0])
    }
    fn photo() -> Command {
        Command::new(id::DO_DIGICAM_CONTROL, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    }
    fn gimbal(pitch: f64) -> Command {
        Command::new(id::DO_MOUNT_CONTROL, [pitch, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0])
    }
    fn hold(s: f64) -> Command {
        Command::new(id::NAV_DELAY, [s, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0])
    }

    /// A mission of waypoints `W1..` 20 m apart with these actions, and one block over `run`.
    fn mission(actions: Vec<Vec<Command>>, run: Range<usize>) -> Mission {
        let waypoints = actions
            .into_iter()
            .enumerate()
            .map(|(k, actions)| Waypoint {
                name: format!("W{}", k + 1),
                position: Enu {
                    x_east_m: 20.0 * k as f64,
                    y_north_m: 0.0,
                    z_up_m: 0.0,
                },
                hover_s: if run.contains(&k) { 0.0 } else { 2.0 },
                actions,
                ..Waypoint::default()
            })
            .collect();
        Mission {
            name: "blocks".into(),
            origin: Origin {
                home: Geodetic {
                    lat_deg: 38.54,
                    lon_deg: -121.76,
                    alt_m: 18.0,
                },
                height_above_home_m: 10.0,
            },
            waypoints,
            default_hover_s: 2.0,
            min_height_above_home_m: 2.0,
            start_actions: Vec::new(),
            pois: Vec::new(),
            fence: Default::default(),
            rally: Vec::new(),
            blocks: vec![Block {
                name: "survey".into(),
                kind: BlockKind::Survey,
                first: run.start,
                len: run.len(),
                reversible: true,
                source: None,
            }],
            source: None,
        }
    }

    fn not_settings(w: &Waypoint) -> Vec<Command> {
        (w.actions.iter())
            .filter(|c| !matches!(c.action(), Action::Set(_)))
            .cloned()
            .collect()
    }

    /// The state in force at each command of a waypoint that is not a setting, file order.
    fn states_at_commands(w: &Waypoint, before: &State) -> Vec<State> {
        let mut state = before.clone();
        let mut out = Vec::new();
        for c in &w.actions {
            if matches!(c.action(), Action::Set(_)) {
                state = state.after(std::slice::from_ref(c));
            } else {
                out.push(state.clone());
            }
        }
        out
    }

    #[test]
    fn a_reversed_survey_turns_its_trigger_on_at_its_far_end_and_off_where_it_leaves() {
        // A point, a survey of four waypoints (trigger on at its entry, off at its exit), a point.
        let m = mission(
            vec![
                vec![photo()],
                vec![trigger(25.0)],
                vec![],
                vec![],
                vec![trigger(0.0)],
                vec![photo()],
            ],
            1..5,
        );
        let r = m.oriented(&[0]);
        let names: Vec<&str> = r.waypoints.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(names, ["W1", "W5", "W4", "W3", "W2", "W6"]);
        // Entered at W5: on there; left from W2: off there; nothing between.
        assert_eq!(r.waypoints[1].actions, vec![trigger(25.0)]);
        assert!(r.waypoints[2].actions.is_empty() && r.waypoints[3].actions.is_empty());
        assert_eq!(r.waypoints[4].actions, vec![trigger(0.0)]);
        // The points around it keep theirs, the flown-through waypoints their zero hover.
        assert_eq!(r.waypoints[0].actions, vec![photo()]);
        assert_eq!(r.waypoints[5].actions, vec![photo()]);
        assert!(r.waypoints[1..5].iter().all(|w| w.hover_s == 0.0));
        // Forward, or no block listed: the mission as it is.
        assert_eq!(m.oriented(&[]), m);
        assert_eq!(m.oriented(&[7]), m);
    }

    #[test]
    fn each_reversed_line_is_flown_at_the_files_speed_on_it() {
        // Lines W1-W2 at 5 m/s, W2-W3 at 8, after the block 3.
        let m = mission(
            vec![vec![speed(5.0)], vec![speed(8.0)], vec![speed(3.0)]],
            0..3,
        );
        let r = m.oriented(&[0]);
        let s = r.file_states();
        // W3 -> W2 at 8, W2 -> W1 at 5, then 3.
        assert_eq!(s.after[0].speed_m_s(), Some(8.0));
        assert_eq!(s.after[1].speed_m_s(), Some(5.0));
        assert_eq!(s.after[2].speed_m_s(), Some(3.0));
    }

    fn command_strategy() -> impl Strategy<Value = Command> {
        prop_oneof![
            (1u8..12).prop_map(|v| speed(f64::from(v))),
            Just(speed(-2.0)),
            (0u8..4).prop_map(|d| trigger(f64::from(d) * 10.0)),
            (-90i8..0).prop_map(|p| gimbal(f64::from(p))),
            Just(photo()),
            (1u8..5).prop_map(|s| hold(f64::from(s))),
        ]
    }

    fn check_reversed(
        m: &Mission,
        r: &Mission,
        file: &FileStates,
        run: Range<usize>,
    ) -> Result<(), TestCaseError> {
        let (a, z) = (run.start, run.end - 1);
        let at = |k: usize| if run.contains(&k) { a + z - k } else { k };
        let flown = r.file_states();
        for k in 0..m.waypoints.len() {
            let (w, v) = (&m.waypoints[k], &r.waypoints[at(k)]);
            prop_assert_eq!(&w.name, &v.name);
            prop_assert_eq!(w.hover_s, v.hover_s);
            // Photos, holds and yaws stay with their waypoint, in order, each run in the
            // file's state at it.
            prop_assert_eq!(w.photos(), v.photos());
            prop_assert_eq!(not_settings(w), not_settings(v));
            prop_assert_eq!(
                states_at_commands(w, &file.before[k]),
                states_at_commands(v, &flown.before[at(k)])
            );
            if !run.contains(&k) {
                prop_assert_eq!(&flown.before[k], &file.before[k]);
                prop_assert_eq!(&flown.after[k], &file.after[k]);
            }
        }
        // Every line of the block: the file flies W(j) -> W(j+1) in after[j]; reversed, it is
        // flown W(j+1) -> W(j), leaving W(j+1).
        for j in a..z {
            prop_assert_eq!(&flown.after[at(j + 1)], &file.after[j], "line {}", j);
        }
        // Left in the file's state after the block.
        prop_assert_eq!(&flown.after[z], &file.after[z]);
        prop_assert_eq!(&flown.end, &file.end);
        Ok(())
    }

    proptest! {
        /// A block with random settings and photos, reversed: every line of it in the file's
        /// state on that line, the state after it the file's, photos per waypoint conserved,
        /// every waypoint outside it as the file flies it.
        #[test]
        fn a_reversed_block_flies_each_line_in_the_files_state(
            actions in prop::collection::vec(prop::collection::vec(command_strategy(), 0..4), 2..10),
            ends in (0usize..10, 0usize..10),
        ) {
            let n = actions.len();
            let (x, y) = (ends.0 % n, ends.1 % n);
            let (a, z) = (x.min(y), x.max(y).max(x.min(y) + 1).min(n - 1));
            prop_assume!(z > a);
            let m = mission(actions, a..z + 1);
            let r = m.oriented(&[0]);
            check_reversed(&m, &r, &m.file_states(), a..z + 1)?;
            // Reversed twice: each line still in the file's state (the layout is the file's
            // again, the commands those of one reversal of the reversal).
            let back = r.oriented(&[0]);
            let names: Vec<&String> = back.waypoints.iter().map(|w| &w.name).collect();
            let file: Vec<&String> = m.waypoints.iter().map(|w| &w.name).collect();
            prop_assert_eq!(names, file);
            prop_assert_eq!(back.file_states().end, m.file_states().end);
        }
    }
}
