//! The one error type of ur3-kin.
//!
//! House style is one error enum per crate, so the inverse-kinematics failures are variants of
//! [`KinError`]; [`IkError`] is an alias for readers who want the IK-specific name. The IK
//! functions return only [`KinError::Unreachable`], [`KinError::NotConverged`],
//! [`KinError::NonFinite`] and [`KinError::InvalidPose`].

/// Everything that can go wrong in ur3-kin.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum KinError {
    /// No model of that name (known: ur3, ur3e, ur5, ur5e, ur10, ur10e).
    #[error("unknown robot model {0:?} (known: ur3, ur3e, ur5, ur5e, ur10, ur10e)")]
    UnknownModel(String),
    /// No hand-joint layout of that name (known: openxr, webxr, meta_ovr, mediapipe).
    #[error("unknown hand layout {0:?} (known: openxr, webxr, meta_ovr, mediapipe)")]
    UnknownLayout(String),
    /// Handedness other than left/right.
    #[error("unknown handedness {0:?} (known: left, right)")]
    UnknownHandedness(String),
    /// Unknown coordinate space.
    #[error("unknown coordinate space {0:?} (known: openxr, webxr, unity, robot_base)")]
    UnknownSpace(String),
    /// An input held a NaN or an infinity.
    #[error("non-finite input: {0}")]
    NonFinite(&'static str),
    /// Finite inputs whose result does not fit an f64 (coordinates near 1e308); names the input.
    #[error("overflow: {0}")]
    Overflow(&'static str),
    /// A pose input is not a rigid transform (rotation not orthonormal / det ≠ +1, bad last row,
    /// zero quaternion).
    #[error("invalid pose: {0}")]
    InvalidPose(&'static str),
    /// No joint configuration of the arm reaches the target pose.
    #[error("target unreachable: {reason}")]
    Unreachable {
        /// Which geometric condition failed.
        reason: &'static str,
    },
    /// The numerical solver did not get the pose error below the tolerance.
    #[error(
        "IK did not converge after {iters} iterations (position residual {pos_residual_m:.3e} m, \
         rotation residual {rot_residual_rad:.3e} rad)"
    )]
    NotConverged {
        /// Gauss-Newton iterations spent in total.
        iters: usize,
        /// Best position error reached, metres.
        pos_residual_m: f64,
        /// Best rotation error reached (angle of the residual rotation), radians.
        rot_residual_rad: f64,
    },
    /// A setting that must be a positive finite number is not (a tolerance, a scale).
    #[error("{name} must be a positive finite number, got {value}")]
    NotPositive {
        /// The setting's name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// Hand joints that do not span a frame (coincident or collinear joints).
    #[error("degenerate hand: {0}")]
    DegenerateHand(&'static str),
}

/// The inverse-kinematics error: the same enum as [`KinError`] (one error type per crate).
pub type IkError = KinError;
