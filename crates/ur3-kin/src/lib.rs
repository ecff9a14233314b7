//! Kinematics of the Universal Robots arms (UR3 first, the family beside it).
//!
//! Frames: everything is expressed in the UR controller's "Base" frame (DH frame 0, Z up, metres,
//! radians). The end effector is `tool0`: the flange with a zero TCP, i.e. what the pendant and
//! RTDE report. Standard DH convention: `T_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`.

mod error;
mod fk;
mod hand;
mod model;

pub use error::KinError;
pub use fk::{fk, fk_all};
pub use hand::{HandLayout, Handedness, Space};
pub use model::{MODELS, UR3, UR3E, UR5, UR5E, UR10, UR10E, UrModel};
pub use nalgebra;

/// Joint angles of a 6-axis UR arm, radians, base to wrist 3.
pub type Joints = [f64; 6];

/// A rigid transform in f64 (rotation + translation), the pose type of this crate.
pub type Pose = nalgebra::Isometry3<f64>;
