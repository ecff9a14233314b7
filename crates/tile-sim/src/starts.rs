//! Where episodes start: the object on the table and the target (with or without its pad).
//!
//! An episode's [`Start`] is plain numbers: the object's centre on the table `(x, y)` (m, Base
//! frame), its yaw about Base Z (rad), the target's offset from the task's nominal target and the
//! pad's offset (m). A [`Variation`] draws one from an episode seed. Three are named:
//!
//! | variation | object x (m) | object y (m) | yaw | target | pad |
//! |---|---|---|---|---|---|
//! | [`Variation::default`] (the paper's) | [0, 0.15] | 0.32 | 0 | fixed | fixed |
//! | [`Variation::robust`] | [−0.075, 0.225] | 0.32 | 0 | ±2 cm in x and y | fixed |
//! | [`Variation::wide`] | [0.035, 0.285] | [0.26, 0.36] | ±30° | ±4 cm in x and y | moves with the target |
//!
//! The wide box is the largest of that shape that keeps every start valid: a tile turned by 30°
//! reaches 0.1025 m from its centre along x, the pad moved 4 cm towards it ends at x = −0.08, so
//! x ≥ 0.035 keeps 1 cm between them; the far corner (0.285, 0.36) stays 3 cm inside the arm's
//! reach with the flange down (see [`Start::check`], and `tests/starts.rs`, which checks a grid
//! over the whole box with the IK). Screw spreads its bolt plate over the same x and y and has no
//! target to move (the target is on the bolt).
//!
//! [`Start::check`] refuses a start whose object leaves the table, touches the pad, or whose
//! grasp point, or the target, is less than [`REACH_MARGIN`] inside the arm's reach with the
//! flange pointing down (IK at the pick height and 10 cm above it, at the point moved
//! [`REACH_MARGIN`] outwards and inwards).

use crate::expert::{ik_on, tool0_for_tcp};
use crate::spec::{TargetSpec, TaskSpec};
use crate::{SimError, Task};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::prelude::Vector;

/// Distance (m) every grasp point and target keeps from the limits of the arm's reach.
pub const REACH_MARGIN: f64 = 0.03;
/// Clearance (m) between the object's footprint and the pad's at the start.
pub const PAD_CLEARANCE: f32 = 0.01;
/// Largest target / pad offset (m) a start may have in x and in y.
pub const MAX_TARGET_OFFSET: f32 = 0.04;
/// Largest object yaw (rad) a start may have: 45°.
pub const MAX_YAW: f32 = std::f32::consts::FRAC_PI_4;

/// One episode's start (see the module docs). Serialized as the reset options name it:
/// `{"object_pose": [x, y, yaw], "target_offset": [dx, dy], "pad_offset": [dx, dy]}`, plus
/// `"pad_yaw": rad` when the pad is turned (a spec's `pad_yaw_deg`; TilePlace's wide starts).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Start {
    /// The object's centre on the table (m, Base frame): x, y.
    pub object_xy: [f32; 2],
    /// The object's yaw about Base Z (rad).
    pub yaw: f32,
    /// The target's offset from the task's nominal target (m): dx, dy. Screw: always 0.
    pub target_offset: [f32; 2],
    /// The pad's offset from its nominal place (m). Screw: always 0.
    pub pad_offset: [f32; 2],
    /// The pad's yaw about Base Z (rad), about its centre; the target (the object lying on the
    /// pad) is turned with it. 0 unless the starts turn the pad.
    pub pad_yaw: f32,
}

impl serde::Serialize for Start {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("object_pose", &[self.object_xy[0], self.object_xy[1], self.yaw])?;
        m.serialize_entry("target_offset", &self.target_offset)?;
        m.serialize_entry("pad_offset", &self.pad_offset)?;
        if self.pad_yaw != 0.0 {
            m.serialize_entry("pad_yaw", &self.pad_yaw)?;
        }
        m.end()
    }
}

impl Start {
    /// The start the reset options name: the object at `object_pose` `[x, y, yaw]`, the target
    /// moved by `target_offset` and the pad by `pad_offset` (default: with the target), the pad
    /// turned by `pad_yaw` (rad, default 0).
    pub fn from_options(
        object_pose: [f32; 3],
        target_offset: [f32; 2],
        pad_offset: Option<[f32; 2]>,
    ) -> Start {
        Start {
            object_xy: [object_pose[0], object_pose[1]],
            yaw: object_pose[2],
            target_offset,
            pad_offset: pad_offset.unwrap_or(target_offset),
            pad_yaw: 0.0,
        }
    }

