//! Episode-start variation: the paper's default draws what it always drew, the robustness
//! evaluation's widens the tile's x range by half on each side and moves the target by up to
//! ±2 cm, and the scripted expert still installs there (the widened task is feasible).

use tile_sim::expert::Expert;
use tile_sim::{Env, Task, Variation, VecEnv, object_start, world};

fn start_and_target(env: &mut Env, seed: u64) -> ([f32; 3], [f32; 3]) {
    let mut o = vec![0.0; env.task().obs_dim()];
    env.reset(Some(seed), &mut o).unwrap();
    let s = env.snapshot();
    let o = s.object.t;
    let t = s.target.t;
    ([o[0] as f32, o[1] as f32, o[2] as f32], [t[0] as f32, t[1] as f32, t[2] as f32])
}

#[test]
fn the_default_variation_is_the_papers_start() {
    let mut env = Env::new(Task::TileSuction, 0);
    assert_eq!(env.variation(), Variation::default());
    let pad = world::pad_target(Task::TileSuction);
    for seed in 0..200 {
        let (o, t) = start_and_target(&mut env, seed);
        let expect = object_start(Task::TileSuction, seed);
        assert_eq!(o[0], expect.x, "seed {seed}");
        assert!((world::OBJECT_X_MIN..=world::OBJECT_X_MAX).contains(&o[0]));
        assert_eq!(t, [pad.x, pad.y, pad.z]);
    }
}

#[test]
fn the_robust_variation_widens_x_and_moves_the_target() {
    let v = Variation::robust();
    assert!((v.object_x[0] + 0.075).abs() < 1e-6 && (v.object_x[1] - 0.225).abs() < 1e-6);
    assert_eq!(v.target_jitter, 0.02);
    let mut env = Env::new(Task::TileSuction, 0);
    env.set_variation(v).unwrap();
    let pad = world::pad_target(Task::TileSuction);
    let (mut xmin, mut xmax, mut dmax) = (f32::MAX, f32::MIN, 0.0f32);
    for seed in 0..500 {
        let (o, t) = start_and_target(&mut env, seed);
        assert!((-0.07501..=0.22501).contains(&o[0]), "seed {seed}: x {}", o[0]);
        let (dx, dy) = (t[0] - pad.x, t[1] - pad.y);
        assert!(dx.abs() <= 0.02 + 1e-6 && dy.abs() <= 0.02 + 1e-6 && t[2] == pad.z);
        xmin = xmin.min(o[0]);
        xmax = xmax.max(o[0]);
        dmax = dmax.max(dx.abs()).max(dy.abs());
    }
    // the draws fill the ranges: both widened ends are reached and the target does move
    assert!(xmin < -0.06 && xmax > 0.21 && dmax > 0.018, "{xmin} {xmax} {dmax}");
}

#[test]
fn out_of_range_variations_are_refused_and_change_nothing() {
    let mut env = Env::new(Task::TileSuction, 0);
    for bad in [
        Variation { object_x: [0.2, 0.1], target_jitter: 0.0, ..Default::default() },
        Variation { object_x: [f32::NAN, 0.1], target_jitter: 0.0, ..Default::default() },
        Variation { object_x: [-0.5, 0.1], target_jitter: 0.0, ..Default::default() },
        Variation { object_x: [0.0, 0.15], target_jitter: 0.05, ..Default::default() },
        Variation { object_x: [0.0, 0.15], target_jitter: -0.01, ..Default::default() },
    ] {
        assert!(env.set_variation(bad).is_err(), "{bad:?}");
        assert_eq!(env.variation(), Variation::default());
    }
    let mut venv = VecEnv::new(Task::TileSuction, 3, 0, 1).unwrap();
    assert!(
        venv.set_variation(Variation { object_x: [0.2, 0.1], target_jitter: 0.0, ..Default::default() })
            .is_err()
    );
    venv.set_variation(Variation::robust()).unwrap();
    assert!((0..3).all(|i| venv.env(i).unwrap().variation() == Variation::robust()));
}

/// Episodes (seeds `0..episodes`) the scripted expert installs in under variation `v`.
fn expert_installs(task: Task, v: Variation, episodes: u64) -> u32 {
    let mut env = Env::new(task, 0);
    env.set_variation(v).unwrap();
    let mut o = vec![0.0; task.obs_dim()];
    let mut a = vec![0.0; task.act_dim()];
    let mut ex = Expert::new(task);
    let mut ok = 0;
    for seed in 0..episodes {
        env.reset(Some(seed), &mut o).unwrap();
        ex.reset();
        loop {
            ex.act(&env.snapshot(), &mut a);
            let r = env.step(&a, &mut o).unwrap();
            if r.terminated || r.truncated {
                ok += r.installed as u32;
                break;
            }
        }
    }
    ok
}

#[test]
fn the_expert_installs_under_the_robust_variation() {
    let ok = expert_installs(Task::TileSuction, Variation::robust(), 200);
    eprintln!("TileSuction expert, robust starts: installed {ok}/200");
    assert!(ok >= 190, "installed {ok}/200");
}

/// The scripted expert installs from the wide starts too (the task stays feasible there).
#[test]
fn the_expert_installs_under_the_wide_variation() {
    let ok = expert_installs(Task::TileSuction, Variation::wide(), 100);
    eprintln!("TileSuction expert, wide starts: installed {ok}/100");
    assert!(ok >= 95, "installed {ok}/100");
}

/// Named variations are the env's own spec's: a spec with other paper and wide boxes gets its
/// boxes (the built-in names give the built-in TileSuction spec's, as before).
#[test]
fn named_variations_come_from_the_spec() {
    use tile_sim::TaskSpec;
    let builtin = TaskSpec::builtin(Task::TileSuction);
    for name in ["training", "robust", "wide"] {
        assert_eq!(Variation::named(name), Variation::named_in(name, &builtin), "{name}");
    }
    assert_eq!(Variation::named("training"), Some(Variation::default()));
    assert_eq!(Variation::named("robust"), Some(Variation::robust()));
    assert_eq!(Variation::towards_wide(0.5), Variation::towards_wide_in(0.5, &builtin));
    let text = include_str!("../tasks/tile_suction.toml")
        .replacen("object_x = [0.035, 0.285]", "object_x = [0.07, 0.25]", 1)
        .replacen("object_x = [0.0, 0.15]", "object_x = [0.02, 0.12]", 1);
    let spec = TaskSpec::from_toml(&text, "mine.toml").unwrap();
    assert_eq!(Variation::named_in("wide", &spec).unwrap().object_x, [0.07, 0.25]);
    assert_eq!(Variation::named_in("training", &spec).unwrap().object_x, [0.02, 0.12]);
    let [lo, hi] = Variation::named_in("robust", &spec).unwrap().object_x;
    assert!((lo + 0.03).abs() < 1e-6 && (hi - 0.17).abs() < 1e-6, "{lo} {hi}");
    assert_eq!(Variation::towards_wide_in(1.0, &spec).object_x, [0.07, 0.25]);
    assert_eq!(Variation::towards_wide_in(0.0, &spec).object_x, [0.02, 0.12]);
    let mut env = Env::from_spec(std::sync::Arc::new(spec), 0);
    env.set_variation(Variation::named_in("wide", env.spec()).unwrap()).unwrap();
    let mut obs = vec![0.0; Task::TileSuction.obs_dim()];
    for seed in 0..40 {
        env.reset(Some(seed), &mut obs).unwrap();
        let x = env.start().object_xy[0];
        assert!((0.07..=0.25).contains(&x), "seed {seed}: x {x}");
    }
}
