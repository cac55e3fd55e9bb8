//! The integration test binary: one crate, one link step (modules below).

mod mission;
mod tidy;
