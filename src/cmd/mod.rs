//! One module per `emplan` subcommand: argument structs (clap) and the code that runs them.

pub mod convert;
pub mod plan;
pub mod tsp;
