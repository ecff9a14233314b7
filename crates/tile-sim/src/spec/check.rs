//! Checks a [`TaskSpec`] field by field: every number finite and in range, the object, target and
//! thresholds the effector's task logic needs present (and none it would ignore). The first bad
//! field is reported as a [`SpecError::Invalid`] with its dotted path, its value and why.

use super::{
    EffectorSpec, MAX_ROW, RowSpec, Rule, SPEC_VERSION, SealSpec, TargetSpec, TaskSpec, ThresholdsSpec,
    VariationSpec,
};
use crate::{MAX_YAW, Start, Task};
use std::fmt::Debug;

/// A task spec that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// The spec file could not be read.
    #[error("{path}: cannot read the task spec: {reason}")]
    Io { path: String, reason: String },
    /// The text is not TOML, or not a task spec (unknown or missing field, wrong type): where
    /// (1-based line and column of the place the TOML reader names, and that line's text
    /// without its comment) and why.
    #[error("{source_name}: {}{reason}", place(*.line, *.column, .text))]
    Parse { source_name: String, line: Option<usize>, column: Option<usize>, text: String, reason: String },
    /// A field's value is out of range or does not fit the task.
    #[error("{field} = {value}: {reason}")]
    Invalid { field: String, value: String, reason: String },
}

impl SpecError {
    pub(super) fn parse(source: &str, text: &str, e: &toml::de::Error) -> SpecError {
        let reason = e.message().trim().to_string();
        let source_name = source.to_string();
        let Some(start) = e.span().map(|s| s.start.min(text.len())) else {
            return SpecError::Parse { source_name, line: None, column: None, text: String::new(), reason };
        };
        let before = &text[..start];
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let line_text = text[line_start..].lines().next().unwrap_or("");
        SpecError::Parse {
            source_name,
            line: Some(before.matches('\n').count() + 1),
            column: Some(before[line_start..].chars().count() + 1),
            text: line_text.split('#').next().unwrap_or("").trim().to_string(),
            reason,
        }
    }

    /// The dotted path of the bad field (`Invalid` only).
    pub fn field(&self) -> Option<&str> {
        match self {
            SpecError::Invalid { field, .. } => Some(field),
            _ => None,
        }
    }
}

/// `line L, column C (text): ` of a parse error, or nothing without a place.
fn place(line: Option<usize>, column: Option<usize>, text: &str) -> String {
    match (line, column) {
        (Some(l), Some(c)) if text.is_empty() => format!("line {l}, column {c}: "),
        (Some(l), Some(c)) => format!("line {l}, column {c} ({text}): "),
        _ => String::new(),
    }
}

fn invalid<T: Debug>(field: &str, value: T, reason: impl Into<String>) -> Result<(), SpecError> {
    Err(SpecError::Invalid { field: field.to_string(), value: format!("{value:?}"), reason: reason.into() })
}

/// Each component finite and > 0.
fn positive(field: &str, v: &[f32]) -> Result<(), SpecError> {
    if v.iter().all(|x| x.is_finite() && *x > 0.0) {
        return Ok(());
    }
    match v {
        [x] => invalid(field, x, "must be a finite number > 0"),
        _ => invalid(field, v, "every component must be a finite number > 0"),
    }
}

fn friction(field: &str, v: f32) -> Result<(), SpecError> {
    if v.is_finite() && (0.0..=10.0).contains(&v) {
        return Ok(());
    }
    invalid(field, v, "a friction coefficient must be in [0, 10]")
}

fn finite(field: &str, v: &[f32]) -> Result<(), SpecError> {
    if v.iter().all(|x| x.is_finite()) {
        return Ok(());
    }
    invalid(field, v, "must be finite")
}

/// A threshold the logic reads: present, finite, and passing `ok`.
fn need<T: Copy + Debug>(
    field: &str,
    v: Option<T>,
    logic: &str,
    ok: impl Fn(T) -> bool,
    range: &str,
) -> Result<(), SpecError> {
    match v {
        None => Err(SpecError::Invalid {
            field: field.to_string(),
            value: "(missing)".into(),
            reason: format!("the {logic} logic needs it ({range})"),
        }),
        Some(x) if !ok(x) => invalid(field, x, format!("must be {range}")),
        Some(_) => Ok(()),
    }
}

