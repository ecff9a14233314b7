//! Hand-tracking joint layouts: the joint order of each tracking runtime, named, and where each
//! joint sits in the OpenXR hand. The one table of these facts: the Python package reads it
//! through `mimicrete._native.kin_hand_layouts()` (`mimicrete.hands.layouts`), and the joints
//! the hand frame is built from ([`HandLayout::wrist`], [`HandLayout::index_proximal`],
//! [`HandLayout::middle_proximal`]) are looked up in it by name.

use crate::KinError;

/// The OpenXR hand joints (`XrHandJointEXT`) in OpenXR order: a joint's position here is its
/// OpenXR index. Every layout's joints are given as OpenXR joints
/// ([`HandLayout::openxr_joints`]).
pub const OPENXR_JOINTS: [&str; 26] = [
    "palm",
    "wrist",
    "thumb_metacarpal",
    "thumb_proximal",
    "thumb_distal",
    "thumb_tip",
    "index_metacarpal",
    "index_proximal",
    "index_intermediate",
    "index_distal",
    "index_tip",
    "middle_metacarpal",
    "middle_proximal",
    "middle_intermediate",
    "middle_distal",
    "middle_tip",
    "ring_metacarpal",
    "ring_proximal",
    "ring_intermediate",
    "ring_distal",
    "ring_tip",
    "little_metacarpal",
    "little_proximal",
    "little_intermediate",
    "little_distal",
    "little_tip",
];

/// WebXR Hand Input `XRHandJoint` names, in WebXR order (the wire format's joint names).
const WEBXR_NAMES: [&str; 25] = [
    "wrist",
    "thumb-metacarpal",
    "thumb-phalanx-proximal",
    "thumb-phalanx-distal",
    "thumb-tip",
    "index-finger-metacarpal",
    "index-finger-phalanx-proximal",
    "index-finger-phalanx-intermediate",
    "index-finger-phalanx-distal",
    "index-finger-tip",
    "middle-finger-metacarpal",
    "middle-finger-phalanx-proximal",
    "middle-finger-phalanx-intermediate",
    "middle-finger-phalanx-distal",
    "middle-finger-tip",
    "ring-finger-metacarpal",
    "ring-finger-phalanx-proximal",
    "ring-finger-phalanx-intermediate",
    "ring-finger-phalanx-distal",
    "ring-finger-tip",
    "pinky-finger-metacarpal",
    "pinky-finger-phalanx-proximal",
    "pinky-finger-phalanx-intermediate",
    "pinky-finger-phalanx-distal",
    "pinky-finger-tip",
];

/// Meta OVRSkeleton legacy `BoneId` names (without the `Hand_` prefix), in bone order.
const META_OVR_NAMES: [&str; 24] = [
    "WristRoot",
    "ForearmStub",
    "Thumb0",
    "Thumb1",
    "Thumb2",
    "Thumb3",
    "Index1",
    "Index2",
    "Index3",
    "Middle1",
    "Middle2",
    "Middle3",
    "Ring1",
    "Ring2",
    "Ring3",
    "Pinky0",
    "Pinky1",
    "Pinky2",
    "Pinky3",
    "ThumbTip",
    "IndexTip",
    "MiddleTip",
    "RingTip",
    "PinkyTip",
];

/// MediaPipe Hands `HandLandmark` names, in landmark order.
const MEDIAPIPE_NAMES: [&str; 21] = [
    "WRIST",
    "THUMB_CMC",
    "THUMB_MCP",
    "THUMB_IP",
    "THUMB_TIP",
    "INDEX_FINGER_MCP",
    "INDEX_FINGER_PIP",
    "INDEX_FINGER_DIP",
    "INDEX_FINGER_TIP",
    "MIDDLE_FINGER_MCP",
    "MIDDLE_FINGER_PIP",
    "MIDDLE_FINGER_DIP",
    "MIDDLE_FINGER_TIP",
    "RING_FINGER_MCP",
    "RING_FINGER_PIP",
    "RING_FINGER_DIP",
    "RING_FINGER_TIP",
    "PINKY_MCP",
    "PINKY_PIP",
    "PINKY_DIP",
    "PINKY_TIP",
];

/// `a == b`, usable in constants.
const fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// The OpenXR index of the joint named `name` in [`OPENXR_JOINTS`] (a constant: an unknown name
/// fails the build).
const fn ox(name: &str) -> Option<usize> {
    let mut i = 0;
    while i < OPENXR_JOINTS.len() {
        if same(OPENXR_JOINTS[i], name) {
            return Some(i);
        }
        i += 1;
    }
    panic!("not an OpenXR joint name")
}

/// Every OpenXR joint, in OpenXR order.
const OPENXR: [Option<usize>; 26] = {
    let mut a = [None; 26];
    let mut i = 0;
    while i < a.len() {
        a[i] = Some(i);
        i += 1;
    }
    a
};

/// WebXR: OpenXR without the palm.
const WEBXR: [Option<usize>; 25] = {
    let mut a = [None; 25];
    let mut i = 0;
    while i < a.len() {
        a[i] = Some(i + 1);
        i += 1;
    }
    a
};

