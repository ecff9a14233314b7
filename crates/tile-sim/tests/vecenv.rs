//! Determinism, resets, VecEnv auto-reset/masks/threads, robustness under random actions.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tile_sim::{Env, SimError, StepBuffers, Task, VecEnv, VecEnvState, episode_seed};

fn random_actions(task: Task, n: usize, seed: u64) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n * task.act_dim()).map(|_| rng.random_range(-1.2f32..=1.2)).collect()
}

/// Run an episode of random actions from `seed`, returning every float/flag as bits.
fn trajectory(env: &mut Env, seed: u64, steps: usize) -> Vec<u32> {
    let task = env.task();
    let mut o = vec![0.0; task.obs_dim()];
    env.reset(Some(seed), &mut o).unwrap();
    let acts = random_actions(task, steps, seed ^ 77);
    let mut bits: Vec<u32> = o.iter().map(|v| v.to_bits()).collect();
    for a in acts.chunks(task.act_dim()) {
        let r = env.step(a, &mut o).unwrap();
        bits.extend(o.iter().map(|v| v.to_bits()));
        bits.push(r.reward.to_bits());
        bits.push(r.terminated as u32 | (r.truncated as u32) << 1 | (r.picked as u32) << 2);
        let s = env.snapshot();
        bits.extend(s.object.t.iter().chain(s.object.q.iter()).map(|v| (*v as f32).to_bits()));
        if r.terminated || r.truncated {
            break;
        }
    }
    bits
}

#[test]
fn same_seed_same_actions_bit_identical() {
    for task in Task::ALL {
        for seed in [0u64, 42, 1234567] {
            let a = trajectory(&mut Env::new(task, 1), seed, 300);
            let b = trajectory(&mut Env::new(task, 999), seed, 300);
            assert_eq!(a, b, "{task:?} seed {seed}");
            assert!(a.len() > 1000);
        }
    }
}

#[test]
fn resets_leave_no_state_behind() {
    for task in Task::ALL {
        let fresh = trajectory(&mut Env::new(task, 5), 31, 200);
        let mut used = Env::new(task, 5);
        // Dirty the env: random episodes, picks, arbitrary teleports.
        for s in 0..3 {
            trajectory(&mut used, 100 + s, 400);
        }
        if task != Task::Screw {
            used.set_object_pose([0.3, 0.1, 0.3], [0.0, 0.0, 0.0, 1.0]).unwrap();
        }
        assert_eq!(trajectory(&mut used, 31, 200), fresh, "{task:?}");
    }
}

#[test]
fn different_seeds_differ_and_reset_none_draws_from_env_rng() {
    let mut o = vec![0.0; Task::TileSuction.obs_dim()];
    let mut e1 = Env::new(Task::TileSuction, 3);
    let mut e2 = Env::new(Task::TileSuction, 3);
    let mut xs = Vec::new();
    for _ in 0..5 {
        e1.reset(None, &mut o).unwrap();
        let s1 = e1.snapshot();
        e2.reset(None, &mut o).unwrap();
        let s2 = e2.snapshot();
        assert_eq!(s1.episode_seed, s2.episode_seed);
        assert_eq!(s1.object, s2.object);
        xs.push(s1.object.t[0]);
    }
    xs.dedup();
    assert_eq!(xs.len(), 5, "tile x changes between episodes");
}

