//! DH parameters of the UR family, from Universal Robots' published table
//! ("DH Parameters for calculations of kinematics and dynamics"; CB3 rows as in ROS-Industrial's
//! `ur_kin.cpp` / `default_kinematics.yaml`). α = [π/2, 0, 0, π/2, −π/2, 0]; a1 = a4 = a5 = a6 = 0;
//! d2 = d3 = 0; θ offsets all zero.

use crate::KinError;
use std::f64::consts::FRAC_PI_2;

/// A UR arm's standard-DH geometry, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UrModel {
    /// Lower-case model name as used on the Python side (`"ur3"`, `"ur5e"`, ...).
    pub name: &'static str,
    /// Base to shoulder height.
    pub d1: f64,
    /// Upper-arm length (negative in UR's convention).
    pub a2: f64,
    /// Forearm length (negative in UR's convention).
    pub a3: f64,
    /// Wrist 1 offset.
    pub d4: f64,
    /// Wrist 2 offset.
    pub d5: f64,
    /// Wrist 3 to flange.
    pub d6: f64,
}

/// UR3 (CB3).
pub const UR3: UrModel =
    UrModel { name: "ur3", d1: 0.1519, a2: -0.24365, a3: -0.21325, d4: 0.11235, d5: 0.08535, d6: 0.0819 };
/// UR3e.
pub const UR3E: UrModel =
    UrModel { name: "ur3e", d1: 0.15185, a2: -0.24355, a3: -0.2132, d4: 0.13105, d5: 0.08535, d6: 0.0921 };
/// UR5 (CB3).
pub const UR5: UrModel =
    UrModel { name: "ur5", d1: 0.089159, a2: -0.425, a3: -0.39225, d4: 0.10915, d5: 0.09465, d6: 0.0823 };
/// UR5e.
pub const UR5E: UrModel =
    UrModel { name: "ur5e", d1: 0.1625, a2: -0.425, a3: -0.3922, d4: 0.1333, d5: 0.0997, d6: 0.0996 };
/// UR10 (CB3).
pub const UR10: UrModel =
    UrModel { name: "ur10", d1: 0.1273, a2: -0.612, a3: -0.5723, d4: 0.163941, d5: 0.1157, d6: 0.0922 };
/// UR10e.
pub const UR10E: UrModel =
    UrModel { name: "ur10e", d1: 0.1807, a2: -0.6127, a3: -0.57155, d4: 0.17415, d5: 0.11985, d6: 0.11655 };

/// Every model this crate knows.
pub const MODELS: [UrModel; 6] = [UR3, UR3E, UR5, UR5E, UR10, UR10E];

/// DH link twists α_i, the same for every UR arm.
pub const ALPHA: [f64; 6] = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];

impl UrModel {
    /// Look a model up by its (case-insensitive) name.
    ///
    /// # Errors
    /// [`KinError::UnknownModel`] for a name not in [`MODELS`].
    pub fn by_name(name: &str) -> Result<&'static UrModel, KinError> {
        let lower = name.to_ascii_lowercase();
        MODELS.iter().find(|m| m.name == lower).ok_or_else(|| KinError::UnknownModel(name.to_string()))
    }

    /// The DH `a_i` column (a1..a6).
    pub fn a(&self) -> [f64; 6] {
        [0.0, self.a2, self.a3, 0.0, 0.0, 0.0]
    }

    /// The DH `d_i` column (d1..d6).
    pub fn d(&self) -> [f64; 6] {
        [self.d1, 0.0, 0.0, self.d4, self.d5, self.d6]
    }

    /// An upper bound on the distance from the shoulder axis point (0, 0, d1) to tool0, metres.
    pub fn reach(&self) -> f64 {
        self.a2.abs() + self.a3.abs() + (self.d4.powi(2) + self.d5.powi(2)).sqrt() + self.d6
    }

    /// The DH lengths by name (`d1`, `a2`, `a3`, `d4`, `d5`, `d6`, metres) and the [`reach`](Self::reach).
    pub fn dh_table(&self) -> std::collections::BTreeMap<&'static str, f64> {
        let kv = [("d1", self.d1), ("a2", self.a2), ("a3", self.a3), ("d4", self.d4), ("d5", self.d5)];
        kv.into_iter().chain([("d6", self.d6), ("reach", self.reach())]).collect()
    }
}
