//! The per-frame teleoperation loop of mimicrete (paper §3.2), in one place for the live server
//! and the hand-log converter: a hand frame and its gesture in, the control steps that fell due
//! out, each recorded into the demo.
//!
//! ```text
//! hand frame ─► One Euro filter ─► hand_to_target ─► IK (warm, unwrapped) ─► joint action
//!   gesture ─► command (suction: only its switches) ───────────────────────┘      │
//!                                                         tile-sim step ◄─────────┘
//!                                                              └─► demo-log record
//! ```
//!
//! The gesture classifier (an SVM, scikit-learn) stays with the caller: each frame comes with its
//! raw class and the smoothed one ([`Frame`]). Everything after that is here, so a caller crosses
//! into Rust once per hand frame.

mod clutch;
mod filter;
pub mod scene;
mod session;

pub use clutch::{Clutch, ClutchInput, MAX_STEP_M, MAX_STEP_RAD, Mapping, step_toward};
pub use filter::OneEuro;
pub use session::{Counts, Frame, Links, NotFollowing, Outcome, Recorder, Session, SessionConfig, Step};

use std::f64::consts::{PI, TAU};
use tile_sim::Task;

/// Largest joint change (rad) an IK answer may ask for in one step before it counts as a jump to
/// another branch (unreachable), not a motion.
pub const BRANCH_JUMP: f64 = 1.5;

/// Gesture class → (end-effector command, spin): tile-sim's action `a[6]`, `a[7]`.
pub const GESTURE_COMMANDS: [(&str, f32, f32); 8] = [
    ("closing", 1.0, 0.0),
    ("opening", -1.0, 0.0),
    ("fixed", 0.0, 0.0),
    ("closing_tightening", 1.0, 1.0),
    ("closing_loosening", 1.0, -1.0),
    ("closing_fixed", 1.0, 0.0),
    ("opening_stopped", -1.0, 0.0),
    ("fixed_stopped", 0.0, 0.0),
];

/// The command and spin of gesture class `name` (None: not a class).
pub fn command_of(name: &str) -> Option<(f32, f32)> {
    GESTURE_COMMANDS.iter().find(|(g, ..)| *g == name).map(|&(_, c, s)| (c, s))
}

/// Errors of a session.
#[derive(Debug, thiserror::Error)]
pub enum TeleopError {
    /// A frame's joint count does not match the session's layout.
    #[error("hand frame has {got} joints, layout {layout} has {expected}")]
    JointCount { layout: &'static str, expected: usize, got: usize },
    /// A frame's time is NaN or infinite.
    #[error("frame time {0} is not finite")]
    Time(f64),
    /// The smoothed gesture is not one of [`GESTURE_COMMANDS`].
    #[error("unknown gesture class {0:?}")]
    UnknownGesture(String),
    /// The session's task spec runs another task's logic than the session's task.
    #[error("the task spec runs {spec}'s logic, the session is {session}")]
    SpecTask { spec: &'static str, session: &'static str },
    /// The simulator refused a step or a reset.
    #[error(transparent)]
    Sim(#[from] tile_sim::SimError),
    /// The recorder failed.
    #[error(transparent)]
    Demo(#[from] demo_log::DemoError),
}

/// Angle wrapped to `[-π, π)`, as numpy's `(a + π) % 2π − π` (floored remainder).
pub fn wrap_to_pi(a: f64) -> f64 {
    let mut m = (a + PI) % TAU;
    if m != 0.0 {
        if m < 0.0 {
            m += TAU;
        }
    } else {
        m = 0.0;
    }
    m - PI
}

/// The end-effector command a demo step records and the env receives, given the newest
/// observation frame. tile-sim's suction latches (on stays on until a drop), so a command that
/// repeats the suction's state (`frame[6]`: +1 on, −1 off) is sent as "fixed" (0): the robot does
/// exactly the same, and the demo marks the two decisions (switch on, drop) instead of labelling
/// every approach step "drop" and every carry step "on" (with level labels a policy keeps some
/// probability of "drop" in carry states, and every such sample loses the tile). The gripper
/// moves only while commanded, so its commands (and the screw's spin) stay as gestured.
pub fn recorded_command(task: Task, cmd: f32, frame: &[f32]) -> f32 {
    // TileRow's and TilePlace's suction heads latch as TileSuction's, and their frame[6] is the
    // suction switch too.
    if !matches!(task, Task::TileSuction | Task::TileRow | Task::TilePlace) {
        return cmd;
    }
    let on = frame[6] > 0.0;
    if (cmd >= 0.5 && on) || (cmd <= -0.5 && !on) { 0.0 } else { cmd }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_keeps_the_floored_remainders_range() {
        for a in [-10.0, -PI, -1.0, 0.0, 1.0, PI, 3.5, 10.0, 1e6] {
            let w = wrap_to_pi(a);
            assert!((-PI..PI).contains(&w), "{a} -> {w}");
            let k = ((a - w) / TAU).round();
            assert!((a - w - k * TAU).abs() < 1e-9, "{a} -> {w} is not a + 2πk");
        }
        assert_eq!(wrap_to_pi(PI), -PI);
    }

    #[test]
    fn the_suction_is_commanded_only_when_it_switches() {
        let mut frame = [0.0f32; 10];
        frame[6] = -1.0; // off
        assert_eq!(recorded_command(Task::TileSuction, 1.0, &frame), 1.0);
        assert_eq!(recorded_command(Task::TileSuction, -1.0, &frame), 0.0);
        frame[6] = 1.0;
        assert_eq!(recorded_command(Task::TileSuction, 1.0, &frame), 0.0);
        assert_eq!(recorded_command(Task::TileSuction, -1.0, &frame), -1.0);
        assert_eq!(recorded_command(Task::BlockGrip, 1.0, &frame), 1.0);
        // TilePlace's frame has TileSuction's suction switch at [6]
        assert_eq!(recorded_command(Task::TilePlace, 1.0, &frame), 0.0);
        assert_eq!(recorded_command(Task::TilePlace, -1.0, &frame), -1.0);
        frame[6] = -1.0;
        assert_eq!(recorded_command(Task::TilePlace, -1.0, &frame), 0.0);
    }
}