#[test]
fn actions_validated_and_clipped() {
    let t = Task::TileSuction;
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(1), &mut o).unwrap();
    let before = env.snapshot();
    assert!(matches!(env.step(&[0.0; 6], &mut o), Err(SimError::ActionShape { expected: 7, got: 6, .. })));
    let mut a = [0.0f32; 7];
    a[3] = f32::NAN;
    assert!(matches!(env.step(&a, &mut o), Err(SimError::NonFiniteAction { index: 3, .. })));
    a[3] = f32::INFINITY;
    assert!(env.step(&a, &mut o).is_err());
    assert!(env.step(&[0.0; 7], &mut [0.0; 3]).is_err());
    assert_eq!(env.snapshot(), before, "errors leave the state unchanged");
    // Out of range is clipped: 5.0 acts like 1.0, bit for bit.
    let mut e2 = Env::new(t, 0);
    let mut o2 = vec![0.0; t.obs_dim()];
    e2.reset(Some(1), &mut o2).unwrap();
    env.step(&[5.0, -3.0, 0.5, 1e9, -1e9, 0.0, 7.0], &mut o).unwrap();
    e2.step(&[1.0, -1.0, 0.5, 1.0, -1.0, 0.0, 1.0], &mut o2).unwrap();
    assert_eq!(o, o2);
    assert_eq!(Task::from_name("nope"), Err(SimError::UnknownTask("nope".into())));
}

#[test]
fn task_names_and_dims() {
    for (n, t) in [
        ("TileSuction", Task::TileSuction),
        ("suction", Task::TileSuction),
        ("BlockGrip", Task::BlockGrip),
        ("grip", Task::BlockGrip),
        ("Screw", Task::Screw),
        ("screw", Task::Screw),
    ] {
        assert_eq!(Task::from_name(n).unwrap(), t);
        assert_eq!(Task::from_name(t.name()).unwrap(), t);
    }
    assert_eq!(
        (Task::TileSuction.obs_frame_dim(), Task::TileSuction.obs_dim(), Task::TileSuction.act_dim()),
        (16, 80, 7)
    );
    assert_eq!(
        (Task::BlockGrip.obs_frame_dim(), Task::BlockGrip.obs_dim(), Task::BlockGrip.act_dim()),
        (16, 80, 7)
    );
    assert_eq!((Task::Screw.obs_frame_dim(), Task::Screw.obs_dim(), Task::Screw.act_dim()), (18, 90, 8));
}

#[test]
fn vecenv_matches_single_envs_and_threads_agree() {
    let task = Task::TileSuction;
    let n = 6;
    let steps = 800; // crosses a truncation: exercises same-step auto-reset
    let acts = random_actions(task, n * steps, 3);
    let run = |threads: usize| {
        let mut v = VecEnv::new(task, n, 10, threads).unwrap();
        let mut o = vec![0.0; n * task.obs_dim()];
        v.reset(Some(500), &mut o).unwrap();
        let mut buf = StepBuffers::new(task, n);
        let mut log = vec![o.clone()];
        let mut finals = 0;
        for k in 0..steps {
            v.step_buffers(&acts[k * n * 7..(k + 1) * n * 7], &mut buf).unwrap();
            log.push(buf.obs.clone());
            log.push(buf.reward.clone());
            for i in 0..n {
                if buf.has_final[i] {
                    finals += 1;
                    log.push(buf.final_obs[i * 80..(i + 1) * 80].to_vec());
                }
            }
        }
        (log, finals)
    };
    let (a, fa) = run(1);
    let (b, fb) = run(2);
    let (c, _) = run(4);
    assert!(fa >= n, "every env truncated at least once");
    assert_eq!(fa, fb);
    let bits = |l: &Vec<Vec<f32>>| l.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(bits(&a), bits(&c));

    // Env i of the VecEnv equals a single Env reset with seed 500 + i, up to its first end.
    let mut e = Env::new(task, 0);
    let mut o = vec![0.0; 80];
    e.reset(Some(503), &mut o).unwrap();
    for k in 0..100 {
        let row = &acts[(k * n + 3) * 7..(k * n + 4) * 7];
        e.step(row, &mut o).unwrap();
        assert_eq!(&a[1 + 2 * k][3 * 80..4 * 80], o.as_slice());
    }
}

