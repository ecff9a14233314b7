//! Kinematics of the Universal Robots arms (UR3 first, the family beside it).
//!
//! Frames: everything is expressed in the UR controller's "Base" frame (DH frame 0, Z up, metres,
//! radians). The end effector is `tool0`: the flange with a zero TCP, i.e. what the pendant and
//! RTDE report. Standard DH convention: `T_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`.
//!
//! - [`fk`], [`fk_all`], [`jacobian`]: forward kinematics and the geometric Jacobian;
//! - [`ik`] (nearest solution to a seed), [`ik_gn`] (the paper's Gauss-Newton alone),
//!   [`ik_all`] (closed form, up to 8 solutions), [`ik_batch`] (threads);
//! - [`fk_batch`], [`ik_batch_matrices`], [`hand_to_target_batch`]: many rows per call, a failed
//!   row an `Err` in its slot (the policy the Python binding exposes as NaN rows and `ok` flags);
//! - [`urdf::link_transforms`] / [`urdf::link_poses`]: every URDF link at a configuration;
//! - [`urdf::to_urdf_string`]: a URDF of any model;
//! - [`hand_to_target`] with [`Calibration`]: tracked hand joints → tool0 target (paper §3.2);
//! - [`HandLayout`]: each tracking runtime's joint order, named, as OpenXR joints ([`OPENXR_JOINTS`]).
//!
//! Errors: one enum, [`KinError`]; [`IkError`] is an alias of it.

mod batch;
mod error;
mod fk;
mod hand;
mod ik;
mod jacobian;
mod layout;
mod limits;
mod model;
pub mod urdf;

pub use batch::{fk_batch, hand_to_target_batch, ik_batch_matrices, split_failures};
pub use error::{IkError, KinError};
pub use fk::{fk, fk_all, fk_matrix};
pub use hand::{
    Calibration, HandPoints, Handedness, Space, hand_frame, hand_to_target, hand_to_target_layout,
    tool_from_hand_rotation,
};
pub use ik::{
    IkOptions, ik, ik_all, ik_all_with_q6, ik_batch, ik_gn, joint_distance, pose_distance, pose_from_matrix,
    pose_residual, wrap_angle, wrap_joints,
};
pub use jacobian::jacobian;
pub use layout::{HandLayout, OPENXR_JOINTS};
pub use limits::JointLimits;
pub use model::{ALPHA, MODELS, UR3, UR3E, UR5, UR5E, UR10, UR10E, UrModel};
pub use nalgebra;

/// Joint angles of a 6-axis UR arm, radians, base to wrist 3.
pub type Joints = [f64; 6];

/// A rigid transform in f64 (rotation + translation), the pose type of this crate.
pub type Pose = nalgebra::Isometry3<f64>;
