//! The paper's random-mission study (in progress).
