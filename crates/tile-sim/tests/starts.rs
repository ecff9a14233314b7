//! Episode starts: the wide variation keeps every start valid (on the table, clear of the pad,
//! within reach with a margin, checked with the IK over a grid of the whole box), explicit starts
//! are placed as given or refused naming the field, and a restore keeps each episode's start
//! (the expert installing from the wide starts is in `variation.rs`).

use tile_sim::{Env, SimError, Start, Task, Variation, VecEnv, world};

/// The tasks whose starts are the paper's and the wide box of `Variation::default` / `wide`.
const PAPER_TASKS: [Task; 3] = [Task::TileSuction, Task::BlockGrip, Task::Screw];

fn msg(r: Result<(), SimError>) -> String {
    match r {
        Err(SimError::InvalidArgument(m)) => m,
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

/// A grid over the wide box: 6 x by 5 y by 3 yaw by 3 x 3 target offsets, every point valid.
#[test]
fn every_start_of_the_wide_box_is_valid() {
    let v = Variation::wide();
    assert!(v.object_x[1] - v.object_x[0] >= 0.25 - 1e-6);
    assert!(v.object_y[1] - v.object_y[0] >= 0.10 - 1e-6);
    assert!((v.yaw[1] - 30f32.to_radians()).abs() < 1e-6 && v.yaw[0] == -v.yaw[1]);
    assert_eq!(v.target_jitter, 0.04);
    let lerp = |r: [f32; 2], k: usize, n: usize| r[0] + (r[1] - r[0]) * k as f32 / (n - 1) as f32;
    // The paper's three tasks share this box; TileRow's row has a box of its own (tests/tile_row.rs).
    for task in PAPER_TASKS {
        let mut checked = 0;
        for ix in 0..6 {
            for iy in 0..5 {
                for iw in 0..3 {
                    for (dx, dy) in [(-1.0f32, -1.0f32), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0), (0.0, 0.0)] {
                        let off = if task == Task::Screw { [0.0; 2] } else { [0.04 * dx, 0.04 * dy] };
                        let yaw = if task == Task::Screw { 0.0 } else { lerp(v.yaw, iw, 3) };
                        let st = Start::from_options(
                            [lerp(v.object_x, ix, 6), lerp(v.object_y, iy, 5), yaw],
                            off,
                            None,
                        );
                        st.check(task).unwrap_or_else(|e| panic!("{task:?} {st:?}: {e}"));
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 450);
    }
}

#[test]
fn wide_draws_fill_the_box_and_the_papers_draws_are_unchanged() {
    for task in PAPER_TASKS {
        let v = Variation::wide();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        let mut dmax = 0.0f32;
        for seed in 0..2000 {
            let st = v.start(task, seed);
            st.check(task).unwrap_or_else(|e| panic!("{task:?} seed {seed}: {e}"));
            let p = [st.object_xy[0], st.object_xy[1], st.yaw];
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            assert_eq!(st.pad_offset, st.target_offset, "the pad moves with the target");
            dmax = dmax.max(st.target_offset[0].abs()).max(st.target_offset[1].abs());
        }
        assert!(hi[0] - lo[0] > 0.24 && hi[1] - lo[1] > 0.09, "{task:?} {lo:?} {hi:?}");
        if task == Task::Screw {
            assert_eq!((lo[2], hi[2], dmax), (0.0, 0.0, 0.0));
        } else {
            assert!(hi[2] > 0.5 && lo[2] < -0.5 && dmax > 0.038, "{task:?} {lo:?} {hi:?} {dmax}");
        }
        // the paper's variation: y fixed, no yaw, the target and pad where they always were
        let st = Variation::default().start(task, 7);
        assert_eq!(
            (st.object_xy[1], st.yaw, st.target_offset, st.pad_offset),
            (world::OBJECT_Y, 0.0, [0.0; 2], [0.0; 2])
        );
    }
}

#[test]
fn bad_starts_are_refused_naming_the_field() {
    let t = Task::TileSuction;
    let at = |x: f32, y: f32, yaw: f32| Start::from_options([x, y, yaw], [0.0; 2], None);
    assert!(msg(at(f32::NAN, 0.3, 0.0).check(t)).starts_with("object_pose"));
    assert!(msg(at(0.66, 0.3, 0.0).check(t)).contains("off the table"));
    // on the pad (its centre is at x = -0.22, y = 0.28)
    let m = msg(at(-0.2, 0.28, 0.0).check(t));
    assert!(m.starts_with("object_pose") && m.contains("pad"), "{m}");
    // far out: 0.55 m from the base, beyond the UR3's reach
    let m = msg(at(0.35, 0.42, 0.0).check(t));
    assert!(m.starts_with("object_pose") && m.contains("out of reach") && m.contains("0.03"), "{m}");
    assert!(msg(at(0.0, 0.0, 0.0).check(t)).contains("out of reach"), "on the base");
    // the reach margin: along a ray, find the farthest grasp point the IK reaches with the flange
    // down (and 10 cm above it); 2 cm inside it is refused, 4 cm inside accepted
    let dir = [0.6f32, 0.8f32];
    let grasp_z = world::TILE_HALF[2] * 2.0;
    let ik_ok = |r: f32| {
        [0.0, 0.10].iter().all(|up| {
            let p = nalgebra::Vector3::new((r * dir[0]) as f64, (r * dir[1]) as f64, (grasp_z + up) as f64);
            let pose = tile_sim::expert::tool0_for_tcp(p, world::CUP_TCP_Z as f64);
            tile_sim::expert::ik_dls(&pose, &tile_sim::HOME_Q).is_some()
        })
    };
    let (mut lo, mut hi) = (0.3f32, 0.8f32);
    assert!(ik_ok(lo) && !ik_ok(hi));
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if ik_ok(mid) { lo = mid } else { hi = mid }
    }
    let inside = |d: f32| at((lo - d) * dir[0], (lo - d) * dir[1], 0.0).check(t);
    assert!(msg(inside(0.02)).contains("out of reach"), "reach limit {lo}");
    inside(0.04).unwrap();
    assert!(msg(at(0.1, 0.3, 1.0).check(t)).contains("yaw"));
    let m = msg(Start::from_options([0.1, 0.3, 0.0], [0.05, 0.0], None).check(t));
    assert!(m.starts_with("target_offset"), "{m}");
    let m = msg(Start::from_options([0.1, 0.3, 0.0], [0.01, 0.0], None).check(Task::Screw));
    assert!(m.starts_with("target_offset") && m.contains("Screw"), "{m}");
    // and an env refuses it without changing its episode
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(3), &mut o).unwrap();
    let before = env.snapshot();
    assert!(env.reset_start(at(0.66, 0.3, 0.0), 1, &mut o).is_err());
    assert_eq!(env.snapshot(), before);
}

#[test]
fn an_explicit_start_puts_the_object_the_pad_and_the_target_where_it_says() {
    for task in [Task::TileSuction, Task::BlockGrip] {
        let st = Start::from_options([0.2, 0.3, 0.4], [0.03, -0.02], None);
        let mut env = Env::new(task, 0);
        let mut o = vec![0.0; task.obs_dim()];
        env.reset_start(st, 77, &mut o).unwrap();
        let s = env.snapshot();
        assert_eq!(env.start(), st);
        assert_eq!(s.episode_seed, 77);
        assert!((s.object.t[0] - 0.2).abs() < 1e-6 && (s.object.t[1] - 0.3).abs() < 1e-6);
        // yaw about Z: q = (0, 0, sin(yaw/2), cos(yaw/2))
        assert!((s.object.q[2] - (0.2f64).sin()).abs() < 1e-5, "{:?}", s.object.q);
        let nominal = world::pad_target(task);
        assert!((s.target.t[0] - (nominal.x + 0.03) as f64).abs() < 1e-6);
        assert!((s.target.t[1] - (nominal.y - 0.02) as f64).abs() < 1e-6);
        let pad = env.scene().items.into_iter().find(|i| i.name == "pad").unwrap();
        assert!((pad.translation[0] - (world::PAD_XY[0] + 0.03)).abs() < 1e-6);
        // the observation's target and object entries (last frame) say the same
        let fd = task.obs_frame_dim();
        let f = &o[o.len() - fd..];
        let k = 6 + 1 + 3;
        assert!((f[k] - (nominal.x + 0.03)).abs() < 1e-6 && (f[k + 3] - 0.2).abs() < 1e-6);
        // the tile rests: a step of no motion leaves it where it was put
        let a = vec![0.0; task.act_dim()];
        let r = env.step(&a, &mut o).unwrap();
        assert!(!r.terminated, "{task:?}: {r:?}");
    }
}

/// A VecEnv's state records each running episode's start: a restore into a VecEnv whose
/// variation differs rebuilds the same episodes, explicit starts included.
#[test]
fn restore_keeps_each_episodes_start() {
    let task = Task::TileSuction;
    let (n, od, ad) = (3, task.obs_dim(), task.act_dim());
    let mut v = VecEnv::new(task, n, 5, 1).unwrap();
    v.set_variation(Variation::wide()).unwrap();
    let mut obs = vec![0.0; n * od];
    v.reset(Some(11), &mut obs).unwrap();
    let explicit = Start::from_options([0.25, 0.35, -0.3], [-0.04, 0.04], None);
    let mut one = vec![0.0; od];
    v.reset_replay(1, 99, Some(explicit), &vec![0.1; 5 * ad], &mut one).unwrap();
    let st = v.state();
    assert_eq!(st.starts[1], explicit);
    assert_eq!(st.starts[0], Variation::wide().start(task, 11));
    let mut w = VecEnv::new(task, n, 0, 1).unwrap(); // the paper's variation
    let mut o2 = vec![0.0; n * od];
    w.restore(&st, &mut o2).unwrap();
    v.restore(&st, &mut obs).unwrap();
    assert_eq!(obs, o2);
    assert_eq!(w.state(), st);
    // explicit starts for every env, validated all-or-nothing
    let starts = [explicit, Start::from_options([0.1, 0.3, 0.0], [0.0; 2], None), explicit];
    w.reset_starts(3, &starts, &mut o2).unwrap();
    assert_eq!(w.env(2).unwrap().start(), explicit);
    let bad = [explicit, Start::from_options([0.9, 0.3, 0.0], [0.0; 2], None), explicit];
    let m = match w.reset_starts(4, &bad, &mut o2) {
        Err(SimError::InvalidArgument(m)) => m,
        other => panic!("{other:?}"),
    };
    assert!(m.starts_with("env 1: object_pose"), "{m}");
    assert_eq!(w.env(0).unwrap().snapshot().episode_seed, tile_sim::episode_seed(3, 0, 0));
}
