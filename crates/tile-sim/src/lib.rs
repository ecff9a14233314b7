//! tile-sim (under construction).