    /// As 8 numbers: x, y, yaw, target dx, dy, pad dx, dy, pad yaw (a checkpoint's row).
    pub fn to_row(&self) -> [f32; 8] {
        let (o, t, p) = (self.object_xy, self.target_offset, self.pad_offset);
        [o[0], o[1], self.yaw, t[0], t[1], p[0], p[1], self.pad_yaw]
    }

    /// The inverse of [`Start::to_row`]; a row of 7 (a checkpoint written before the pad could
    /// turn) is a pad that is not turned.
    pub fn from_row(r: &[f32]) -> Start {
        let at = |i: usize| r.get(i).copied().unwrap_or(0.0);
        Start {
            object_xy: [at(0), at(1)],
            yaw: at(2),
            target_offset: [at(3), at(4)],
            pad_offset: [at(5), at(6)],
            pad_yaw: at(7),
        }
    }
}

/// How episode starts vary (the module docs name the three in use). Each range is `[lo, hi]`; a
/// range with `lo == hi` is not drawn from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variation {
    /// The object's start x is uniform in `[object_x[0], object_x[1]]` (m, Base frame).
    pub object_x: [f32; 2],
    /// The object's start y (m).
    pub object_y: [f32; 2],
    /// The object's yaw (rad).
    pub yaw: [f32; 2],
    /// The target moves by `(dx, dy)`, each uniform in `[-target_jitter, target_jitter]` (m)
    /// (TileSuction and BlockGrip). 0 = the fixed target.
    pub target_jitter: f32,
    /// The pad moves with the target (else it stays: a 0.2 m pad holds a 0.15 m tile moved 2.5 cm).
    pub pad_follows: bool,
    /// The pad's yaw (rad), turning the target with it; `[0, 0]`: square (every task but
    /// TilePlace's wide starts).
    pub pad_yaw: [f32; 2],
}

/// The paper's starts, as the built-in TileSuction spec gives them (`starts.paper`; the three
/// built-in tasks share them).
impl Default for Variation {
    fn default() -> Self {
        TaskSpec::builtin(Task::TileSuction).starts.paper.variation()
    }
}

fn drawn(r: [f32; 2]) -> bool {
    r[0] < r[1]
}

impl Variation {
    /// The robustness evaluation: the x range widened by half its width on each side
    /// (`[-0.075, 0.225]` m) and the target moved by up to ±2 cm in x and y (the pad stays).
    pub fn robust() -> Variation {
        Variation::robust_of(Variation::default())
    }

    /// [`Variation::robust`] about the paper's starts `paper` (a spec's `starts.paper`).
    pub fn robust_of(paper: Variation) -> Variation {
        let [lo, hi] = paper.object_x;
        let half = 0.5 * (hi - lo);
        Variation { object_x: [lo - half, hi + half], target_jitter: 0.02, pad_follows: false, ..paper }
    }

    /// The wide starts (module docs): the object over 0.25 m of x and 0.10 m of y, turned by up
    /// to ±30°, the target and its pad moved by up to ±4 cm in x and y (the built-in TileSuction
    /// spec's `starts.wide`; BlockGrip's are the same, Screw's keep the bolt square and its target).
    pub fn wide() -> Variation {
        TaskSpec::builtin(Task::TileSuction).starts.wide.variation()
    }

    /// `s` of the way from the paper's starts (`s = 0`) to the wide ones (`s = 1`): every range
    /// grows linearly about the paper's (a forward curriculum's schedule). `s` is clamped to [0, 1].
    pub fn towards_wide(s: f32) -> Variation {
        Variation::towards_wide_in(s, &TaskSpec::builtin(Task::TileSuction))
    }

