//! emplan: a ground-control mission planner that orders multirotor waypoint missions by minimum
//! energy, uploads them over MAVLink with a verified read-back, and measures per-leg energy.
//!
//! Layers (dependencies point down only; see ARCHITECTURE.md):
//! `mission` (files, geodesy) -> `physics` (energy model and table) and `tour` (cost matrices,
//! ATSP solvers, baselines, sorties; never imports `physics`) -> `planner` (a mission and a
//! vehicle in, a priced and checked `Plan` out) ; `link` (MAVLink) and `sim` (mock autopilot).

pub mod flightlog;
pub mod ledger;
pub mod link;
pub mod logfit;
pub mod mission;
pub mod names;
pub mod output;
pub mod physics;
pub mod planner;
pub mod plot;
pub mod rng;
pub mod service;
pub mod session;
pub mod sim;
pub mod tour;
