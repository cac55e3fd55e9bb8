//! The integration test binary: one crate, one link step (modules below).

mod cli;
mod mission;
mod physics;
mod solvers;
mod sorties;
mod study;
mod tidy;
mod upload;
