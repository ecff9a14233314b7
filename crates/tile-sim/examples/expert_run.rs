//! Runs the scripted expert on N seeds of a task and prints the success rate.
//! `cargo run -p tile-sim --release --example expert_run -- TileSuction 100`
use tile_sim::{Env, Task, expert::Expert};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let task = Task::from_name(args.get(1).map(String::as_str).unwrap_or("TileSuction")).expect("task");
    let n: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100);
    let mut env = Env::new(task, 0);
    let mut obs = vec![0.0; task.obs_dim()];
    let mut act = vec![0.0; task.act_dim()];
    let mut ex = Expert::new(task);
    let (mut ok, mut picked, mut steps) = (0, 0, 0u64);
    for seed in 0..n {
        env.reset(Some(seed), &mut obs).expect("reset");
        ex.reset();
        loop {
            ex.act(&env.snapshot(), &mut act);
            let o = env.step(&act, &mut obs).expect("step");
            if o.terminated || o.truncated {
                if o.installed {
                    ok += 1;
                } else {
                    let s = env.snapshot();
                    println!(
                        "seed {seed} failed: fell={} trunc={} phase={} step={} obj={:?} tcp={:?}",
                        o.fell,
                        o.truncated,
                        ex.phase(),
                        s.step,
                        s.object.t,
                        s.tcp.t
                    );
                }
                if o.picked {
                    picked += 1;
                }
                steps += env.snapshot().step as u64;
                break;
            }
        }
    }
    println!(
        "{}: installed {ok}/{n}, picked {picked}/{n}, mean length {:.1}",
        task.name(),
        steps as f64 / n as f64
    );
}
