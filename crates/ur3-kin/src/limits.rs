//! Joint limits of the UR family: position limits (rad) and maximum joint speeds (rad/s).
//!
//! Speeds are the data sheets' "joint ranges / speed" rows (Universal Robots' technical
//! specifications of each model: UR3 and UR3e "wrist joints 360°/s, other joints 180°/s";
//! UR5 and UR5e "all joints 180°/s"; UR10 and UR10e "base and shoulder 120°/s, elbow and
//! wrists 180°/s"). Positions are the data sheets' ±360° per joint, with two changes that the ROS
//! descriptions make too (`ur_description/config/<model>/joint_limits.yaml`,
//! ros-industrial/universal_robot and UniversalRobots/Universal_Robots_ROS2_Description): the
//! elbow is limited to ±180° (self-collision; universal_robot issue #265), and the UR3's and
//! UR3e's wrist 3 turns without limit (their data sheets: "infinite rotation on the end joint";
//! ROS2 `has_position_limits: false`). The simulator wraps every joint to [−π, π], which lies
//! inside all of these.

use crate::UrModel;
use std::f64::consts::{PI, TAU};

/// A model's joint limits, base to wrist 3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower and upper position limit per joint (rad; infinite for a joint without limit).
    pub position: [[f64; 2]; 6],
    /// Maximum joint speed (rad/s).
    pub velocity: [f64; 6],
}

impl JointLimits {
    /// Whether every joint of `q` lies within its position limits.
    pub fn contains(&self, q: &[f64; 6]) -> bool {
        q.iter().zip(&self.position).all(|(v, [lo, hi])| *lo <= *v && *v <= *hi)
    }
}

const fn deg(d: f64) -> f64 {
    d * PI / 180.0
}

impl UrModel {
    /// This model's joint limits (module docs give the sources).
    pub fn joint_limits(&self) -> JointLimits {
        let full = [-TAU, TAU];
        let elbow = [-PI, PI];
        let free = [f64::NEG_INFINITY, f64::INFINITY];
        let (wrist3, velocity) = match self.name {
            "ur3" | "ur3e" => {
                (free, [deg(180.0), deg(180.0), deg(180.0), deg(360.0), deg(360.0), deg(360.0)])
            }
            "ur10" | "ur10e" => {
                (full, [deg(120.0), deg(120.0), deg(180.0), deg(180.0), deg(180.0), deg(180.0)])
            }
            _ => (full, [deg(180.0); 6]),
        };
        JointLimits { position: [full, full, elbow, full, full, wrist3], velocity }
    }
}
