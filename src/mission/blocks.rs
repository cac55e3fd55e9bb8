//! Blocks: a fixed run of a mission's waypoints flown whole, entered at one end and left at the
//! other (a QGroundControl survey, corridor scan or structure scan, or a list written by hand in
//! TOML). The planner orders blocks with the single points, each block as a cluster of its
//! directions; a block's waypoints stay contiguous in every order, forward or (when reversible)
//! reversed, and its camera trigger stays on its own lines.
//!
//! Invariant: a block's waypoints are `first..first + len` of the mission's waypoints, at least
//! two, and no waypoint belongs to two blocks.

use std::ops::Range;

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
}