    /// [`Variation::towards_wide`] from `spec`'s paper starts to its wide ones.
    pub fn towards_wide_in(s: f32, spec: &TaskSpec) -> Variation {
        let s = if s.is_nan() { 0.0 } else { s.clamp(0.0, 1.0) };
        let (a, b) = (spec.starts.paper.variation(), spec.starts.wide.variation());
        let mix = |p: [f32; 2], q: [f32; 2]| [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])];
        Variation {
            object_x: mix(a.object_x, b.object_x),
            object_y: mix(a.object_y, b.object_y),
            yaw: mix(a.yaw, b.yaw),
            target_jitter: s * b.target_jitter,
            pad_follows: s > 0.0,
            pad_yaw: mix(a.pad_yaw, b.pad_yaw),
        }
    }

    /// Checks the ranges: finite and ordered, within the table, yaw within ±45°, jitter in
    /// `[0, 0.025]` m with the pad fixed or `[0, 0.04]` m with the pad following.
    pub fn validate(&self) -> Result<(), SimError> {
        self.validate_for(&ur3_kin::UR3)
    }

    /// [`Variation::validate`] for the arm `arm`: the x and y bounds (|x| ≤ 0.3 m, |y| ≤ 0.5 m
    /// on the UR3) grow with the arm ([`workspace_scale`]).
    pub fn validate_for(&self, arm: &ur3_kin::UrModel) -> Result<(), SimError> {
        let bad = |what: String| Err(SimError::InvalidArgument(what));
        let k = workspace_scale(arm);
        for (name, [lo, hi], lim) in [
            ("object_x", self.object_x, 0.3f32 * k),
            ("object_y", self.object_y, 0.5 * k),
            ("yaw", self.yaw, MAX_YAW),
            ("pad_yaw", self.pad_yaw, MAX_YAW),
        ] {
            if !(lo.is_finite() && hi.is_finite()) || lo > hi || lo < -lim || hi > lim {
                return bad(format!("{name} [{lo}, {hi}] must be an ordered range within [-{lim}, {lim}]"));
            }
        }
        let max_jitter = if self.pad_follows { MAX_TARGET_OFFSET } else { 0.025 };
        if !(0.0..=max_jitter).contains(&self.target_jitter) {
            return bad(format!("target_jitter {} must be in [0, {max_jitter}] m", self.target_jitter));
        }
        Ok(())
    }

    /// The start of episode `seed` of `task`. The draws come from one ChaCha8 stream in a fixed
    /// order: x, then (if the target moves) dx and dy, then y, yaw and the pad's yaw where their
    /// ranges are not a point; so the paper's variation draws exactly what it always drew.
    pub fn start(&self, task: Task, seed: u64) -> Start {
        let mut ep = ChaCha8Rng::seed_from_u64(seed);
        let x: f32 = ep.random_range(self.object_x[0]..=self.object_x[1]);
        let mut offset = [0.0; 2];
        if self.target_jitter > 0.0 && task != Task::Screw {
            let j = self.target_jitter;
            offset = [ep.random_range(-j..=j), ep.random_range(-j..=j)];
        }
        let y = if drawn(self.object_y) {
            ep.random_range(self.object_y[0]..=self.object_y[1])
        } else {
            self.object_y[0]
        };
        let yaw = if drawn(self.yaw) { ep.random_range(self.yaw[0]..=self.yaw[1]) } else { self.yaw[0] };
        let yaw = if task == Task::Screw { 0.0 } else { yaw };
        let pad_yaw = if drawn(self.pad_yaw) {
            ep.random_range(self.pad_yaw[0]..=self.pad_yaw[1])
        } else {
            self.pad_yaw[0]
        };
        Start {
            object_xy: [x, y],
            yaw,
            target_offset: offset,
            pad_offset: if self.pad_follows { offset } else { [0.0; 2] },
            pad_yaw,
        }
    }
}

/// How much larger `arm`'s workspace is than the UR3's: its upper arm and forearm (|a2| + |a3|)
/// over the UR3's, at least 1 (exactly 1 for the UR3 and the UR3e, whose arms are as long
/// within 0.2 mm); what the start boxes' sanity bounds scale by.
pub fn workspace_scale(arm: &ur3_kin::UrModel) -> f32 {
    let len = |m: &ur3_kin::UrModel| m.a2.abs() + m.a3.abs();
    let k = len(arm) / len(&ur3_kin::UR3);
    if k < 1.01 { 1.0 } else { k as f32 }
}

