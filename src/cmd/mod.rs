//! One module per `emplan` subcommand: argument structs (clap) and the code that runs them.

pub mod calibrate;
pub mod convert;
pub mod download;
pub mod energy;
pub mod mock_autopilot;
pub mod plan;
pub mod table;
pub mod tsp;
pub mod upload;
