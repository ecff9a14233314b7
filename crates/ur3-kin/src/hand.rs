//! Hand-tracking joint layouts and the hand → end-effector target mapping (paper §3.2).
//!
//! Only the layout table lives here so far; `hand_to_target` and calibration come with the
//! kinematics issue.

use crate::KinError;

/// A hand-tracking runtime's joint order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandLayout {
    /// OpenXR `XrHandJointEXT`: 26 joints, 0 palm, 1 wrist, then thumb (4) and four fingers (5 each).
    OpenXr,
    /// WebXR Hand Input `XRHandJoint`: 25 joints, OpenXR without the palm.
    WebXr,
    /// Meta OVRSkeleton legacy `BoneId`: 24 bones (19 skinnable + 5 tips).
    MetaOvr,
    /// MediaPipe Hands landmarks: 21 points.
    MediaPipe,
}

impl HandLayout {
    /// Every layout, in a fixed order.
    pub const ALL: [HandLayout; 4] =
        [HandLayout::OpenXr, HandLayout::WebXr, HandLayout::MetaOvr, HandLayout::MediaPipe];

    /// The name used in hand-log headers and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            HandLayout::OpenXr => "openxr",
            HandLayout::WebXr => "webxr",
            HandLayout::MetaOvr => "meta_ovr",
            HandLayout::MediaPipe => "mediapipe",
        }
    }

    /// Parse a layout name (case-insensitive; `-` and `_` are equivalent).
    ///
    /// # Errors
    /// [`KinError::UnknownLayout`] for any other name.
    pub fn from_name(name: &str) -> Result<HandLayout, KinError> {
        let n = name.to_ascii_lowercase().replace('-', "_");
        HandLayout::ALL
            .into_iter()
            .find(|l| l.name() == n)
            .ok_or_else(|| KinError::UnknownLayout(name.to_string()))
    }

    /// Number of joints a frame in this layout carries.
    pub fn joint_count(self) -> usize {
        match self {
            HandLayout::OpenXr => 26,
            HandLayout::WebXr => 25,
            HandLayout::MetaOvr => 24,
            HandLayout::MediaPipe => 21,
        }
    }

    /// Index of the wrist joint.
    pub fn wrist(self) -> usize {
        match self {
            HandLayout::OpenXr => 1,
            HandLayout::WebXr => 0,
            HandLayout::MetaOvr => 0,
            HandLayout::MediaPipe => 0,
        }
    }

    /// Index of the index finger's proximal joint (the MCP knuckle).
    pub fn index_proximal(self) -> usize {
        match self {
            HandLayout::OpenXr => 7,
            HandLayout::WebXr => 6,
            HandLayout::MetaOvr => 6,
            HandLayout::MediaPipe => 5,
        }
    }

    /// Index of the middle finger's proximal joint (the MCP knuckle).
    pub fn middle_proximal(self) -> usize {
        match self {
            HandLayout::OpenXr => 12,
            HandLayout::WebXr => 11,
            HandLayout::MetaOvr => 9,
            HandLayout::MediaPipe => 9,
        }
    }
}

/// Which hand a frame belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Handedness {
    /// The left hand.
    Left,
    /// The right hand.
    Right,
}

impl Handedness {
    /// Parse `"left"` / `"right"` (case-insensitive).
    ///
    /// # Errors
    /// [`KinError::UnknownHandedness`] for anything else.
    pub fn from_name(name: &str) -> Result<Handedness, KinError> {
        match name.to_ascii_lowercase().as_str() {
            "left" => Ok(Handedness::Left),
            "right" => Ok(Handedness::Right),
            _ => Err(KinError::UnknownHandedness(name.to_string())),
        }
    }

    /// `"left"` or `"right"`.
    pub fn name(self) -> &'static str {
        match self {
            Handedness::Left => "left",
            Handedness::Right => "right",
        }
    }
}

/// The coordinate space hand positions are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Space {
    /// OpenXR / WebXR reference space: right-handed, +Y up, −Z forward, metres.
    OpenXr,
    /// Unity world space: left-handed, +Y up, +Z forward, metres.
    Unity,
    /// The robot's Base frame: right-handed, +Z up, metres.
    RobotBase,
}

impl Space {
    /// `"openxr"` (also accepts `"webxr"`), `"unity"` or `"robot_base"`.
    ///
    /// # Errors
    /// [`KinError::UnknownSpace`] for anything else.
    pub fn from_name(name: &str) -> Result<Space, KinError> {
        match name.to_ascii_lowercase().replace('-', "_").as_str() {
            "openxr" | "webxr" => Ok(Space::OpenXr),
            "unity" => Ok(Space::Unity),
            "robot_base" | "base" => Ok(Space::RobotBase),
            _ => Err(KinError::UnknownSpace(name.to_string())),
        }
    }

    /// The canonical name.
    pub fn name(self) -> &'static str {
        match self {
            Space::OpenXr => "openxr",
            Space::Unity => "unity",
            Space::RobotBase => "robot_base",
        }
    }
}
