//! The simulated arm per UR model: its links as capsules built from the model's DH table, and
//! the sizes of the housings around them (link radii, the links' lateral offsets, the base).
//!
//! Every capsule lies in a DH frame of `ur3_kin::fk_all` (1..=5; standard DH, so joint i+1
//! turns about z_i): the shoulder column and housing in frame 1, the upper arm from the shoulder
//! (at −a2 along x2) to the elbow and the elbow housing in frame 2, the forearm and the wrist-1
//! housing in frame 3, the wrist-2 housing along z4 (length d5) and the wrist-3 housing along
//! z5 up to the flange (length d6). The real upper arm and forearm do not lie in the DH plane:
//! they sit `shoulder_offset` and `elbow_offset` out along the joint-2/3 axes (these enter no
//! kinematics, only the shapes).
//!
//! Where the numbers come from (ROS: `ros-industrial/universal_robot`
//! `ur_description/config/<model>/physical_parameters.yaml`; data sheet: Universal Robots'
//! technical specifications of the model, its "footprint" row):
//! - UR3: the simulator's numbers since the first version, kept bit for bit (the built-in
//!   tasks' results depend on them): offsets 0.12 / 0.027 m (ROS: `shoulder_offset` 0.1198,
//!   forearm 0.0275); radii measured off the UR3 housings (column 0.06, shoulder 0.055, upper
//!   arm and elbow 0.045, forearm and wrists 0.035, wrist 3 0.032 = ROS `links.wrist_3.radius`);
//!   base Ø 128 mm (data sheet footprint), 9 cm high.
//! - UR3e: the same housings (same joint sizes; ROS gives the UR3e the same offsets 0.120 /
//!   0.027 and wrist-3 radius 0.032); its DH table differs (d4, d6).
//! - UR5e: ROS offsets `shoulder_offset` 0.138, `elbow_offset` 0.007; ROS radii "manually
//!   measured": shoulder 0.060, upper arm 0.054, elbow 0.060, forearm 0.040, wrist 0.045, and
//!   `links.wrist_3.radius` 0.0375; base Ø 149 mm (data sheet footprint).
//! - UR10e: ROS offsets `shoulder_offset` 0.1762, `elbow_offset` 0.0393; the ROS file marks its
//!   measured radii as copied from the UR5 ("don't use"), so every link takes its inertia
//!   cylinder's radius, `links.*.radius` 0.075 (an over-estimate of the wrists), wrist 3 0.045;
//!   base Ø 190 mm (data sheet footprint).
//!
//! The shoulder column runs from frame 1 down to about 2 mm above the base housing's top
//! (d1 − column length − 0.09 m ≈ 0.002 m), as the UR3's always has.

use ur3_kin::UrModel;

/// The housings of one model around its DH skeleton (module docs give the sources), metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmDims {
    /// The model's name, as `ur3_kin` names it.
    pub model: &'static str,
    /// The upper arm's offset from the DH plane along the joint-2 axis.
    pub shoulder_offset: f32,
    /// The forearm's offset from the DH plane along the joint-3 axis.
    pub elbow_offset: f32,
    /// Length of the shoulder column below frame 1 (along −y1).
    pub column: f32,
    /// Capsule radii, in [`CAPSULE_NAMES`] order.
    pub radii: [f32; 8],
    /// The base housing (a fixed cylinder on the table, axis z): radius and half height.
    pub base_radius: f32,
    pub base_half_height: f32,
}

/// The arm's capsules by name, in the order [`capsules`] gives them.
pub const CAPSULE_NAMES: [&str; 8] =
    ["shoulder_column", "shoulder", "upper_arm", "elbow", "forearm", "wrist1", "wrist2", "wrist3"];

