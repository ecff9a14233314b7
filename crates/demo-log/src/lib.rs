//! demo-log (under construction).