/// Half extents (x, y) of the object's footprint on the table, unturned (the bolt's plate for Screw).
fn footprint_half(spec: &TaskSpec) -> [f32; 2] {
    match (&spec.target, spec.object.half_extents) {
        (TargetSpec::Bolt { plate_half_extents: p, .. }, _) => [p[0], p[1]],
        (_, Some(h)) => [h[0], h[1]],
        (_, None) => {
            let r = spec.object.radius.unwrap_or(0.0);
            [r, r]
        }
    }
}

/// Half extent along x and y of a `half` box turned by `yaw`.
fn turned_half(half: [f32; 2], yaw: f32) -> [f32; 2] {
    let (s, c) = (yaw.sin().abs(), yaw.cos().abs());
    [half[0] * c + half[1] * s, half[0] * s + half[1] * c]
}

/// The tool0 pose heights and points at which a reachable place must have an IK solution.
fn reachable(arm: &ur3_kin::UrModel, p: Vector3<f64>, tcp_z: f64, home: &[f64; 6]) -> bool {
    let radial = Vector3::new(p.x, p.y, 0.0);
    let n = radial.norm();
    let dir = if n > 1e-9 { radial / n } else { Vector3::x() };
    [REACH_MARGIN, -REACH_MARGIN].iter().all(|&m| {
        [0.0, 0.10].iter().all(|&up| {
            let q = p + dir * m + Vector3::new(0.0, 0.0, up);
            ik_on(arm, &tool0_for_tcp(q, tcp_z), home).is_some()
        })
    })
}

/// How far from the base axis (m) the arm reaches a TCP at height `z` in the direction of
/// `p` with the flange down (bisection of [`reachable`] without the margin), for messages.
fn reach_along(arm: &ur3_kin::UrModel, p: Vector3<f64>, tcp_z: f64, home: &[f64; 6]) -> f64 {
    let radial = Vector3::new(p.x, p.y, 0.0);
    let dir = if radial.norm() > 1e-9 { radial / radial.norm() } else { Vector3::x() };
    let ok =
        |r: f64| ik_on(arm, &tool0_for_tcp(dir * r + Vector3::new(0.0, 0.0, p.z), tcp_z), home).is_some();
    let (mut lo, mut hi) = (0.2, (arm.reach() + 0.1).max(1.0));
    if !ok(lo) {
        return 0.0;
    }
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if ok(mid) { lo = mid } else { hi = mid }
    }
    lo
}

impl Start {
    /// The object's centre (Base frame) at this start: resting on the table, or caught on the
    /// bolt's thread (a bolt target).
    pub fn object_centre(&self, spec: &TaskSpec) -> Vector {
        let [x, y] = self.object_xy;
        match &spec.target {
            TargetSpec::Bolt { .. } => Vector::new(x, y, nut_start_z(spec)),
            TargetSpec::Pad { .. } => Vector::new(x, y, spec.table.top_z + spec.object_half_height()),
        }
    }

    /// The pad's centre (x, y) at this start (a pad target; `[0, 0]` otherwise).
    pub fn pad_xy(&self, spec: &TaskSpec) -> [f32; 2] {
        match &spec.target {
            TargetSpec::Pad { xy, .. } => [xy[0] + self.pad_offset[0], xy[1] + self.pad_offset[1]],
            TargetSpec::Bolt { .. } => [0.0; 2],
        }
    }

    /// The target (the object's centre when the task is done) at this start.
    pub fn target(&self, spec: &TaskSpec) -> Vector {
        match &spec.target {
            TargetSpec::Bolt { pitch, turns, .. } => {
                let c = self.object_centre(spec);
                Vector::new(c.x, c.y, nut_start_z(spec) - (*turns as f32) * pitch)
            }
            TargetSpec::Pad { .. } => {
                let d = self.target_offset;
                crate::world::pad_target_of(spec) + Vector::new(d[0], d[1], 0.0)
            }
        }
    }

    /// Object `i` of a row's centre at this start (a spec's `[row]`): object 0's,
    /// [`Start::object_centre`], moved by `i` object pitches (m, Base frame).
    pub fn row_object_centre(&self, spec: &TaskSpec, i: usize) -> Vector {
        let c = self.object_centre(spec);
        if i == 0 {
            return c;
        }
        let d = spec.object_offset(i);
        c + Vector::new(d[0], d[1], 0.0)
    }

