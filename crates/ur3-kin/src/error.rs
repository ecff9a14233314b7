//! The one error type of ur3-kin.

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
}
