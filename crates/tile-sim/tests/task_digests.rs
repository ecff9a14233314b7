//! Bit-identical episodes across refactors (issue 26 §1): for each task, the scripted expert and a
//! fixed random-action sequence are run on a few seeds at the paper's and at the wide starts, and
//! every step's observation, reward, terminated / truncated bits and event flags (plus the
//! snapshot's object, TCP and target poses) are hashed (`to_bits`, FNV-1a 64) into one digest per
//! task; the scene description and the constants record get digests of their own.
//!
//! The digests were recorded with the code of commit 22561ac, before the tasks moved behind one
//! trait and their numbers into spec files. A digest that changes here means episodes changed:
//! find out why before recording a new one.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tile_sim::expert::Expert;
use tile_sim::{Constants, Env, StepOutcome, Task, Variation};

/// FNV-1a, 64 bits: small, dependency-free, and stable across Rust versions (unlike `DefaultHasher`).
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f32s(&mut self, v: &[f32]) {
        v.iter().for_each(|x| self.u32(x.to_bits()));
    }
    fn f64s(&mut self, v: &[f64]) {
        v.iter().for_each(|x| self.u64(x.to_bits()));
    }
    fn flag(&mut self, b: bool) {
        self.bytes(&[b as u8]);
    }
}

fn feed_step(h: &mut Fnv, env: &Env, obs: &[f32], o: &StepOutcome) {
    h.f32s(obs);
    h.u32(o.reward.to_bits());
    for b in [o.terminated, o.truncated, o.picked, o.held, o.installed, o.fell] {
        h.flag(b);
    }
    let s = env.snapshot();
    for p in [&s.object, &s.tcp, &s.target] {
        h.f64s(&p.t);
        h.f64s(&p.q);
    }
    h.f64s(&[s.gripper_width, s.spin_angle]);
    h.flag(s.suction_on);
}

/// Seeds each digest runs: two from the paper's starts, two from the wide ones.
const SEEDS: [u64; 2] = [3, 17];

fn variations() -> [Variation; 2] {
    [Variation::default(), Variation::wide()]
}

/// Expert episodes to their end (or truncation), then 120 steps of seeded random actions (joint
/// parts in [-1.2, 1.2], so clipping is exercised, commands spread over the three bands) across
/// as many episodes as they take, for every seed and variation.
fn episode_digest(task: Task) -> (u64, u32) {
    let mut h = Fnv::new();
    let mut installs = 0;
    let mut obs = vec![0.0f32; task.obs_dim()];
    let mut act = vec![0.0f32; task.act_dim()];
    for v in variations() {
        for &seed in &SEEDS {
            let mut env = Env::new(task, seed);
            env.set_variation(v).unwrap();
            // Expert.
            env.reset(Some(seed), &mut obs).unwrap();
            h.f32s(&obs);
            let mut expert = Expert::new(task);
            expert.reset();
            loop {
                expert.act(&env.snapshot(), &mut act);
                let o = env.step(&act, &mut obs).unwrap();
                feed_step(&mut h, &env, &obs, &o);
                installs += o.installed as u32;
                if o.terminated || o.truncated {
                    break;
                }
            }
            // Random actions.
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
            env.reset(Some(seed + 1000), &mut obs).unwrap();
            h.f32s(&obs);
            for _ in 0..120 {
                for (i, a) in act.iter_mut().enumerate() {
                    *a =
                        if i < 6 { rng.random_range(-1.2f32..=1.2) } else { rng.random_range(-1.0f32..=1.0) };
                }
                let o = env.step(&act, &mut obs).unwrap();
                feed_step(&mut h, &env, &obs, &o);
                if o.terminated || o.truncated {
                    env.reset(None, &mut obs).unwrap();
                    h.f32s(&obs);
                }
            }
        }
    }
    (h.0, installs)
}

/// The scene items (Debug prints every f32 exactly) at the starts of the digest's seeds.
fn scene_digest(task: Task) -> u64 {
    let mut h = Fnv::new();
    for v in variations() {
        for &seed in &SEEDS {
            let start = v.start(task, seed);
            let mut env = Env::new(task, 0);
            let mut obs = vec![0.0f32; task.obs_dim()];
            env.reset_start(start, seed, &mut obs).unwrap();
            h.bytes(format!("{:?}", env.scene()).as_bytes());
            // These tasks' pads are never turned; the start as it printed before it had a pad yaw.
            assert_eq!(start.pad_yaw, 0.0);
            h.bytes(format!("{:?}", start).replace(", pad_yaw: 0.0", "").as_bytes());
        }
    }
    h.0
}

/// (task, episode digest, scene digest), recorded at commit 22561ac.
const GOLDEN: [(Task, u64, u64); 3] = [
    (Task::TileSuction, 0xbdd1ce7c5166f8f4, 0x6b942cfdbe7897f4),
    (Task::BlockGrip, 0x8e6966444f2b059d, 0x07d7493d2a4d0cb6),
    (Task::Screw, 0xd7b55523696f9646, 0x1a674f43b8c96380),
];