/// A threshold the logic does not read: absent (a present one would be silently ignored).
fn unused<T: Debug>(field: &str, v: Option<T>, logic: &str) -> Result<(), SpecError> {
    match v {
        Some(x) => invalid(field, x, format!("the {logic} logic does not read it: remove it")),
        None => Ok(()),
    }
}

fn check_variation(field: &str, v: &VariationSpec, arm: &ur3_kin::UrModel) -> Result<(), SpecError> {
    let max_yaw_deg = MAX_YAW.to_degrees();
    let k = crate::starts::workspace_scale(arm);
    for (name, [lo, hi], lim) in [
        ("object_x", v.object_x, 0.3f32 * k),
        ("object_y", v.object_y, 0.5 * k),
        ("yaw_deg", v.yaw_deg, max_yaw_deg),
    ] {
        if !(lo.is_finite() && hi.is_finite()) || lo > hi || lo < -lim || hi > lim {
            return invalid(
                &format!("{field}.{name}"),
                [lo, hi],
                format!("must be an ordered range [lo, hi] within [-{lim}, {lim}]"),
            );
        }
    }
    if let Some([lo, hi]) = v.pad_yaw_deg {
        if !(lo.is_finite() && hi.is_finite()) || lo > hi || lo < -max_yaw_deg || hi > max_yaw_deg {
            return invalid(
                &format!("{field}.pad_yaw_deg"),
                [lo, hi],
                format!("must be an ordered range [lo, hi] within [-{max_yaw_deg}, {max_yaw_deg}]"),
            );
        }
    }
    let max_jitter = if v.pad_follows { crate::MAX_TARGET_OFFSET } else { 0.025 };
    if !(v.target_jitter.is_finite() && (0.0..=max_jitter).contains(&v.target_jitter)) {
        let why = if v.pad_follows { "with the pad following" } else { "with the pad fixed" };
        return invalid(
            &format!("{field}.target_jitter"),
            v.target_jitter,
            format!("must be in [0, {max_jitter}] m {why}"),
        );
    }
    Ok(())
}

/// The name of `task`'s logic in messages (the effector that selects it).
fn logic(task: Task) -> &'static str {
    match task {
        Task::TileSuction => "suction",
        Task::BlockGrip => "gripper",
        Task::Screw => "screw",
        Task::TileRow => "suction row",
        Task::TilePlace => "placed suction",
    }
}

/// A threshold read by the logics `readers`: required (and passing `ok`) for `task` if it is one
/// of them, else absent.
fn threshold<T: Copy + Debug>(
    task: Task,
    readers: &[Task],
    field: &str,
    v: Option<T>,
    ok: impl Fn(T) -> bool,
    range: &str,
) -> Result<(), SpecError> {
    match readers.contains(&task) {
        true => need(field, v, logic(task), ok, range),
        false => unused(field, v, logic(task)),
    }
}