#[test]
fn vecenv_same_step_autoreset_keeps_final_obs() {
    let task = Task::TileSuction;
    let n = 3;
    let mut v = VecEnv::new(task, n, 0, 2).unwrap();
    let mut o = vec![0.0; n * 80];
    v.reset(Some(0), &mut o).unwrap();
    // Knock env 1's tile off the table: it terminates with -0.5 within a few steps.
    v.env_mut(1).unwrap().set_object_pose([0.9, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let mut buf = StepBuffers::new(task, n);
    let zeros = vec![0.0f32; n * 7];
    let mut ended = false;
    for _ in 0..40 {
        v.step_buffers(&zeros, &mut buf).unwrap();
        assert!(!buf.has_final[0] && !buf.has_final[2]);
        if buf.has_final[1] {
            assert!(buf.terminated[1] && buf.fell[1]);
            assert_eq!(buf.reward[1], -0.5);
            // Terminal obs: tile far off the table; new obs: a fresh episode (zero padded).
            let fin = &buf.final_obs[80..160];
            assert!(fin[64 + 13] > 0.5, "terminal frame has the fallen tile");
            let new = &buf.obs[80..160];
            assert!(new[..64].iter().all(|&x| x == 0.0));
            assert!((0.0..=0.15).contains(&new[64 + 13]));
            assert_eq!(v.env(1).unwrap().snapshot().step, 0);
            ended = true;
            break;
        }
    }
    assert!(ended);
    // reset_mask resets only env 2, others report their current obs.
    let mut o2 = vec![0.0; n * 80];
    let before0 = v.env(0).unwrap().snapshot();
    v.reset_mask(&[false, false, true], &mut o2).unwrap();
    assert_eq!(v.env(0).unwrap().snapshot(), before0);
    assert_eq!(&o2[..80], v.env(0).unwrap().observation());
    assert_eq!(v.env(2).unwrap().snapshot().step, 0);
    assert!(o2[160..160 + 64].iter().all(|&x| x == 0.0));
    // Errors: wrong shapes, NaN: nothing moves.
    let s0 = v.env(0).unwrap().snapshot();
    assert!(v.reset_mask(&[true], &mut o2).is_err());
    assert!(v.step_buffers(&zeros[..7], &mut buf).is_err());
    let mut bad = zeros.clone();
    bad[15] = f32::NAN;
    assert!(matches!(v.step_buffers(&bad, &mut buf), Err(SimError::NonFiniteAction { index: 1, .. })));
    assert_eq!(v.env(0).unwrap().snapshot(), s0);
    assert!(VecEnv::new(task, 0, 0, 1).is_err());
}

/// The final-observation rule: after a step, `final_obs` rows of envs that did not end are zeros,
/// whatever the buffer held before (a terminal row of an earlier step included).
#[test]
fn final_obs_rows_of_running_envs_are_zeros() {
    let task = Task::TileSuction;
    let (n, od) = (2, task.obs_dim());
    let mut v = VecEnv::new(task, n, 0, 1).unwrap();
    let mut o = vec![0.0; n * od];
    v.reset(Some(0), &mut o).unwrap();
    v.env_mut(1).unwrap().set_object_pose([0.9, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let mut buf = StepBuffers::new(task, n);
    buf.final_obs.fill(7.0);
    let zeros = vec![0.0f32; n * task.act_dim()];
    let mut seen_final = false;
    for _ in 0..40 {
        v.step_buffers(&zeros, &mut buf).unwrap();
        for i in 0..n {
            let row = &buf.final_obs[i * od..(i + 1) * od];
            if buf.has_final[i] {
                assert!(row.iter().any(|&x| x != 0.0 && x != 7.0));
                seen_final = true;
            } else {
                assert!(row.iter().all(|&x| x == 0.0), "env {i}: stale final_obs row");
            }
        }
        if seen_final {
            // The next step: env 1 runs again, its old terminal row must be gone.
            v.step_buffers(&zeros, &mut buf).unwrap();
            assert!(!buf.has_final[1]);
            assert!(buf.final_obs[od..2 * od].iter().all(|&x| x == 0.0));
            break;
        }
    }
    assert!(seen_final);
}

/// A million random-action env steps over 64 worlds: no NaN, no escaped body.
#[test]
fn million_random_steps_stay_finite() {
    for (task, steps) in
        [(Task::TileSuction, 1_000_000usize), (Task::BlockGrip, 200_000), (Task::Screw, 200_000)]
    {
        let n = 64;
        let mut v = VecEnv::new(task, n, 7, 2).unwrap();
        let mut o = vec![0.0; n * task.obs_dim()];
        v.reset(Some(0), &mut o).unwrap();
        let mut buf = StepBuffers::new(task, n);
        let acts = random_actions(task, n * 512, 11);
        let ad = task.act_dim();
        let mut episodes = 0;
        let mut rewards = [0usize; 3];
        for k in 0..steps / n {
            let b = k % 512;
            v.step_buffers(&acts[b * n * ad..(b + 1) * n * ad], &mut buf).unwrap();
            assert!(buf.obs.iter().all(|x| x.is_finite()), "{task:?} NaN obs at {k}");
            episodes += buf.has_final.iter().filter(|&&d| d).count();
            for &r in &buf.reward {
                if r > 0.0 {
                    rewards[0] += 1;
                } else if r < 0.0 {
                    rewards[1] += 1;
                }
            }
            if k % 500 == 0 {
                for i in 0..n {
                    assert!(v.env(i).unwrap().bodies_sane(), "{task:?} env {i} escaped at {k}");
                }
            }
        }
        for i in 0..n {
            assert!(v.env(i).unwrap().bodies_sane());
        }
        // Joint angles stay in [-pi, pi] (observation q part of every newest frame).
        let fd = task.obs_frame_dim();
        for i in 0..n {
            let f = &buf.obs[i * task.obs_dim() + 4 * fd..][..6];
            assert!(f.iter().all(|q| q.abs() <= std::f32::consts::PI + 1e-6));
        }
        assert!(episodes >= (steps / 750) - n, "{task:?}: episodes end ({episodes})");
        rewards[2] = episodes;
        eprintln!(
            "{task:?}: {steps} random steps, +rewards {}, -rewards {}, episodes {}",
            rewards[0], rewards[1], rewards[2]
        );
    }
}

mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Any finite action (huge, tiny, out of range) keeps the sim finite and q within [-π, π].
        #[test]
        fn any_finite_actions_keep_state_finite(
            seed in 0u64..1000,
            acts in proptest::collection::vec(proptest::collection::vec(-1e6f32..1e6f32, 8), 1..120),
            task_i in 0usize..3,
        ) {
            let task = Task::ALL[task_i];
            let mut env = Env::new(task, seed);
            let mut o = vec![0.0; task.obs_dim()];
            env.reset(Some(seed), &mut o).unwrap();
            for a in &acts {
                let r = env.step(&a[..task.act_dim()], &mut o).unwrap();
                prop_assert!(o.iter().all(|x| x.is_finite()));
                let s = env.snapshot();
                prop_assert!(s.q.iter().all(|q| q.abs() <= std::f64::consts::PI));
                prop_assert!(env.bodies_sane());
                prop_assert!([0.0f32, 1.0, 2.0, -0.5, 0.5].contains(&r.reward));
                if r.terminated || r.truncated { break; }
            }
        }
    }
}

/// Step `v` with `steps` rounds of `acts` (cycled), logging obs, rewards, flags and terminal rows.
fn run_log(v: &mut VecEnv, acts: &[f32], steps: usize) -> (Vec<u32>, usize) {
    let (task, n) = (v.task(), v.num_envs());
    let (ad, od) = (task.act_dim(), task.obs_dim());
    let rounds = acts.len() / (n * ad);
    let mut buf = StepBuffers::new(task, n);
    let mut bits = Vec::new();
    let mut ends = 0;
    for k in 0..steps {
        let b = k % rounds;
        v.step_buffers(&acts[b * n * ad..(b + 1) * n * ad], &mut buf).unwrap();
        bits.extend(buf.obs.iter().chain(&buf.reward).map(|x| x.to_bits()));
        for i in 0..n {
            bits.push(
                buf.terminated[i] as u32 | (buf.truncated[i] as u32) << 1 | (buf.has_final[i] as u32) << 2,
            );
            if buf.has_final[i] {
                ends += 1;
                bits.extend(buf.final_obs[i * od..(i + 1) * od].iter().map(|x| x.to_bits()));
            }
        }
    }
    (bits, ends)
}

/// gymnasium's contract across auto-resets: a used VecEnv reset with seed `s` follows the same
/// trajectories (auto-reset episodes included) as a fresh one reset with `s`, and `new(s)` is
/// `reset(Some(s))`.
#[test]
fn reset_with_seed_fixes_autoreset_episodes_too() {
    let task = Task::TileSuction;
    let n = 3;
    let acts = random_actions(task, n * 400, 21);
    let steps = 1600; // two truncations per env
    let mut used = VecEnv::new(task, n, 9, 2).unwrap();
    let mut o = vec![0.0; n * task.obs_dim()];
    run_log(&mut used, &random_actions(task, n * 50, 5), 900);
    used.reset_mask(&[true, false, true], &mut o).unwrap();
    used.reset(Some(77), &mut o).unwrap();
    let mut fresh = VecEnv::new(task, n, 1234, 1).unwrap();
    let mut o2 = vec![0.0; n * task.obs_dim()];
    fresh.reset(Some(77), &mut o2).unwrap();
    assert_eq!(o, o2);
    let (a, ends) = run_log(&mut used, &acts, steps);
    let (b, _) = run_log(&mut fresh, &acts, steps);
    assert!(ends >= 2 * n, "auto-resets happened ({ends})");
    assert_eq!(a, b);
    // new(s) == reset(Some(s))
    let mut born = VecEnv::new(task, n, 77, 2).unwrap();
    let (c, _) = run_log(&mut born, &acts, steps);
    assert_eq!(a, c);
    // and the episode seeds are the documented function of (base, env, episode)
    for i in 0..n {
        let e = fresh.env(i).unwrap().snapshot().episode_seed;
        assert_eq!(e, episode_seed(77, i as u64, 2), "env {i} in its third episode");
    }
    // a different seed gives different auto-reset episodes
    fresh.reset(Some(78), &mut o2).unwrap();
    let (d, _) = run_log(&mut fresh, &acts, steps);
    assert_ne!(a, d);
}

#[test]
fn episode_seeds_are_distinct_and_keep_the_documented_first_episode() {
    let mut seen = std::collections::HashSet::new();
    for base in [0u64, 1, u64::MAX] {
        assert_eq!(episode_seed(base, 5, 0), base.wrapping_add(5));
        for env in 0..64u64 {
            for ep in 1..200u64 {
                assert!(seen.insert((base, episode_seed(base, env, ep))), "{base} {env} {ep}");
            }
        }
    }
}

/// `state` + `restore` rebuild a VecEnv mid-episode exactly: the restored one continues bit for
/// bit like the original, through auto-resets.
#[test]
fn state_restore_continues_bit_for_bit() {
    for task in Task::ALL {
        let n = 3;
        let ad = task.act_dim();
        let acts = random_actions(task, n * 300, 40);
        for cut in [1usize, 333, 749, 1100] {
            let mut a = VecEnv::new(task, n, 3, 2).unwrap();
            let mut o = vec![0.0; n * task.obs_dim()];
            a.reset(Some(11), &mut o).unwrap();
            run_log(&mut a, &acts, cut);
            let st = a.state();
            let max_steps = task.spec().episode.max_steps as usize;
            assert!(st.actions.iter().all(|r| r.len() % ad == 0 && r.len() < max_steps * ad));
            let obs_then: Vec<f32> = (0..n).flat_map(|i| a.env(i).unwrap().observation().to_vec()).collect();
            let mut b = VecEnv::new(task, n, 999, 1).unwrap();
            let mut ob = vec![0.0; n * task.obs_dim()];
            b.restore(&st, &mut ob).unwrap();
            assert_eq!(ob, obs_then, "{task:?} cut {cut}: restored observations");
            assert_eq!(b.state(), st);
            let later = random_actions(task, n * 200, 41);
            let (la, _) = run_log(&mut a, &later, 900);
            let (lb, _) = run_log(&mut b, &later, 900);
            assert_eq!(la, lb, "{task:?} cut {cut}");
        }
    }
}

/// The paper's start of each seed (what a VecEnv at the default variation draws).
fn paper_starts(seeds: &[u64]) -> Vec<tile_sim::Start> {
    seeds.iter().map(|&s| tile_sim::Variation::default().start(Task::TileSuction, s)).collect()
}

#[test]
fn restore_refuses_states_that_do_not_fit() {
    let task = Task::TileSuction;
    let mut v = VecEnv::new(task, 2, 0, 1).unwrap();
    let mut o = vec![0.0; 2 * 80];
    run_log(&mut v, &random_actions(task, 2 * 10, 1), 10);
    let before = v.state();
    let seeds = vec![episode_seed(4, 0, 0), episode_seed(4, 1, 3)];
    let good = VecEnvState {
        base_seed: 4,
        episodes: vec![0, 3],
        seeds: seeds.clone(),
        starts: paper_starts(&seeds),
        actions: vec![vec![0.1; 7], vec![]],
    };
    let bad = [
        VecEnvState { episodes: vec![0], ..good.clone() },
        VecEnvState { seeds: vec![1], ..good.clone() },
        VecEnvState { starts: paper_starts(&[1]), ..good.clone() },
        VecEnvState { actions: vec![vec![0.0; 6], vec![]], ..good.clone() },
        VecEnvState { actions: vec![vec![0.0; 750 * 7], vec![]], ..good.clone() },
        VecEnvState { actions: vec![vec![f32::NAN; 7], vec![]], ..good.clone() },
    ];
    for st in &bad {
        assert!(v.restore(st, &mut o).is_err(), "{st:?}");
        assert_eq!(v.state(), before, "a refused state changes nothing");
    }
    // Recorded actions that end the episode: the scripted expert's installing episode.
    let mut e = Env::new(task, 0);
    let mut eo = vec![0.0; 80];
    e.reset(Some(episode_seed(4, 0, 0)), &mut eo).unwrap();
    let mut ex = tile_sim::expert::Expert::new(task);
    let mut rows = Vec::new();
    let mut a = [0.0f32; 7];
    loop {
        ex.act(&e.snapshot(), &mut a);
        rows.extend_from_slice(&a);
        let r = e.step(&a, &mut eo).unwrap();
        if r.terminated || r.truncated {
            assert!(r.installed, "the expert installs");
            break;
        }
    }
    let first = vec![episode_seed(4, 0, 0), episode_seed(4, 1, 0)];
    let ends = VecEnvState {
        base_seed: 4,
        episodes: vec![0, 0],
        seeds: first.clone(),
        starts: paper_starts(&first),
        actions: vec![rows.clone(), vec![]],
    };
    let err = v.restore(&ends, &mut o).unwrap_err().to_string();
    assert!(err.contains("env 0: the recorded episode ends at action"), "{err}");
    assert_eq!(v.state(), before);
    rows.truncate(rows.len() - 7); // one step before the install: a running episode
    let running = VecEnvState {
        base_seed: 4,
        episodes: vec![0, 0],
        starts: paper_starts(&first),
        seeds: first,
        actions: vec![rows, vec![]],
    };
    v.restore(&running, &mut o).unwrap();
    assert!(v.env(0).unwrap().snapshot().held);
    v.restore(&good, &mut o).unwrap();
    assert_eq!(v.state(), good);
    assert_eq!(v.env(1).unwrap().snapshot().episode_seed, episode_seed(4, 1, 3));
}

/// `reset_replay(seed, first k actions)` lands in the state that stepping a fresh episode of the
/// same seed through those actions reaches: same observation, and the same trajectory after it.
#[test]
fn reset_replay_matches_stepping_the_recorded_episode() {
    for task in [Task::TileSuction, Task::BlockGrip, Task::Screw] {
        let (ad, od) = (task.act_dim(), task.obs_dim());
        // small motions so the episode runs past the replayed prefix
        let acts: Vec<f32> = random_actions(task, 60, 5).iter().map(|a| a * 0.05).collect();
        for k in [0usize, 1, 17, 40] {
            let mut a = Env::new(task, 1);
            let mut oa = vec![0.0; od];
            a.reset(Some(1234), &mut oa).unwrap();
            for row in acts[..k * ad].chunks(ad) {
                a.step(row, &mut oa).unwrap();
            }
            let mut v = VecEnv::new(task, 3, 99, 1).unwrap();
            let mut ob = vec![0.0; od];
            let mut all = vec![0.0; 3 * od];
            v.reset(None, &mut all).unwrap();
            let other_before = all[..od].to_vec();
            assert_eq!(v.reset_replay(2, 1234, None, &acts[..k * ad], &mut ob).unwrap(), k);
            assert_eq!(oa, ob, "{task:?} k={k}: replayed observation differs");
            assert_eq!(v.env(0).unwrap().observation(), &other_before[..], "env 0 moved");
            assert_eq!(v.env(2).unwrap().snapshot().step, k as u32);
            // the continuation is the same too
            let mut env_b = Env::new(task, 1);
            env_b.reset_replay(1234, None, &acts[..k * ad], &mut ob).unwrap();
            for row in acts[k * ad..].chunks(ad) {
                let ra = a.step(row, &mut oa).unwrap();
                let rb = env_b.step(row, &mut ob).unwrap();
                assert_eq!(oa, ob);
                assert_eq!(ra.reward.to_bits(), rb.reward.to_bits());
                if ra.terminated || ra.truncated {
                    break;
                }
            }
        }
    }
}

#[test]
fn reset_replay_refuses_bad_input() {
    let task = Task::TileSuction;
    let (ad, od) = (task.act_dim(), task.obs_dim());
    let mut v = VecEnv::new(task, 2, 0, 1).unwrap();
    let mut o = vec![0.0; od];
    assert!(matches!(v.reset_replay(2, 1, None, &[], &mut o), Err(SimError::InvalidArgument(_))));
    assert!(matches!(
        v.reset_replay(0, 1, None, &vec![0.0; ad + 1], &mut o),
        Err(SimError::InvalidArgument(_))
    ));
    let mut bad = vec![0.0; ad];
    bad[3] = f32::NAN;
    assert!(matches!(v.reset_replay(0, 1, None, &bad, &mut o), Err(SimError::NonFiniteAction { .. })));
    // 750 idle steps: the episode is truncated inside the replay, which is refused
    let idle = vec![0.0; 750 * ad];
    assert!(matches!(v.reset_replay(1, 1, None, &idle, &mut o), Err(SimError::InvalidArgument(_))));
    // and the env is left at the start of that episode, steppable
    assert_eq!(v.env(1).unwrap().snapshot().step, 0);
    assert_eq!(v.env(1).unwrap().snapshot().episode_seed, 1);
}

/// A demo start (`reset_replay`) is a new episode of its env: `state` records the demo's seed and
/// the replayed actions, and `restore` rebuilds it exactly (the trainer's checkpoints rely on it).
#[test]
fn state_and_restore_keep_a_demo_start() {
    let task = Task::TileSuction;
    let (ad, od) = (task.act_dim(), task.obs_dim());
    let mut v = VecEnv::new(task, 2, 9, 1).unwrap();
    let acts: Vec<f32> = random_actions(task, 30, 3).iter().map(|a| a * 0.05).collect();
    let mut o1 = vec![0.0; od];
    v.reset_replay(1, 12345, None, &acts[..20 * ad], &mut o1).unwrap();
    let st = v.state();
    assert_eq!((st.seeds[1], st.episodes[1], st.actions[1].len()), (12345, 1, 20 * ad));
    let mut w = VecEnv::new(task, 2, 0, 1).unwrap();
    let mut o = vec![0.0; 2 * od];
    w.restore(&st, &mut o).unwrap();
    assert_eq!(&o[od..], &o1[..]);
    assert_eq!(w.state(), st);
}