#[test]
fn episodes_and_scenes_are_bit_identical_to_the_recorded_ones() {
    let mut got = Vec::new();
    for (task, _, _) in GOLDEN {
        let (digest, installs) = episode_digest(task);
        // The digests cover real episodes: the expert succeeds at least at the paper's starts.
        assert!(installs >= SEEDS.len() as u32, "{task:?}: the expert succeeded {installs} times");
        got.push((task, digest, scene_digest(task)));
    }
    let table: Vec<String> =
        got.iter().map(|(t, e, s)| format!("(Task::{t:?}, {e:#018x}, {s:#018x}),")).collect();
    assert_eq!(got, GOLDEN, "digests changed; now:\n{}", table.join("\n"));
}

/// A TileRow observation in the frame layout its digest was recorded with (31 floats: the frame
/// without the current tile's target and centre, floats 10..16, and its two differences, floats
/// 16..22, added after), each frame's current-tile floats checked against the snapshot's object
/// and target, and its differences against them, on the way (the newest frame's; the older
/// frames are earlier steps', checked when they were the newest).
fn row_obs_as_recorded(env: &Env, obs: &[f32]) -> Vec<f32> {
    let dim = Task::TileRow.obs_frame_dim();
    let newest = &obs[obs.len() - dim..];
    let s = env.snapshot();
    for (k, v) in s.target.t.iter().chain(&s.object.t).enumerate() {
        assert_eq!(newest[10 + k], *v as f32, "current tile's float {k}");
    }
    for k in 0..3 {
        assert_eq!(newest[16 + k], newest[13 + k] - newest[7 + k], "tile - cup {k}");
        assert_eq!(newest[19 + k], newest[10 + k] - newest[13 + k], "target - tile {k}");
    }
    obs.chunks(dim).flat_map(|f| f[..10].iter().chain(&f[22..]).copied()).collect()
}

/// TileRow's episodes (expert and random actions, its own paper and wide starts, every tile's
/// pose and flags each step), recorded when the task was added (branch tile-row): a change here
/// means TileRow's episodes changed. The observation is hashed as it was recorded
/// ([`row_obs_as_recorded`]), so the digest also says the older floats did not change.
fn row_digest() -> (u64, u32) {
    let task = Task::TileRow;
    let spec = task.spec();
    let mut h = Fnv::new();
    let mut installs = 0;
    let mut obs = vec![0.0f32; task.obs_dim()];
    let mut act = vec![0.0f32; task.act_dim()];
    let feed = |h: &mut Fnv, env: &Env, obs: &[f32], o: &StepOutcome| {
        feed_step(h, env, &row_obs_as_recorded(env, obs), o);
        for r in env.snapshot().row {
            h.f64s(&r.object.t);
            h.f64s(&r.object.q);
            h.f64s(&r.target.t);
            h.flag(r.picked);
            h.flag(r.installed);
        }
    };
    for v in [spec.starts.paper.variation(), spec.starts.wide.variation()] {
        for &seed in &SEEDS {
            let mut env = Env::new(task, seed);
            env.set_variation(v).unwrap();
            env.reset(Some(seed), &mut obs).unwrap();
            h.f32s(&row_obs_as_recorded(&env, &obs));
            let mut expert = Expert::new(task);
            loop {
                expert.act(&env.snapshot(), &mut act);
                let o = env.step(&act, &mut obs).unwrap();
                feed(&mut h, &env, &obs, &o);
                installs += o.installed as u32;
                if o.terminated || o.truncated {
                    break;
                }
            }
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
            env.reset(Some(seed + 1000), &mut obs).unwrap();
            h.f32s(&row_obs_as_recorded(&env, &obs));
            for _ in 0..120 {
                for (i, a) in act.iter_mut().enumerate() {
                    *a =
                        if i < 6 { rng.random_range(-1.2f32..=1.2) } else { rng.random_range(-1.0f32..=1.0) };
                }
                let o = env.step(&act, &mut obs).unwrap();
                feed(&mut h, &env, &obs, &o);
                if o.terminated || o.truncated {
                    env.reset(None, &mut obs).unwrap();
                    h.f32s(&row_obs_as_recorded(&env, &obs));
                }
            }
            h.bytes(format!("{:?}", env.scene()).as_bytes());
        }
    }
    (h.0, installs)
}

#[test]
fn tile_row_episodes_are_bit_identical_to_the_recorded_ones() {
    let (digest, installs) = row_digest();
    assert_eq!(installs, 2 * SEEDS.len() as u32, "the expert installs every row it is given");
    assert_eq!(digest, 0xd2713cd36d31181c, "TileRow digest now {digest:#018x}");
}

/// The constants record as it was (digest recorded at commit 22561ac), plus TileRow's and
/// TilePlace's sizes: the record without those entries hashes to the recorded digest, so every
/// older value is unchanged, and the two entries are checked on their own.
#[test]
fn constants_record_is_unchanged() {
    let mut c = Constants::get();
    let row = c.tasks.remove("TileRow").expect("the record lists TileRow");
    assert_eq!((row.obs_frame_dim, row.obs_dim, row.act_dim), (43, 215, 7));
    let place = c.tasks.remove("TilePlace").expect("the record lists TilePlace");
    assert_eq!((place.obs_frame_dim, place.obs_dim, place.act_dim), (32, 160, 7));
    let mut h = Fnv::new();
    h.bytes(format!("{c:?}").as_bytes());
    assert_eq!(h.0, 0x9665706803e23574, "constants digest now {:#018x}", h.0);
}
