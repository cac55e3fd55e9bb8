//! Splitting a mission one battery cannot fly into sorties (in progress).