/// Meta OVR legacy: the forearm stub and the trapezium (`Thumb0`) have no OpenXR joint; the
/// thumb's `Thumb1`-`Thumb3` are OpenXR's metacarpal, proximal and distal; the index, middle and
/// ring fingers have no metacarpal bone; the little finger's `Pinky0` is its metacarpal; the five
/// tips come last.
const META_OVR: [Option<usize>; 24] = [
    ox("wrist"),
    None,
    None,
    ox("thumb_metacarpal"),
    ox("thumb_proximal"),
    ox("thumb_distal"),
    ox("index_proximal"),
    ox("index_intermediate"),
    ox("index_distal"),
    ox("middle_proximal"),
    ox("middle_intermediate"),
    ox("middle_distal"),
    ox("ring_proximal"),
    ox("ring_intermediate"),
    ox("ring_distal"),
    ox("little_metacarpal"),
    ox("little_proximal"),
    ox("little_intermediate"),
    ox("little_distal"),
    ox("thumb_tip"),
    ox("index_tip"),
    ox("middle_tip"),
    ox("ring_tip"),
    ox("little_tip"),
];

/// MediaPipe: the thumb's CMC, MCP and IP are OpenXR's metacarpal, proximal and distal; a
/// finger's MCP, PIP and DIP are its proximal, intermediate and distal (no metacarpals, no palm).
const MEDIAPIPE: [Option<usize>; 21] = [
    ox("wrist"),
    ox("thumb_metacarpal"),
    ox("thumb_proximal"),
    ox("thumb_distal"),
    ox("thumb_tip"),
    ox("index_proximal"),
    ox("index_intermediate"),
    ox("index_distal"),
    ox("index_tip"),
    ox("middle_proximal"),
    ox("middle_intermediate"),
    ox("middle_distal"),
    ox("middle_tip"),
    ox("ring_proximal"),
    ox("ring_intermediate"),
    ox("ring_distal"),
    ox("ring_tip"),
    ox("little_proximal"),
    ox("little_intermediate"),
    ox("little_distal"),
    ox("little_tip"),
];

/// The position of OpenXR joint `joint` in `map` (a layout's [`HandLayout::openxr_joints`]).
const fn position(map: &[Option<usize>], joint: Option<usize>) -> usize {
    let mut i = 0;
    while i < map.len() {
        if let (Some(a), Some(b)) = (map[i], joint) {
            if a == b {
                return i;
            }
        }
        i += 1;
    }
    panic!("the layout lacks the joint")
}

/// `[wrist, index proximal, middle proximal]` of each layout (indexed by `layout as usize`), found
/// in the tables above when the crate is built.
const FRAME_JOINTS: [[usize; 3]; 4] = {
    let mut out = [[0; 3]; 4];
    let mut l = 0;
    while l < HandLayout::ALL.len() {
        let layout = HandLayout::ALL[l];
        let map = layout.openxr_joints();
        out[layout as usize] = [
            position(map, ox("wrist")),
            position(map, ox("index_proximal")),
            position(map, ox("middle_proximal")),
        ];
        l += 1;
    }
    out
};

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

    /// The runtime's own name of each joint, in this layout's order (OpenXR: [`OPENXR_JOINTS`];
    /// WebXR: `XRHandJoint`; Meta OVR: `BoneId` without `Hand_`; MediaPipe: `HandLandmark`).
    pub fn joint_names(self) -> &'static [&'static str] {
        match self {
            HandLayout::OpenXr => &OPENXR_JOINTS,
            HandLayout::WebXr => &WEBXR_NAMES,
            HandLayout::MetaOvr => &META_OVR_NAMES,
            HandLayout::MediaPipe => &MEDIAPIPE_NAMES,
        }
    }

    /// The OpenXR joint (index into [`OPENXR_JOINTS`]) at each index of this layout; `None` for a
    /// joint OpenXR has not (Meta OVR's forearm stub and trapezium).
    pub const fn openxr_joints(self) -> &'static [Option<usize>] {
        match self {
            HandLayout::OpenXr => &OPENXR,
            HandLayout::WebXr => &WEBXR,
            HandLayout::MetaOvr => &META_OVR,
            HandLayout::MediaPipe => &MEDIAPIPE,
        }
    }

    /// Where the OpenXR joint named `name` (one of [`OPENXR_JOINTS`]) sits in this layout; `None`
    /// when the layout lacks it (or the name is not an OpenXR joint).
    pub fn index_of(self, name: &str) -> Option<usize> {
        let joint = OPENXR_JOINTS.iter().position(|n| *n == name)?;
        self.openxr_joints().iter().position(|j| *j == Some(joint))
    }

    /// Number of joints a frame in this layout carries.
    pub fn joint_count(self) -> usize {
        self.openxr_joints().len()
    }

    fn frame_joints(self) -> [usize; 3] {
        FRAME_JOINTS[self as usize]
    }

    /// Index of the wrist joint.
    pub fn wrist(self) -> usize {
        self.frame_joints()[0]
    }

    /// Index of the index finger's proximal joint (the MCP knuckle).
    pub fn index_proximal(self) -> usize {
        self.frame_joints()[1]
    }

    /// Index of the middle finger's proximal joint (the MCP knuckle).
    pub fn middle_proximal(self) -> usize {
        self.frame_joints()[2]
    }
}
