//! Debug aid: first divergence between skip and no-skip expert runs: `-- TASK SEED`.
use tile_sim::{Env, Task, expert::Expert};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let task = Task::from_name(&args[1]).expect("task");
    let seed: u64 = args[2].parse().expect("seed");
    let mut logs = Vec::new();
    for skip in [true, false] {
        let mut env = Env::new(task, 0);
        env.set_skip_idle_physics(skip);
        let mut o = vec![0.0; task.obs_dim()];
        let mut a = vec![0.0; task.act_dim()];
        let mut ex = Expert::new(task);
        env.reset(Some(seed), &mut o).expect("reset");
        let mut log = Vec::new();
        loop {
            ex.act(&env.snapshot(), &mut a);
            let r = env.step(&a, &mut o).expect("step");
            let s = env.snapshot();
            log.push((s.step, ex.phase(), s.object.t, s.held, r.reward, env.skipped_steps()));
            if r.terminated || r.truncated {
                break;
            }
        }
        logs.push(log);
    }
    for (x, y) in logs[0].iter().zip(logs[1].iter()) {
        let d = (0..3).map(|i| (x.2[i] - y.2[i]).abs()).fold(0.0, f64::max);
        if d > 1e-6 || x.3 != y.3 {
            println!("skip {:?}\nfull {:?}", x, y);
        }
    }
    println!("lens {} {}", logs[0].len(), logs[1].len());
}