fn check_thresholds(task: Task, t: &ThresholdsSpec) -> Result<(), SpecError> {
    use Task::{BlockGrip as G, Screw as S, TilePlace as P, TileRow as R, TileSuction as T};
    let dist = |x: f32| x.is_finite() && x > 0.0 && x < 1.0;
    let cos = |x: f32| x.is_finite() && x > 0.0 && x < 1.0;
    let (d, c) = ("a distance in (0, 1) m", "a cosine in (0, 1)");
    let height = |x: f32| x.is_finite();
    let speed = |x: f32| x.is_finite() && x > 0.0;
    threshold(task, &[T, R], "thresholds.pick_dist", t.pick_dist, dist, d)?;
    threshold(task, &[T, G, R, P], "thresholds.success_dist", t.success_dist, dist, d)?;
    threshold(task, &[T, G, R, P], "thresholds.fall_z", t.fall_z, height, "a finite height (m)")?;
    threshold(task, &[T, G, R, P], "thresholds.fall_speed", t.fall_speed, speed, "a speed > 0 m/s")?;
    threshold(task, &[T, R, P], "thresholds.fall_tilt_cos", t.fall_tilt_cos, cos, c)?;
    let yaw = |x: f32| x.is_finite() && x > 0.0 && x < 45.0;
    threshold(
        task,
        &[P],
        "thresholds.success_yaw_deg",
        t.success_yaw_deg,
        yaw,
        "an angle in (0, 45) degrees",
    )?;
    let small = |x: f32| x.is_finite() && x > 0.0 && x < 0.1;
    let sd = "a distance in (0, 0.1) m";
    threshold(task, &[P], "thresholds.release_height", t.release_height, small, sd)?;
    threshold(task, &[P], "thresholds.rest_height", t.rest_height, small, sd)?;
    threshold(task, &[P], "thresholds.rest_speed", t.rest_speed, speed, "a speed > 0 m/s")?;
    let steps = |x: u32| (1..=100).contains(&x);
    threshold(task, &[P], "thresholds.rest_steps", t.rest_steps, steps, "1 to 100 steps")?;
    threshold(task, &[S], "thresholds.align_cos", t.align_cos, cos, c)?;
    threshold(task, &[S], "thresholds.slip_dist", t.slip_dist, dist, d)?;
    let turns = |x: f64| x.is_finite() && x > 0.0;
    threshold(task, &[S], "thresholds.fail_turns", t.fail_turns, turns, "a number of turns > 0")
}

/// `[effector.seal]` and `thresholds.rule` go together: the placed rule needs the seal (a proximity
/// hold would let a tile be set down from the air), the paper's rule runs the paper's rigid hold.
fn check_seal(seal: Option<&SealSpec>, rule: Option<Rule>, row: bool) -> Result<(), SpecError> {
    let placed = rule == Some(Rule::Placed);
    if placed && row {
        return invalid(
            "thresholds.rule",
            "placed",
            "the placed rule is not built for a [row] yet (TileRow)",
        );
    }
    let Some(s) = seal else {
        if placed {
            return invalid(
                "effector.seal",
                "(missing)",
                "the placed rule holds a tile by its sealed cups: add [effector.seal]",
            );
        }
        return Ok(());
    };
    if !placed {
        return invalid(
            "effector.seal",
            "{...}",
            "the seal runs with thresholds.rule = \"placed\" (the paper's rule holds rigidly within pick_dist)",
        );
    }
    positive("effector.seal.gap", &[s.gap])?;
    if s.gap >= 0.05 {
        return invalid(
            "effector.seal.gap",
            s.gap,
            "must be below 0.05 m (a lip seals on the face, not from the air)",
        );
    }
    if !(s.angle_deg.is_finite() && s.angle_deg > 0.0 && s.angle_deg < 45.0) {
        return invalid("effector.seal.angle_deg", s.angle_deg, "must be an angle in (0, 45) degrees");
    }
    if !(s.vacuum_kpa.is_finite() && s.vacuum_kpa > 0.0 && s.vacuum_kpa < 101.325) {
        return invalid(
            "effector.seal.vacuum_kpa",
            s.vacuum_kpa,
            "must be a relative vacuum in (0, 101.325) kPa (below the atmosphere's pressure)",
        );
    }
    if !(s.time.is_finite() && s.time >= 0.0 && s.time <= 5.0) {
        return invalid("effector.seal.time", s.time, "must be in [0, 5] s");
    }
    if !(s.safety_factor.is_finite() && s.safety_factor >= 1.0) {
        return invalid("effector.seal.safety_factor", s.safety_factor, "must be a finite number >= 1");
    }
    if !(s.stroke.is_finite() && (0.0..=0.05).contains(&s.stroke)) {
        return invalid("effector.seal.stroke", s.stroke, "must be a travel in [0, 0.05] m");
    }
    friction("effector.seal.lip_friction", s.lip_friction)
}

