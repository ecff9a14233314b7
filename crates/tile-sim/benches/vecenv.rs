//! VecEnv throughput: env-steps per second with uniform random actions in [-1, 1] (the EE
//! command included), auto-resets and observation stacking included, 1 and 2 threads.
//!
//! `cargo bench -p tile-sim --bench vecenv [-- NUM_ENVS SECONDS]` (defaults 64 envs, 3 s per
//! configuration). Prints one line per (task, threads) and a machine-readable `RESULT` line,
//! then TileSuction per arm model (UR3, UR3e, UR5e, UR10e: the built-in spec with its model
//! swapped for the UR3e, `tasks/tile_suction_ur5e.toml`, `..._ur10e.toml`), 2 threads, each
//! beside the UR3 as a ratio (printed, never asserted). Last, the scripted expert's episodes of
//! TileSuction and TilePlace, one thread, one env after another (random actions seldom pick a
//! tile, and TilePlace's held tile runs the solver every step: this is the steps/s a training's
//! successful episodes cost), TilePlace beside TileSuction as a ratio.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::time::Instant;
use tile_sim::{StepBuffers, Task, TaskSpec, VecEnv};

fn run(task: Task, n: usize, threads: usize, seconds: f64) -> (f64, u64, f64) {
    run_spec(TaskSpec::builtin(task), n, threads, seconds)
}

/// TileSuction's specs per arm model: (model, spec).
fn family() -> Vec<(&'static str, Arc<TaskSpec>)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks");
    let file = |name: &str| Arc::new(TaskSpec::from_file(&dir.join(name)).expect("family spec"));
    let ur3e = TaskSpec::builtin_toml(Task::TileSuction).replace("model = \"ur3\"", "model = \"ur3e\"");
    vec![
        ("ur3", TaskSpec::builtin(Task::TileSuction)),
        ("ur3e", Arc::new(TaskSpec::from_toml(&ur3e, "tile_suction (ur3e)").expect("ur3e spec"))),
        ("ur5e", file("tile_suction_ur5e.toml")),
        ("ur10e", file("tile_suction_ur10e.toml")),
    ]
}

fn run_spec(spec: Arc<TaskSpec>, n: usize, threads: usize, seconds: f64) -> (f64, u64, f64) {
    let task = spec.task();
    let mut env = VecEnv::from_spec(spec, n, 0, threads).expect("vecenv");
    let mut obs = vec![0.0; n * task.obs_dim()];
    env.reset(Some(0), &mut obs).expect("reset");
    let mut buf = StepBuffers::new(task, n);
    // Pre-drawn random actions (256 batches, cycled) so RNG cost is not measured.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let batches: Vec<Vec<f32>> = (0..256)
        .map(|_| (0..n * task.act_dim()).map(|_| rng.random_range(-1.0f32..=1.0)).collect())
        .collect();
    // Warm-up.
    for b in batches.iter().take(20) {
        env.step_buffers(b, &mut buf).expect("step");
    }
    let mut steps = 0u64;
    let mut episodes = 0u64;
    let t0 = Instant::now();
    let mut k = 0usize;
    while t0.elapsed().as_secs_f64() < seconds {
        for _ in 0..50 {
            env.step_buffers(&batches[k % batches.len()], &mut buf).expect("step");
            episodes += buf.has_final.iter().filter(|&&d| d).count() as u64;
            k += 1;
        }
        steps += 50 * n as u64;
    }
    let rate = steps as f64 / t0.elapsed().as_secs_f64();
    let skipped: u64 = (0..n).filter_map(|i| env.env(i)).map(|e| e.skipped_steps()).sum();
    let total = steps + 20 * n as u64;
    (rate, episodes, skipped as f64 / total as f64)
}

/// Env-steps/s of the scripted expert's episodes of `task` (one env, one thread), for `seconds`;
/// also the share of episodes that succeeded.
fn run_expert(task: Task, seconds: f64) -> (f64, f64) {
    let mut env = tile_sim::Env::new(task, 0);
    let mut ex = tile_sim::expert::Expert::new(task);
    let mut obs = vec![0.0; task.obs_dim()];
    let mut a = vec![0.0; task.act_dim()];
    let (mut steps, mut episodes, mut wins) = (0u64, 0u64, 0u64);
    let mut seed = 0u64;
    env.reset(Some(seed), &mut obs).expect("reset");
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < seconds {
        ex.act(&env.snapshot(), &mut a);
        let out = env.step(&a, &mut obs).expect("step");
        steps += 1;
        if out.terminated || out.truncated {
            episodes += 1;
            wins += u64::from(out.installed);
            seed += 1;
            ex.reset();
            env.reset(Some(seed), &mut obs).expect("reset");
        }
    }
    (steps as f64 / t0.elapsed().as_secs_f64(), wins as f64 / episodes.max(1) as f64)
}

fn main() {
    let args: Vec<String> = std::env::args().filter(|a| !a.starts_with("--")).collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(64);
    let secs: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3.0);
    // Optional: a single thread count and task (for profiling), e.g. `-- 64 3 2 TileSuction`.
    let only_threads: Option<usize> = args.get(3).and_then(|s| s.parse().ok());
    let only_task = args.get(4).and_then(|s| Task::from_name(s).ok());
    println!("tile-sim VecEnv({n}) random actions, env-steps/s (physics + FK + obs stacking + auto-reset)");
    for task in Task::ALL {
        if only_task.is_some_and(|t| t != task) {
            continue;
        }
        let mut line = format!("RESULT task={}", task.name());
        for threads in [1, 2] {
            if only_threads.is_some_and(|t| t != threads) {
                continue;
            }
            let (sps, eps, idle) = run(task, n, threads, secs);
            println!(
                "  {:<12} threads={threads}: {:>10.0} env-steps/s  ({eps} episodes ended, solver skipped on {:.0} % of steps)",
                task.name(),
                sps,
                100.0 * idle
            );
            line.push_str(&format!(" threads{threads}={sps:.0}"));
        }
        println!("{line}");
    }
    if only_task.is_none() {
        println!(
            "Scripted expert episodes, 1 thread, env-steps/s (TilePlace: ratio to TileSuction in this run)"
        );
        let (suction, ws) = run_expert(Task::TileSuction, secs);
        let (place, wp) = run_expert(Task::TilePlace, secs);
        println!("  TileSuction  {suction:>10.0} env-steps/s  ({:.0} % installed)", 100.0 * ws);
        println!(
            "  TilePlace    {place:>10.0} env-steps/s  x{:.2} of TileSuction  ({:.0} % placed)",
            place / suction,
            100.0 * wp
        );
        println!("RESULT expert TileSuction={suction:.0} TilePlace={place:.0}");
    }
    if only_task.is_some_and(|t| t != Task::TileSuction) {
        return;
    }
    let threads = only_threads.unwrap_or(2);
    println!("TileSuction per arm model, threads={threads}, env-steps/s (ratio to the UR3 in this run)");
    let mut ur3 = None;
    let mut line = String::from("RESULT family");
    for (model, spec) in family() {
        let (sps, eps, _) = run_spec(spec, n, threads, secs);
        let base = *ur3.get_or_insert(sps);
        println!("  {model:<6} {sps:>10.0} env-steps/s  x{:.2} of ur3  ({eps} episodes ended)", sps / base);
        line.push_str(&format!(" {model}={sps:.0}"));
    }
    println!("{line}");
}