/// The UR3's housings (the UR3e has the same, module docs).
const UR3_DIMS: ArmDims = ArmDims {
    model: "ur3",
    shoulder_offset: 0.12,
    elbow_offset: 0.027,
    column: 0.06,
    radii: [0.06, 0.055, 0.045, 0.045, 0.035, 0.035, 0.035, 0.032],
    base_radius: 0.064,
    base_half_height: 0.045,
};

/// The models the simulator has an arm for.
pub const SIMULATED: [ArmDims; 4] = [
    UR3_DIMS,
    ArmDims { model: "ur3e", ..UR3_DIMS },
    ArmDims {
        model: "ur5e",
        shoulder_offset: 0.138,
        elbow_offset: 0.007,
        column: 0.07,
        radii: [0.06, 0.06, 0.054, 0.06, 0.04, 0.045, 0.045, 0.0375],
        base_radius: 0.0745,
        base_half_height: 0.045,
    },
    ArmDims {
        model: "ur10e",
        shoulder_offset: 0.1762,
        elbow_offset: 0.0393,
        column: 0.09,
        radii: [0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.045],
        base_radius: 0.095,
        base_half_height: 0.045,
    },
];

/// The housings of `model`, or `None` for a model the simulator has no arm for.
pub fn dims(model: &UrModel) -> Option<&'static ArmDims> {
    SIMULATED.iter().find(|d| d.model == model.name)
}

/// The names of the simulated models, for messages.
pub fn simulated_names() -> Vec<&'static str> {
    SIMULATED.iter().map(|d| d.model).collect()
}

/// One capsule: (DH frame index, end a, end b, radius), ends in that frame.
pub type Capsule = (u8, [f32; 3], [f32; 3], f32);

/// The arm's link capsules from `model`'s DH table and the housings `d` (module docs).
pub fn capsules_of(model: &UrModel, d: &ArmDims) -> Vec<Capsule> {
    let (a2, a3, d4, d5, d6) =
        (-model.a2 as f32, -model.a3 as f32, model.d4 as f32, model.d5 as f32, model.d6 as f32);
    let (up, fo, r) = (d.shoulder_offset, d.elbow_offset, d.radii);
    vec![
        // frame 1 (shoulder): column down to the base (−y1 is down) and the shoulder housing along z1.
        (1, [0.0, -d.column, 0.0], [0.0, 0.0, 0.0], r[0]),
        (1, [0.0, 0.0, 0.0], [0.0, 0.0, up], r[1]),
        // frame 2 (elbow at origin): upper arm from the shoulder (at +a2 along x2) to the elbow.
        (2, [a2, 0.0, up], [0.0, 0.0, up], r[2]),
        (2, [0.0, 0.0, up], [0.0, 0.0, fo], r[3]),
        // frame 3 (wrist 1): forearm from the elbow, then the wrist-1 housing up to d4.
        (3, [a3, 0.0, fo], [0.0, 0.0, fo], r[4]),
        (3, [0.0, 0.0, fo], [0.0, 0.0, d4], r[5]),
        // frame 4: wrist-2 housing along z4 up to d5.
        (4, [0.0, 0.0, 0.0], [0.0, 0.0, d5], r[6]),
        // frame 5: wrist-3 housing along z5 up to the flange (cap ends at d6).
        (5, [0.0, 0.0, 0.0], [0.0, 0.0, d6 - r[7]], r[7]),
    ]
}

/// The arm's link capsules of a simulated `model` ([`capsules_of`] with its [`dims`]).
///
/// # Panics
/// For a model the simulator has no arm for (a checked spec names only simulated ones).
pub fn capsules(model: &UrModel) -> Vec<Capsule> {
    let d = dims(model).unwrap_or_else(|| panic!("invariant: no simulated arm for {}", model.name));
    capsules_of(model, d)
}

/// The model's display name (`UR3`, `UR5e`), for messages.
pub fn display_name(model: &UrModel) -> String {
    let up = model.name.to_ascii_uppercase();
    match up.strip_suffix('E') {
        Some(stem) => format!("{stem}e"),
        None => up,
    }
}
