//! CPU-time cost of one env step (random actions) on one thread, from /proc/self/stat
//! (robust to other processes sharing the cores): `-- TASK STEPS`.
use rand::{RngExt, SeedableRng};
use tile_sim::{Env, Task};
fn cpu_secs() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ut: f64 = f.get(11).and_then(|v| v.parse().ok()).unwrap_or(0.0);
    let st: f64 = f.get(12).and_then(|v| v.parse().ok()).unwrap_or(0.0);
    (ut + st) / 100.0
}
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let task = Task::from_name(args.get(1).map(String::as_str).unwrap_or("TileSuction")).expect("task");
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200_000);
    let mut env = Env::new(task, 0);
    let mut obs = vec![0.0; task.obs_dim()];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let acts: Vec<f32> = (0..4096 * task.act_dim()).map(|_| rng.random_range(-1.0f32..=1.0)).collect();
    env.reset(Some(0), &mut obs).expect("reset");
    let c0 = cpu_secs();
    let t0 = std::time::Instant::now();
    let mut eps = 0;
    for k in 0..n {
        let a = &acts[(k % 4096) * task.act_dim()..][..task.act_dim()];
        let o = env.step(a, &mut obs).expect("step");
        if o.terminated || o.truncated {
            env.reset(None, &mut obs).expect("reset");
            eps += 1;
        }
    }
    let cpu = cpu_secs() - c0;
    println!(
        "{}: {:.2} cpu-us/step, {:.2} wall-us/step, {eps} episodes",
        task.name(),
        cpu * 1e6 / n as f64,
        t0.elapsed().as_secs_f64() * 1e6 / n as f64
    );
}
