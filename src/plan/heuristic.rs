//! Direction-preserving local search for large asymmetric tours (in progress).