    /// Pad `i` of a row's centre (x, y) at this start: pad 0's, [`Start::pad_xy`], moved by `i`
    /// pad pitches (m).
    pub fn row_pad_xy(&self, spec: &TaskSpec, i: usize) -> [f32; 2] {
        let p = self.pad_xy(spec);
        if i == 0 {
            return p;
        }
        let d = spec.pad_offset(i);
        [p[0] + d[0], p[1] + d[1]]
    }

    /// Target `i` of a row (object `i`'s centre lying on pad `i`) at this start: target 0's,
    /// [`Start::target`], moved by `i` pad pitches (m).
    pub fn row_target(&self, spec: &TaskSpec, i: usize) -> Vector {
        let t = self.target(spec);
        if i == 0 {
            return t;
        }
        let d = spec.pad_offset(i);
        t + Vector::new(d[0], d[1], 0.0)
    }

    /// Refuses a start that is not finite, leaves the table, touches the pad, or lies out of
    /// reach (module docs) for the built-in `task`; with a row, every object and pad of it is
    /// checked, and neighbouring objects must not overlap; the message names the field (`object_pose`
    /// or `target_offset`).
    pub fn check(&self, task: Task) -> Result<(), SimError> {
        self.check_in(&TaskSpec::builtin(task))
    }

    /// [`Start::check`] for the task `spec` describes.
    pub fn check_in(&self, spec: &TaskSpec) -> Result<(), SimError> {
        let task = spec.task();
        let bad = |m: String| Err(SimError::InvalidArgument(m));
        let [x, y] = self.object_xy;
        if ![x, y, self.yaw].iter().all(|v| v.is_finite()) {
            return bad(format!("object_pose [{x}, {y}, {}] must be finite", self.yaw));
        }
        let offsets = self.target_offset.iter().chain(self.pad_offset.iter());
        if !offsets.clone().all(|v| v.is_finite()) {
            return bad(format!("target_offset {:?} must be finite", self.target_offset));
        }
        if offsets.clone().any(|v| v.abs() > MAX_TARGET_OFFSET + 1e-6) {
            return bad(format!(
                "target_offset {:?} moves the target more than {MAX_TARGET_OFFSET} m in x or y",
                self.target_offset
            ));
        }
        if task == Task::Screw && offsets.clone().any(|v| *v != 0.0) {
            return bad("target_offset: Screw's target is on the bolt and cannot move".into());
        }
        if self.yaw.abs() > MAX_YAW {
            return bad(format!("object_pose yaw {} rad is beyond ±{MAX_YAW:.4} rad (45°)", self.yaw));
        }
        if !self.pad_yaw.is_finite() || self.pad_yaw.abs() > MAX_YAW {
            return bad(format!(
                "pad_yaw {} rad must be finite and within ±{MAX_YAW:.4} rad (45°)",
                self.pad_yaw
            ));
        }
        if self.pad_yaw != 0.0 && (task == Task::Screw || spec.row.is_some()) {
            return bad("pad_yaw: only a single pad can be turned (not a bolt's plate, not a row)".into());
        }
        let h = turned_half(footprint_half(spec), self.yaw);
        let table = spec.table.half_extents;
        let (tx, ty) = (table[0] - h[0], table[1] - h[1]);
        let n = spec.row_len();
        // "the object", or which object of a row.
        let which =
            |i: usize| if n > 1 { format!("object {i} of the row") } else { "the object".to_string() };
        for i in 0..n {
            let c = self.row_object_centre(spec, i);
            let (x, y) = (c.x, c.y);
            if x.abs() > tx || y.abs() > ty {
                let [x0, y0] = self.object_xy;
                let at = if n > 1 { format!(" (at ({x}, {y}))") } else { String::new() };
                return bad(format!(
                    "object_pose ({x0}, {y0}) m puts {}{at} off the table (|x| <= {tx:.3}, |y| <= {ty:.3})",
                    which(i)
                ));
            }
            let TargetSpec::Pad { half_extents: pad_half, .. } = &spec.target else { continue };
            // A turned pad's footprint: the box around it (a little conservative).
            let pad_half = turned_half([pad_half[0], pad_half[1]], self.pad_yaw);
            for j in 0..n {
                let pad = self.row_pad_xy(spec, j);
                let gap_x = (x - pad[0]).abs() - h[0] - pad_half[0];
                let gap_y = (y - pad[1]).abs() - h[1] - pad_half[1];
                if gap_x.max(gap_y) < PAD_CLEARANCE {
                    let [x0, y0] = self.object_xy;
                    return bad(format!(
                        "object_pose ({x0}, {y0}) m, yaw {} rad: {} comes within {PAD_CLEARANCE} m of the pad at ({}, {})",
                        self.yaw,
                        which(i),
                        pad[0],
                        pad[1]
                    ));
                }
            }
        }
        if let Some(row) = spec.row {
            if let Some(gap) = row_gap(spec, row.object_pitch, self.yaw) {
                return bad(format!(
                    "object_pose yaw {} rad: neighbouring objects of the row (pitch {:?} m) overlap by {:.4} m",
                    self.yaw, row.object_pitch, -gap
                ));
            }
        }
        let tcp_z = spec.tcp_z() as f64;
        let home = &spec.robot.home_q;
        let arm = spec.arm();
        let v3 = |p: Vector| Vector3::new(p.x as f64, p.y as f64, p.z as f64);
        let why = |p: Vector3<f64>| {
            let (r, limit) = (p.xy().norm(), reach_along(arm, p, tcp_z, home));
            if r + REACH_MARGIN < limit {
                format!(
                    "{r:.3} m from the base axis is too close to the base for the flange to point down there (with {REACH_MARGIN} m to spare)"
                )
            } else {
                format!(
                    "{r:.3} m from the base axis; the {} reaches {limit:.3} m that way with the flange down, and starts keep {REACH_MARGIN} m inside its reach",
                    crate::arm::display_name(arm)
                )
            }
        };
        for i in 0..n {
            let grasp = v3(self.row_object_centre(spec, i) + Vector::new(0.0, 0.0, grasp_height(spec)));
            if !reachable(arm, grasp, tcp_z, home) {
                return bad(match n > 1 {
                    true => {
                        format!("object_pose ({x}, {y}) m puts {} out of reach: {}", which(i), why(grasp))
                    }
                    false => format!("object_pose ({x}, {y}) m is out of reach: {}", why(grasp)),
                });
            }
        }
        for i in 0..n {
            let target = v3(self.row_target(spec, i));
            if task != Task::Screw && !reachable(arm, target, tcp_z, home) {
                let whose = if n > 1 { format!("target {i} of the row") } else { "the target".to_string() };
                return bad(format!(
                    "target_offset {:?} puts {whose} out of reach: {}",
                    self.target_offset,
                    why(target)
                ));
            }
        }
        Ok(())
    }
}