impl TaskSpec {
    /// Every start of the distribution `v` valid as an explicit start is (on the table, 1 cm
    /// clear of the pad, the grasp point and the target within reach with the flange down):
    /// checked over a grid of its box (5 x, 5 y, 3 yaw, the target offset's four corners and
    /// none), so a spec whose object, pad or ranges do not fit together is refused here, not
    /// mid-training at a start that happens to be drawn.
    fn check_start_box(&self, field: &str, v: &VariationSpec) -> Result<(), SpecError> {
        let grid = |[lo, hi]: [f32; 2], n: usize| -> Vec<f32> {
            match lo == hi {
                true => vec![lo],
                false => (0..n).map(|k| lo + (hi - lo) * k as f32 / (n - 1) as f32).collect(),
            }
        };
        let screw = self.task() == Task::Screw;
        let j = if screw { 0.0 } else { v.target_jitter };
        let offsets: Vec<[f32; 2]> = match j > 0.0 {
            true => vec![[0.0, 0.0], [-j, -j], [-j, j], [j, -j], [j, j]],
            false => vec![[0.0, 0.0]],
        };
        let yaws = if screw { vec![0.0] } else { grid(v.yaw_deg, 3) };
        let pad_yaws = grid(v.pad_yaw_deg.unwrap_or([0.0; 2]), 3);
        for x in grid(v.object_x, 5) {
            for y in grid(v.object_y, 5) {
                for &yaw_deg in &yaws {
                    for &off in &offsets {
                        for &pad_yaw_deg in &pad_yaws {
                            let pad = if v.pad_follows { off } else { [0.0; 2] };
                            let st = Start {
                                pad_yaw: pad_yaw_deg.to_radians(),
                                ..Start::from_options([x, y, yaw_deg.to_radians()], off, Some(pad))
                            };
                            if let Err(e) = st.check_in(self) {
                                return invalid(
                                    field,
                                    format!(
                                        "{{object ({x}, {y}), yaw {yaw_deg} deg, target moved {off:?}, pad turned {pad_yaw_deg} deg}}"
                                    ),
                                    format!("a start of this distribution is refused: {e}"),
                                );
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn check_about(&self) -> Result<(), SpecError> {
        let a = &self.about;
        for (field, text) in [("about.instruction", &a.instruction), ("about.success", &a.success)] {
            if text.trim().is_empty() || text.len() > 300 || text.chars().any(char::is_control) {
                return invalid(field, text, "must be a line of text (1 to 300 characters)");
            }
        }
        let want = if self.task() == Task::Screw { "screw" } else { "grip" };
        if a.gestures != want {
            return invalid(
                "about.gestures",
                &a.gestures,
                format!("the {} logic is driven by the \"{want}\" gesture classes", self.task().name()),
            );
        }
        Ok(())
    }

    /// Check every field (see the module docs).
    ///
    /// # Errors
    /// The first bad field, as [`SpecError::Invalid`].
    pub fn check(&self) -> Result<(), SpecError> {
        if self.version != SPEC_VERSION {
            return invalid("version", self.version, format!("this simulator reads version {SPEC_VERSION}"));
        }
        if self.name.is_empty() || !self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return invalid("name", &self.name, "must be a non-empty name of letters, digits and '_'");
        }
        self.check_about()?;
        let simulated =
            ur3_kin::UrModel::by_name(&self.robot.model).ok().filter(|m| crate::arm::dims(m).is_some());
        let Some(arm) = simulated else {
            let names = crate::arm::simulated_names().join(", ");
            return invalid(
                "robot.model",
                &self.robot.model,
                format!("the simulator has an arm for {names}"),
            );
        };
        if self.robot.model != arm.name {
            return invalid(
                "robot.model",
                &self.robot.model,
                format!("write the model in lower case (\"{}\")", arm.name),
            );
        }
        if !self.robot.home_q.iter().all(|q| q.is_finite() && q.abs() <= std::f64::consts::PI) {
            return invalid(
                "robot.home_q",
                self.robot.home_q,
                "joint angles must be finite and within [-pi, pi] rad",
            );
        }
        if !arm.joint_limits().contains(&self.robot.home_q) {
            return invalid(
                "robot.home_q",
                self.robot.home_q,
                format!("outside the {}'s joint limits", arm.name),
            );
        }
        if let Some(k) = self.robot.hand_scale {
            if !(k.is_finite() && k > 0.0) {
                return invalid(
                    "robot.hand_scale",
                    k,
                    "must be a finite scale > 0 (tool metres per hand metre)",
                );
            }
        }
        if let Some(step) = self.robot.joint_step {
            // The slowest joint's rated speed bounds a step every joint takes at full action.
            let rated = arm.joint_limits().velocity.iter().copied().fold(f64::INFINITY, f64::min);
            let most = rated * f64::from(crate::CONTROL_DT);
            if !(step.is_finite() && step > 0.0) {
                return invalid(
                    "robot.joint_step",
                    step,
                    "must be a finite joint motion > 0 (rad per control step at full action)",
                );
            }
            if step > most {
                return invalid(
                    "robot.joint_step",
                    step,
                    format!(
                        "must be at most {most:.4} rad per step: {rated:.4} rad/s, the {}'s slowest rated \
                         joint speed, over the {} s control step",
                        arm.name,
                        crate::CONTROL_DT
                    ),
                );
            }
        }
        self.check_tool_space()?;
        self.check_tcp_box(arm)?;
        positive("table.half_extents", &self.table.half_extents)?;
        finite("table.top_z", &[self.table.top_z])?;
        friction("table.friction", self.table.friction)?;
        self.check_effector()?;
        self.check_object()?;
        self.check_target()?;
        self.check_row()?;
        check_variation("starts.paper", &self.starts.paper, arm)?;
        check_variation("starts.wide", &self.starts.wide, arm)?;
        check_thresholds(self.task(), &self.thresholds)?;
        let r = &self.rewards;
        finite("rewards.pick", &[r.pick])?;
        finite("rewards.success", &[r.success])?;
        finite("rewards.fail", &[r.fail])?;
        if !(1..=100_000).contains(&self.episode.max_steps) {
            return invalid("episode.max_steps", self.episode.max_steps, "must be in [1, 100000] steps");
        }
        self.check_start_box("starts.paper", &self.starts.paper)?;
        self.check_start_box("starts.wide", &self.starts.wide)
    }

    /// A `[row]`: a suction effector's (the TileRow logic), 2 to [`MAX_ROW`] long, its pitches
    /// finite, neighbouring pads not overlapping (they may touch) and neighbouring objects not
    /// overlapping at any yaw of either start box (the objects are turned alike about their own
    /// centres). Checked at both ends of each yaw range and every 0.1° between: the true
    /// narrowest gap is within half a step of a sample, where the gap differs by less than
    /// |pitch| · 0.0009 (0.15 mm for TileRow's 0.17 m pitch).
    fn check_row(&self) -> Result<(), SpecError> {
        let Some(RowSpec { count, object_pitch, pad_pitch, .. }) = self.row else { return Ok(()) };
        if !matches!(self.effector, EffectorSpec::Suction { .. }) {
            return invalid("row", count, "only the suction logic (TileRow) installs a row of objects");
        }
        if !(2..=MAX_ROW).contains(&count) {
            return invalid(
                "row.count",
                count,
                format!("must be 2 to {MAX_ROW} (TileRow's observation frame has {MAX_ROW} tile slots)"),
            );
        }
        finite("row.object_pitch", &object_pitch)?;
        finite("row.pad_pitch", &pad_pitch)?;
        if let TargetSpec::Pad { half_extents: h, .. } = &self.target {
            let tol = 1e-6;
            if pad_pitch[0].abs() < 2.0 * h[0] - tol && pad_pitch[1].abs() < 2.0 * h[1] - tol {
                return invalid(
                    "row.pad_pitch",
                    pad_pitch,
                    format!(
                        "neighbouring pads overlap: they are {} x {} m, so the pitch must be at least that in x or in y",
                        2.0 * h[0],
                        2.0 * h[1]
                    ),
                );
            }
        }
        for (field, v) in [("starts.paper", &self.starts.paper), ("starts.wide", &self.starts.wide)] {
            let [lo, hi] = v.yaw_deg;
            let n = ((hi - lo) / 0.1).ceil().clamp(0.0, 1000.0) as usize;
            let yaws = (0..=n).map(|k| if k == n { hi } else { lo + 0.1 * k as f32 });
            for yaw_deg in yaws {
                if let Some(gap) = crate::starts::row_gap(self, object_pitch, yaw_deg.to_radians()) {
                    return invalid(
                        "row.object_pitch",
                        object_pitch,
                        format!(
                            "neighbouring objects overlap by {:.4} m when turned by {yaw_deg:.1} deg ({field}.yaw_deg)",
                            -gap
                        ),
                    );
                }
            }
        }
        Ok(())
    }

    /// `robot.tool_step` / `robot.tool_turn`: only with `robot.action = "tool"`, finite, > 0
    /// and at most 0.05 m / 0.2 rad per step.
    fn check_tool_space(&self) -> Result<(), SpecError> {
        let tool = self.action_space() == super::ActionSpace::Tool;
        for (field, value, most, unit) in [
            ("robot.tool_step", self.robot.tool_step, 0.05, "m"),
            ("robot.tool_turn", self.robot.tool_turn, 0.2, "rad"),
        ] {
            let Some(v) = value else { continue };
            if !tool {
                return invalid(field, v, "only with robot.action = \"tool\" (the joint space moves joints)");
            }
            if !(v.is_finite() && v > 0.0 && v <= most) {
                return invalid(
                    field,
                    v,
                    format!("must be a finite motion > 0 and at most {most} {unit} per step at full action"),
                );
            }
        }
        Ok(())
    }

    /// `robot.tcp_box`: finite, each min below its max, the TCP at `home_q` inside.
    fn check_tcp_box(&self, arm: &ur3_kin::UrModel) -> Result<(), SpecError> {
        let Some([lo, hi]) = self.robot.tcp_box else { return Ok(()) };
        if !(lo.iter().chain(&hi).all(|v| v.is_finite()) && lo.iter().zip(&hi).all(|(a, b)| a < b)) {
            return invalid(
                "robot.tcp_box",
                [lo, hi],
                "must be [[x, y, z] min, [x, y, z] max] in m, each min below its max",
            );
        }
        let home = ur3_kin::fk(arm, &self.robot.home_q);
        let tcp = home * nalgebra::Point3::new(0.0, 0.0, f64::from(self.tcp_z()));
        if (0..3).any(|i| tcp[i] < lo[i] || tcp[i] > hi[i]) {
            return invalid(
                "robot.tcp_box",
                [lo, hi],
                format!(
                    "the TCP at home_q, ({:.3}, {:.3}, {:.3}) m, lies outside it",
                    tcp[0], tcp[1], tcp[2]
                ),
            );
        }
        Ok(())
    }

    fn check_effector(&self) -> Result<(), SpecError> {
        match &self.effector {
            EffectorSpec::Suction { plate_half_extents, cup_offset, cup_radius, tcp_z, seal } => {
                check_seal(seal.as_ref(), self.thresholds.rule, self.row.is_some())?;
                positive("effector.plate_half_extents", plate_half_extents)?;
                positive("effector.cup_offset", &[*cup_offset])?;
                positive("effector.cup_radius", &[*cup_radius])?;
                if !(tcp_z.is_finite() && *tcp_z > 2.0 * plate_half_extents[2]) {
                    return invalid(
                        "effector.tcp_z",
                        tcp_z,
                        "the cup lips must be below the plate's face (tcp_z > 2 * plate_half_extents[2])",
                    );
                }
            }
            EffectorSpec::Gripper {
                body_half_extents,
                finger_half_extents,
                finger_z,
                max_width,
                speed,
                finger_friction,
                spin_rate,
            } => {
                if self.thresholds.rule == Some(Rule::Placed) {
                    return invalid(
                        "thresholds.rule",
                        "placed",
                        "the placed rule is built for the suction head only (TilePlace) so far",
                    );
                }
                positive("effector.body_half_extents", body_half_extents)?;
                positive("effector.finger_half_extents", finger_half_extents)?;
                positive("effector.finger_z", &[*finger_z])?;
                positive("effector.max_width", &[*max_width])?;
                positive("effector.speed", &[*speed])?;
                friction("effector.finger_friction", *finger_friction)?;
                if let Some(r) = spin_rate {
                    positive("effector.spin_rate", &[*r])?;
                }
            }
        }
        Ok(())
    }

    fn check_object(&self) -> Result<(), SpecError> {
        let o = &self.object;
        if o.name.is_empty() {
            return invalid("object.name", &o.name, "must not be empty");
        }
        match o.shape.as_str() {
            "box" => {
                let Some(h) = o.half_extents else {
                    return invalid(
                        "object.half_extents",
                        "(missing)",
                        "a box object needs its half extents (m)",
                    );
                };
                positive("object.half_extents", &h)?;
                for (f, v) in [("object.radius", o.radius), ("object.half_height", o.half_height)] {
                    if let Some(v) = v {
                        return invalid(f, v, "a box object has half_extents only");
                    }
                }
            }
            "cylinder" => {
                let (Some(r), Some(hh)) = (o.radius, o.half_height) else {
                    return invalid(
                        "object.radius",
                        o.radius,
                        "a cylinder object needs radius and half_height (m)",
                    );
                };
                positive("object.radius", &[r])?;
                positive("object.half_height", &[hh])?;
                if let Some(h) = o.half_extents {
                    return invalid(
                        "object.half_extents",
                        h,
                        "a cylinder object has radius and half_height only",
                    );
                }
            }
            other => return invalid("object.shape", other, "must be \"box\" or \"cylinder\""),
        }
        if let Some(m) = o.mass {
            positive("object.mass", &[m])?;
        }
        if let Some(f) = o.friction {
            friction("object.friction", f)?;
        }
        if !o.rgba.iter().all(|c| (0.0..=1.0).contains(c)) {
            return invalid("object.rgba", o.rgba, "colour components must be in [0, 1]");
        }
        let (task, shape) = (self.task(), o.shape.as_str());
        match (task, shape) {
            (Task::TileSuction | Task::BlockGrip | Task::TileRow | Task::TilePlace, "box")
            | (Task::Screw, "cylinder") => Ok(()),
            (Task::Screw, _) => invalid("object.shape", shape, "the screw logic turns a cylinder (the nut)"),
            _ => invalid("object.shape", shape, format!("the {} logic moves a box", task.name())),
        }
    }

    fn check_target(&self) -> Result<(), SpecError> {
        match (&self.target, self.task()) {
            (
                TargetSpec::Pad { xy, half_extents, friction: f },
                Task::TileSuction | Task::BlockGrip | Task::TileRow | Task::TilePlace,
            ) => {
                finite("target.xy", xy)?;
                positive("target.half_extents", half_extents)?;
                friction("target.friction", *f)
            }
            (
                TargetSpec::Bolt { plate_half_extents, radius, top_z, pitch, catch_gap, turns },
                Task::Screw,
            ) => {
                positive("target.plate_half_extents", plate_half_extents)?;
                positive("target.radius", &[*radius])?;
                positive("target.pitch", &[*pitch])?;
                positive("target.catch_gap", &[*catch_gap])?;
                if !(turns.is_finite() && *turns > 0.0) {
                    return invalid("target.turns", turns, "must be a number of turns > 0");
                }
                let nut_r = self.object.radius.unwrap_or(0.0);
                if nut_r <= *radius {
                    return invalid(
                        "target.radius",
                        radius,
                        format!("the nut (radius {nut_r} m) must be wider than the bolt"),
                    );
                }
                let nut_start = top_z - self.object_half_height() - catch_gap;
                let low = 2.0 * plate_half_extents[2] + self.object_half_height();
                if !(top_z.is_finite() && nut_start - (*turns as f32) * pitch > low) {
                    return invalid(
                        "target.top_z",
                        top_z,
                        format!("the bolt is too short for {turns} turns of the nut above the plate"),
                    );
                }
                Ok(())
            }
            (TargetSpec::Pad { .. }, t) => {
                invalid("target.kind", "pad", format!("the {} logic needs a bolt target", t.name()))
            }
            (TargetSpec::Bolt { .. }, t) => {
                invalid("target.kind", "bolt", format!("the {} logic needs a pad target", t.name()))
            }
        }
    }
}
