//! Prints an expert episode step by step (debug aid): `-- TASK SEED`.
use tile_sim::{Env, Task, expert::Expert};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let task = Task::from_name(&args[1]).expect("task");
    let seed: u64 = args[2].parse().expect("seed");
    let mut env = Env::new(task, 0);
    let mut obs = vec![0.0; task.obs_dim()];
    let mut act = vec![0.0; task.act_dim()];
    let mut ex = Expert::new(task);
    env.reset(Some(seed), &mut obs).expect("reset");
    for _ in 0..200 {
        ex.act(&env.snapshot(), &mut act);
        let o = env.step(&act, &mut obs).expect("step");
        let s = env.snapshot();
        println!(
            "{} ph{} obj {:.4?} tcp {:.4?} w {:.4} held {} r {}",
            s.step,
            ex.phase(),
            s.object.t,
            s.tcp.t,
            s.gripper_width,
            s.held,
            o.reward
        );
        if o.terminated || o.truncated {
            break;
        }
    }
}