/// Height of the grasp point above the object's centre: the upper face for suction, the
/// centre for the fingers.
fn grasp_height(spec: &TaskSpec) -> f32 {
    match spec.task() {
        Task::TileSuction | Task::TileRow | Task::TilePlace => spec.object_half_height(),
        Task::BlockGrip | Task::Screw => 0.0,
    }
}

/// How far apart (m) two neighbouring objects of a row `pitch` apart are, each turned by `yaw`
/// about its own centre: `None` when they are clear of each other, else `Some` of the (negative)
/// gap. Boxes turned alike are apart when the pitch, in their own axes, is at least their size
/// along one of them (their only separating axes).
pub(crate) fn row_gap(spec: &TaskSpec, pitch: [f32; 2], yaw: f32) -> Option<f32> {
    let h = footprint_half(spec);
    let (s, c) = (yaw.sin(), yaw.cos());
    let (u, v) = (pitch[0] * c + pitch[1] * s, -pitch[0] * s + pitch[1] * c);
    let gap = (u.abs() - 2.0 * h[0]).max(v.abs() - 2.0 * h[1]);
    (gap < 0.0).then_some(gap)
}

/// The nut's centre height when it has just caught the thread (turns = 0; a bolt target).
pub(crate) fn nut_start_z(spec: &TaskSpec) -> f32 {
    match &spec.target {
        TargetSpec::Bolt { top_z, catch_gap, .. } => top_z - spec.object_half_height() - catch_gap,
        TargetSpec::Pad { .. } => 0.0,
    }
}
