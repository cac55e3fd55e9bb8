//! `--pack NAME` and `--ledger PATH|URL` of the commands that fly, record or plan: the pack
//! named, the ledger read for what earlier flights taught (`emplan::session::ledger`), and the
//! planning vehicle on that pack.

use std::path::Path;

use anyhow::Context;
use emplan::flightlog::flight_plan::{PackSource, PackUse};
use emplan::ledger::LedgerSpec;
use emplan::session::ledger::Learned;

/// The pack flown and the ledger.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct PackArgs {
    /// The battery pack flown, by name (its label or serial): kept with the flight (plan.json,
    /// the ledger), and the capacity the ledger learned of it in earlier flights is what the
    /// battery check and the energy guard start from. Without it, the pack the autopilot names
    /// (SMART_BATTERY_INFO), if it names one
    #[arg(long, value_name = "NAME")]
    pub pack: Option<String>,
    /// The ledger flights are written to and learned from: a SQLite file, or a postgres:// URL
    /// (default: ledger.sqlite in the log directory, beside the flights)
    #[arg(long, value_name = "PATH|postgres://...")]
    pub ledger: Option<String>,
}

impl PackArgs {
    /// The pack named, checked.
    pub fn name(&self) -> anyhow::Result<Option<String>> {
        (self.pack.as_deref())
            .map(|p| emplan::session::ledger::pack_name(p).context("--pack"))
            .transpose()
    }

    /// The ledger: `--ledger`, else the one in `log_dir`.
    pub fn spec(&self, log_dir: &Path) -> LedgerSpec {
        match &self.ledger {
            Some(text) => LedgerSpec::parse(text),
            None => emplan::session::ledger::default_spec(log_dir),
        }
    }

    /// `--ledger` only (the recorder's default is the log directory's).
    pub fn given(&self) -> Option<LedgerSpec> {
        self.ledger.as_deref().map(LedgerSpec::parse)
    }

    /// What the ledger (`--ledger`, else the one in `log_dir`) knows of the pack named and of
    /// `vehicle`, its notes said on stderr; nothing without a pack named. A ledger that does
    /// not exist is not created (nothing learned yet).
    pub fn learned(&self, log_dir: &Path, vehicle: &str) -> anyhow::Result<Option<Pack>> {
        let Some(name) = self.name()? else {
            return Ok(None);
        };
        let spec = self.spec(log_dir);
        let learned = emplan::session::ledger::learned(&spec, Some(&name), vehicle)
            .with_context(|| format!("--pack {name}: reading the ledger"))?;
        for note in &learned.notes {
            eprintln!("note: {note}");
        }
        Ok(Some(Pack { name, learned }))
    }
}

/// A pack named, and what the ledger taught of it and of the vehicle.
#[derive(Debug, Clone)]
pub struct Pack {
    pub name: String,
    pub learned: Learned,
}

impl Pack {
    /// plan.json's pack (named by the user).
    pub fn used(&self) -> PackUse {
        self.learned.pack_use(&self.name, PackSource::User)
    }

    /// The battery check's keys: the pack, its capacity ratio and flights.
    pub fn battery(
        &self,
        battery: emplan::planner::json::BatteryJson,
    ) -> emplan::planner::json::BatteryJson {
        let ratio = self
            .learned
            .pack
            .as_ref()
            .map(|_| self.learned.capacity_ratio());
        battery.on_pack(&self.name, ratio, self.learned.pack_flights())
    }

    /// The line the text output says of it.
    pub fn line(&self) -> String {
        match &self.learned.pack {
            Some(p) => format!(
                "pack {}: {:.3} of its label as learned from {} flights (the ledger's): the battery is checked with it",
                self.name, p.capacity_ratio, p.flights
            ),
            None => format!("pack {}: nothing learned of it yet: the battery is checked on its label", self.name),
        }
    }
}
